"""The link to a robot over the standard ROS 2 interfaces a ros2_control robot offers, nothing else.

* ``<ns>/joint_states`` (``sensor_msgs/JointState``): every message is checked (names unique,
  lengths consistent, values finite and bounded; with the arm's rules, every arm joint it holds,
  whole or partial message, within the limits and the velocity limits) before it updates
  :class:`JointStateCache`; malformed ones are dropped and counted, and the last reason is kept
  for the error message. Once the connection has pinned the driver (:meth:`JointStateCache.pin`),
  messages of any other publisher identity are dropped too;
* ``<ns>/controller_manager/list_controllers`` / ``switch_controller`` (the controller manager);
* ``<ns>/<controller>/joint_trajectory`` (``trajectory_msgs/JointTrajectory``) and
  ``<ns>/<controller>/follow_joint_trajectory`` (``control_msgs/action/FollowJointTrajectory``) of a
  JointTrajectoryController, and ``<ns>/<controller>/commands`` (``std_msgs/Float64MultiArray``)
  of a forward command controller;
* ``/clock`` (``rosgraph_msgs/Clock``), only when asked (``use_sim_time``).

Times are the local monotonic clock at receipt: a state's age never depends on the robot's clock. The
header stamps only order the driver's messages: one stamped before the values already cached (a message
delivered late) is dropped, and the time between two stamps may lengthen (never shorten) the time a joint
was allowed to move between them.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from multiros.envs.real.errors import ControllerNotActiveError, RobotConnectionError, TrajectoryGoalError
from multiros.robot_state import RobotState
from multiros.ros.controller_manager import ControllerManagerClient, ControllerManagerError
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_action, get_message
from multiros.ros.qos import qos_profile_clock

_logger = logging.getLogger(__name__)

JointState = get_message("sensor_msgs/msg/JointState")
JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
JointTrajectoryPoint = get_message("trajectory_msgs/msg/JointTrajectoryPoint")
Float64MultiArray = get_message("std_msgs/msg/Float64MultiArray")
Clock = get_message("rosgraph_msgs/msg/Clock")
FollowJointTrajectory = get_action("control_msgs/action/FollowJointTrajectory")

# Largest |value| accepted in joint_states (rad, m, rad/s, N m): anything beyond is a broken message.
MAX_STATE_VALUE = 1e6
MAX_JOINTS = 1024
#: A message stamped at most this many seconds before the cached values is a late one and is dropped;
#: further back, or ``MAX_LATE_STREAK`` in a row, is the driver's clock jumping back, and is taken.
MAX_LATE = 1.0
MAX_LATE_STREAK = 3


#: A robot's joint state as the link samples it: the one state record (``received`` is the local
#: monotonic time the oldest of its values arrived, ``stamp`` that value's header stamp).
JointSample = RobotState


def check_joint_state(msg: Any) -> str | None:
    """Why a ``JointState`` message is unusable, or ``None`` when it is fine."""
    names = list(msg.name)
    n = len(names)
    if n == 0:
        return "no joint names"
    if n > MAX_JOINTS:
        return f"{n} joints (more than {MAX_JOINTS})"
    if len(set(names)) != n or not all(isinstance(s, str) and s for s in names):
        return f"joint names are empty or repeated: {names[:16]}"
    if len(msg.position) != n:
        return f"{n} names but {len(msg.position)} positions"
    for field in ("velocity", "effort"):
        values = getattr(msg, field)
        if len(values) not in (0, n):
            return f"{n} names but {len(values)} {field} values"
    for field in ("position", "velocity", "effort"):
        values = np.asarray(getattr(msg, field), dtype=np.float64)
        if values.size and not np.all(np.isfinite(values)):
            return f"{field} contains NaN or infinite values"
        if values.size and np.max(np.abs(values)) > MAX_STATE_VALUE:
            return f"{field} has values beyond {MAX_STATE_VALUE:g}"
    return None


def _stamp(msg: Any) -> float:
    """A message's header stamp in seconds (0.0: not stamped)."""
    return float(msg.header.stamp.sec) + float(msg.header.stamp.nanosec) * 1e-9


