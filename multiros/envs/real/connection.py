"""A real ros2_control robot, as the env core drives it (:class:`RealConnection`).

The connection talks to the robot only through what a ros2_control robot offers
(:class:`~multiros.envs.real.robot_link.RobotLink`): no simulation service, no simulation clock.
Every arm command passes :class:`~multiros.envs.real.safety.SafetyRules` first; a step waits the
control cycle (:class:`~multiros.envs.real.control_loop.ControlLoop`) while a watchdog checks the
robot's states; a stale or malformed ``joint_states`` stops commanding and raises
:class:`~multiros.envs.real.errors.StaleStateError`. When the env errors or closes it sends nothing
more: a JointTrajectoryController holds the end of its last trajectory, a forward command
controller its last command. Nothing here imports the simulation.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from multiros.envs.connection import STEP_OK, CameraRequest, RobotConnection, SceneEntity, StepStatus
from multiros.envs.errors import EnvError, ResetError
from multiros.envs.real.control_loop import ControlLoop
from multiros.envs.real.errors import RobotConnectionError, StaleStateError, UnsafeCommandError
from multiros.envs.real.robot_link import RobotLink
from multiros.envs.real.safety import SafetyDecision, SafetyRules
from multiros.envs.real.scene import RealScene, RealSceneOptions
from multiros.robot_state import RobotState, RobotStates
from multiros.utils.rotations import quat_from_matrix

__all__ = ["RealConnection"]

_logger = logging.getLogger(__name__)
#: Seconds of joint states a reset looks back over to tell an arm at rest (see :class:`_Settling`).
_SETTLE_WINDOW = 0.5
#: rad/s: slower than this, in every joint, the arm is at rest.
_SETTLE_SPEED = 0.02


@dataclass(frozen=True)
class CameraImages:
    """A real camera's newest images (:meth:`RealConnection.read_camera`): what a simulated camera's
    ``CameraFrame`` gives, without the intrinsics (a driver publishes its own ``camera_info``)."""

    camera: str
    rgb: np.ndarray | None
    depth: np.ndarray | None


def _interactive() -> bool:
    try:
        return sys.stdin is not None and sys.stdin.isatty()
    except (ValueError, OSError):
        return False


class _Settling:
    """Whether an arm that stopped short of its reset target has come to rest near it.

    Samples of the last :data:`_SETTLE_WINDOW` seconds are kept; the arm is still when the mean of the
    window's newer half differs from its older half's by less than :data:`_SETTLE_SPEED` rad/s in every
    joint (means, so that joint-state noise of a few milliradians does not read as motion), and settled
    when, still, the newer half's mean is within ``tolerance`` of the target.
    """

    def __init__(self, tolerance: float) -> None:
        self.tolerance = float(tolerance)
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self.still = False
        self.last_error = float("inf")

    def add(self, now: float, position: np.ndarray, goal: np.ndarray) -> float | None:
        """Add a sample; the settled error (rad) once settled within the tolerance, else ``None``."""
        self.times.append(now)
        self.positions.append(np.array(position, dtype=np.float64))
        while self.times and self.times[0] < now - _SETTLE_WINDOW:
            self.times.pop(0)
            self.positions.pop(0)
        if self.tolerance <= 0 or len(self.times) < 6 or now - self.times[0] < 0.8 * _SETTLE_WINDOW:
            return None
        half = len(self.positions) // 2
        older, newer = np.mean(self.positions[:half], axis=0), np.mean(self.positions[half:], axis=0)
        span = max((self.times[-1] - self.times[0]) / 2, 1e-3)
        self.still = bool(np.all(np.abs(newer - older) / span < _SETTLE_SPEED))
        self.last_error = float(np.max(np.abs(newer - goal)))
        return self.last_error if self.still and self.last_error <= self.tolerance else None


class RealConnection(RobotConnection):
    """A real robot over its ROS 2 driver (see the module docstring; the knobs are
    :class:`~multiros.envs.real.core.RealEnvCore`'s)."""

    def __init__(
        self,
        node: Any,
        *,
        owner: str,
        namespace: str,
        robot_name: str,
        arm_joints: Sequence[str],
        arm_controller: str | None,
        arm_controller_type: str,
        command_interface: str,
        controllers_list: Sequence[str],
        load_controllers: bool,
        check_controllers: bool = True,
        reset_controllers: bool,
        reset_controllers_prompt: bool,
        joint_states_topic: str,
        loop: ControlLoop,
        safety: SafetyRules | None,
        joint_state_timeout: float,
        startup_timeout: float,
        timeout_sec: float,
        reset_joint_speed: float,
        reset_tolerance: float,
        reset_settle_tolerance: float,
        reset_timeout: float,
        reset_env_prompt: bool,
        close_env_prompt: bool,
        use_sim_time: bool,
        log_internal_state: bool,
    ) -> None:
        self.owner = owner
        self.node = node
        self.namespace = namespace
        self.robot_name = robot_name
        self.arm_joints = tuple(arm_joints)
        self.arm_controller = arm_controller
        self.arm_controller_type = arm_controller_type
        self.command_interface = command_interface
        self.controllers_list = list(controllers_list)
        self.check_controllers = bool(check_controllers)
        self.reset_controllers = bool(reset_controllers)
        self.reset_controllers_prompt = bool(reset_controllers_prompt)
        self.loop = loop
        self.safety = safety
        self.joint_state_timeout = float(joint_state_timeout)
        self.startup_timeout = float(startup_timeout)
        self.timeout_sec = float(timeout_sec)
        self.reset_joint_speed = float(reset_joint_speed)
        self.reset_tolerance = float(reset_tolerance)
        self.reset_settle_tolerance = float(reset_settle_tolerance)
        self.reset_timeout = float(reset_timeout)
        self.reset_env_prompt = bool(reset_env_prompt)
        self.close_env_prompt = bool(close_env_prompt)
        self.log_internal_state = bool(log_internal_state)
        self.fault: BaseException | None = None
        self.last_command: np.ndarray | None = None
        self.last_decision: SafetyDecision | None = None
        self.commands_sent = 0
        self._state: RobotState | None = None
        self._states: RobotStates | None = None
        self._observed: tuple[str, ...] = ()
        self._driver_endpoint: Any = None  # the graph's record of the driver the states were pinned to
        self._closed = False
        self._frame_sources: dict[str, Callable[[RobotStates], tuple[np.ndarray, np.ndarray | None]]] = {}
        self._routes: dict[str, Callable[[np.ndarray], None]] = {}
        self._cameras: dict[str, tuple[Any, Any]] = {}  # name -> (rgb, depth) ImageTopic
        self._base = np.zeros(3)
        self.scene = RealScene(self, RealSceneOptions())
        self.link = RobotLink(node, namespace, joint_states_topic=joint_states_topic, use_sim_time=use_sim_time,
                              timeout_sec=self.timeout_sec)
        self._connect(load_controllers)

    # -- start-up ---------------------------------------------------------------------------
    @property
    def _controllers(self) -> list[str]:
        """The controllers the robot's controller manager must have active (none without one to ask)."""
        if not self.check_controllers:
            return []
        return ([self.arm_controller] if self.arm_controller else []) + [
            c for c in self.controllers_list if c != self.arm_controller]

    def _connect(self, load_controllers: bool) -> None:
        link = self.link
        needed = self.arm_joints
        deadline = time.monotonic() + self.startup_timeout
        ok = link.node.context.wait_for(
            lambda: link.states.received_count > 0 and all(j in link.states.names for j in needed),
            self.startup_timeout)
        if not ok:
            raise RobotConnectionError(
                f"no usable joint states from {link.joint_states_topic} within {self.startup_timeout:g} s "
                f"({link.states.describe_problem(needed)}): is the robot's driver running in namespace "
                f"{self.namespace!r}, with the same ROS_DOMAIN_ID ({link.node.context.domain_id}) and "
                f"{link.node.context.reach()} as this process?"
            )
        if self.safety is not None:
            link.states.guard(self.safety, fresh_for=self.joint_state_timeout / 2)
        self._adopt_driver(deadline)
        if not link.states.pinned:
            raise RobotConnectionError(f"joint_states on {link.joint_states_topic} stopped arriving during start-up "
                                       f"({link.states.describe_problem(needed)}): is the robot's driver running?")
        # The joints observed: the driver's own (values heard before it was pinned are gone).
        if not link.node.context.wait_for(lambda: bool(names := link.states.names) and all(j in names for j in needed),
                                          max(0.0, deadline - time.monotonic())):
            raise RobotConnectionError(
                f"the driver of {link.joint_states_topic} ({self.driver()}) sent no usable state of {list(needed)} "
                f"within {self.startup_timeout:g} s ({link.states.describe_problem(needed)})")
        self._observed = tuple(dict.fromkeys((*needed, *link.states.names)))
        controllers = self._controllers
        if controllers:
            if load_controllers:
                link.spawn_controllers(controllers)
            link.require_active(controllers)
        if self.arm_controller:
            remaining = max(0.5, deadline - time.monotonic())
            if self.arm_controller_type == "trajectory" and self.command_interface == "action":
                ready = link.wait_for_action(self.arm_controller, remaining)
                where = link.action_name(self.arm_controller)
            else:
                kind = "trajectory" if self.arm_controller_type == "trajectory" else "forward"
                ready = link.wait_for_subscriber(self.arm_controller, kind, remaining)
                where = (link.trajectory_topic(self.arm_controller) if kind == "trajectory"
                         else link.commands_topic(self.arm_controller))
            if not ready:
                raise RobotConnectionError(f"nobody serves {where} (controller {self.arm_controller!r} is active, but "
                                           f"its command interface did not appear within {remaining:.1f} s)")
        self._accept(self.fresh_sample())
        _logger.info("%s drives %r in %s: joint_states from %s", self.owner, self.robot_name, self.namespace,
                     self.driver())

    # -- state ------------------------------------------------------------------------------
    def publishers(self) -> list[str]:
        """Who publishes the robot's ``joint_states``: ``namespace/node`` per publisher in the graph."""
        infos = self.node.get_publishers_info_by_topic(self.link.joint_states_topic)
        return [f"{e.namespace.rstrip('/')}/{e.node_name}" + (f" (session {e.origin})" if e.origin else "")
                for e in infos]

    def check_single_publisher(self) -> None:
        """Exactly one driver must publish the robot's ``joint_states``: two robots' states (another
        user's robot on a shared graph) or a forged one mixed in would steer the safety rules.

        Raises:
            RobotConnectionError: more than one publisher (they are named); the env stops commanding.
        """
        count = self.node.count_publishers(self.link.joint_states_topic)
        if count > 1:
            err = RobotConnectionError(
                f"{count} publishers on {self.link.joint_states_topic} ({', '.join(self.publishers()) or 'unnamed'}): "
                f"a Real env must hear exactly one robot driver. Stop the others, or give this robot its own "
                "namespace, ROS_DOMAIN_ID or Zenoh router (docs/real_robots.md, docs/pitfalls.md)")
            self.fault = err
            raise err

    def _adopt_driver(self, deadline: float) -> None:
        """The one-driver rule, then take ``joint_states`` only from that driver's identity.

        A driver that just died may stay in the graph a moment (until its session is seen to end): a
        second publisher must persist until ``deadline`` to be refused. The identity is the one the
        graph lists for the publisher (its GID) when its messages carry it; a driver whose messages
        carry another (an rmw_zenoh driver: its GIDs are another hash of the same token) is pinned by
        the one identity heard; several identities heard with one publisher in the graph mean a
        process outside the graph publishes too, and are refused. A transport that gives no message
        identity (rclpy) leaves the publisher count as the only check.

        Raises:
            RobotConnectionError: several publishers, none in the graph, or several identities heard.
        """
        link, node = self.link, self.node
        topic = link.joint_states_topic
        remaining = lambda: max(0.0, deadline - time.monotonic())  # noqa: E731
        window = max(self.joint_state_timeout, 0.5)
        # One publisher; or none and nothing heard (a driver that is gone: the states' wait says so).
        node.context.wait_for(lambda: node.count_publishers(topic) == 1 or not link.states.sources(window),
                              remaining())
        self.check_single_publisher()
        infos = node.get_publishers_info_by_topic(topic)
        if not infos:
            if not link.states.sources(window):
                return
            err = RobotConnectionError(
                f"joint_states arrive on {topic} but no publisher of them is in the ROS graph: a process outside "
                "ROS puts them (a robot driver is a ROS node). Stop it, or give this robot its own namespace, "
                "ROS_DOMAIN_ID or Zenoh router (docs/real_robots.md)")
            self.fault = err
            raise err
        heard = link.states.sources(window)
        if infos[0] == self._driver_endpoint and link.states.driver in heard:
            return  # the same driver, still heard: nothing to decide again (no wait at a reset)
        expected: bytes | None = getattr(infos[0], "gid", b"") or None
        if expected is not None:
            # Its own identity, when its messages carry it: wait a little for one.
            node.context.wait_for(lambda: expected in link.states.sources(window), min(remaining(), 2 * window))
        heard = link.states.sources(window)
        if not heard:
            return  # a silent driver: the wait for fresh states says so
        if expected is not None and expected in heard:
            source: bytes | None = expected
        elif heard == [None]:
            source = None  # the transport gives no identities: the publisher count is the check
        elif len(heard) == 1 and heard[0] is not None:
            source = heard[0]
            _logger.info("%s: the messages of %s carry identity %s, not the one of its graph token (an rmw_zenoh "
                         "driver): only it is heard, it is pinned", self.owner, topic, source.hex()[:12])
        else:
            err = RobotConnectionError(
                f"joint_states on {topic} come from {len(heard)} publisher identities while the graph has one "
                f"publisher ({self.driver()}): a process outside the graph publishes on the topic too. Stop it, or "
                "give this robot its own namespace, ROS_DOMAIN_ID or Zenoh router (docs/real_robots.md)")
            self.fault = err
            raise err
        self._driver_endpoint = infos[0]
        if link.states.driver != source:
            _logger.info("%s takes joint_states only from %s (identity %s)", self.owner, self.driver(),
                         "none given" if source is None else source.hex()[:12])
        link.states.pin(source)

    def driver(self) -> str:
        """The one publisher of the robot's ``joint_states`` this env listens to (``namespace/node``)."""
        names = self.publishers()
        return names[0] if names else "(not in the graph)"

    def fresh_sample(self) -> RobotState:
        """The freshest state of the observed joints; :class:`StaleStateError` when too old."""
        sample = self.link.states.sample(self._observed)
        now = time.monotonic()
        if sample is None or sample.received is None or now - sample.received > self.joint_state_timeout:
            age = "never" if sample is None or sample.received is None else f"{now - sample.received:.3f} s ago"
            err = StaleStateError(
                f"joint_states of {self.robot_name!r} ({self.link.joint_states_topic}) are stale: the last usable "
                f"state arrived {age}, limit joint_state_timeout={self.joint_state_timeout:g} s "
                f"({self.link.states.describe_problem(self._observed)}). The env stopped commanding; the robot "
                "holds its last command. Check the robot driver, then reset the env or make a new one."
            )
            self.fault = err
            raise err
        return sample

    def _accept(self, sample: RobotState) -> None:
        self._state = sample
        self._states = None

    @property
    def state(self) -> RobotState:
        if self._state is None:
            raise EnvError("no robot state yet")
        return self._state

    @property
    def states(self) -> RobotStates:
        """:attr:`state` as a batch of one (views of its arrays)."""
        states = self._states
        if states is None:
            s = self.state
            states = self._states = RobotStates(s.sim_time, s.names, s.position[None], s.velocity[None],
                                                s.effort[None], s.frame_positions[None], s.frame_orientations[None])
        return states

    @property
    def robot_time(self) -> float | None:
        """The robot side's ``/clock`` (with ``use_sim_time``), else ``None``."""
        return self.link.robot_time

    def _watchdog(self) -> None:
        self.fresh_sample()

    def _observe(self, info: dict[str, Any]) -> None:
        self._accept(self.fresh_sample())
        info["state_age_sec"] = self.state.age()
        if self.robot_time is not None:
            info["robot_time"] = self.robot_time

    # -- commanding -------------------------------------------------------------------------
    def ensure_commandable(self) -> None:
        if self._closed:
            raise EnvError(f"{self.owner} is closed")
        if self.fault is not None:
            raise EnvError(f"{self.owner} stopped after an error ({self.fault}); reset it once the robot is back, or "
                           "make a new env")

    def before_act(self) -> None:
        """The watchdog before an action: the env must be able to command, hear one driver, and the state be fresh."""
        self.ensure_commandable()
        self.check_single_publisher()
        self.fresh_sample()

    def send_joint_targets(self, targets: Sequence[float] | np.ndarray,
                           info: dict[str, Any] | None = None) -> SafetyDecision:
        """Command the arm: the safety rules first, then the arm controller (nothing sent if refused).
        The decision is kept as :attr:`last_decision` and, given ``info``, put in ``info["safety"]``."""
        self.ensure_commandable()
        if self.safety is None or self.arm_controller is None:
            raise EnvError(f"{self.owner} has no arm joints/controller configured")
        current = self.fresh_sample()
        idx = self._arm_index()
        decision = self.safety.check(targets, current.position[idx], self.last_command)
        self.last_decision = decision
        if info is not None:
            info["safety"] = decision.as_info()
        if decision.events:
            _logger.log(logging.INFO if self.log_internal_state else logging.DEBUG, "safety: %s", decision.reason)
        if decision.refused or decision.target is None:
            return decision
        self._send(decision.target, self.loop.cycle)
        return decision

    def _arm_index(self) -> list[int]:
        index = {name: i for i, name in enumerate(self._observed)}
        return [index[j] for j in self.arm_joints]

    def _send(self, target: np.ndarray, duration: float) -> Any:
        assert self.arm_controller is not None
        handle = None
        if self.arm_controller_type == "forward":
            self.link.publish_forward(self.arm_controller, target)
        elif self.command_interface == "action":
            handle = self.link.send_trajectory_goal(self.arm_controller, self.arm_joints, target, duration,
                                                    stale_after=self.joint_state_timeout)
        else:
            self.link.publish_trajectory(self.arm_controller, self.arm_joints, target, duration)
        self.last_command = np.asarray(target, dtype=np.float64).copy()
        self.commands_sent += 1
        return handle

    # -- what a simulation returns with each step, from the robot's side ---------------------------------
    def add_frame_source(self, frame: str,
                         poses: Callable[[RobotStates], tuple[np.ndarray, np.ndarray | None]]) -> None:
        """Serve ``frame`` to :meth:`frame_positions` and :meth:`frame_poses`: ``poses(states)`` gives its
        ``(N, 3)`` world positions and ``(N, 4)`` quaternions ``(w, x, y, z)``, or ``None`` for no
        orientation (identity): forward kinematics of the observed joints, a tracker's newest pose. The
        robot layer adds the frames its task reads, as a simulated robot's env asks for them with each
        step."""
        self._frame_sources[frame] = poses

    @property
    def frames(self) -> tuple[str, ...]:
        return tuple(self._frame_sources)

    def _frame_source(self, frame: str) -> Callable[[RobotStates], tuple[np.ndarray, np.ndarray | None]]:
        try:
            return self._frame_sources[frame]
        except KeyError:
            raise EnvError(f"frame {frame!r}: robot {self.robot_name!r} serves the frames {list(self._frame_sources)} "
                           "(add_frame_source)") from None

    def frame_positions(self, states: RobotStates, frame: str) -> np.ndarray:
        return self._frame_source(frame)(states)[0]

    def frame_poses(self, states: RobotStates, frame: str) -> tuple[np.ndarray, np.ndarray]:
        where, orientations = self._frame_source(frame)(states)
        if orientations is None:
            return where, np.tile([1.0, 0.0, 0.0, 0.0], (len(where), 1))
        return where, orientations

    def add_camera(self, name: str, rgb_topic: str, depth_topic: str | None = None) -> None:
        """Serve camera ``name`` to :meth:`read_camera`: the newest images of a camera driver's
        ``sensor_msgs/Image`` topics (relative names resolve in the robot's namespace), as a simulation
        renders its cameras. Subscribes now; images arrive in the background."""
        from multiros.envs.real.sensor_link import ImageTopic

        self.close_camera(name)
        rgb = ImageTopic(self.node, self.link.resolve(rgb_topic), "rgb")
        depth = ImageTopic(self.node, self.link.resolve(depth_topic), "depth") if depth_topic else None
        self._cameras[name] = (rgb, depth)

    def open_camera(self, request: CameraRequest) -> tuple[str, tuple[int, int]]:
        """The camera driver's image topics (the request's ``rgb_topic`` and ``depth_topic``), served as
        camera ``<camera>`` (the last part of the request's name; ``"camera"`` for the view camera, which
        on a robot is the one mounted where its simulated twin has it). The size is the request's; a named
        camera without one takes its first image's (waiting up to ``startup_timeout``)."""
        short = (request.name or "camera").strip("/").rsplit("/", 1)[-1]
        self.add_camera(short, request.rgb_topic, request.depth_topic)
        if request.width is not None and request.height is not None:
            return short, (int(request.height), int(request.width))
        return short, self.camera_size(short, self.startup_timeout)

    def _camera(self, name: str) -> tuple[Any, Any]:
        try:
            return self._cameras[name]
        except KeyError:
            raise EnvError(f"camera {name!r}: robot {self.robot_name!r} serves the cameras {list(self._cameras)} "
                           "(add_camera)") from None

    def camera_size(self, name: str, timeout: float) -> tuple[int, int]:
        """``(height, width)`` of camera ``name``'s images: its first image's (waiting up to ``timeout``)."""
        first = self._camera(name)[0].wait_first(timeout)
        return int(first.shape[0]), int(first.shape[1])

    def read_camera(self, name: str, *, rgb: bool = True, depth: bool = False, width: int | None = None,
                    height: int | None = None, max_age: float = 1.0) -> CameraImages:
        """Camera ``name``'s newest images, at ``height`` x ``width`` when given (nearest pixel). An image
        older than ``max_age`` seconds is stale: the env stops, as for stale joint states
        (:class:`~multiros.envs.real.sensor_link.StaleSensorError`)."""
        from multiros.envs.real.sensor_link import resize_nearest

        rgb_topic, depth_topic = self._camera(name)
        if depth and depth_topic is None:
            raise EnvError(f"camera {name!r} has no depth topic (add_camera(..., depth_topic=))")

        def newest(topic: Any) -> np.ndarray:
            image = topic.latest(max_age)
            return image if width is None or height is None else resize_nearest(image, height, width)

        try:
            return CameraImages(name, newest(rgb_topic) if rgb else None, newest(depth_topic) if depth else None)
        except StaleStateError as exc:
            self.fault = exc
            raise

    def close_camera(self, name: str) -> None:
        """Unsubscribe camera ``name``'s topics (nothing when there is no such camera)."""
        for topic in self._cameras.pop(name, ()):
            if topic is not None:
                topic.close()

    # -- where the robot stands, its task's scene and joint range ---------------------------------------
    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot's base, as :meth:`set_base_position` was told (the origin by default)."""
        return self._base.copy()

    def set_base_position(self, position: npt.ArrayLike) -> None:
        """Where the robot's base stands in the task's world (a simulated twin's spawn position), so that
        frames, goals and observations are the twin's."""
        base = np.asarray(position, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(base)):
            raise ValueError(f"base_position must be 3 finite numbers, got {base.tolist()}")
        self._base = base

    def add_kinematic_frame(self, frame: str, chain: Any) -> None:
        """Serve ``frame`` as a simulation returns it with each step: forward kinematics of the observed
        joints of ``chain`` (a :class:`~multiros.utils.kinematics.KinematicChain` from the base link to
        ``frame``), in the task's world (a real robot offers no end-effector pose; the simulated frame is
        the same link of the same description), its orientation too (the base is not turned)."""
        joints = tuple(chain.joint_names)
        index: dict[tuple[str, ...], list[int]] = {}

        def fk(states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
            idx = index.get(states.names)
            if idx is None:
                where = {name: i for i, name in enumerate(states.names)}
                missing = [j for j in joints if j not in where]
                if missing:
                    raise EnvError(f"frame {frame!r}: robot {self.robot_name!r} reports no joints {missing}")
                idx = index[states.names] = [where[j] for j in joints]
            tf = chain.fk_matrix(states.position[:, idx])  # one pass: position and orientation
            return tf[:, :3, 3] + self._base, quat_from_matrix(tf[:, :3, :3])

        self.add_frame_source(frame, fk)

    def set_scene_options(self, options: RealSceneOptions) -> None:
        """How this robot's scene is reached: its tracker and gripper driver (:mod:`~multiros.envs.real.scene`)."""
        self.scene.close()
        self.scene = RealScene(self, options)

    def add_scene(self, entities: Sequence[SceneEntity]) -> None:
        """Nothing to spawn: the scene stands. The movable object's frame is the tracker's pose (waiting
        up to ``startup_timeout`` for the first), a fixture's where the task says it is."""
        self.scene.add(entities)

    def use_gripper(self, controller: str, task_range: tuple[float, float]) -> None:
        """Reach the gripper's driver and route ``controller``'s commands to it (:mod:`~multiros.envs.real.scene`)."""
        self.scene.use_gripper(controller, task_range)

    def reset_gripper(self, controller: str, joints: Sequence[str], positions: Sequence[float]) -> None:
        """Open (or close) the gripper for the episode's start: a command to its driver."""
        self.scene.reset_gripper(controller, positions)

    def observation_time(self, states: RobotStates) -> float:
        """The local time the robot's state arrived (seconds, monotonic)."""
        received = self.state.received
        return float(received) if received is not None else 0.0

    def limit_joints(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None:
        """Tighten the safety rules' joint limits to a task's (the tighter bound wins)."""
        if self.safety is None:
            raise EnvError(f"{self.owner} has no safety rules to tighten")
        self.safety = self.safety.with_joint_limits(lower, upper)

    def command_arm(self, controller: str, targets: np.ndarray, info: dict[str, Any]) -> None:
        """The arm's command through the safety rules to the driver's arm controller (whatever the
        simulation calls it); their decision goes to ``info["safety"]``."""
        self.send_joint_targets(targets, info)

    def route_controller(self, controller: str, send: Callable[[np.ndarray], None]) -> None:
        """Commands for ``controller`` go to ``send`` (after the checks every command passes): a controller
        the simulation has whose driver on the robot takes another interface (a gripper's action)."""
        self._routes[controller] = send

    def command(self, controller: str, values: np.ndarray) -> None:
        """The arm controller's command goes through :meth:`send_joint_targets`; a routed controller's
        (:meth:`route_controller`) to its route; another (e.g. a gripper's forward command controller)
        gets finite values on ``<controller>/commands``."""
        if controller == self.arm_controller:
            self.send_joint_targets(values)
            return
        self.ensure_commandable()
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim != 1 or not np.all(np.isfinite(arr)):
            raise UnsafeCommandError(f"command for {controller!r} must be a 1-D finite vector, got {values!r}; "
                                     "nothing was sent")
        self.fresh_sample()
        route = self._routes.get(controller)
        if route is not None:
            route(arr)
            return
        self.link.publish_forward(controller, arr)

    def advance(self, info: dict[str, Any]) -> StepStatus:
        """One control cycle: wait (the watchdog checking the states), then observe the freshest state."""
        self.ensure_commandable()
        acted = time.monotonic()
        started = self.loop.last_observe
        observed = self.loop.wait(acted, self._watchdog)
        self._observe(info)
        info["cycle_time_sec"] = observed - (started if started is not None else acted)
        if self.log_internal_state:
            _logger.info("%s: state age %.4f s, cycle %.4f s, safety %s", self.robot_name, info["state_age_sec"],
                         info["cycle_time_sec"], info.get("safety"))
        return STEP_OK

    # -- episodes ---------------------------------------------------------------------------
    def prompt(self, message: str) -> None:
        if _interactive():
            input(message)
        else:
            _logger.warning("%s: not waiting for the operator (stdin is not a terminal): %s", self.owner, message)

    def reset(self, info: dict[str, Any]) -> None:
        if self._closed:
            raise EnvError(f"{self.owner} is closed")
        if self.reset_env_prompt:
            self.prompt("Reset the robot's surroundings, then press Enter to start the episode: ")
        # The one-driver rule, as in every step; the driver may have been restarted (a new identity).
        link = self.link
        self._adopt_driver(time.monotonic() + self.startup_timeout)
        # A fault (stale state) ends once fresh states arrive again.
        ok = self.node.context.wait_for(
            lambda: (s := link.states.sample(self._observed)) is not None and s.received is not None
            and time.monotonic() - s.received <= self.joint_state_timeout, self.startup_timeout)
        self.fault = None
        if not ok:
            self.fresh_sample()  # raises with the reason
        controllers = self._controllers
        if self.reset_controllers and controllers:
            if self.reset_controllers_prompt:
                self.prompt(f"Press Enter to restart the controllers {controllers}: ")
            link.reset_controllers(controllers)
        if controllers:
            link.require_active(controllers)
        self._accept(self.fresh_sample())

    def start_episode(self, info: dict[str, Any]) -> None:
        self.loop.start_episode()
        info.pop("safety", None)
        self._observe(info)

    def move_to_initial_pose(self, names: Sequence[str], positions: npt.ArrayLike, tolerance: float = 1e-3) -> None:
        """Move the arm to ``positions`` at ``reset_joint_speed`` and wait until it is there.

        The target is clamped to the joint limits and the path checked against the workspace and
        floor (a violation refuses the move). Raises :class:`ResetError` when the arm does not arrive
        within ``reset_tolerance`` (or ``tolerance`` if larger) in time.
        """
        self.ensure_commandable()
        if self.safety is None:
            raise EnvError(f"{self.owner} has no arm joints/controller configured")
        order = {n: i for i, n in enumerate(names)}
        if set(order) != set(self.arm_joints):
            raise EnvError(f"move_to_initial_pose moves the arm joints {list(self.arm_joints)}, got {list(names)}")
        target = np.asarray(positions, dtype=np.float64)[[order[j] for j in self.arm_joints]]
        current = self.fresh_sample()
        idx = self._arm_index()
        decision = self.safety.check_move(target, current.position[idx])
        if decision.refused or decision.target is None:
            raise ResetError(f"initial pose of {self.robot_name!r}: {decision.reason}; move the robot by hand")
        goal = decision.target
        start = current.position[idx]
        # The move's length: from the measured state, and from the last command (where the robot was
        # sent: a measured state that claims the robot is already there cannot shorten the move).
        # Before the first command, from the furthest the arm can be (a forged state cannot shorten
        # the first move either); a joint without finite limits falls back to the measured state.
        distance = float(np.max(np.abs(goal - start)))
        if self.last_command is not None:
            distance = max(distance, float(np.max(np.abs(goal - self.last_command))))
        else:
            worst = self.safety.worst_case_distance(goal)
            finite = np.isfinite(worst)
            if np.any(finite):
                distance = max(distance, float(np.max(worst[finite])))
        duration = max(self.loop.cycle, distance / max(self.reset_joint_speed, 1e-6))
        tol = max(float(tolerance), self.reset_tolerance)
        began = time.monotonic()
        deadline = began + duration + self.reset_timeout
        if self.arm_controller_type == "forward":
            steps = max(1, int(np.ceil(duration / self.loop.period)))
            for k in range(1, steps + 1):
                self._send(start + (goal - start) * (k / steps), self.loop.period)
                self.loop.wait(time.monotonic(), self._watchdog)
        else:
            handle = self._send(goal, duration)
            if handle is not None:
                self.link.check_goal_result(handle, f"moving {self.robot_name!r} to its initial pose",
                                            duration + self.reset_timeout)
        settle = _Settling(self.reset_settle_tolerance)
        error = np.inf
        while True:
            sample = self.fresh_sample()
            now = time.monotonic()
            error = float(np.max(np.abs(sample.position[idx] - goal)))
            if now >= began + duration:  # the trajectory takes its time
                if error <= tol:
                    self._accept(sample)
                    return
                settled = settle.add(now, sample.position[idx], goal)
                if settled is not None:
                    _logger.warning("robot %r settled %.4g rad from its initial pose (> reset_tolerance %g, <= "
                                    "reset_settle_tolerance %g): the episode starts where it settled",
                                    self.robot_name, settled, tol, self.reset_settle_tolerance)
                    self._accept(sample)
                    return
            if now > deadline:
                hint = (f"it stopped {settle.last_error:.4g} rad short, beyond reset_settle_tolerance "
                        f"{self.reset_settle_tolerance:g}" if settle.still else "check the controller is tracking "
                        "(gains, limits)")
                raise ResetError(
                    f"robot {self.robot_name!r} did not reach its initial pose {np.round(goal, 4).tolist()} within "
                    f"{duration + self.reset_timeout:.1f} s (max joint error {error:.4g} rad > {tol:g}); {hint}, or "
                    "raise reset_tolerance / reset_settle_tolerance / reset_timeout")
            time.sleep(min(0.01, self.loop.tick))

    # -- closing ----------------------------------------------------------------------------
    def close(self) -> None:
        """Stop talking to the robot; nothing more is sent (it holds its last command)."""
        if self._closed:
            return
        self._closed = True
        if self.close_env_prompt:
            self.prompt("Closing the env: the robot holds its last command. Press Enter: ")
        try:
            self.scene.close()
        except Exception:  # noqa: BLE001 - closing must go on
            _logger.debug("the scene's tracker or gripper did not close cleanly", exc_info=True)
        for name in list(self._cameras):
            try:
                self.close_camera(name)
            except Exception:  # noqa: BLE001 - closing must go on
                _logger.debug("camera %s did not close cleanly", name, exc_info=True)
        try:
            self.link.close()
        except Exception:  # noqa: BLE001 - closing must go on
            _logger.debug("robot link did not close cleanly", exc_info=True)
