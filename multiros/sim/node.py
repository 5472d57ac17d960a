"""The MuJoCo simulation node: a ROS 2 node serving ``simulation_interfaces`` over a :class:`World`.

Service callbacks stay thin: decode the request, call one ``World`` method under the node's lock,
encode the reply with the standard result code. Per-robot topics and controller-manager services
live in :mod:`multiros.sim.robot_io`.

Services (``~`` = this node, default ``/mujoco_sim``):
``~/get_simulator_features``, ``~/spawn_entity``, ``~/delete_entity``, ``~/get_entities``,
``~/get_entity_state``, ``~/set_entity_state``, ``~/get_entities_states``, ``~/reset_simulation``,
``~/get_simulation_state``, ``~/set_simulation_state``, ``~/step_simulation``, and the project's own
``~/step_robot`` (the lockstep env step), ``~/set_robot_joint_state``,
``~/get_physics_properties``, ``~/set_physics_properties``, ``~/render_camera``.
Topics: ``/clock`` while time advances; per robot ``joint_states``, ``robot_description``,
controller command topics; ``/tf``.
"""

from __future__ import annotations

import functools
import logging
import re
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlsplit

import numpy as np

from multiros.ros import Node, ParameterDescriptor
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.qos import qos_profile_clock
from multiros.sim import convert
from multiros.sim.actions import SimulateStepsAction
from multiros.sim.description import SourcePolicy, UnsupportedFormatError, load_description
from multiros.sim.distro_adapters import create_services, get_message, get_service
from multiros.sim.errors import (
    CommandError,
    ControllerError,
    DescriptionError,
    EntityError,
    RenderError,
    StepInterruptedError,
    UnstableSimulationError,
)
from multiros.sim.limits import MAX_STEPS_PER_CALL, DescriptionLimits
from multiros.sim.robot_io import RobotInterfaces
from multiros.sim.services import SIM_SERVICES
from multiros.sim.world import EntityCategory, RealTimeRunner, ResetScope, World, WorldOptions

_logger = logging.getLogger(__name__)

Result = get_message("simulation_interfaces/msg/Result")
SimulationState = get_message("simulation_interfaces/msg/SimulationState")
SimulatorFeatures = get_message("simulation_interfaces/msg/SimulatorFeatures")
EntityStateMsg = get_message("simulation_interfaces/msg/EntityState")
Clock = get_message("rosgraph_msgs/msg/Clock")
Marker = get_message("visualization_msgs/msg/Marker")
MarkerArray = get_message("visualization_msgs/msg/MarkerArray")

# The native (Rolling) variants; Jazzy/Kilted peers are served through multiros.sim.distro_adapters.
_SRV = {name: get_service(type_name) for name, type_name in SIM_SERVICES.items()}

OK, NOT_FOUND, INCORRECT_STATE, FAILED = (
    Result.RESULT_OK,
    Result.RESULT_NOT_FOUND,
    Result.RESULT_INCORRECT_STATE,
    Result.RESULT_OPERATION_FAILED,
)
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_MAX_FRAMES = 1024  # frames per StepRobot request
_MAX_FRAME_SETS = 64  # cached frame lists (a new list per call must not grow memory without end)
_NAMESPACE = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)*/?$")

_FEATURES = [
    SimulatorFeatures.SPAWNING,
    SimulatorFeatures.DELETING,
    SimulatorFeatures.ENTITY_CATEGORIES,
    SimulatorFeatures.SPAWNING_RESOURCE_STRING,
    SimulatorFeatures.SPAWNABLES,
    SimulatorFeatures.ENTITY_STATE_GETTING,
    SimulatorFeatures.ENTITY_STATE_SETTING,
    SimulatorFeatures.SIMULATION_RESET,
    SimulatorFeatures.SIMULATION_RESET_TIME,
    SimulatorFeatures.SIMULATION_RESET_STATE,
    SimulatorFeatures.SIMULATION_RESET_SPAWNED,
    SimulatorFeatures.SIMULATION_STATE_GETTING,
    SimulatorFeatures.SIMULATION_STATE_SETTING,
    SimulatorFeatures.SIMULATION_STATE_PAUSE,
    SimulatorFeatures.STEP_SIMULATION_SINGLE,
    SimulatorFeatures.STEP_SIMULATION_MULTIPLE,
]