#: How many publisher identities a cache remembers having heard (the oldest is forgotten first).
MAX_SOURCES = 64


def _source_name(source: bytes | None) -> str:
    return "unknown" if source is None else source.hex()[:12]


class JointStateCache:
    """The latest valid value of every joint, merged over ``joint_states`` messages (thread-safe).

    With a guard (:meth:`guard`: the arm's safety rules), a message whose guarded joints cannot be
    the robot's (outside their limits, or moved faster than their velocity limits since the joint's
    last accepted value) is dropped as malformed, with the reason: a well-formed state from another
    process cannot teleport the arm in the env's eyes. Every guarded joint a message holds is
    checked, whether the message holds the whole arm or part of it. A value older than
    ``fresh_for`` no longer bounds the next one (only the limits do): one bad value that got in
    (the first message, say) is replaced by the driver's after ``fresh_for`` seconds at most.

    Once pinned (:meth:`pin`), only messages from that publisher identity count: the others are
    dropped and counted in :attr:`foreign_count`.

    Values never go back in time: a message stamped before the cached values of the joints it holds
    (a message delivered late, after a newer one) is dropped and counted in :attr:`late_count`. The
    time a joint may have moved is the longer of the receipt times' and the stamps' difference (the
    latter at most ``fresh_for``): a message that arrives right after a late one is not a jump.
    Messages without stamps (zero) are ordered by receipt only.
    """

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._values: dict[str, tuple[float, float, float, float, float]] = {}  # pos, vel, eff, recv, stamp
        self.received_count = 0
        self.malformed_count = 0
        self.foreign_count = 0
        self.late_count = 0
        self._late_streak = 0
        self.last_error: str | None = None
        self.last_received: float | None = None
        self.last_foreign: bytes | None = None
        self._rules: Any = None
        self._fresh_for = math.inf
        self._pinned = False
        self._driver: bytes | None = None
        self._sources: dict[bytes | None, float] = {}  # last receipt per publisher identity

    def guard(self, rules: Any, fresh_for: float = math.inf) -> None:
        """Check every later message's joints of ``rules.joint_names`` with ``rules.plausible``; a
        joint's value bounds its next one (velocity limits) for ``fresh_for`` seconds."""
        with self._cond:
            self._rules = rules
            self._fresh_for = float(fresh_for)

    def pin(self, source: bytes | None) -> None:
        """Take messages only from the publisher identity ``source`` (``None``: a transport that
        gives none, every message counts). A new identity drops the values cached so far."""
        with self._cond:
            if not self._pinned or source != self._driver:
                self._values.clear()
            self._pinned = True
            self._driver = source
            self._cond.notify_all()

    @property
    def pinned(self) -> bool:
        """Whether :meth:`pin` chose whose messages count."""
        return self._pinned

    @property
    def driver(self) -> bytes | None:
        """The pinned publisher identity (``None``: not pinned, or a transport without identities)."""
        return self._driver

    def sources(self, within: float, now: float | None = None) -> list[bytes | None]:
        """The publisher identities heard in the last ``within`` seconds, most recent first."""
        now = time.monotonic() if now is None else now
        with self._cond:
            heard = sorted(self._sources.items(), key=lambda kv: -kv[1])
        return [src for src, t in heard if now - t <= within]

    def _implausible(self, msg: Any, now: float, stamp: float) -> str | None:
        rules = self._rules
        if rules is None:
            return None
        where = {name: i for i, name in enumerate(msg.name)}
        index = [k for k, j in enumerate(rules.joint_names) if j in where]
        if not index:
            return None
        q = np.array([float(msg.position[where[rules.joint_names[k]]]) for k in index])
        last = np.full(len(index), np.nan)  # NaN: no fresh value to bound this joint's move
        ages = np.zeros(len(index))
        for n, k in enumerate(index):
            prev = self._values.get(rules.joint_names[k])
            if prev is not None and now - prev[3] <= self._fresh_for:
                since_stamp = stamp - prev[4] if stamp > 0.0 and prev[4] > 0.0 else 0.0
                last[n], ages[n] = prev[0], max(now - prev[3], min(since_stamp, self._fresh_for))
        return rules.plausible(q, last, ages, index=index)

    def _late(self, msg: Any, stamp: float) -> bool:
        """Whether ``msg`` is stamped before the cached values of the joints it holds (and within
        ``MAX_LATE`` of them, and not the ``MAX_LATE_STREAK``-th such message in a row)."""
        if stamp <= 0.0:
            return False
        newest = max((self._values[n][4] for n in msg.name if n in self._values), default=0.0)
        if not 0.0 < newest - stamp <= MAX_LATE:
            self._late_streak = 0
            return False
        self._late_streak += 1
        if self._late_streak >= MAX_LATE_STREAK:  # not late messages: the driver's clock went back
            self._late_streak = 0
            return False
        return True

    def receive(self, msg: Any, source: bytes | None) -> bool:
        """A subscription's callback (``with_source``): :meth:`update` with the publisher's identity."""
        return self.update(msg, source=source)

    def update(self, msg: Any, now: float | None = None, source: bytes | None = None) -> bool:
        """Take one message from the publisher identity ``source``; ``False`` (and counted) when it
        is malformed, implausible, or (pinned) from another publisher."""
        reason = check_joint_state(msg)
        now = time.monotonic() if now is None else now
        with self._cond:
            self._sources.pop(source, None)
            self._sources[source] = now
            if len(self._sources) > MAX_SOURCES:
                self._sources.pop(next(iter(self._sources)))
            if self._pinned and source != self._driver:
                self.foreign_count += 1
                self.last_foreign = source
                self._cond.notify_all()
                return False
            stamp = _stamp(msg)
            if reason is None and self._late(msg, stamp):
                self.late_count += 1
                self._cond.notify_all()
                return False
            if reason is None:
                reason = self._implausible(msg, now, stamp)
            if reason is not None:
                self.malformed_count += 1
                self.last_error = reason
                self._cond.notify_all()
                return False
            pos = np.asarray(msg.position, dtype=np.float64)
            vel = np.asarray(msg.velocity, dtype=np.float64) if len(msg.velocity) else np.zeros(len(pos))
            eff = np.asarray(msg.effort, dtype=np.float64) if len(msg.effort) else np.zeros(len(pos))
            for i, name in enumerate(msg.name):
                self._values[name] = (float(pos[i]), float(vel[i]), float(eff[i]), now, stamp)
            self.received_count += 1
            self.last_received = now
            self._cond.notify_all()
        return True

    @property
    def names(self) -> tuple[str, ...]:
        with self._cond:
            return tuple(self._values)

    def sample(self, names: Sequence[str]) -> JointSample | None:
        """The values of ``names``, or ``None`` while one of them never arrived."""
        with self._cond:
            try:
                rows = [self._values[n] for n in names]
            except KeyError:
                return None
        arr = np.array(rows, dtype=np.float64).reshape(len(rows), 5)
        oldest = int(np.argmin(arr[:, 3])) if len(rows) else 0
        return RobotState(float(arr[oldest, 4]) if len(rows) else 0.0, tuple(names), arr[:, 0].copy(),
                          arr[:, 1].copy(), arr[:, 2].copy(),
                          received=float(arr[oldest, 3]) if len(rows) else -math.inf)

    def wait_for(self, names: Sequence[str], newer_than: float, timeout: float) -> JointSample | None:
        """Wait until every joint of ``names`` has a value received after ``newer_than``."""
        deadline = time.monotonic() + max(0.0, timeout)
        with self._cond:
            while True:
                s = self.sample(names)
                if s is not None and s.received is not None and s.received > newer_than:
                    return s
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return s
                self._cond.wait(min(remaining, 0.05))

    def describe_problem(self, names: Sequence[str]) -> str:
        """A sentence on why a fresh state of ``names`` is missing (for error messages)."""
        with self._cond:
            missing = [n for n in names if n not in self._values]
            parts = []
            if self.received_count == 0 and self.malformed_count == 0:
                parts.append("no joint_states message arrived")
            if missing and self.received_count:
                parts.append(f"joints {missing} never appeared in joint_states (seen: {sorted(self._values)})")
            if self.malformed_count:
                parts.append(f"{self.malformed_count} malformed joint_states message(s) dropped, the last because "
                             f"{self.last_error}")
            if self.late_count:
                parts.append(f"{self.late_count} joint_states message(s) stamped before values already received "
                             "dropped as late")
            if self.foreign_count:
                parts.append(f"{self.foreign_count} joint_states message(s) from a publisher other than the driver "
                             f"(identity {_source_name(self.last_foreign)}, the driver's "
                             f"{_source_name(self._driver)}) dropped")
            return "; ".join(parts) or "joint_states stopped arriving"


