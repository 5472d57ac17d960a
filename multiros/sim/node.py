"""The MuJoCo simulation node: a ROS 2 node serving ``simulation_interfaces`` over a :class:`World`.

Service callbacks stay thin: decode the request, call one ``World`` method under the node's lock,
encode the reply with the standard result code. The larger handlers live beside this module:
SpawnEntity in :mod:`multiros.sim.node_spawn`, StepSimulation and StepRobot in
:mod:`multiros.sim.node_stepping`, the result helpers in :mod:`multiros.sim.node_results`.
Per-robot topics and controller-manager services live in :mod:`multiros.sim.robot_io`, the
actions in :mod:`multiros.sim.actions`.

Services (``~`` = this node, default ``/mujoco_sim``):
``~/get_simulator_features``, ``~/spawn_entity``, ``~/delete_entity``, ``~/get_entities``,
``~/get_entity_state``, ``~/set_entity_state``, ``~/get_entities_states``, ``~/reset_simulation``,
``~/get_simulation_state``, ``~/set_simulation_state``, ``~/step_simulation``, and the project's own
``~/step_robot`` (the lockstep env step), ``~/step_robots`` (a batch of robots in one round trip),
``~/get_node_load`` (robots, limits, physics rate, memory), ``~/set_robot_joint_state``,
``~/get_physics_properties``, ``~/set_physics_properties``, ``~/render_camera``, ``~/set_entity_properties``.
Topics: ``/clock`` while time advances; per robot ``joint_states``, ``robot_description``,
controller command topics; ``/tf`` and ``/tf_static`` (every link by its URDF name,
:mod:`multiros.sim.tf_publisher`); the cameras' images at their own rate, beside the physics
(:mod:`multiros.sim.camera_stream`).
"""

from __future__ import annotations

import dataclasses
import logging
import re
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from multiros.ros import Node, ParameterDescriptor
from multiros.ros.callback_groups import ReentrantCallbackGroup
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.logging import LogThrottle
from multiros.ros.processes import is_private_graph
from multiros.ros.qos import qos_profile_clock
from multiros.ros.service import current_caller
from multiros.sim import convert
from multiros.sim.actions import SimulateStepsAction
from multiros.sim.camera_stream import DEFAULT_CAMERA_RATE, CameraStream
from multiros.sim.cameras import CameraFrame, CameraHub, CameraSpec, camera_specs
from multiros.sim.description import SourcePolicy
from multiros.sim.distro_adapters import create_services, get_message, get_service
from multiros.sim.errors import ControllerError, DescriptionError, EntityError, RenderError, UnstableSimulationError
from multiros.sim.fair_lock import FairLock
from multiros.sim.limits import (
    MAX_ENTITIES_PER_CLIENT,
    MAX_ROBOTS,
    MAX_STEPS_PER_CALL,
    STEP_CHUNK,
    DescriptionLimits,
    default_max_entities,
)
from multiros.sim.node_load import LoadMeter, get_node_load
from multiros.sim.node_quota import EntityQuota
from multiros.sim.node_results import FAILED, NOT_FOUND, OK, Result, fail, guarded, ok
from multiros.sim.node_spawn import spawn_entity
from multiros.sim.node_stepping import FrameSetCache, step_robot, step_robots, step_simulation
from multiros.sim.robot_io import RobotInterfaces
from multiros.sim.services import SIM_SERVICES
from multiros.sim.state_gather import StateGather
from multiros.sim.tf_publisher import TFPublisher, check_frame_prefix
from multiros.sim.world import EntityCategory, RealTimeRunner, ResetScope, World, WorldOptions

SimulationState = get_message("simulation_interfaces/msg/SimulationState")
SimulatorFeatures = get_message("simulation_interfaces/msg/SimulatorFeatures")
EntityStateMsg = get_message("simulation_interfaces/msg/EntityState")
Clock = get_message("rosgraph_msgs/msg/Clock")
Marker = get_message("visualization_msgs/msg/Marker")
MarkerArray = get_message("visualization_msgs/msg/MarkerArray")

# The native (Rolling) variants; Jazzy/Kilted peers are served through multiros.sim.distro_adapters.
_SRV = {name: get_service(type_name) for name, type_name in SIM_SERVICES.items()}