def _fail(result: Any, code: int, message: str) -> None:
    result.result = code
    result.error_message = message


def _ok(result: Any) -> None:
    result.result = OK
    result.error_message = ""


def _guarded(handler: Callable[[Any, Any, Any], Any]) -> Callable[[Any, Any, Any], Any]:
    """An unexpected exception in a service handler becomes RESULT_OPERATION_FAILED with a
    message (and a log entry), never a traceback to the caller or a dead node."""

    @functools.wraps(handler)
    def guarded(self: Any, request: Any, response: Any) -> Any:
        try:
            return handler(self, request, response)
        except Exception as exc:  # the handler's own errors are mapped inside; this is the safety net
            _logger.exception("%s failed unexpectedly", handler.__name__.removeprefix("_srv_"))
            result = getattr(response, "result", None)
            if result is not None:
                detail = f"{type(exc).__name__}: {exc}"
                _fail(result, FAILED, f"{handler.__name__.removeprefix('_srv_')} failed unexpectedly: {detail[:400]}")
            return response

    return guarded


class SimulationNode(Node):
    """The MuJoCo simulation node.

    Args:
        node_name: ROS node name (``mujoco_sim`` by default).
        world: the world to serve; a new empty one (with ``options``) when omitted.
        options: physics options of a new world.
        real_time_factor: speed of the ``STATE_PLAYING`` mode (1.0 = wall clock, <= 0 = as fast as
            possible).
        paused: start paused (lockstep, the default for training) rather than playing.
        serve: create the simulation services now. ``False`` holds them back until
            :meth:`start_serving`, so a launcher can spawn its robots first and never answer a
            request about a world that is not ready.
        spin_topics: run this node's topic callbacks (controller commands, markers) in a background
            executor thread. Services never need it: they are answered on the caller's or the
            transport's thread. Turn it off when you spin the node yourself.
        allow_xacro_strings: run xacro on description text that arrives in a SpawnEntity request.
            Off by default: xacro evaluates Python in ``${...}``, so any peer that reaches the node
            could run code as the node's user. Turn it on only when every peer is trusted.
        trusted_paths: directories (besides the package index's roots) whose files a request may
            name by plain path or ``file://`` URI, e.g. the directory of your own robot file.
        max_steps_per_call: most physics steps one StepSimulation/StepRobot call may ask for
            (default :data:`multiros.sim.limits.MAX_STEPS_PER_CALL`; also the read-only ROS
            parameter ``max_steps_per_call``, so ``--ros-args -p max_steps_per_call:=N`` works).
        description_limits: size and value bounds of spawned descriptions (default
            :class:`~multiros.sim.limits.DescriptionLimits`).
        **node_kwargs: passed to :class:`multiros.ros.Node` (``context``, ``namespace``, ...).
    """

    def __init__(
        self,
        node_name: str = "mujoco_sim",
        *,
        world: World | None = None,
        options: WorldOptions | None = None,
        real_time_factor: float = 1.0,
        paused: bool = True,
        spin_topics: bool = True,
        serve: bool = True,
        allow_xacro_strings: bool = False,
        trusted_paths: Sequence[str | Path] = (),
        max_steps_per_call: int = MAX_STEPS_PER_CALL,
        description_limits: DescriptionLimits | None = None,
        **node_kwargs: Any,
    ) -> None:
        super().__init__(node_name, **node_kwargs)
        self._stopping = threading.Event()  # set first by destroy_node: long step calls stop at the next chunk
        self.source_policy = SourcePolicy.create(trusted_paths, allow_xacro_strings)
        self.description_limits = description_limits or DescriptionLimits()
        steps = self.declare_parameter(
            "max_steps_per_call", int(max_steps_per_call),
            ParameterDescriptor(read_only=True, description="most physics steps per StepSimulation/StepRobot call"),
        ).value
        if not isinstance(steps, int) or steps < 1:
            raise ValueError(f"max_steps_per_call must be an integer >= 1, got {steps!r}")
        self.max_steps_per_call = steps
        self._executor: Any = None
        self._spin_thread: threading.Thread | None = None
        self.world = world if world is not None else World(options)
        self._runner = RealTimeRunner(
            self.world, real_time_factor=real_time_factor, on_chunk=self._after_realtime_chunk,
            on_error=self._realtime_error,
        )
        self.lock = self._runner.lock
        self._state = SimulationState.STATE_PAUSED
        self._robots: dict[str, RobotInterfaces] = {}
        self._frame_sets: dict[tuple[str, tuple[str, ...]], Any] = {}
        self._renderer: Any = None
        self._viewer: Any = None
        self._clock_pub = self.create_publisher(Clock, "/clock", qos_profile_clock)
        self._marker_subs = [
            self.create_subscription(Marker, "/visualization_marker", self._on_marker, 100),
            self.create_subscription(MarkerArray, "/visualization_marker_array",
                                     lambda msg: [self._on_marker(m) for m in msg.markers], 10),
        ]
        self._services: list[Any] = []
        if serve:
            self.start_serving()
        for name in self.world.entity_names():
            self._attach_robot(name)
        if not paused:
            self._set_state(SimulationState.STATE_PLAYING)
        if spin_topics:
            self._executor = SingleThreadedExecutor(context=self.context)
            self._executor.add_node(self)
            self._spin_thread = threading.Thread(target=self._executor.spin, name=f"{node_name}-topics", daemon=True)
            self._spin_thread.start()

    def start_serving(self) -> None:
        """Create the simulation services (once); until then the node answers no service call."""
        if self._services:
            return
        self._services = [  # every served distribution's variant of each (multiros.sim.distro_adapters)
            srv for name, type_name in SIM_SERVICES.items()
            for srv in create_services(self, type_name, f"~/{name}", getattr(self, f"_srv_{name}"))
        ]
        self._simulate_steps = SimulateStepsAction(self)  # ~/simulate_steps (multiros.sim.actions)

    # -- helpers ----------------------------------------------------------------------------
    def _locked(self, fn: Callable[[], None]) -> None:
        with self.lock:
            fn()

    def _publish_clock(self) -> None:
        if self._clock_pub.get_subscription_count() > 0:
            self._clock_pub.publish(Clock(clock=convert.time_msg(self.world.time)))

    def _after_step(self) -> None:
        self._publish_clock()
        for robot in self._robots.values():
            robot.publish_state()

    def _after_realtime_chunk(self, world: World) -> None:
        self._after_step()

    def _realtime_error(self, exc: BaseException) -> None:
        self.get_logger().error("real-time physics stopped: %s", exc)

    def _attach_robot(self, name: str) -> None:
        info = self.world.entity(name)
        if info.category == EntityCategory.ROBOT:
            self._robots[name] = RobotInterfaces(self, self.world, info, self.lock)

    def _detach_robot(self, name: str) -> None:
        robot = self._robots.pop(name, None)
        if robot is not None:
            robot.destroy()
        for key in [k for k in self._frame_sets if k[0] == name]:
            del self._frame_sets[key]

    @property
    def simulation_state(self) -> int:
        """The ``SimulationState`` constant the node is in."""
        return self._state

    def _set_state(self, state: int) -> None:
        if state == SimulationState.STATE_PLAYING:
            self._runner.start()
        else:
            self._runner.stop()
        if state == SimulationState.STATE_STOPPED:
            with self.lock:
                self._sync_robots(self.world.reset(ResetScope.ALL))
        self._state = state

    def _sync_robots(self, respawned: tuple[str, ...] = ()) -> None:
        """Drop interfaces of robots a reset removed; re-create those of entities it spawned anew."""
        for name in list(self._robots):
            if not self.world.has_entity(name) or name in respawned:
                self._detach_robot(name)
        for name in respawned:
            if self.world.has_entity(name):
                self._attach_robot(name)

    # -- simulation_interfaces ---------------------------------------------------------------
    def _srv_get_simulator_features(self, request: Any, response: Any) -> Any:
        features = response.features
        features.features = np.array(_FEATURES, dtype=np.uint16)
        features.spawn_formats = ["urdf", "xacro", "mjcf"]
        features.custom_info = (
            "uniros MuJoCo simulation node; lockstep env step: uniros_interfaces/srv/StepRobot; "
            "xacro arguments as URI query (package://pkg/robot.urdf.xacro?arg=value)"
        )
        return response

    def _srv_get_spawnables(self, request: Any, response: Any) -> Any:
        if len(request.sources) > 0:
            _fail(response.result, Result.RESULT_FEATURE_UNSUPPORTED,
                  "additional sources are not searched; spawnables come from the installed description packages")
            return response
        from multiros.sim.spawnables import list_spawnables

        Spawnable = get_message("simulation_interfaces/msg/Spawnable")
        items = []
        for uri, text in list_spawnables(self.world.index):
            item = Spawnable(description=text)
            item.entity_resource.uri = uri
            items.append(item)
        response.spawnables = items
        _ok(response.result)
        return response

    @_guarded
    def _srv_spawn_entity(self, request: Any, response: Any) -> Any:
        return self._spawn(request, response, self.source_policy)

    def _spawn(self, request: Any, response: Any, policy: SourcePolicy | None) -> Any:
        """SpawnEntity. ``policy`` None trusts the request (the node's own command line)."""
        res = response.result
        uri, text = request.entity_resource.uri, request.entity_resource.resource_string
        if not uri and not text:
            _fail(res, response.NO_RESOURCE, "both entity_resource.uri and resource_string are empty")
            return response
        namespace = request.entity_namespace
        if namespace and not _NAMESPACE.match(namespace if namespace.startswith("/") else "/" + namespace):
            _fail(res, response.NAMESPACE_INVALID, f"namespace {namespace!r} is not a valid ROS namespace")
            return response
        frame = request.initial_pose.header.frame_id
        if frame not in ("", "world"):
            _fail(res, FAILED, f"initial_pose frame {frame!r} is not supported; use 'world' (or empty)")
            return response
        position, quat = convert.pose_to_arrays(request.initial_pose.pose)
        problem = convert.validate_quaternion(quat) or (
            None if np.all(np.isfinite(position)) else f"position {position.tolist()} is not finite"
        )
        if problem:
            _fail(res, response.INVALID_POSE, problem)
            return response
        limits = self.description_limits
        if len(uri) > 8192 or len(text) > limits.max_chars:
            what = "entity_resource.uri" if len(uri) > 8192 else "entity_resource.resource_string"
            most = 8192 if len(uri) > 8192 else limits.max_chars
            _fail(res, response.RESOURCE_PARSE_ERROR, f"{what} is longer than {most} characters (the node's limit)")
            return response
        description: str = text
        args: dict[str, str] = {}
        if uri:
            parts = urlsplit(uri)
            if parts.query:
                args = dict(parse_qsl(parts.query, keep_blank_values=True))
                uri = parts._replace(query="").geturl()
            if parts.scheme != "string":  # "string:?opts" = options for the resource_string
                description = uri
        controllers_yaml: Any = args.pop("__controllers_file", None)
        controllers = [c for c in args.pop("__controllers", "").split(",") if c] or None
        try:
            if controllers_yaml:
                controllers_yaml = (policy.resolve(controllers_yaml, self.world.index, what="controllers file")
                                    if policy is not None else self.world.index.resolve_uri(controllers_yaml))
            # Parsed outside the world: a refused or out-of-bounds description never touches it.
            desc = load_description(description, args=args or None, index=self.world.index,
                                    mesh_cache=self.world.mesh_cache,
                                    default_armature=self.world.options.default_armature, policy=policy,
                                    limits=limits)
        except UnsupportedFormatError as exc:
            _fail(res, response.UNSUPPORTED_FORMAT, str(exc))
            return response
        except DescriptionError as exc:
            code = response.MISSING_ASSETS if exc.missing_assets else response.RESOURCE_PARSE_ERROR
            _fail(res, code, str(exc))
            return response
        except (RecursionError, MemoryError) as exc:
            _fail(res, response.RESOURCE_PARSE_ERROR, f"the description is too large or too deep to load "
                  f"({type(exc).__name__}); see the node's description limits")
            return response
        with self.lock:
            name = self._entity_name(request.name, request.allow_renaming, response)
            if name is None:
                return response
            try:
                info = self.world.spawn(
                    name,
                    desc,
                    pose=(position, quat),
                    namespace=namespace or None,
                    controllers=controllers,
                    controllers_yaml=controllers_yaml,
                )
            except DescriptionError as exc:
                code = response.MISSING_ASSETS if exc.missing_assets else response.RESOURCE_PARSE_ERROR
                _fail(res, code, str(exc))
                return response
            except EntityError as exc:
                _fail(res, response.NAME_INVALID, str(exc))
                return response
            except ControllerError as exc:
                _fail(res, FAILED, f"controllers of {name!r}: {exc}")
                return response
            except ValueError as exc:
                _fail(res, response.INVALID_POSE, str(exc))
                return response
            try:
                self._attach_robot(info.name)
            except Exception as exc:
                self.world.delete(info.name)
                _fail(res, FAILED, f"spawned {info.name!r} but could not create its ROS interfaces: {exc}")
                return response
        response.entity_name = info.name
        _ok(res)
        return response

    def _entity_name(self, name: str, allow_renaming: bool, response: Any) -> str | None:
        res = response.result
        if name and not _NAME.match(name):
            if not allow_renaming:
                _fail(res, response.NAME_INVALID, f"entity name {name!r} must match [A-Za-z_][A-Za-z0-9_]*")
                return None
            name = re.sub(r"[^A-Za-z0-9_]", "_", name) or "entity"
        if not name:
            if not allow_renaming:
                _fail(res, response.NAME_INVALID, "entity name is empty and allow_renaming is false")
                return None
            name = "entity"
        if self.world.has_entity(name):
            if not allow_renaming:
                _fail(res, response.NAME_NOT_UNIQUE, f"an entity named {name!r} exists; pick another name")
                return None
            base, i = name, 1
            while self.world.has_entity(f"{base}_{i}"):
                i += 1
            name = f"{base}_{i}"
        return name

    def _srv_delete_entity(self, request: Any, response: Any) -> Any:
        with self.lock:
            if not self.world.has_entity(request.entity):
                known = list(self.world.entity_names())
                _fail(response.result, NOT_FOUND, f"no entity {request.entity!r}; entities: {known}")
                return response
            self._detach_robot(request.entity)
            self.world.delete(request.entity)
        _ok(response.result)
        return response

    def _filtered_entities(self, filters: Any, result: Any) -> list[str] | None:
        try:
            pattern = re.compile(filters.filter) if filters.filter else None
        except re.error as exc:
            _fail(result, FAILED, f"filter {filters.filter!r} is not a valid regular expression: {exc}")
            return None
        if len(filters.tags.tags) > 0:
            _fail(result, Result.RESULT_FEATURE_UNSUPPORTED, "entity tags are not supported")
            return None
        if filters.bounds.type != 0 or len(filters.bounds.points) > 0:
            _fail(result, Result.RESULT_FEATURE_UNSUPPORTED, "bounds filters are not supported")
            return None
        categories = {int(c.category) for c in filters.categories}
        names = []
        for name in self.world.entity_names():
            if pattern is not None and not pattern.search(name):
                continue
            if categories and int(self.world.entity(name).category) not in categories:
                continue
            names.append(name)
        return names

    def _srv_get_entities(self, request: Any, response: Any) -> Any:
        with self.lock:
            names = self._filtered_entities(request.filters, response.result)
        if names is not None:
            response.entities = names
            _ok(response.result)
        return response

    def _entity_state(self, name: str) -> Any:
        state = self.world.get_entity_state(name)
        msg = EntityStateMsg()
        msg.header.frame_id = "world"
        msg.header.stamp = convert.time_msg(self.world.time)
        convert.fill_pose(msg.pose, state.position, state.orientation)
        lin, ang = msg.twist.linear, msg.twist.angular
        lin.x, lin.y, lin.z = (float(v) for v in state.linear_velocity)
        ang.x, ang.y, ang.z = (float(v) for v in state.angular_velocity)
        return msg

    def _srv_get_entity_state(self, request: Any, response: Any) -> Any:
        with self.lock:
            if not self.world.has_entity(request.entity):
                _fail(response.result, NOT_FOUND, f"no entity {request.entity!r}")
                return response
            response.state = self._entity_state(request.entity)
        _ok(response.result)
        return response

    def _srv_get_entities_states(self, request: Any, response: Any) -> Any:
        with self.lock:
            names = self._filtered_entities(request.filters, response.result)
            if names is None:
                return response
            response.entities = names
            response.states = [self._entity_state(n) for n in names]
        _ok(response.result)
        return response

    def _srv_set_entity_state(self, request: Any, response: Any) -> Any:
        res = response.result
        frame = request.state.header.frame_id
        if frame not in ("", "world"):
            _fail(res, FAILED, f"frame {frame!r} is not supported; use 'world' (or empty)")
            return response
        kwargs: dict[str, Any] = {}
        if request.set_pose:
            position, quat = convert.pose_to_arrays(request.state.pose)
            problem = convert.validate_quaternion(quat)
            if problem or not np.all(np.isfinite(position)):
                _fail(res, response.INVALID_POSE, problem or f"position {position.tolist()} is not finite")
                return response
            kwargs.update(position=position, orientation=quat)
        if request.set_twist:
            t = request.state.twist
            kwargs.update(
                linear_velocity=(t.linear.x, t.linear.y, t.linear.z),
                angular_velocity=(t.angular.x, t.angular.y, t.angular.z),
            )
        with self.lock:
            if not self.world.has_entity(request.entity):
                _fail(res, NOT_FOUND, f"no entity {request.entity!r}")
                return response
            try:
                self.world.set_entity_state(request.entity, **kwargs)
            except ValueError as exc:
                _fail(res, FAILED, str(exc))
                return response
        _ok(res)
        return response

    def _srv_reset_simulation(self, request: Any, response: Any) -> Any:
        # SCOPE_DEFAULT (0) and SCOPE_ALL (255): the launched world comes back (World.reset).
        scope = int(request.scope)
        with self.lock:
            try:
                respawned = self.world.reset(scope)
            except (DescriptionError, EntityError, ControllerError, ValueError) as exc:
                self._sync_robots(self.world.entity_names())
                _fail(response.result, FAILED, f"reset (scope {scope}) could not re-create the launched world: {exc}")
                return response
            self._sync_robots(respawned)
            for robot in self._robots.values():
                robot.on_reset()
        _ok(response.result)
        return response

    def _srv_get_simulation_state(self, request: Any, response: Any) -> Any:
        response.state.state = self._state
        _ok(response.result)
        return response

    def _srv_set_simulation_state(self, request: Any, response: Any) -> Any:
        target = int(request.state.state)
        valid = (SimulationState.STATE_STOPPED, SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED)
        if target not in valid:
            _fail(response.result, response.INCORRECT_TRANSITION, f"state {target} cannot be set on this node")
            return response
        if target == self._state:
            _fail(response.result, response.ALREADY_IN_TARGET_STATE, "already in the requested state")
            return response
        if target == SimulationState.STATE_PAUSED and self._state == SimulationState.STATE_STOPPED:
            # The standard allows pausing a stopped simulation: start it paused.
            self._state = SimulationState.STATE_PAUSED
        else:
            self._set_state(target)
        _ok(response.result)
        return response

    def _too_many_steps(self, steps: int, result: Any) -> bool:
        if steps <= self.max_steps_per_call:
            return False
        _fail(result, FAILED, f"steps={steps} exceeds this node's max_steps_per_call ({self.max_steps_per_call}); "
              f"split the call, or start the node with a larger max_steps_per_call")
        return True

    def _step_world(self, steps: int) -> None:
        """Step in chunks that stop when the node shuts down (lock held by the caller)."""
        self.world.step(steps, should_stop=self._stopping.is_set)

    @_guarded
    def _srv_step_simulation(self, request: Any, response: Any) -> Any:
        steps = int(request.steps)
        if self._too_many_steps(steps, response.result):
            return response
        if self._state != SimulationState.STATE_PAUSED:
            _fail(response.result, FAILED, "StepSimulation needs a paused simulation; pause it first")
            return response
        with self.lock:
            try:
                self._step_world(steps)
            except (UnstableSimulationError, StepInterruptedError) as exc:
                _fail(response.result, FAILED, str(exc))
                return response
            self._after_step()
        _ok(response.result)
        return response

    # -- uniros_interfaces ------------------------------------------------------------------
    @_guarded
    def _srv_step_robot(self, request: Any, response: Any) -> Any:
        res = response.result
        steps = int(request.steps)
        if self._too_many_steps(steps, res):
            return response
        if len(request.frames) > _MAX_FRAMES:
            _fail(res, response.UNKNOWN_FRAME, f"{len(request.frames)} frames requested; at most {_MAX_FRAMES}")
            return response
        if steps > 0 and self._state != SimulationState.STATE_PAUSED:
            _fail(res, INCORRECT_STATE, "StepRobot with steps > 0 needs a paused simulation (lockstep mode)")
            return response
        entity = request.entity
        with self.lock:
            robot = self._robots.get(entity)
            if robot is None:
                _fail(res, NOT_FOUND, f"no robot {entity!r}; robots: {list(self._robots)}")
                return response
            try:
                for command in request.commands:
                    self.world.set_command(entity, command.controller, command.command)
            except CommandError as exc:
                _fail(res, response.BAD_COMMAND, str(exc))
                return response
            except ControllerError as exc:
                _fail(res, response.UNKNOWN_CONTROLLER, str(exc))
                return response
            frames = tuple(request.frames)
            frame_set = None
            if frames:
                key = (entity, frames)
                frame_set = self._frame_sets.get(key)
                if frame_set is None:
                    try:
                        frame_set = self.world.frame_set(frames, entity)
                    except EntityError as exc:
                        _fail(res, response.UNKNOWN_FRAME, str(exc))
                        return response
                    if len(self._frame_sets) >= _MAX_FRAME_SETS:  # distinct frame lists are not unbounded memory
                        self._frame_sets.clear()
                    self._frame_sets[key] = frame_set
            if steps > 0:
                try:
                    self._step_world(steps)
                except UnstableSimulationError as exc:
                    _fail(res, response.UNSTABLE, str(exc))
                    return response
                except StepInterruptedError as exc:
                    _fail(res, FAILED, str(exc))
                    return response
                self._after_step()
            robot.fill_joint_state(response.joint_state)
            response.sim_time = convert.time_msg(self.world.time)
            if frame_set is not None:
                response.frame_poses = [convert.pose_from_row(row) for row in frame_set.poses()]
        _ok(res)
        return response

    def _srv_set_robot_joint_state(self, request: Any, response: Any) -> Any:
        js = request.joint_state
        with self.lock:
            robot = self._robots.get(request.entity)
            if robot is None:
                _fail(response.result, NOT_FOUND, f"no robot {request.entity!r}; robots: {list(self._robots)}")
                return response
            velocities = js.velocity if len(js.velocity) else None
            try:
                self.world.set_joint_positions(
                    request.entity, list(js.name), js.position, velocities, hold=request.hold
                )
            except EntityError as exc:
                _fail(response.result, response.UNKNOWN_JOINT, str(exc))
                return response
            except ValueError as exc:
                _fail(response.result, response.BAD_VALUE, str(exc))
                return response
            robot.fill_joint_state(response.joint_state)
            response.sim_time = convert.time_msg(self.world.time)
        _ok(response.result)
        return response

    def _srv_get_physics_properties(self, request: Any, response: Any) -> Any:
        with self.lock:
            response.time_step = float(self.world.timestep)
            response.real_time_factor = float(self._runner.real_time_factor)
            g = self.world.gravity
            response.gravity.x, response.gravity.y, response.gravity.z = (float(v) for v in g)
        _ok(response.result)
        return response

    def _srv_set_physics_properties(self, request: Any, response: Any) -> Any:
        if request.set_time_step and not (np.isfinite(request.time_step) and request.time_step > 0):
            _fail(response.result, FAILED, f"time_step must be > 0 seconds, got {request.time_step}")
            return response
        g = request.gravity
        if request.set_gravity and not np.all(np.isfinite([g.x, g.y, g.z])):
            _fail(response.result, FAILED, "gravity must be finite")
            return response
        if request.set_real_time_factor and not np.isfinite(request.real_time_factor):
            _fail(response.result, FAILED, "real_time_factor must be finite (<= 0 = as fast as possible)")
            return response
        with self.lock:
            if request.set_time_step:
                self.world.timestep = float(request.time_step)
            if request.set_gravity:
                self.world.gravity = (g.x, g.y, g.z)
            if request.set_real_time_factor:
                self._runner.real_time_factor = float(request.real_time_factor)
        self._srv_get_physics_properties(None, response)
        return response

    def _get_renderer(self) -> Any:
        if self._renderer is None:
            from multiros.sim.render_service import Renderer

            self._renderer = Renderer(self.world)
        return self._renderer

    def _on_marker(self, marker: Any) -> None:
        from multiros.sim.render_service import apply_marker

        with self.lock:
            try:
                apply_marker(self._get_renderer(), marker)
            except ValueError as exc:
                self.get_logger().warning("marker %s/%s ignored: %s", marker.ns, marker.id, exc)

    def _srv_render_camera(self, request: Any, response: Any) -> Any:
        from multiros.sim.render_service import render_image_msgs

        with self.lock:
            try:
                render_image_msgs(self._get_renderer(), request, response, self.world.time)
            except (RenderError, EntityError, ValueError) as exc:
                _fail(response.result, FAILED, str(exc))
                return response
        _ok(response.result)
        return response

    # -- conveniences for the launcher -------------------------------------------------------
    def spawn_from_cli(self, name: str, uri: str) -> str:
        """Spawn ``NAME=URI`` from the command line through the SpawnEntity service logic.

        The command line is the node owner's: its URI may name any file the user can read and
        xacro runs on it (the source policy applies to requests only); the limits still apply.

        Raises:
            RuntimeError: the spawn failed (the message is the service's error message).
        """
        srv = _SRV["spawn_entity"]
        request = srv.Request(name=name)
        request.entity_resource.uri = uri
        response = self._spawn(request, srv.Response(), None)
        if response.result.result != OK:
            raise RuntimeError(f"cannot spawn {name!r} from {uri!r}: {response.result.error_message}")
        return response.entity_name

    def mark_launched(self, names: tuple[str, ...] | list[str] | None = None) -> tuple[str, ...]:
        """Record entities (default: all present now) as the launched world, which
        ``ResetSimulation`` with ``SCOPE_ALL``/``SCOPE_DEFAULT`` restores (see :meth:`World.mark_launched`)."""
        with self.lock:
            return self.world.mark_launched(names)

    def open_viewer(self) -> None:
        """Open the interactive MuJoCo viewer on this node's world (needs a display)."""
        from multiros.sim.render import open_viewer

        with self.lock:
            self._viewer = open_viewer(self.world)

    # -- lifecycle --------------------------------------------------------------------------
    def destroy_node(self) -> None:
        """Stop real-time physics and the topic thread, drop the per-robot interfaces and the renderer,
        destroy the node. A step call in progress stops at its next chunk."""
        self._stopping.set()
        self._runner.stop()
        if self._executor is not None:
            self._executor.shutdown()
            if self._spin_thread is not None and self._spin_thread is not threading.current_thread():
                self._spin_thread.join(timeout=5.0)
            self._executor = None
        for name in list(self._robots):
            self._detach_robot(name)
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        super().destroy_node()
