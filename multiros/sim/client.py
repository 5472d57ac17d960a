"""Client side of the MuJoCo simulation node: typed calls over ROS 2 services.

Everything that drives the simulation node from outside (environments, ``multiros.utils.sim_core``,
the CLI, tests) goes through :class:`SimulationClient`. It owns one ROS client per service, created
lazily and reused, so the per-step path (:meth:`SimulationClient.step_robot`) is a single service
call with no name resolution or allocation beyond the messages themselves.

Every call has a timeout. A result code other than ``RESULT_OK`` raises
:class:`SimulationServiceError`, which carries the service name, the code and the node's message.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from multiros.robot_state import RobotState
from multiros.ros.controller_manager import (
    BEST_EFFORT,
    STRICT,
    ControllerManagerClient,
    ControllerManagerError,
    destroy_clients,
)
from multiros.ros.exceptions import ServiceCallError
from multiros.ros.interfaces import get_message, get_service
from multiros.sim.services import SIM_SERVICES

DEFAULT_NODE_NAME = "mujoco_sim"

Result = get_message("simulation_interfaces/msg/Result")
SimulationState = get_message("simulation_interfaces/msg/SimulationState")
ControllerCommand = get_message("uniros_interfaces/msg/ControllerCommand")
RobotStep = get_message("uniros_interfaces/msg/RobotStep")
RobotStepResult = get_message("uniros_interfaces/msg/RobotStepResult")
Pose = get_message("geometry_msgs/msg/Pose")


_RESULT_NAMES = {
    value: name
    for name, value in vars(Result).items()
    if name.startswith("RESULT_") and isinstance(value, int)
}


class SimulationNodeError(RuntimeError):
    """The simulation node could not be reached, or did not answer in time."""


class SimulationServiceError(RuntimeError):
    """A simulation service answered with a result code other than ``RESULT_OK``.

    Attributes:
        service: the fully qualified service name.
        code: the ``simulation_interfaces/msg/Result`` code (or a service-specific code > 100).
        message: the node's error message.
    """

    def __init__(self, service: str, code: int, message: str) -> None:
        self.service = service
        self.code = int(code)
        self.message = message
        label = _RESULT_NAMES.get(self.code, f"code {self.code}")
        super().__init__(f"{service} failed ({label}): {message}")


def _check(service: str, result: Any) -> None:
    if result.result != Result.RESULT_OK:
        raise SimulationServiceError(service, result.result, result.error_message)


def time_seconds(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def _robot_state(response: Any, sim_time: Any = None) -> RobotState:
    js = response.joint_state
    poses = response.frame_poses
    if poses:
        positions = np.array([(p.position.x, p.position.y, p.position.z) for p in poses])
        orientations = np.array([(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z) for p in poses])
    else:
        positions, orientations = np.empty((0, 3)), np.empty((0, 4))
    return RobotState(  # multiros.robot_state: the one state record of sim and real robots
        sim_time=time_seconds(response.sim_time if sim_time is None else sim_time),
        names=tuple(js.name),
        position=np.asarray(js.position, dtype=np.float64),
        velocity=np.asarray(js.velocity, dtype=np.float64),
        effort=np.asarray(js.effort, dtype=np.float64),
        frame_positions=positions,
        frame_orientations=orientations,
    )


@dataclass(frozen=True)
class RobotStepOutcome:
    """One robot's part of a :meth:`SimulationClient.step_robots` answer.

    Attributes:
        entity: the robot.
        status: ``uniros_interfaces/msg/RobotStepResult`` code (0 = OK; 104 = UNSTABLE: physics
            diverged and the robot was restored at rest; 101-103, 105: its request part was refused).
        message: the node's explanation when ``status`` is not OK.
        state: the robot's state after the step (``None`` for an unknown robot).
    """

    entity: str
    status: int
    message: str
    state: RobotState | None


@dataclass(slots=True)
class RobotStepSpec:
    """One robot's part of a :meth:`SimulationClient.step_robots` request."""

    entity: str
    commands: Mapping[str, Iterable[float]] | None = None
    frames: Sequence[str] = ()
    reset: bool = False