_TURN_SEC = 0.002  # work a long step call does between two turns of the others (seconds)
_MIN_CHUNK = 10  # steps

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
        max_robots: most robots the node holds (default :data:`multiros.sim.limits.MAX_ROBOTS`;
            also the read-only ROS parameter ``max_robots``); SpawnEntity refuses more.
        max_entities: most entities (robots and objects, every client together) the node holds
            (default :func:`multiros.sim.limits.default_max_entities` of ``max_robots``: 4 per robot
            + 64; also the read-only ROS parameter ``max_entities``); SpawnEntity refuses more.
        max_entities_per_client: entities one client may hold besides 4 per robot it holds
            (default :data:`multiros.sim.limits.MAX_ENTITIES_PER_CLIENT`; read-only ROS parameter
            ``max_entities_per_client``); see :mod:`multiros.sim.node_quota`.
        frame_prefix: TF frame prefix of every entity's links (read-only ROS parameter
            ``frame_prefix``): ``""`` (default) publishes the description's link names as they are,
            as robot_state_publisher does; ``"{entity}/"`` puts each entity's name first (never twice).
        camera_rate: images per second of each subscribed camera topic whose sensor has no
            ``<update_rate>`` (read-only ROS parameter ``camera_rate``, default 15), rendered beside
            the physics (:mod:`multiros.sim.camera_stream`).
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
        max_robots: int = MAX_ROBOTS,
        max_entities: int | None = None,
        max_entities_per_client: int = MAX_ENTITIES_PER_CLIENT,
        frame_prefix: str = "",
        camera_rate: float = DEFAULT_CAMERA_RATE,
        **node_kwargs: Any,
    ) -> None:
        super().__init__(node_name, **node_kwargs)
        self._stopping = threading.Event()  # set first by destroy_node: long step calls stop at the next chunk
        self.source_policy = SourcePolicy.create(trusted_paths, allow_xacro_strings)
        self.description_limits = description_limits or DescriptionLimits()
        self.max_steps_per_call = self._declare_limit(
            "max_steps_per_call", max_steps_per_call, "most physics steps per StepSimulation/StepRobot call")
        robots = self.max_robots = self._declare_limit("max_robots", max_robots, "most robots this node holds")
        entities = self._declare_limit(
            "max_entities", default_max_entities(robots) if max_entities is None else max_entities,
            "most entities (robots and objects) this node holds")
        per_client = self._declare_limit(
            "max_entities_per_client", max_entities_per_client,
            "most entities one client holds on this node, besides 4 per robot it holds")
        self.entity_quota = EntityQuota(entities, per_client, robots)  # multiros.sim.node_quota
        prefix = check_frame_prefix(self.declare_parameter(
            "frame_prefix", str(frame_prefix),
            ParameterDescriptor(read_only=True, description="TF frame prefix of the entities' links ('{entity}/' "
                                                            "for each entity's name; '' for the URDF's names)"),
        ).value)
        rate = self.declare_parameter(
            "camera_rate", float(camera_rate),
            ParameterDescriptor(read_only=True, description="images per second of a subscribed camera topic "
                                                            "(sensors' <update_rate> first)"),
        ).value
        self.load = LoadMeter()  # ~/get_node_load
        self._executor: Any = None
        self._spin_thread: threading.Thread | None = None
        self.world = world if world is not None else World(options)
        self._owns_world = world is None  # destroy_node closes a world it made
        # One lock over the world, granting turns first come first served; long step calls give way
        # between chunks (multiros.sim.fair_lock), so no client monopolises the node.
        self._runner = RealTimeRunner(
            self.world, real_time_factor=real_time_factor, on_chunk=self._after_realtime_chunk,
            on_error=self._realtime_error, lock=FairLock(),
        )
        self.lock = self._runner.lock
        self._step_cost = 2e-5  # seconds per physics step, a running estimate (sizes the chunks of long calls)
        self._state_lock = threading.Lock()  # SetSimulationState transitions, one at a time
        self._state = SimulationState.STATE_PAUSED
        self._robots: dict[str, RobotInterfaces] = {}
        self._frame_sets = FrameSetCache(max(64, 2 * self.max_robots))  # StepRobot(s)' frame sets
        self.state_gather = StateGather(self.world)  # composed StepRobots calls read all robots at once
        self._renderer: Any = None
        self._viewer: Any = None
        self._clock_pub = self.create_publisher(Clock, "/clock", qos_profile_clock)
        self._marker_subs = [
            self.create_subscription(Marker, "/visualization_marker", self._on_marker, 100),
            self.create_subscription(MarkerArray, "/visualization_marker_array",
                                     lambda msg: [self._on_marker(m) for m in msg.markers], 10),
        ]
        # A marker applies when it arrives, in the delivering thread (the publisher's in-process; over
        # Zenoh its receive thread, in order with the requests behind it), never later from a topic
        # executor: the goal marker an env publishes in reset() is in the very next rendered image.
        self._renderer_lock = threading.Lock()
        self._ignored_markers = LogThrottle()
        for sub in self._marker_subs:
            sub._deliver_directly(wire_inline=True)
        # Camera topics (sensor_msgs/Image, CameraInfo) of the entities' cameras (multiros.sim.cameras).
        self.cameras = CameraHub(self, self._get_renderer, lambda text: self.get_logger().error("%s", text),
                                 log_unpublished=lambda text: self._log_for_the_graph(logging.ERROR, text))
        self.camera_stream = CameraStream(
            self.cameras, self.world, self.lock, rate=rate, pacing=self._pacing,
            warn=lambda text: self.get_logger().warning("%s", text),
            error=lambda text: self.get_logger().error("%s", text))
        self.tf = TFPublisher(self, self.world, self.lock, prefix,
                              warn=lambda text: self._log_for_the_graph(logging.WARNING, text))
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

    def _declare_limit(self, name: str, value: int, description: str) -> int:
        """Declare the read-only integer parameter ``name`` (a limit of the node) and return it.

        Raises:
            ValueError: it is not an integer >= 1.
        """
        declared = self.declare_parameter(name, int(value), ParameterDescriptor(read_only=True,
                                                                                description=description)).value
        if not isinstance(declared, int) or declared < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {declared!r}")
        return declared

    def _log_for_the_graph(self, level: int, text: str) -> None:
        """A refusal that matters to ROS 2 tools looking at the node (a TF frame clash, a camera not
        published): at ``level`` where they may look; on a graph of its owner's only (in-process: an env's
        own node, the robots of a vector env; a process-mode node's private graph) nobody else can, so it
        is only logged at INFO."""
        self.get_logger().log(logging.INFO if is_private_graph(self.context) else level, "%s", text)

    def start_serving(self) -> None:
        """Create the simulation services (once); until then the node answers no service call."""
        if self._services:
            return
        # Concurrent: every callback guards the world with the node's lock, so a quick request is
        # answered while a long one is in progress (and waits its turn, not the whole long call).
        group = ReentrantCallbackGroup()
        self._services = [  # every served distribution's variant of each (multiros.sim.distro_adapters)
            srv for name, type_name in SIM_SERVICES.items()
            for srv in create_services(self, type_name, f"~/{name}", getattr(self, f"_srv_{name}"),
                                       callback_group=group)
        ]
        self._simulate_steps = SimulateStepsAction(self)  # ~/simulate_steps (multiros.sim.actions)

    # -- helpers ----------------------------------------------------------------------------
    def _locked(self, fn: Callable[[], None]) -> None:
        with self.lock:
            fn()

    def _publish_clock(self) -> bool:
        if self._clock_pub.has_subscribers():
            self._clock_pub.publish(Clock(clock=convert.time_msg(self.world.time)))
            return True
        return False

    def _after_step(self) -> None:
        """After the world advanced: running trajectory goals check their tolerances; /clock, each
        robot's state topics and the cameras are published to whoever listens. Nobody listening at a
        graph version (lockstep training, the usual case), the next steps at that version skip the
        per-topic checks."""
        for robot in self._robots.values():
            robot.on_step()
        version = self.context.transport.graph_version()
        if version is not None and version == self._quiet_at:
            return
        listened = self._publish_clock()
        for robot in self._robots.values():
            listened = robot.publish_state() or listened
        listened = self.tf.publish() or listened
        self._quiet_at = None if listened else version

    _quiet_at: int | None = None

    def _after_realtime_chunk(self, world: World) -> None:
        self._after_step()

    def _pacing(self) -> tuple[bool, float, float | None]:
        """Whether the node plays in real time, its target and its measured real-time factor."""
        runner = self._runner
        return runner.running, float(runner.real_time_factor), runner.measured_real_time_factor

    def _realtime_error(self, exc: BaseException) -> None:
        if isinstance(exc, UnstableSimulationError):  # contained: real time goes on
            self._on_unstable(exc)
            self.get_logger().warning("%s", exc)
            return
        self.get_logger().error("real-time physics stopped: %s", exc)

    def _on_unstable(self, exc: UnstableSimulationError) -> None:
        """Drop the ROS interfaces of robots the world removed (lock held by this thread's call)."""
        for name in exc.removed:
            self._detach_robot(name)

    def unknown_robot_message(self, name: str) -> str:
        """Why no robot ``name`` is served: the world removed it (and why), or it is not there."""
        reason = self.world.removal_reason(name)
        if reason is not None and not self.world.has_entity(name):
            return f"robot {name!r} {reason}"
        return f"no robot {name!r}; robots: {list(self._robots)}"

    def _attach_robot(self, name: str) -> None:
        info = self.world.entity(name)
        specs = camera_specs(info.name, info.namespace, info.description, self.world.model)
        frames = None
        if info.category == EntityCategory.ROBOT or specs:  # robots, and whatever carries a camera
            frames = self.tf.attach(name, [(spec.camera, spec.frame_name) for spec in specs])
        if info.category == EntityCategory.ROBOT:
            self._robots[name] = RobotInterfaces(self, self.world, info, self.lock)
        self.cameras.attach(info, None if frames is None else
                            (lambda spec: frames.camera_frames.get(spec.camera, spec.frame_id)))
        if self.cameras.entities:
            self.camera_stream.start()

    def _detach_robot(self, name: str) -> None:
        robot = self._robots.pop(name, None)
        if robot is not None:
            robot.destroy()
        self.tf.detach(name)
        self.cameras.detach(name)
        self._frame_sets.forget(name)

    def trust_paths(self, paths: Iterable[str | Path]) -> None:
        """Let descriptions name local files under ``paths`` too: for envs composed in this process
        (the node's owner), whose robot files live in their own package folders. A node in another
        process takes its trusted paths at start (``--trusted-path``) and from nobody else."""
        extra = SourcePolicy.create(paths).trusted_paths
        with self.lock:
            known = self.source_policy.trusted_paths
            self.source_policy = dataclasses.replace(
                self.source_policy, trusted_paths=known + tuple(p for p in extra if p not in known))

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
            self.tf.changed()
        self._state = state

    def _sync_robots(self, respawned: tuple[str, ...] = ()) -> None:
        """Drop interfaces of robots a reset removed; re-create those of entities it spawned anew."""
        for name in {*self._robots, *self.cameras.entities}:
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
            fail(response.result, Result.RESULT_FEATURE_UNSUPPORTED,
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
        ok(response.result)
        return response

    @guarded
    def _srv_spawn_entity(self, request: Any, response: Any) -> Any:
        # The limits and the caller's quota are checked before anything is loaded (multiros.sim.node_quota).
        return spawn_entity(self, request, response, self.source_policy, caller=current_caller())

    @property
    def max_entities(self) -> int:
        """Most entities (robots and objects) this node holds (read-only parameter ``max_entities``)."""
        return self.entity_quota.max_entities

    @property
    def max_entities_per_client(self) -> int:
        """Entities one client may hold besides 4 per robot (read-only parameter ``max_entities_per_client``)."""
        return self.entity_quota.max_entities_per_client

    def _srv_delete_entity(self, request: Any, response: Any) -> Any:
        with self.lock:
            if not self.world.has_entity(request.entity):
                known = list(self.world.entity_names())
                fail(response.result, NOT_FOUND, f"no entity {request.entity!r}; entities: {known}")
                return response
            self._detach_robot(request.entity)
            self.world.delete(request.entity)
        ok(response.result)
        return response

    def _filtered_entities(self, filters: Any, result: Any) -> list[str] | None:
        try:
            pattern = re.compile(filters.filter) if filters.filter else None
        except re.error as exc:
            fail(result, FAILED, f"filter {filters.filter!r} is not a valid regular expression: {exc}")
            return None
        if len(filters.tags.tags) > 0:
            fail(result, Result.RESULT_FEATURE_UNSUPPORTED, "entity tags are not supported")
            return None
        if filters.bounds.type != 0 or len(filters.bounds.points) > 0:
            fail(result, Result.RESULT_FEATURE_UNSUPPORTED, "bounds filters are not supported")
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
            ok(response.result)
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
                fail(response.result, NOT_FOUND, f"no entity {request.entity!r}")
                return response
            response.state = self._entity_state(request.entity)
        ok(response.result)
        return response

    def _srv_get_entities_states(self, request: Any, response: Any) -> Any:
        with self.lock:
            names = self._filtered_entities(request.filters, response.result)
            if names is None:
                return response
            response.entities = names
            response.states = [self._entity_state(n) for n in names]
        ok(response.result)
        return response

    def _srv_set_entity_state(self, request: Any, response: Any) -> Any:
        res = response.result
        frame = request.state.header.frame_id
        if frame not in ("", "world"):
            fail(res, FAILED, f"frame {frame!r} is not supported; use 'world' (or empty)")
            return response
        kwargs: dict[str, Any] = {}
        if request.set_pose:
            position, quat = convert.pose_to_arrays(request.state.pose)
            problem = convert.validate_quaternion(quat)
            if problem or not np.all(np.isfinite(position)):
                fail(res, response.INVALID_POSE, problem or f"position {position.tolist()} is not finite")
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
                fail(res, NOT_FOUND, f"no entity {request.entity!r}")
                return response
            try:
                self.world.set_entity_state(request.entity, **kwargs)
            except ValueError as exc:
                fail(res, FAILED, str(exc))
                return response
        self.tf.changed()
        ok(res)
        return response

    def _srv_reset_simulation(self, request: Any, response: Any) -> Any:
        # SCOPE_DEFAULT (0) and SCOPE_ALL (255): the launched world comes back (World.reset).
        scope = int(request.scope)
        with self.lock:
            try:
                respawned = self.world.reset(scope)
            except (DescriptionError, EntityError, ControllerError, ValueError) as exc:
                self._sync_robots(self.world.entity_names())
                fail(response.result, FAILED, f"reset (scope {scope}) could not re-create the launched world: {exc}")
                return response
            self._sync_robots(respawned)
            for robot in self._robots.values():
                robot.on_reset()
        self.tf.changed()
        ok(response.result)
        return response

    def _srv_get_simulation_state(self, request: Any, response: Any) -> Any:
        response.state.state = self._state
        ok(response.result)
        return response

    def _srv_set_simulation_state(self, request: Any, response: Any) -> Any:
        with self._state_lock:
            return self._set_simulation_state(request, response)

    def _set_simulation_state(self, request: Any, response: Any) -> Any:
        target = int(request.state.state)
        valid = (SimulationState.STATE_STOPPED, SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED)
        if target not in valid:
            fail(response.result, response.INCORRECT_TRANSITION, f"state {target} cannot be set on this node")
            return response
        if target == self._state:
            fail(response.result, response.ALREADY_IN_TARGET_STATE, "already in the requested state")
            return response
        if target == SimulationState.STATE_PAUSED and self._state == SimulationState.STATE_STOPPED:
            # The standard allows pausing a stopped simulation: start it paused.
            self._state = SimulationState.STATE_PAUSED
        else:
            self._set_state(target)
        ok(response.result)
        return response

    def _step_world(self, steps: int) -> None:
        """Step (lock held by the caller); a long call runs in chunks of about
        :data:`_TURN_SEC` of work, between which it stops when the node shuts down and lets every
        request that arrived meanwhile have its turn. A call shorter than two such chunks runs as
        one: a turn taken inside it would save the others less than a turn's length, and each chunk
        costs a snapshot and the actuator writes of every robot (a vector env's step of 25 physics
        steps on a node of four RX200s was cut in two). Robots the world removed lose their interfaces.

        Raises:
            UnstableSimulationError, StepInterruptedError: as ``World.step``.
        """
        start = time.perf_counter()
        chunk = max(_MIN_CHUNK, min(STEP_CHUNK, int(_TURN_SEC / self._step_cost)))
        if steps < 2 * chunk:
            chunk = steps
        try:
            self.world.step(steps, should_stop=self._between_chunks, chunk=chunk)
        except UnstableSimulationError as exc:
            self._on_unstable(exc)
            raise
        finally:
            elapsed = time.perf_counter() - start
            self.load.record(steps, elapsed)
            if steps >= 10:
                self._step_cost = 0.8 * self._step_cost + 0.2 * max(elapsed / steps, 1e-7)

    def _between_chunks(self) -> bool:
        """Between two chunks of a long step call: True to stop (shutting down); else give way."""
        if self._stopping.is_set():
            return True
        self.lock.yield_turn()
        return self._stopping.is_set()

    @guarded
    def _srv_step_simulation(self, request: Any, response: Any) -> Any:
        return step_simulation(self, request, response)

    # -- uniros_interfaces ------------------------------------------------------------------
    @guarded
    def _srv_step_robot(self, request: Any, response: Any) -> Any:
        return step_robot(self, request, response)

    @guarded
    def _srv_step_robots(self, request: Any, response: Any) -> Any:
        return step_robots(self, request, response)

    def _srv_get_node_load(self, request: Any, response: Any) -> Any:
        return get_node_load(self, request, response)

    def _srv_set_robot_joint_state(self, request: Any, response: Any) -> Any:
        js = request.joint_state
        with self.lock:
            robot = self._robots.get(request.entity)
            if robot is None:
                fail(response.result, NOT_FOUND, self.unknown_robot_message(request.entity))
                return response
            velocities = js.velocity if len(js.velocity) else None
            try:
                self.world.set_joint_positions(
                    request.entity, list(js.name), js.position, velocities, hold=request.hold
                )
            except EntityError as exc:
                fail(response.result, response.UNKNOWN_JOINT, str(exc))
                return response
            except ValueError as exc:
                fail(response.result, response.BAD_VALUE, str(exc))
                return response
            robot.fill_joint_state(response.joint_state)
            response.sim_time = convert.time_msg(self.world.time)
        self.tf.changed()
        ok(response.result)
        return response

    def _srv_set_entity_properties(self, request: Any, response: Any) -> Any:
        from multiros.sim.entity_properties import PropertyError

        with self.lock:
            if not self.world.has_entity(request.entity):
                fail(response.result, NOT_FOUND, self.world.unknown_entity_message(request.entity))
                return response
            try:
                response.changed = self.world.set_entity_properties(
                    request.entity, list(request.targets), list(request.names), list(request.properties),
                    list(request.values), restore=bool(request.restore))
            except PropertyError as exc:
                code = response.UNKNOWN_NAME if " has no " in str(exc) else response.BAD_VALUE
                fail(response.result, code, str(exc))
                return response
        ok(response.result)
        return response

    def _srv_get_physics_properties(self, request: Any, response: Any) -> Any:
        with self.lock:
            response.time_step = float(self.world.timestep)
            response.real_time_factor = float(self._runner.real_time_factor)
            g = self.world.gravity
            response.gravity.x, response.gravity.y, response.gravity.z = (float(v) for v in g)
        ok(response.result)
        return response

    def _srv_set_physics_properties(self, request: Any, response: Any) -> Any:
        if request.set_time_step and not (np.isfinite(request.time_step) and request.time_step > 0):
            fail(response.result, FAILED, f"time_step must be > 0 seconds, got {request.time_step}")
            return response
        g = request.gravity
        if request.set_gravity and not np.all(np.isfinite([g.x, g.y, g.z])):
            fail(response.result, FAILED, "gravity must be finite")
            return response
        if request.set_real_time_factor and not np.isfinite(request.real_time_factor):
            fail(response.result, FAILED, "real_time_factor must be finite (<= 0 = as fast as possible)")
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
        with self._renderer_lock:
            if self._renderer is None:
                from multiros.sim.render_service import Renderer

                self._renderer = Renderer(self.world)
            return self._renderer

    def _on_marker(self, marker: Any) -> None:
        # Runs in the delivering thread without the world lock: the renderer guards its markers.
        from multiros.sim.render_service import apply_marker

        try:
            apply_marker(self._get_renderer(), marker)
        except ValueError as exc:
            self._ignored_markers.log(self.get_logger(), logging.WARNING, "marker %s/%s ignored: %s", marker.ns,
                                      marker.id, exc)

    def _srv_render_camera(self, request: Any, response: Any) -> Any:
        from multiros.sim.render_service import render_image_msgs

        with self.lock:
            try:
                render_image_msgs(self._get_renderer(), request, response, self.world.time)
            except (RenderError, EntityError, ValueError) as exc:
                fail(response.result, FAILED, str(exc))
                return response
            spec = self.cameras.spec(request.camera)
            if spec is not None:  # a camera sensor's image is in its optical frame, as its topics' are
                response.image.header.frame_id = spec.frame_id
        ok(response.result)
        return response

    # -- conveniences for the launcher -------------------------------------------------------
    def spawn_from_cli(self, name: str, uri: str) -> str:
        """Spawn ``NAME=URI`` from the command line through the SpawnEntity service logic.

        The command line is the node owner's: its URI may name any file the user can read and
        xacro runs on it (the source policy applies to requests only); the description limits still
        apply, the entity limits and quotas do not (its entities belong to no client).

        Raises:
            RuntimeError: the spawn failed (the message is the service's error message).
        """
        srv = _SRV["spawn_entity"]
        request = srv.Request(name=name)
        request.entity_resource.uri = uri
        response = spawn_entity(self, request, srv.Response(), None, limited=False)
        if response.result.result != OK:
            raise RuntimeError(f"cannot spawn {name!r} from {uri!r}: {response.result.error_message}")
        return response.entity_name

    def mark_launched(self, names: tuple[str, ...] | list[str] | None = None) -> tuple[str, ...]:
        """Record entities (default: all present now) as the launched world, which
        ``ResetSimulation`` with ``SCOPE_ALL``/``SCOPE_DEFAULT`` restores (see :meth:`World.mark_launched`)."""
        with self.lock:
            return self.world.mark_launched(names)

    def camera_specs(self) -> list[CameraSpec]:
        """The cameras this node publishes: names, image sizes, depth or not, topics."""
        with self.lock:
            return self.cameras.specs()

    def read_camera(self, camera: str, *, rgb: bool = True, depth: bool = False, width: int | None = None,
                    height: int | None = None) -> CameraFrame:
        """A camera's images of the world as it is now, without messages (for a composed client):
        the pixels its topics carry for this state, rendered once for both. Size: the sensor's,
        unless given.

        Raises:
            RenderError: an unknown camera, a size out of range, or no offscreen GL (set
                ``MUJOCO_GL=egl`` or ``osmesa``).
        """
        with self.lock:
            return self.cameras.read(camera, rgb=rgb, depth=depth, width=width, height=height)

    def open_viewer(self) -> None:
        """Open the interactive MuJoCo viewer on this node's world (needs a display)."""
        from multiros.sim.render import open_viewer

        with self.lock:
            self._viewer = open_viewer(self.world)

    # -- lifecycle --------------------------------------------------------------------------
    def destroy_node(self) -> None:
        """Stop real-time physics and the topic thread, drop the per-robot interfaces and the renderer,
        destroy the node. A step call in progress stops at its next chunk."""
        if not hasattr(self, "_runner"):  # __init__ failed early (e.g. rcl refused the node): nothing to stop
            return
        self._stopping.set()
        self._runner.stop()
        self.camera_stream.close()
        self.tf.close()
        if self._executor is not None:
            self._executor.shutdown()
            if self._spin_thread is not None and self._spin_thread is not threading.current_thread():
                self._spin_thread.join(timeout=5.0)
            self._executor = None
        for name in list(self._robots):
            self._detach_robot(name)
        self.cameras.destroy()
        with self._renderer_lock:
            if self._renderer is not None:
                self._renderer.close()
                self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        super().destroy_node()
        if self._owns_world:  # its MuJoCo memory goes now, not at the next full garbage collection
            with self.lock:
                self.world.close()
                self._frame_sets.clear()
                self.state_gather.clear()
