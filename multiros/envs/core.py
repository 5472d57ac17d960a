"""What MujocoBaseEnv and MujocoGoalEnv share: the connection to the simulation node, spawning,
resetting, stepping, and the hook dispatch.

The environment never touches MuJoCo: it drives the simulation node through
:class:`multiros.sim.client.SimulationClient`, i.e. through ROS 2 services. In the default
``lockstep`` step mode one env step is one ``StepRobot`` round trip: the commands that
``_set_action`` queued, ``num_sim_steps`` physics steps, and the robot's joint state and frame poses
back. Observation hooks read that cached state (``self.joint_positions``, ``self.frame_position``)
without further calls.

Hooks (one canonical set; MultiROS and FRobs_RL spellings are accepted, see ``docs/envs.md``):

* robot layer: ``_check_connection_and_readiness()``, ``_set_episode_init_params()``,
  ``_check_if_done()``;
* task layer: ``_set_init_pose()``, ``_set_action(action)``, ``_get_obs()``, ``_check_if_done()``,
  ``_get_reward()`` (plain envs) or ``_compute_reward(achieved_goal, desired_goal, info)`` (goal envs).
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.envs.config import SpawnPose, StepConfig, parse_reset_mode, parse_step_mode
from multiros.envs.errors import EnvError, ResetError
from multiros.envs.joint_access import JointStateAccess
from multiros.sim.client import RobotState, SimulationClient, SimulationNodeError

_logger = logging.getLogger(__name__)

# ResetSimulation scopes (simulation_interfaces/srv/ResetSimulation).
_SCOPE_TIME, _SCOPE_STATE = 1, 2


@functools.lru_cache(maxsize=1024)
def _hook_name(cls: type, base: type, names: tuple[str, ...]) -> str | None:
    """Which of ``names`` (aliases of one hook) ``cls`` implements below ``base``.

    The most derived class that defines any alias wins, so a task env's MultiROS-named hook is not
    hidden by a robot env's canonically named one; within one class the canonical name wins.
    Classes are immutable for this purpose, so the answer is cached per class.
    """
    for klass in cls.__mro__:
        if klass is base:
            return None
        for name in names:
            if name in vars(klass):
                return name
    return None


class MujocoEnvCore(JointStateAccess):
    """Machinery shared by :class:`MujocoBaseEnv` and :class:`MujocoGoalEnv`.

    Args:
        spawn_robot: spawn the robot described below when the env starts.
        robot_name: entity name of the robot in the simulation (MultiROS: ``robot_model_name``).
        robot_model_xml: a URDF, xacro or MJCF file path / ``package://`` URI, or the text itself.
        urdf_pkg_name, urdf_file_name, urdf_folder: MultiROS-style location of the description
            (``package://<pkg><folder>/<file>``), used when ``robot_model_xml`` is not given.
        urdf_xacro_args: xacro arguments, as a ``{"name": "value"}`` dict or ``["name:=value"]`` list.
        namespace: the robot's ROS namespace (controllers, ``joint_states``); default ``/<robot_name>``.
        robot_pos_x, robot_pos_y, robot_pos_z: spawn position in the world.
        robot_ori_w, robot_ori_x, robot_ori_y, robot_ori_z: spawn orientation; identity by default.
        controllers_file: a ros2_control controllers YAML (path or ``package://``) overriding the one
            the description names.
        controllers_list: controllers to activate (default: what the YAML configures).
        reset_controllers: restart the controllers on every reset.
        reset_mode: ``"world"`` (state only; sim time keeps running) or ``"simulation"`` (state and time).
        step_mode: ``"lockstep"`` (default), ``"pause_unpause"`` or ``"realtime"``; MultiROS' 1/2 accepted.
        num_sim_steps: physics steps per env step in lockstep mode (MultiROS: ``num_gazebo_steps``).
        action_cycle_time: seconds between acting and observing in the other step modes.
        sim_timestep: physics time step in seconds (``None`` keeps the node's).
        real_time_factor: real-time factor of the ``realtime`` mode (1.0 = wall clock, <= 0 = as fast
            as possible).
        frames: robot links or sites whose world poses each step returns (e.g. the end effector).
        sim_mode: ``"composed"`` (node in this process, the fast default), ``"process"`` (a child
            process over Zenoh) or ``"existing"`` (connect to a running node named ``sim_node_name``).
        sim_node_name: the simulation node's name.
        transport: ``"inproc"`` or ``"zenoh"`` (default: inproc when composed, zenoh otherwise).
        gui: open the MuJoCo viewer (composed or child-process node, when a display exists).
        seed: seed for the first reset only; later resets continue the same random stream.
        timeout_sec: bound on every call to the node.
        max_reset_attempts: how often a reset may retry reaching the initial pose.
        render_mode: ``None``, ``"rgb_array"``, ``"depth_array"`` or ``"human"``.
        render_camera: camera for rendering (a camera name in the world; empty = the default view).
        render_width, render_height: rendered image size.
        sim_connection: a :class:`~multiros.sim.launch.SimulationConnection` shared with other envs
            (a vector env's batch, see :mod:`multiros.envs.batch`): the env spawns its robot there,
            does not close the connection, and its reset puts back only its own robot, never the world.
        world_slot: offset ``(x, y, z)`` in metres of this env's slot in a shared world: the robot spawns
            at its spawn position plus the offset and frame positions are reported minus it, so the
            task sees the same numbers as alone in its own world.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "depth_array", "human"], "render_fps": 25}

    # -- pickling: an env is re-created from its constructor arguments, as Gymnasium's MuJoCo envs
    # (EzPickle) are; the copy has its own simulation node and starts from a fresh reset.
    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        self = super().__new__(cls)
        self._ctor_args = (args, dict(kwargs))
        return self

    def __getstate__(self) -> dict[str, Any]:
        args, kwargs = getattr(self, "_ctor_args", ((), {}))
        if kwargs.get("sim_mode") == "existing" or kwargs.get("sim_connection") is not None:
            raise TypeError(
                f"{type(self).__name__} with sim_mode='existing' cannot be pickled or copied: a copy would spawn "
                "a second robot into the same running simulation node; create another env instead"
            )
        return {"_ctor_args": (args, kwargs)}

    def __setstate__(self, state: dict[str, Any]) -> None:
        args, kwargs = state["_ctor_args"]
        self.__dict__.update(type(self)(*args, **kwargs).__dict__)

    def _init_core(
        self,
        *,
        spawn_robot: bool = True,
        robot_name: str = "robot",
        robot_model_xml: str | None = None,
        urdf_pkg_name: str | None = None,
        urdf_file_name: str | None = None,
        urdf_folder: str = "/urdf",
        urdf_xacro_args: Mapping[str, Any] | Sequence[str] | None = None,
        namespace: str | None = None,
        robot_pos_x: float = 0.0,
        robot_pos_y: float = 0.0,
        robot_pos_z: float = 0.0,
        robot_ori_w: float = 1.0,
        robot_ori_x: float = 0.0,
        robot_ori_y: float = 0.0,
        robot_ori_z: float = 0.0,
        controllers_file: str | None = None,
        controllers_list: Sequence[str] | None = None,
        reset_controllers: bool = False,
        reset_mode: Any = "world",
        step_mode: Any = "lockstep",
        num_sim_steps: int = 20,
        action_cycle_time: float = 0.0,
        sim_timestep: float | None = None,
        real_time_factor: float | None = None,
        frames: Sequence[str] = (),
        sim_mode: str = "composed",
        sim_node_name: str = "mujoco_sim",
        transport: str | None = None,
        gui: bool = False,
        seed: int | None = None,
        timeout_sec: float = 10.0,
        max_reset_attempts: int = 3,
        render_mode: str | None = None,
        render_camera: str = "",
        render_width: int = 480,
        render_height: int = 480,
        sim_connection: Any = None,
        world_slot: Sequence[float] = (0.0, 0.0, 0.0),
        **legacy: Any,
    ) -> None:
        # MultiROS / FRobs_RL spellings of the same knobs.
        renames = {
            "robot_model_name": "robot_name",
            "model_name_in_gazebo": "robot_name",
            "num_gazebo_steps": "num_sim_steps",
            "sim_step_mode": "step_mode",
            "gazebo_timestep": "sim_timestep",
            "gazebo_max_update_rate": "real_time_factor",
            "ros_controllers_list": "controllers_list",
            "controller_list": "controllers_list",
            "controller_file": "controllers_file",
            "pkg_name": "urdf_pkg_name",
            "urdf_file": "urdf_file_name",
            "model_pos_x": "robot_pos_x",
            "model_pos_y": "robot_pos_y",
            "model_pos_z": "robot_pos_z",
            "model_ori_w": "robot_ori_w",
            "model_ori_x": "robot_ori_x",
            "model_ori_y": "robot_ori_y",
            "model_ori_z": "robot_ori_z",
        }
        given = dict(locals())
        for old, new in renames.items():
            if old in legacy:
                given[new] = legacy.pop(old)
        # Knobs of the Gazebo originals that have no meaning here (ROS master ports, xterms, ...).
        ignored = {
            "launch_gazebo", "gazebo_init_paused", "gazebo_use_gui", "ros_port", "gazebo_port",
            "gazebo_pid", "kill_rosmaster", "kill_gazebo", "clean_logs", "new_robot_state_term",
            "robot_state_publisher_max_freq", "robot_ref_frame", "unpause_pause_physics",
            "log_internal_state",
        }
        unknown = sorted(set(legacy) - ignored)
        if unknown:
            raise TypeError(
                f"{type(self).__name__} got unexpected keyword argument(s) {unknown}; "
                "see multiros.envs.core.MujocoEnvCore for the accepted knobs"
            )
        if legacy:
            _logger.debug("ignoring Gazebo-only knobs %s", sorted(legacy))

        self.robot_name: str = given["robot_name"]
        ns = given["namespace"]
        self.namespace: str = ("/" + self.robot_name) if ns in (None, "", "/") else "/" + ns.strip("/")
        self.spawn_pose = SpawnPose(
            (given["robot_pos_x"], given["robot_pos_y"], given["robot_pos_z"]),
            (given["robot_ori_w"], given["robot_ori_x"], given["robot_ori_y"], given["robot_ori_z"]),
        )
        self.step_config = StepConfig(
            parse_step_mode(given["step_mode"]), int(given["num_sim_steps"]), float(given["action_cycle_time"])
        )
        self.reset_mode = parse_reset_mode(given["reset_mode"])
        self.reset_controllers = bool(given["reset_controllers"])
        self.controllers_list = list(given["controllers_list"] or [])
        self.frames: tuple[str, ...] = tuple(given["frames"])
        self.timeout_sec = float(timeout_sec)
        self.max_reset_attempts = int(max_reset_attempts)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self._render_options = (render_camera, int(render_width), int(render_height))
        self._pending_seed = seed
        self._pending_commands: dict[str, np.ndarray] = {}
        self._state: RobotState | None = None
        self._frame_index: dict[str, int] = {}
        self._set_joint_order(())
        self._action_bounds: tuple[Any, np.ndarray, np.ndarray] | None = None
        self._closed = False
        self.info: dict[str, Any] = {}
        slot = np.asarray(world_slot, dtype=np.float64)
        if slot.shape != (3,) or not np.all(np.isfinite(slot)):
            raise ValueError(f"world_slot must be 3 finite numbers (x, y, z), got {world_slot!r}")
        self._slot: np.ndarray | None = slot if np.any(slot) else None
        self._shared_world = sim_connection is not None

        from multiros.sim.launch import connect, local_description_dirs  # the sim layer sits above envs (DESIGN §2)

        self._connection = sim_connection if sim_connection is not None else connect(
            sim_mode,
            node_name=sim_node_name,
            transport=transport,
            gui=gui,
            timeout_sec=self.timeout_sec,
            trusted_paths=local_description_dirs(given["robot_model_xml"], given["controllers_file"])
            if spawn_robot else (),
        )
        try:
            self.node = self._connection.node
            self.sim: SimulationClient = self._connection.client
            if sim_timestep is not None or real_time_factor is not None:
                self.sim.set_physics_properties(time_step=sim_timestep, real_time_factor=real_time_factor)
            if self.step_config.mode == "lockstep":
                self.sim.pause()
            if spawn_robot:
                self._spawn(given)
            if self.step_config.mode == "realtime":
                self.sim.unpause()  # physics runs free; the env acts and observes at its own pace
            self._refresh_state()
        except BaseException:
            if not self._shared_world:
                self._connection.close()
            raise

    # -- set-up -----------------------------------------------------------------------------
    def _spawn(self, given: Mapping[str, Any]) -> None:
        from multiros.sim.launch import robot_resource

        uri, text = robot_resource(
            robot_model_xml=given["robot_model_xml"],
            urdf_pkg_name=given["urdf_pkg_name"],
            urdf_file_name=given["urdf_file_name"],
            urdf_folder=given["urdf_folder"],
            xacro_args=given["urdf_xacro_args"],
            controllers_file=given["controllers_file"],
            controllers_list=self.controllers_list or None,
        )
        self.robot_name = self.sim.spawn_entity(
            self.robot_name,
            uri=uri,
            resource_string=text,
            namespace=self.namespace,
            position=tuple(np.add(self.spawn_pose.position, 0.0 if self._slot is None else self._slot)),
            orientation=self.spawn_pose.orientation,
            timeout_sec=max(self.timeout_sec, 30.0),
        )

    # -- state access for hooks -------------------------------------------------------------
    def _refresh_state(self, steps: int = 0) -> RobotState:
        """One ``StepRobot`` round trip: pending commands, ``steps`` physics steps, fresh state."""
        commands, self._pending_commands = self._pending_commands, {}
        return self._accept_state(self.sim.step_robot(self.robot_name, commands, steps, self.frames))

    def _accept_state(self, state: RobotState) -> RobotState:
        """Make ``state`` (from StepRobot, or a vector env's StepRobots) the one hooks read."""
        if self._slot is not None and len(state.frame_positions):
            # a fresh array per state: made relative to this env's slot in place
            np.subtract(state.frame_positions, self._slot, out=state.frame_positions)
        if self._state is None or state.names != self._state.names:
            self._set_joint_order(state.names)
        if not self._frame_index:
            self._frame_index = {name: i for i, name in enumerate(self.frames)}
        self._state = state
        return state

    @property
    def robot_state(self) -> RobotState:
        """The robot's state after the last step or reset."""
        if self._state is None:
            raise EnvError("no robot state yet: was the robot spawned?")
        return self._state

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of all the robot's joints, in the order of the joint arrays."""
        return self.robot_state.names

    def frame_position(self, frame: str) -> np.ndarray:
        """World position of a frame listed in ``frames``."""
        return self.robot_state.frame_positions[self._frame(frame)].copy()

    def frame_orientation(self, frame: str) -> np.ndarray:
        """World orientation ``(w, x, y, z)`` of a frame listed in ``frames``."""
        return self.robot_state.frame_orientations[self._frame(frame)].copy()

    def _frame(self, frame: str) -> int:
        try:
            return self._frame_index[frame]
        except KeyError:
            raise EnvError(
                f"frame {frame!r} is not in this env's frames {self.frames}; add it to `frames` so each step returns it"
            ) from None

    @property
    def sim_time(self) -> float:
        """Simulation time in seconds after the last step."""
        return self.robot_state.sim_time

    # -- acting -----------------------------------------------------------------------------
    def send_command(self, controller: str, command: Sequence[float] | np.ndarray) -> None:
        """Command a controller of the robot.

        In lockstep mode the command travels with the next step's ``StepRobot`` request; in the
        other modes it is applied at once.
        """
        values = np.asarray(command, dtype=np.float64)
        if values.ndim != 1 or not np.isfinite(values).all():
            raise ValueError(f"command for controller {controller!r} must be a 1-D finite vector, got {command!r}")
        self._pending_commands[controller] = values
        if self.step_config.mode != "lockstep":
            self._refresh_state(0)

    def set_joint_positions(self, names: Sequence[str], positions: Sequence[float], hold: bool = True) -> None:
        """Teleport joints (e.g. to the episode's initial pose); ``hold`` keeps them there."""
        self.sim.set_robot_joint_state(self.robot_name, names, positions, hold=hold)

    def move_to_initial_pose(self, names: Sequence[str], positions: Sequence[float], tolerance: float = 1e-3) -> None:
        """Teleport joints and check they arrived, retrying up to ``max_reset_attempts`` times.

        Raises:
            ResetError: the joints did not reach ``positions`` within ``tolerance``.
        """
        target = np.asarray(positions, dtype=np.float64)
        error = np.inf
        for _ in range(self.max_reset_attempts):
            self.set_joint_positions(names, target, hold=True)
            self._refresh_state(0)
            error = float(np.max(np.abs(self.joint_positions(names) - target)))
            if error <= tolerance:
                return
        raise ResetError(
            f"robot {self.robot_name!r} did not reach its initial pose {target.tolist()} for joints {list(names)} "
            f"after {self.max_reset_attempts} attempts (max error {error:.4g}); "
            "check the pose is within the joint limits"
        )

    def _advance(self) -> None:
        mode = self.step_config.mode
        if mode == "lockstep":
            self._refresh_state(self.step_config.num_sim_steps)
            return
        if mode == "pause_unpause":
            self.sim.unpause()
            self._wait_wall(self.step_config.action_cycle_time)
            self.sim.pause()
        else:
            self._wait_wall(self.step_config.action_cycle_time)
        self._refresh_state(0)

    @staticmethod
    def _wait_wall(seconds: float) -> None:
        # Acting then observing after a fixed control period is the real-time control loop itself,
        # not a wait for readiness: this is the one place a timed wait is the specification.
        deadline = time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0:
            time.sleep(min(remaining, 0.05))

    def _check_action(self, action: Any) -> np.ndarray:
        """Refuse NaN/infinite values and wrong shapes; clip a Box action into its bounds."""
        space = self.action_space
        if isinstance(space, spaces.Box):
            low, high = self._box_action_bounds()
            arr = np.asarray(action, dtype=np.float64)
            if arr.shape != space.shape:
                raise ValueError(f"action shape {arr.shape} does not match the action space {space.shape}")
            if not np.isfinite(arr).all():
                raise ValueError(f"action contains NaN or infinite values: {arr}")
            return np.minimum(np.maximum(arr, low), high)
        if not space.contains(action):
            raise ValueError(f"action {action!r} is not in the action space {space}")
        return np.asarray(action)

    def _box_action_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The Box action space's bounds as float64 arrays (cached per space object)."""
        space = self.action_space
        bounds = self._action_bounds
        if bounds is None or bounds[0] is not space:  # the space may be replaced after __init__
            bounds = self._action_bounds = (space, space.low.astype(np.float64), space.high.astype(np.float64))
        return bounds[1], bounds[2]

    # -- hook dispatch ----------------------------------------------------------------------
    def _hook(self, base: type, *names: str) -> Any:
        """The bound hook a subclass implements under one of ``names`` (see :func:`_hook_name`), or ``None``."""
        name = _hook_name(type(self), base, names)
        return None if name is None else getattr(self, name)

    @classmethod
    def _hook_implemented(cls, base: type, *names: str) -> str | None:
        """Which of ``names`` (aliases of one hook) this class implements below ``base``, or ``None``."""
        return _hook_name(cls, base, names)

    def _run_reset_hooks(self, base: type, options: dict[str, Any] | None) -> None:
        ready = self._hook(base, "_check_connection_and_readiness", "_check_subs_and_pubs_connection")
        if ready is not None and ready() is False:
            raise EnvError(f"{type(self).__name__}: the robot env reported it is not ready")
        init_pose = self._hook(base, "_set_init_pose")
        if init_pose is not None:
            init_pose()
        init_params = self._hook(base, "_set_episode_init_params")
        if init_params is not None:
            init_params()
        else:
            legacy = self._hook(base, "_set_init_params")
            if legacy is not None:
                legacy(options)

    def _set_action_hook(self, base: type, action: np.ndarray) -> None:
        hook = self._hook(base, "_set_action", "_send_action")
        if hook is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _set_action(action)")
        hook(action)

    def _reset_simulation(self) -> None:
        if self._shared_world:  # other envs' robots share this world: put back only this one
            self.sim.reset_robot(self.robot_name)
            return
        scope = _SCOPE_STATE if self.reset_mode == "world" else _SCOPE_STATE | _SCOPE_TIME
        self.sim.reset_simulation(scope)
        if self.reset_controllers:
            self.sim.reset_controllers(self.namespace, self.controllers_list or None)

    def _core_reset(self, base: type, seed: int | None, options: dict[str, Any] | None) -> None:
        self.info = {}
        self._pending_commands = {}
        self._reset_simulation()
        self._run_reset_hooks(base, options)
        self._refresh_state(0)

    # -- rendering and closing --------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """An image of the scene (``rgb_array``: HxWx3 uint8; ``depth_array``: HxW float32 metres)."""
        if self.render_mode is None:
            return None
        camera, width, height = self._render_options
        if self.render_mode == "human":
            from multiros.sim.render import display_available

            if not display_available():
                raise EnvError('render_mode="human" opens the MuJoCo viewer and needs a display (DISPLAY or '
                               'WAYLAND_DISPLAY is not set); use render_mode="rgb_array" for images without one')
            self._connection.show_viewer()
            return None
        return self.sim.render(camera, width, height, depth=self.render_mode == "depth_array")

    def close(self) -> None:
        """Stop everything this env started (composed node, child process, ROS context)."""
        if self._closed:
            return
        self._closed = True
        connection = getattr(self, "_connection", None)
        if connection is not None and not getattr(self, "_shared_world", False):
            try:
                connection.close()
            except SimulationNodeError:
                _logger.warning("simulation node did not close cleanly", exc_info=True)