def make_pose(position: Sequence[float], orientation_wxyz: Sequence[float] = (1.0, 0.0, 0.0, 0.0)) -> Any:
    """A ``geometry_msgs/Pose`` from a position and a ``(w, x, y, z)`` quaternion.

    Raises:
        ValueError: the quaternion is zero, not finite, or the position is not 3 finite numbers.
    """
    pos = np.asarray(position, dtype=np.float64)
    quat = np.asarray(orientation_wxyz, dtype=np.float64)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise ValueError(f"position must be 3 finite numbers, got {position!r}")
    norm = float(np.linalg.norm(quat)) if quat.shape == (4,) else 0.0
    if quat.shape != (4,) or not np.isfinite(norm) or norm < 1e-9:
        raise ValueError(
            f"orientation must be a non-zero quaternion (w, x, y, z), got {orientation_wxyz!r}; "
            "use (1, 0, 0, 0) for no rotation"
        )
    quat = quat / norm
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in pos)
    o = pose.orientation
    o.w, o.x, o.y, o.z = (float(v) for v in quat)
    return pose


class SimulationClient:
    """Typed access to one simulation node's services.

    Args:
        node: the ROS node that owns the clients (any ``multiros.ros.Node``).
        sim_node: the simulation node's fully qualified name, e.g. ``"/mujoco_sim"``.
        timeout_sec: default timeout of every call.
    """

    def __init__(self, node: Any, sim_node: str = "/" + DEFAULT_NODE_NAME, timeout_sec: float = 10.0) -> None:
        if not sim_node.startswith("/"):
            sim_node = "/" + sim_node
        self._node = node
        self._prefix = sim_node.rstrip("/")
        self.timeout_sec = float(timeout_sec)
        self._clients: dict[str, Any] = {}
        self._controller_managers: dict[str, ControllerManagerClient] = {}
        self._types = {name: get_service(type_name) for name, type_name in SIM_SERVICES.items()}

    @property
    def sim_node(self) -> str:
        """Fully qualified name of the simulation node."""
        return self._prefix

    def service_name(self, name: str) -> str:
        """Fully qualified name of one of the node's services."""
        return f"{self._prefix}/{name}"

    def _client(self, name: str) -> Any:
        client = self._clients.get(name)
        if client is None:
            client = self._node.create_client(self._types[name], self.service_name(name))
            self._clients[name] = client
        return client

    def _call(self, name: str, request: Any, timeout_sec: float | None = None) -> Any:
        timeout = self.timeout_sec if timeout_sec is None else timeout_sec
        try:
            return self._client(name).call(request, timeout_sec=timeout)
        except TimeoutError as exc:
            raise SimulationNodeError(
                f"simulation node {self._prefix!r} did not answer {self.service_name(name)} within "
                f"{timeout:g} s; is the node running (and on the same transport and ROS_DOMAIN_ID)?"
            ) from exc
        except ServiceCallError as exc:
            raise SimulationNodeError(f"simulation node {self._prefix!r} failed: {exc}") from exc

    def request(self, service: str, /, **fields: Any) -> Any:
        """A new request message for ``service`` (e.g. ``"step_robot"``)."""
        return self._types[service].Request(**fields)

    # -- readiness --------------------------------------------------------------------------
    def wait_until_ready(self, timeout_sec: float = 10.0) -> None:
        """Block until the node's services are available.

        Raises:
            SimulationNodeError: not available within ``timeout_sec``.
        """
        if not self._client("step_robot").wait_for_service(timeout_sec=timeout_sec):
            raise SimulationNodeError(
                f"simulation node {self._prefix!r} not available after {timeout_sec:g} s "
                f"(no service {self.service_name('step_robot')})"
            )

    def get_simulator_features(self) -> Any:
        """The node's ``simulation_interfaces/msg/SimulatorFeatures``."""
        return self._call("get_simulator_features", self.request("get_simulator_features")).features

    # -- entities ---------------------------------------------------------------------------
    def spawn_entity(
        self,
        name: str,
        *,
        uri: str = "",
        resource_string: str = "",
        namespace: str = "",
        position: Sequence[float] = (0.0, 0.0, 0.0),
        orientation: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
        allow_renaming: bool = False,
        timeout_sec: float | None = None,
    ) -> str:
        """Spawn a robot or object from a URDF, xacro or MJCF file (``uri``) or text.

        ``orientation`` is a ``(w, x, y, z)`` quaternion. Returns the entity's unique name.
        """
        req = self.request("spawn_entity", name=name, allow_renaming=allow_renaming, entity_namespace=namespace)
        # Rolling: a Resource field; Jazzy/Kilted (simulation_interfaces 1.x): top-level fields.
        resource = getattr(req, "entity_resource", req)
        resource.uri = uri
        resource.resource_string = resource_string
        req.initial_pose.header.frame_id = "world"
        req.initial_pose.pose = make_pose(position, orientation)
        res = self._call("spawn_entity", req, timeout_sec)
        _check(self.service_name("spawn_entity"), res.result)
        return res.entity_name

    def delete_entity(self, name: str) -> None:
        """Remove an entity; the others keep their state."""
        res = self._call("delete_entity", self.request("delete_entity", entity=name))
        _check(self.service_name("delete_entity"), res.result)

    def get_entities(self, name_filter: str = "") -> list[str]:
        """Names of the entities whose name matches the regular expression ``name_filter``."""
        req = self.request("get_entities")
        req.filters.filter = name_filter
        res = self._call("get_entities", req)
        _check(self.service_name("get_entities"), res.result)
        return list(res.entities)

    def get_entity_state(self, name: str) -> Any:
        """The entity's ``simulation_interfaces/msg/EntityState`` (world frame)."""
        res = self._call("get_entity_state", self.request("get_entity_state", entity=name))
        _check(self.service_name("get_entity_state"), res.result)
        return res.state

    def set_entity_pose(
        self, name: str, position: Sequence[float], orientation: Sequence[float] = (1.0, 0.0, 0.0, 0.0)
    ) -> None:
        """Teleport an entity to a world pose (``orientation`` as ``(w, x, y, z)``).

        With Jazzy/Kilted definitions (``ROS_DISTRO``) the request has no ``set_pose`` flag and sets
        the whole state, so the entity also stops (zero twist); with Rolling's only the pose is set.
        """
        req = self.request("set_entity_state", entity=name)
        if hasattr(req, "set_pose"):
            req.set_pose = True
        req.state.header.frame_id = "world"
        req.state.pose = make_pose(position, orientation)
        res = self._call("set_entity_state", req)
        _check(self.service_name("set_entity_state"), res.result)

    # -- simulation control -----------------------------------------------------------------
    def reset_simulation(self, scope: int = 255) -> None:
        """``ResetSimulation`` with a scope bit field (255 = all, 1 = time, 2 = state, 4 = spawned)."""
        res = self._call("reset_simulation", self.request("reset_simulation", scope=scope))
        _check(self.service_name("reset_simulation"), res.result)

    def get_simulation_state(self) -> int:
        """The ``SimulationState`` constant the node is in (``STATE_PLAYING``, ``STATE_PAUSED``, ...)."""
        res = self._call("get_simulation_state", self.request("get_simulation_state"))
        _check(self.service_name("get_simulation_state"), res.result)
        return int(res.state.state)

    def set_simulation_state(self, state: int) -> None:
        """Play, pause or stop the simulation. Already being in that state is not an error."""
        req = self.request("set_simulation_state")
        req.state.state = state
        res = self._call("set_simulation_state", req)
        already = get_service(SIM_SERVICES["set_simulation_state"]).Response.ALREADY_IN_TARGET_STATE
        if res.result.result != already:
            _check(self.service_name("set_simulation_state"), res.result)

    def pause(self) -> None:
        """Pause physics (real-time mode stops advancing)."""
        self.set_simulation_state(SimulationState.STATE_PAUSED)

    def unpause(self) -> None:
        """Run physics in real time (at the node's real-time factor)."""
        self.set_simulation_state(SimulationState.STATE_PLAYING)

    def step_simulation(self, steps: int = 1) -> None:
        """Advance a paused simulation by ``steps`` physics steps."""
        res = self._call("step_simulation", self.request("step_simulation", steps=int(steps)))
        _check(self.service_name("step_simulation"), res.result)

    # -- the lockstep hot path --------------------------------------------------------------
    def step_robot(
        self,
        entity: str,
        commands: Mapping[str, Iterable[float]] | None = None,
        steps: int = 1,
        frames: Sequence[str] = (),
        timeout_sec: float | None = None,
    ) -> RobotState:
        """Apply controller commands to one robot, advance ``steps`` physics steps, return its state.

        Args:
            entity: the robot's entity name.
            commands: controller name -> command vector (``""`` = the robot's default controller).
            steps: physics steps to advance; 0 only applies the commands and reads the state.
            frames: link or site names whose world poses to return.
        """
        req = self.request("step_robot", entity=entity, steps=int(steps), frames=list(frames))
        if commands:
            req.commands = [
                ControllerCommand(controller=name, command=np.asarray(values, dtype=np.float64))
                for name, values in commands.items()
            ]
        res = self._call("step_robot", req, timeout_sec)
        _check(self.service_name("step_robot"), res.result)
        return _robot_state(res)

    def step_robots_request(self, robots: Sequence[RobotStepSpec], steps: int = 1) -> Any:
        """The ``StepRobots`` request for ``robots`` (see :meth:`step_robots`)."""
        items = []
        for spec in robots:
            item = RobotStep(entity=spec.entity, reset=bool(spec.reset), frames=list(spec.frames))
            if spec.commands:
                item.commands = [
                    ControllerCommand(controller=name, command=np.asarray(values, dtype=np.float64))
                    for name, values in spec.commands.items()
                ]
            items.append(item)
        return self.request("step_robots", robots=items, steps=int(steps))

    def step_robots_async(self, request: Any, timeout_sec: float | None = None) -> Any:
        """Send a ``StepRobots`` request; a future of the response (see :meth:`step_robots_outcomes`)."""
        timeout = self.timeout_sec if timeout_sec is None else timeout_sec
        return self._client("step_robots").call_async(request, timeout_sec=timeout)

    def step_robots_call(self, request: Any, timeout_sec: float | None = None) -> Any:
        """Send a ``StepRobots`` request and wait for the response (see :meth:`step_robots_outcomes`)."""
        return self._call("step_robots", request, timeout_sec)

    def step_robots_outcomes(self, request: Any, response: Any) -> list[RobotStepOutcome]:
        """Per-robot outcomes of a ``StepRobots`` response (raises if the call as a whole failed)."""
        _check(self.service_name("step_robots"), response.result)
        if len(response.robots) != len(request.robots):
            raise SimulationNodeError(
                f"simulation node {self._prefix!r} answered StepRobots for {len(response.robots)} robots, "
                f"asked for {len(request.robots)}"
            )
        out = []
        for item, part in zip(request.robots, response.robots):
            known = part.status != RobotStepResult.UNKNOWN_ROBOT
            state = _robot_state(part, response.sim_time) if known else None
            out.append(RobotStepOutcome(item.entity, int(part.status), part.message, state))
        return out

    def step_robots(
        self, robots: Sequence[RobotStepSpec], steps: int = 1, timeout_sec: float | None = None
    ) -> list[RobotStepOutcome]:
        """Step a batch of robots in one round trip: per robot an optional reset and its commands,
        then ``steps`` physics steps for the whole world, then each robot's state.

        A robot's own failure (bad command, divergence, ...) is in its outcome's ``status``; the
        others step on. Raises :class:`SimulationServiceError` when the call as a whole fails.
        """
        request = self.step_robots_request(robots, steps)
        return self.step_robots_outcomes(request, self._call("step_robots", request, timeout_sec))

    def reset_robot(self, entity: str) -> RobotState:
        """Put one robot back in its spawn state (joints, at rest, controllers holding it); the
        other robots, objects and time are untouched."""
        (outcome,) = self.step_robots([RobotStepSpec(entity, reset=True)], steps=0)
        if outcome.state is None or outcome.status != RobotStepResult.OK:
            raise SimulationServiceError(self.service_name("step_robots"), outcome.status, outcome.message)
        return outcome.state

    def get_node_load(self) -> dict[str, Any]:
        """The node's load and limits: ``robots``, ``max_robots``, ``entities``, ``physics_steps``,
        ``physics_steps_per_sec``, ``busy_fraction``, ``model_bytes``, ``process_rss_bytes``."""
        res = self._call("get_node_load", self.request("get_node_load"))
        _check(self.service_name("get_node_load"), res.result)
        keys = ("robots", "max_robots", "entities", "physics_steps", "physics_steps_per_sec", "busy_fraction",
                "model_bytes", "process_rss_bytes")
        return {k: getattr(res, k) for k in keys}

    def set_robot_joint_state(
        self,
        entity: str,
        names: Sequence[str],
        positions: Iterable[float],
        velocities: Iterable[float] | None = None,
        hold: bool = True,
    ) -> None:
        """Teleport joints of a robot; with ``hold`` the positions become controller setpoints."""
        req = self.request("set_robot_joint_state", entity=entity, hold=hold)
        req.joint_state.name = list(names)
        req.joint_state.position = np.asarray(list(positions), dtype=np.float64)
        if velocities is not None:
            req.joint_state.velocity = np.asarray(list(velocities), dtype=np.float64)
        res = self._call("set_robot_joint_state", req)
        _check(self.service_name("set_robot_joint_state"), res.result)

    # -- physics ----------------------------------------------------------------------------
    def get_physics_properties(self) -> dict[str, Any]:
        """``{"time_step": s, "real_time_factor": f, "gravity": (x, y, z)}``."""
        res = self._call("get_physics_properties", self.request("get_physics_properties"))
        _check(self.service_name("get_physics_properties"), res.result)
        g = res.gravity
        return {"time_step": res.time_step, "real_time_factor": res.real_time_factor, "gravity": (g.x, g.y, g.z)}

    def set_physics_properties(
        self,
        *,
        time_step: float | None = None,
        real_time_factor: float | None = None,
        gravity: Sequence[float] | None = None,
    ) -> None:
        """Change the physics time step, real-time factor or gravity (``None`` keeps a value)."""
        req = self.request("set_physics_properties")
        if time_step is not None:
            req.set_time_step, req.time_step = True, float(time_step)
        if real_time_factor is not None:
            req.set_real_time_factor, req.real_time_factor = True, float(real_time_factor)
        if gravity is not None:
            req.set_gravity = True
            req.gravity.x, req.gravity.y, req.gravity.z = (float(v) for v in gravity)
        res = self._call("set_physics_properties", req)
        _check(self.service_name("set_physics_properties"), res.result)

    def set_entity_properties(self, entity: str, rows: Sequence[tuple[str, str, str, float]], *,
                              restore: bool = False) -> int:
        """Set an entity's physical properties apart from its description (domain randomisation): rows
        ``(target, name, property, value)`` as :mod:`multiros.sim.entity_properties` lists them; ``restore``
        first puts back its spawned values. Returns the model values written."""
        req = self.request("set_entity_properties")
        req.entity, req.restore = entity, bool(restore)
        req.targets = [r[0] for r in rows]
        req.names = [r[1] for r in rows]
        req.properties = [r[2] for r in rows]
        req.values = [float(r[3]) for r in rows]
        res = self._call("set_entity_properties", req)
        _check(self.service_name("set_entity_properties"), res.result)
        return int(res.changed)

    # -- rendering --------------------------------------------------------------------------
    def render(self, camera: str = "", width: int = 640, height: int = 480, depth: bool = False) -> np.ndarray:
        """An image of the scene: HxWx3 uint8 RGB, or HxW float32 depth in metres."""
        from multiros.sim.render_service import image_to_array

        req = self.request("render_camera", camera=camera, width=int(width), height=int(height), depth=bool(depth))
        res = self._call("render_camera", req, max(self.timeout_sec, 30.0))
        _check(self.service_name("render_camera"), res.result)
        return image_to_array(res.image)

    # -- controller manager (per robot namespace) ---------------------------------------------
    def controller_manager(self, namespace: str) -> ControllerManagerClient:
        """The (cached) client of the controller manager of the robot in ``namespace``."""
        cm = self._controller_managers.get(namespace)
        if cm is None:
            cm = self._controller_managers[namespace] = ControllerManagerClient(
                self._node, namespace, timeout_sec=self.timeout_sec
            )
        return cm

    def _managed(self, namespace: str, action: Callable[[ControllerManagerClient], Any]) -> Any:
        """Run a controller-manager call, reporting failures as this client's errors."""
        cm = self.controller_manager(namespace)
        try:
            return action(cm)
        except ControllerManagerError as exc:
            if isinstance(exc.__cause__, TimeoutError):
                raise SimulationNodeError(str(exc)) from exc
            raise SimulationServiceError(
                cm.service_name("switch_controller"), Result.RESULT_OPERATION_FAILED, str(exc)
            ) from exc
        except ServiceCallError as exc:
            raise SimulationNodeError(f"controller manager {namespace!r} failed: {exc}") from exc

    def list_controllers(self, namespace: str) -> list[Any]:
        """Every controller of the robot in ``namespace`` (name, state, type, claimed interfaces)."""
        return self._managed(namespace, lambda cm: cm.list_controllers())

    def switch_controllers(
        self, namespace: str, activate: Sequence[str] = (), deactivate: Sequence[str] = (), strict: bool = True
    ) -> None:
        """Activate/deactivate controllers of a robot (ros2_control ``switch_controller``).

        Raises:
            SimulationServiceError: the controller manager refused the switch.
        """
        strictness = STRICT if strict else BEST_EFFORT
        self._managed(namespace, lambda cm: cm.switch(activate, deactivate, strictness=strictness))

    def reset_controllers(self, namespace: str, names: Sequence[str] | None = None) -> None:
        """Restart controllers (deactivate, then activate): they drop their state and hold the current pose."""
        self._managed(namespace, lambda cm: cm.reset(names))

    def close(self) -> None:
        """Destroy the clients this object created."""
        destroy_clients(self._node, self._clients)
        for cm in self._controller_managers.values():
            cm.close()
        self._controller_managers.clear()
