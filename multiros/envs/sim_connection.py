"""A robot on a simulation node, as the env core drives it (:class:`SimConnection`).

The connection spawns the robot (and, for a task, its objects) on a node it starts or joins
(:func:`multiros.sim.launch.connect`), steps it through a :class:`~multiros.sim.stepper.RobotStepper`
(direct calls into a node composed in this process, the StepRobot service otherwise) and keeps its
latest state. In the default ``lockstep`` step mode one env step is one call: the commands queued
since the last step, ``num_sim_steps`` physics steps, the joint state and the frame poses back.

In a shared world (a vector env's batch, :mod:`multiros.envs.batch`) the robot sits in its own
**world slot**, an offset far from the others: it spawns at its spawn position plus the offset and
frame positions are reported minus it, so the env sees the numbers it would see alone. A reset
then puts back only the robot and the entities spawned into its namespace, exactly as a world
reset puts them back when they are alone.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from multiros.envs.config import SpawnPose, StepConfig
from multiros.envs.connection import STEP_OK, CameraRequest, RobotConnection, SceneEntity, StepStatus
from multiros.envs.errors import EnvError, ResetError
from multiros.envs.sensing import SensorModel
from multiros.robot_state import RobotState, RobotStates
from multiros.sim.cameras import CameraFrame
from multiros.sim.client import RobotStepSpec, SimulationClient, SimulationNodeError
from multiros.sim.launch import SimulationConnection, connect, local_description_dirs, robot_resource
from multiros.sim.stepper import RobotStepper, StepReply

__all__ = ["SimConnection", "RobotModel"]

_logger = logging.getLogger(__name__)
#: An observation camera whose first image spans at most this many levels (of 255) sees nothing of use:
#: the inside of a body, a patch of floor, the sky. The shipped views span well over 100.
_FLAT_IMAGE_LEVELS = 8

# ResetSimulation scopes (simulation_interfaces/srv/ResetSimulation).
_SCOPE_TIME, _SCOPE_STATE = 1, 2


@dataclass(frozen=True)
class RobotModel:
    """Where the robot's description comes from and how it is spawned (the base env's knobs)."""

    robot_model_xml: str | None = None
    urdf_pkg_name: str | None = None
    urdf_file_name: str | None = None
    urdf_folder: str = "/urdf"
    urdf_xacro_args: Mapping[str, Any] | Sequence[str] | None = None
    controllers_file: str | None = None
    #: the joint positions the robot is spawned (and a world reset puts it back) at; ``None``: the
    #: description's ``initial_value``, else zeros clamped into the limits.
    initial_joint_positions: Mapping[str, float] | None = None


class SimConnection(RobotConnection):
    """One robot on a simulation node (see the module docstring).

    Args:
        robot_name: the robot's entity name (the node may rename it when spawning is asked to).
        namespace: its ROS namespace.
        model: its description; ``None`` with ``spawn_robot=False`` (the robot is already there).
        spawn_pose: spawn position and orientation (before the world slot's offset).
        step_config: how one env step advances the simulation.
        reset_mode: ``"world"`` or ``"simulation"`` (also rewinds time).
        controllers_list, reset_controllers: the controllers to activate; restart them on each reset.
        frames: links or sites whose world poses each step returns.
        sim_mode, sim_node_name, transport, gui: how to reach the node (:func:`multiros.sim.launch.connect`).
        sim_timestep, real_time_factor: physics properties to set (``None`` keeps the node's).
        timeout_sec: bound on every call; max_reset_attempts: retries of the initial pose.
        shared: an open :class:`~multiros.sim.launch.SimulationConnection` to join (a batch's node):
            not closed by this connection, and its resets never touch the world.
        floor_color: the floor of a node this connection starts (``"light"``/``"dark"``); a shared
            node's is the batch's.
        world_slot: the robot's slot offset ``(x, y, z)`` in a shared world.
    """

    def __init__(
        self,
        *,
        robot_name: str,
        namespace: str,
        model: RobotModel | None,
        spawn_pose: SpawnPose,
        step_config: StepConfig,
        reset_mode: str = "world",
        controllers_list: Sequence[str] = (),
        reset_controllers: bool = False,
        frames: Sequence[str] = (),
        sim_mode: str = "composed",
        sim_node_name: str = "mujoco_sim",
        transport: str | None = None,
        gui: bool = False,
        sim_timestep: float | None = None,
        real_time_factor: float | None = None,
        timeout_sec: float = 10.0,
        max_reset_attempts: int = 3,
        shared: SimulationConnection | None = None,
        floor_color: str | None = None,
        world_slot: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.robot_name = robot_name
        self.namespace = namespace
        self.spawn_pose = spawn_pose
        self.step_config = step_config
        self.reset_mode = reset_mode
        self.controllers_list = list(controllers_list)
        self.reset_controllers = bool(reset_controllers)
        self.timeout_sec = float(timeout_sec)
        self.max_reset_attempts = int(max_reset_attempts)
        self._frames: tuple[str, ...] = tuple(frames)
        self._frame_index: dict[str, int] = {}
        self._pending: dict[str, np.ndarray] = {}
        self._state: RobotState | None = None
        self._states: RobotStates | None = None
        self._row: tuple[RobotStates, int] | None = None  # the state as row j of a step's stacked states
        self._closed = False
        slot = np.asarray(world_slot, dtype=np.float64)
        if slot.shape != (3,) or not np.all(np.isfinite(slot)):
            raise ValueError(f"world_slot must be 3 finite numbers (x, y, z), got {world_slot!r}")
        self.world_slot = slot
        self._slot: np.ndarray | None = slot if np.any(slot) else None
        self.shared = shared is not None
        if shared is not None and model is not None:  # a batch's node: this env's own robot files
            shared.trust(local_description_dirs(model.robot_model_xml, model.controllers_file))
        self.link = shared if shared is not None else connect(
            sim_mode, node_name=sim_node_name, transport=transport, gui=gui, timeout_sec=self.timeout_sec,
            floor_color=floor_color,
            trusted_paths=local_description_dirs(model.robot_model_xml, model.controllers_file) if model else ())
        try:
            self.node = self.link.node
            self.sim: SimulationClient = self.link.client
            self.stepper: RobotStepper = self.link.stepper(self.timeout_sec)
            if sim_timestep is not None or real_time_factor is not None:
                self.sim.set_physics_properties(time_step=sim_timestep, real_time_factor=real_time_factor)
            if step_config.mode == "lockstep":
                self.sim.pause()
            if model is not None:
                self._spawn_robot(model)
            if step_config.mode == "realtime":
                self.sim.unpause()  # physics runs free; the env acts and observes at its own pace
            self.refresh(0)
        except BaseException:
            if not self.shared:
                self.link.close()
            raise

    # -- set-up --------------------------------------------------------------------------------
    def _spawn_robot(self, model: RobotModel) -> None:
        uri, text = robot_resource(
            robot_model_xml=model.robot_model_xml, urdf_pkg_name=model.urdf_pkg_name,
            urdf_file_name=model.urdf_file_name, urdf_folder=model.urdf_folder, xacro_args=model.urdf_xacro_args,
            controllers_file=model.controllers_file, controllers_list=self.controllers_list or None,
            joint_positions=model.initial_joint_positions)
        self.robot_name = self.sim.spawn_entity(
            self.robot_name, uri=uri, resource_string=text, namespace=self.namespace,
            position=tuple(self.to_world(np.asarray(self.spawn_pose.position, dtype=np.float64))),
            orientation=self.spawn_pose.orientation, timeout_sec=max(self.timeout_sec, 30.0))

    def spawn_entity(self, name: str, uri: str, position: Sequence[float] | np.ndarray,
                     orientation: Sequence[float] | np.ndarray = (1.0, 0.0, 0.0, 0.0), *,
                     resource_string: str = "") -> str:
        """Spawn an object of the robot's task (a table, a cube) into the robot's namespace, at a
        position in the robot's frame of the world (its slot's offset added): a shared-world reset
        puts it back with the robot. ``resource_string``: its MJCF or URDF text instead of ``uri``."""
        return self.sim.spawn_entity(name, uri=uri, resource_string=resource_string, namespace=self.namespace,
                                     position=tuple(self.to_world(np.asarray(position, dtype=np.float64))),
                                     orientation=tuple(orientation), timeout_sec=max(self.timeout_sec, 30.0))

    def place_entity(self, name: str, position: Sequence[float] | np.ndarray,
                     orientation: Sequence[float] | np.ndarray = (1.0, 0.0, 0.0, 0.0)) -> None:
        """Teleport an entity (at rest) to a pose in the robot's frame of the world."""
        self.sim.set_entity_pose(name, tuple(self.to_world(np.asarray(position, dtype=np.float64))),
                                 tuple(orientation))

    @property
    def base_position(self) -> np.ndarray:
        """Where the robot was spawned, in the env's frame of the world."""
        return np.asarray(self.spawn_pose.position, dtype=np.float64).copy()

    def add_scene(self, entities: Sequence[SceneEntity]) -> None:
        """Spawn the entities in order into the robot's namespace (a shared world's reset puts them back
        with the robot) and ask every step for their frames too."""
        for entity in entities:
            self.spawn_entity(entity.name, "" if entity.mjcf else entity.uri, entity.position,
                              resource_string=entity.mjcf)
        self.add_frames(tuple(entity.frame for entity in entities))
        self.refresh(0)

    def reset_gripper(self, controller: str, joints: Sequence[str], positions: Sequence[float]) -> None:
        """Teleport the gripper's joints to ``positions`` and hold them there."""
        self.set_joint_positions(joints, positions)

    def to_world(self, position: np.ndarray) -> np.ndarray:
        """A position in the env's own frame of the world as the shared world has it (slot added)."""
        return position if self._slot is None else position + self._slot

    def add_frames(self, frames: Sequence[str]) -> None:
        """Ask every step for these frames' poses too (e.g. ``"<object entity>/<link>"``)."""
        self._frames = (*self._frames, *frames)
        self._frame_index = {}

    # -- state ---------------------------------------------------------------------------------
    @property
    def state(self) -> RobotState:
        state = self._state
        if state is None:
            if self._row is None:
                raise EnvError("no robot state yet: was the robot spawned?")
            stacked, j = self._row
            state = self._state = stacked.row(j)
        return state

    @property
    def states(self) -> RobotStates:
        """:attr:`state` as a batch of one (its arrays are views of the state's)."""
        states = self._states
        if states is None:
            if self._row is not None:
                stacked, j = self._row
                states = RobotStates(stacked.sim_time, stacked.names, stacked.position[j:j + 1],
                                     stacked.velocity[j:j + 1], stacked.effort[j:j + 1],
                                     stacked.frame_positions[j:j + 1], stacked.frame_orientations[j:j + 1])
            else:
                s = self.state
                states = RobotStates(s.sim_time, s.names, s.position[None], s.velocity[None], s.effort[None],
                                     s.frame_positions[None], s.frame_orientations[None])
            self._states = states
        return states

    @property
    def frames(self) -> tuple[str, ...]:
        return self._frames

    def frame_index(self, frame: str) -> int:
        index = self._frame_index
        if not index:
            index = self._frame_index = {name: i for i, name in enumerate(self._frames)}
        try:
            return index[frame]
        except KeyError:
            raise EnvError(f"frame {frame!r} is not in this env's frames {self._frames}; add it to `frames` so each "
                           "step returns it") from None

    # -- randomisation (rl_environments.randomization draws it per episode) ---------------------
    #: What the robot's sensors add to the truth (:mod:`multiros.envs.sensing`); ``None``: the truth.
    sensors: SensorModel | None = None

    @property
    def control_period(self) -> float:
        """Seconds of simulated time one env step advances (lockstep: ``num_sim_steps`` physics steps)."""
        period = self.__dict__.get("_control_period")
        if period is None:
            period = self.step_config.num_sim_steps * float(self.sim.get_physics_properties()["time_step"])
            self.__dict__["_control_period"] = period
        return float(period)

    def set_entity_properties(self, entity: str, rows: Sequence[tuple[str, str, str, float]], *,
                              restore: bool = False) -> int:
        """Set physical properties of the robot or one of its task's entities apart from their description
        (:mod:`multiros.sim.entity_properties`); ``restore`` first puts back the spawned values."""
        return self.sim.set_entity_properties(entity, rows, restore=restore)

    # -- the step seam (a batch steps many connections in one call) ---------------------------
    def step_spec(self, reset: bool = False) -> RobotStepSpec:
        """This robot's part of a step call: its queued commands (handed over) and its frames."""
        commands, self._pending = self._pending, {}
        return RobotStepSpec(self.robot_name, commands, self._frames, reset)

    def accept(self, state: RobotState) -> None:
        """Make ``state`` (this robot's part of a step's reply) the one the env reads: frame positions
        are made relative to the world slot, in place (the reply's arrays are fresh)."""
        if self._slot is not None and len(state.frame_positions):
            np.subtract(state.frame_positions, self._slot, out=state.frame_positions)
        if self.sensors is not None:
            self.sensors.apply(state.position, state.frame_positions, state.sim_time)
        self._state, self._states, self._row = state, None, None

    def refresh(self, steps: int = 0) -> StepStatus:
        """One call for this robot alone: its queued commands, ``steps`` physics steps, its state."""
        reply = self.stepper.step([self.step_spec()], steps)
        return self.accept_reply(reply, 0)

    def accept_reply(self, reply: StepReply, j: int) -> StepStatus:
        """Take robot ``j``'s part of a step reply; its status (an unknown robot raises). From a
        reply whose states are stacked, the state stays row ``j`` of them (read as such by a
        batch-first task, made a :class:`~multiros.robot_state.RobotState` only when asked)."""
        stacked = reply.stacked
        if stacked is not None:
            if self._slot is not None and stacked.frame_positions.shape[1]:
                np.subtract(stacked.frame_positions[j], self._slot, out=stacked.frame_positions[j])
            if self.sensors is not None:
                self.sensors.apply(stacked.position[j], stacked.frame_positions[j], stacked.sim_time)
            self._row, self._state = (stacked, j), None
            self._states = stacked if len(stacked) == 1 else None
        else:
            state = reply.states[j]
            if state is None:
                raise EnvError(f"robot {self.robot_name!r} is gone from the simulation node ({reply.message[j]}); "
                               "close this env and make a new one")
            self.accept(state)
        code = reply.status[j]
        return STEP_OK if code == 0 else StepStatus(code, reply.message[j])

    # -- acting and stepping -------------------------------------------------------------------
    def command_arm(self, controller: str, targets: np.ndarray, info: dict[str, Any]) -> None:
        """The arm's targets, as its encoders read (with calibration offsets, the model's frame differs)."""
        sensors = self.sensors
        if sensors is not None and sensors.offsets.any():
            targets = targets - sensors.offsets
        self.command(controller, targets)

    def command(self, controller: str, values: np.ndarray) -> None:
        """Queue a controller command: it travels with the next step (lockstep), or is applied at
        once in the other step modes."""
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim != 1 or not all(map(math.isfinite, arr.tolist())):  # Python floats: a tenth of numpy's time
            raise ValueError(f"command for controller {controller!r} must be a 1-D finite vector, got {values!r}")
        self._pending[controller] = arr
        if self.step_config.mode != "lockstep":
            self.refresh(0)

    def advance(self, info: dict[str, Any]) -> StepStatus:
        mode = self.step_config.mode
        if mode == "lockstep":
            return self.refresh(self.step_config.num_sim_steps)
        if mode == "pause_unpause":
            self.sim.unpause()
            _wait_wall(self.step_config.action_cycle_time)
            self.sim.pause()
        else:
            _wait_wall(self.step_config.action_cycle_time)
        return self.refresh(0)

    # -- episodes -------------------------------------------------------------------------------
    def reset(self, info: dict[str, Any]) -> None:
        self._pending = {}
        if self.shared:  # other envs' robots share this world: put back only this robot and its objects
            reply = self.stepper.step([RobotStepSpec(self.robot_name, None, self._frames, True)], 0)
            self.accept_reply(reply, 0)
            return
        scope = _SCOPE_STATE if self.reset_mode == "world" else _SCOPE_STATE | _SCOPE_TIME
        self.sim.reset_simulation(scope)
        if self.reset_controllers:
            self.sim.reset_controllers(self.namespace, self.controllers_list or None)

    def start_episode(self, info: dict[str, Any]) -> None:
        if self.sensors is not None:
            self.sensors.forget()  # the tracker's first reading of the episode: the object where it was placed
        self.refresh(0)

    def set_joint_positions(self, names: Sequence[str], positions: npt.ArrayLike, hold: bool = True) -> None:
        """Teleport joints (e.g. to the episode's initial pose); ``hold`` keeps them there."""
        self.sim.set_robot_joint_state(self.robot_name, names, np.asarray(positions, dtype=np.float64), hold=hold)

    def move_to_initial_pose(self, names: Sequence[str], positions: npt.ArrayLike, tolerance: float = 1e-3) -> None:
        """Teleport joints and check they arrived, retrying up to ``max_reset_attempts`` times."""
        target = np.asarray(positions, dtype=np.float64)
        index = {name: i for i, name in enumerate(self.state.names)}
        try:
            idx = [index[n] for n in names]
        except KeyError as exc:
            raise EnvError(f"robot {self.robot_name!r} has no joint {exc.args[0]!r}; joints: "
                           f"{self.state.names}") from None
        error = np.inf
        truth, sensors = target, self.sensors
        if sensors is not None:  # the pose as the encoders read it: the model's is off by their offsets
            truth = sensors.to_model(idx, target)
            tolerance = max(tolerance, 5.0 * sensors.joint_noise)
        for _ in range(self.max_reset_attempts):
            self.set_joint_positions(names, truth, hold=True)
            self.refresh(0)
            error = float(np.max(np.abs(self.state.position[idx] - target)))
            if error <= tolerance:
                return
        raise ResetError(
            f"robot {self.robot_name!r} did not reach its initial pose {target.tolist()} for joints {list(names)} "
            f"after {self.max_reset_attempts} attempts (max error {error:.4g}); check the pose is within the joint "
            "limits")

    # -- rendering and closing ------------------------------------------------------------------
    def render(self, camera: str, width: int, height: int, depth: bool) -> np.ndarray:
        """An image of the scene from ``camera`` (HxWx3 uint8, or HxW float32 metres with ``depth``)."""
        return self.sim.render(camera, width, height, depth=depth)

    def read_camera(self, camera: str, *, rgb: bool = True, depth: bool = False, width: int | None = None,
                    height: int | None = None, max_age: float | None = None) -> CameraFrame:
        """A camera sensor's images of the world after the last step (a camera observation): from a
        composed node the very pixels its Image topics carry for this state, without messages; from
        another process through its RenderCamera service
        (:meth:`~multiros.sim.launch.SimulationConnection.read_camera`). ``max_age`` is the real
        connection's (how old a driver's image may be); a rendered image is of the state now.

        Raises:
            multiros.sim.errors.RenderError: an unknown camera, a bad size, or no offscreen GL (the
                message says to set ``MUJOCO_GL=egl`` or ``osmesa``).
        """
        frame: CameraFrame = self.link.read_camera(camera, rgb=rgb, depth=depth, width=width, height=height)
        return frame

    def open_camera(self, request: CameraRequest) -> tuple[str, tuple[int, int]]:
        """A camera of the world to observe through: the named one (``"<camera>"`` of the robot, or
        ``"<entity>/<camera>"``), or the view camera spawned into the robot's namespace at the request's
        place (``<namespace>/camera/...`` topics); a first image is rendered now.

        Raises:
            multiros.sim.errors.RenderError: the camera cannot render (unknown, bad size, no offscreen GL).
        """
        from multiros.sim.errors import RenderError
        from multiros.sim.view_camera import VIEW_CAMERA, camera_entity_urdf

        if request.name is not None:
            name = request.name.strip("/")
            source = name if "/" in name else f"{self.robot_name}/{name}"
        else:
            if request.position is None or request.lookat is None or request.width is None or request.height is None:
                raise ValueError("the view camera needs its position, lookat, width and height")
            text = camera_entity_urdf(request.position, request.lookat, request.width, request.height, request.fovy,
                                      self.namespace)
            entity = self.sim.spawn_entity(
                f"{self.robot_name}_{VIEW_CAMERA}", uri="", resource_string=text,
                namespace=f"{self.namespace.rstrip('/')}/{VIEW_CAMERA}_mount",
                position=tuple(self.to_world(np.asarray(request.position, dtype=np.float64))),
                timeout_sec=max(self.timeout_sec, 30.0))
            source = f"{entity}/{VIEW_CAMERA}"
        try:
            frame = self.read_camera(source, rgb=True, depth=False, width=request.width, height=request.height)
        except RenderError as exc:
            raise RenderError(f"robot {self.robot_name!r}: the observation camera {source!r} cannot render: "
                              f"{exc}") from exc
        assert frame.rgb is not None
        if frame.rgb.size and int(frame.rgb.max()) - int(frame.rgb.min()) <= _FLAT_IMAGE_LEVELS:
            _logger.warning("robot %r: the observation camera %r sees almost one colour in its first image (levels "
                            "%d-%d): is it inside a body, or looking away from the robot? (camera_position=, "
                            "camera_lookat=, camera_fovy=)", self.robot_name, source,
                            int(frame.rgb.min()), int(frame.rgb.max()))
        return source, (int(frame.rgb.shape[0]), int(frame.rgb.shape[1]))

    def show_viewer(self) -> None:
        self.link.show_viewer()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if not self.shared:
            try:
                self.link.close()
            except SimulationNodeError:
                _logger.warning("simulation node did not close cleanly", exc_info=True)


def _wait_wall(seconds: float) -> None:
    # Acting then observing after a fixed control period is the real-time control loop itself,
    # not a wait for readiness: this is the one place a timed wait is the specification.
    deadline = time.monotonic() + seconds
    while (remaining := deadline - time.monotonic()) > 0:
        time.sleep(min(remaining, 0.05))