def _duration(seconds: float) -> Any:
    msg = get_message("builtin_interfaces/msg/Duration")()
    sec = int(math.floor(seconds))
    msg.sec, msg.nanosec = sec, min(int(round((seconds - sec) * 1e9)), 999_999_999)
    return msg


class RobotLink:
    """A robot's standard ROS 2 interfaces, reached through one node of ours.

    Args:
        node: our ``multiros.ros.Node``.
        namespace: the robot's namespace (``"/rx200"``; ``"/"`` or ``""`` for none).
        joint_states_topic: relative to the namespace unless absolute.
        use_sim_time: subscribe to ``/clock`` and expose the robot's time.
        timeout_sec: bound on each service call and on waiting for topics.
    """

    def __init__(self, node: Any, namespace: str = "/", *, joint_states_topic: str = "joint_states",
                 use_sim_time: bool = False, timeout_sec: float = 5.0) -> None:
        self.node = node
        ns = (namespace or "").strip("/")
        self.ns = "/" + ns if ns else ""
        self.timeout_sec = float(timeout_sec)
        self.states = JointStateCache()
        self.joint_states_topic = self.resolve(joint_states_topic)
        self._sub = node.create_subscription(JointState, self.joint_states_topic, self.states.receive, 10,
                                             with_source=True)
        self._clock_sub = None
        self.robot_time: float | None = None
        if use_sim_time:
            self._clock_sub = node.create_subscription(Clock, "/clock", self._on_clock, qos_profile_clock)
        self.controller_manager = ControllerManagerClient(node, self.ns or None, timeout_sec=self.timeout_sec)
        self._publishers: dict[tuple[str, str], Any] = {}
        self._action_clients: dict[str, Any] = {}
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        self._spin = threading.Thread(target=self._executor.spin, name=f"{node.get_name()}-robot-link", daemon=True)
        self._spin.start()

    def resolve(self, name: str) -> str:
        """``name`` inside the robot's namespace (absolute names stay)."""
        return name if name.startswith("/") else f"{self.ns}/{name}"

    def _on_clock(self, msg: Any) -> None:
        t = float(msg.clock.sec) + float(msg.clock.nanosec) * 1e-9
        if math.isfinite(t):
            self.robot_time = t

    # -- controllers ------------------------------------------------------------------------
    def controller_states(self) -> dict[str, str]:
        """``{controller: state}`` from ``list_controllers``.

        Raises:
            RobotConnectionError: the controller manager does not answer.
        """
        try:
            return self.controller_manager.states()
        except ControllerManagerError as exc:
            raise RobotConnectionError(
                f"the robot's controller manager ({self.ns}/controller_manager/list_controllers) did not answer "
                f"within {self.timeout_sec:g} s: is the robot's ros2_control driver running in namespace "
                f"{self.ns or '/'!r}, on this ROS_DOMAIN_ID ({self.node.context.domain_id}) and "
                f"{self.node.context.reach()}?"
            ) from exc

    def require_active(self, controllers: Sequence[str]) -> None:
        """Raise :class:`ControllerNotActiveError` unless every one of ``controllers`` is active."""
        states = self.controller_states()
        bad = {c: states.get(c, "not loaded") for c in controllers if states.get(c) != "active"}
        if bad:
            raise ControllerNotActiveError(
                f"controller(s) {bad} of the robot in {self.ns or '/'!r} must be active (controllers: {states}); "
                f"activate them (e.g. `ros2 control switch_controllers --activate {' '.join(bad)}`, or pass "
                "load_controllers=True), or name the robot's controllers with arm_controller=/controllers_list="
            )

    def spawn_controllers(self, controllers: Sequence[str]) -> None:
        """Load (if needed), configure and activate ``controllers``."""
        try:
            self.controller_manager.spawn(list(controllers))
        except ControllerManagerError as exc:
            raise ControllerNotActiveError(f"could not activate {list(controllers)}: {exc}") from exc

    def reset_controllers(self, controllers: Sequence[str] | None) -> None:
        """Stop then start ``controllers`` (default: the active ones)."""
        try:
            self.controller_manager.reset(list(controllers) if controllers else None)
        except ControllerManagerError as exc:
            raise ControllerNotActiveError(f"could not restart the controllers {controllers}: {exc}") from exc

    # -- commands ---------------------------------------------------------------------------
    def _publisher(self, msg_type: Any, topic: str) -> Any:
        key = (topic, msg_type.__name__)
        pub = self._publishers.get(key)
        if pub is None:
            pub = self._publishers[key] = self.node.create_publisher(msg_type, topic, 10)
        return pub

    def trajectory_topic(self, controller: str) -> str:
        return self.resolve(f"{controller}/joint_trajectory")

    def commands_topic(self, controller: str) -> str:
        return self.resolve(f"{controller}/commands")

    def action_name(self, controller: str) -> str:
        return self.resolve(f"{controller}/follow_joint_trajectory")

    def wait_for_subscriber(self, controller: str, kind: str, timeout: float) -> bool:
        """Wait until the controller's command topic has a subscriber (a publish before that is lost)."""
        msg_type, topic = ((JointTrajectory, self.trajectory_topic(controller)) if kind == "trajectory"
                           else (Float64MultiArray, self.commands_topic(controller)))
        pub = self._publisher(msg_type, topic)
        return self.node.context.wait_for(lambda: pub.get_subscription_count() > 0, timeout)

    @staticmethod
    def trajectory(joints: Sequence[str], positions: np.ndarray, duration: float) -> Any:
        """A one-point ``JointTrajectory`` reaching ``positions`` after ``duration`` s, starting now."""
        point = JointTrajectoryPoint(positions=np.asarray(positions, dtype=np.float64),
                                     velocities=np.zeros(len(joints)), time_from_start=_duration(duration))
        return JointTrajectory(joint_names=list(joints), points=[point])

    def publish_trajectory(self, controller: str, joints: Sequence[str], positions: np.ndarray,
                           duration: float) -> None:
        """Send a one-point trajectory on the controller's ``joint_trajectory`` topic."""
        self._publisher(JointTrajectory, self.trajectory_topic(controller)).publish(
            self.trajectory(joints, positions, duration))

    def publish_forward(self, controller: str, values: np.ndarray) -> None:
        """Send a forward command controller's ``commands``."""
        self._publisher(Float64MultiArray, self.commands_topic(controller)).publish(
            Float64MultiArray(data=np.asarray(values, dtype=np.float64)))

    def _action_client(self, controller: str) -> Any:
        client = self._action_clients.get(controller)
        if client is None:
            from multiros.ros.action import ActionClient

            client = self._action_clients[controller] = ActionClient(
                self.node, FollowJointTrajectory, self.action_name(controller))
        return client

    def wait_for_action(self, controller: str, timeout: float) -> bool:
        return self._action_client(controller).wait_for_server(timeout_sec=timeout)

    def send_trajectory_goal(self, controller: str, joints: Sequence[str], positions: np.ndarray, duration: float,
                             *, goal_time_tolerance: float = 1.0, stale_after: float | None = None) -> Any:
        """Send a FollowJointTrajectory goal and wait until it is accepted; returns the goal handle.

        ``stale_after``: stop waiting as soon as ``joint_states`` have been silent this long (a robot
        killed mid-episode: its action server may linger in the graph for seconds).

        Raises:
            TrajectoryGoalError: rejected, no answer within ``timeout_sec``, or the robot went silent.
        """
        goal = FollowJointTrajectory.Goal()
        goal.trajectory = self.trajectory(joints, positions, duration)
        goal.goal_time_tolerance = _duration(goal_time_tolerance)
        client = self._action_client(controller)
        future = client.send_goal_async(goal, timeout_sec=self.timeout_sec)
        deadline = time.monotonic() + self.timeout_sec + 0.5  # the call's own bound fails the future first
        while not future.wait(0.02 if stale_after is not None else self.timeout_sec + 0.5):
            now = time.monotonic()
            last = self.states.last_received
            if stale_after is not None and last is not None and now - last > stale_after:
                raise TrajectoryGoalError(f"{self.action_name(controller)} did not answer the goal"
                                          f"{self._robot_news(client)}")
            if now > deadline:
                raise TrajectoryGoalError(f"{self.action_name(controller)} did not answer the goal within "
                                          f"{self.timeout_sec:g} s{self._robot_news(client)}")
        exc = future.exception()
        if exc is not None:
            raise TrajectoryGoalError(f"{self.action_name(controller)} gave no answer to the goal "
                                      f"({type(exc).__name__}){self._robot_news(client)}") from exc
        handle = future.result()
        if not handle.accepted:
            raise TrajectoryGoalError(
                f"{self.action_name(controller)} rejected the trajectory to {np.round(positions, 4).tolist()} for "
                f"{list(joints)}: is the controller active and are these exactly its joints?")
        return handle

    def _robot_news(self, client: Any = None) -> str:
        """What the robot's side last showed, for an error about it (``": ..."`` or ``""``)."""
        parts = []
        last = self.states.last_received
        if last is None:
            parts.append(f"no {self.joint_states_topic} message ever arrived")
        else:
            age = time.monotonic() - last
            if age > 0.2:
                parts.append(f"{self.joint_states_topic} stopped {age:.1f} s ago")
        if client is not None and not client.server_is_ready():
            parts.append(f"the action server {client.action_name} is no longer in the ROS graph")
        if not parts:
            return ""
        return ": the robot looks lost (" + "; ".join(parts) + "): is its driver still running?"

    @staticmethod
    def check_goal_result(handle: Any, what: str, timeout: float) -> None:
        """Wait for a goal's result; raise :class:`TrajectoryGoalError` unless it succeeded."""
        try:
            response = handle.get_result(timeout_sec=timeout)
        except Exception as exc:  # noqa: BLE001 - timeouts and server errors all mean: no success
            raise TrajectoryGoalError(f"{what}: no result within {timeout:g} s ({exc})") from exc
        status = int(response.status)
        if status != 4:  # action_msgs/GoalStatus.STATUS_SUCCEEDED
            result = response.result
            raise TrajectoryGoalError(
                f"{what}: the trajectory controller ended the goal with status {status} (error_code "
                f"{getattr(result, 'error_code', '?')}: {getattr(result, 'error_string', '')!r})")

    def close(self) -> None:
        """Stop the spinning thread and destroy our subscriptions, publishers and clients."""
        self._executor.shutdown()
        self._spin.join(timeout=2.0)
        for client in self._action_clients.values():
            try:
                client.destroy()
            except Exception:  # noqa: BLE001 - closing must go on
                _logger.debug("action client destroy failed", exc_info=True)
        self._action_clients.clear()
        self.controller_manager.close()
