"""``uniros-fake-robot``: a fake ros2_control robot, for trying a Real env with no robot.

Not the simulation node: no physics, no simulation services, no ``/clock``. It serves what a real
ros2_control robot serves, in the robot's namespace ``<ns>``:

* ``<ns>/joint_states`` (``sensor_msgs/JointState``) at a fixed rate, stamped with the wall clock;
* ``<ns>/controller_manager/{list,load,configure,switch,unload}_controller(s)`` (every supported
  distribution's ``controller_manager_msgs`` variant);
* ``<ns>/<controller>/commands`` (``std_msgs/Float64MultiArray``) per forward command controller;
* ``<ns>/<controller>/joint_trajectory`` (``trajectory_msgs/JointTrajectory``) and
  ``<ns>/<controller>/follow_joint_trajectory`` (``control_msgs/action/FollowJointTrajectory``) per
  joint trajectory controller.

Joints follow their commands with a first-order lag under the URDF's velocity and position limits
(:mod:`multiros.hardware.fake_hardware`). Commands that are malformed (wrong length, NaN) are
ignored with a log line. Fault injection for tests: ``--stall-after`` stops ``joint_states``,
``--reject-goals`` refuses every trajectory goal.

``--gap PROFILE`` (:mod:`multiros.hardware.gap`: ``none``, ``mild``, ``hard`` or a YAML file;
``--gap-set KEY=VALUE``, ``--gap-seed N``) gives it a measurable reality gap: command latency, lag,
backlash, droop and calibration offsets at the joints, noisy, dropped, late and jittered
``joint_states`` on the wire, and the truth on ``<ns>/<node>/ground_truth/joint_states``
(``<ns>/controller_manager/ground_truth/joint_states``: true positions, every publish, no noise).

Run ``uniros-fake-robot --robot rx200`` (or ``python -m multiros.hardware.fake_robot``).
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from multiros.hardware.fake_hardware import DEFAULT_TIME_CONSTANT, FakeHardware
from multiros.hardware.gap import (
    PROFILES,
    GapProfile,
    GapProfileError,
    StateGap,
    gap_generators,
    load_gap_profile,
    parse_gap_assignments,
)
from multiros.hardware.robot_spec import PRESETS, RobotSpec, load_robot_spec, parse_assignments, parse_xacro_args
from multiros.ros import Context, Node
from multiros.ros.action import GoalResponse
from multiros.ros.exceptions import TransportError
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.names import split_ros_arguments
from multiros.ros.processes import add_child_options, discovery_environment, start_child_program
from multiros.ros.transport import wire_transport
from multiros.sim.actions import TrajectoryActions
from multiros.sim.controller_io import ControllerInterfaces
from multiros.sim.distro_adapters import get_message
from multiros.sim.errors import ControllerError, SimError

__all__ = ["FakeRobot", "build_parser", "gap_from_options", "main", "serve", "DEFAULT_RATE", "TRUTH_TOPIC"]

_logger = logging.getLogger(__name__)

JointState = get_message("sensor_msgs/msg/JointState")

#: joint_states rate in Hz.
DEFAULT_RATE = 100.0
#: With a gap: where the true joint states go, relative to the node (``<ns>/controller_manager/...``).
TRUTH_TOPIC = "ground_truth/joint_states"
_NS_PER_S = 1_000_000_000


def _stamp(msg: Any, seconds: float) -> None:
    ns = int(seconds * _NS_PER_S)
    msg.header.stamp.sec, msg.header.stamp.nanosec = ns // _NS_PER_S, ns % _NS_PER_S


class _Actions(TrajectoryActions):
    """The simulation node's FollowJointTrajectory servers, with an optional refuse-everything fault."""

    reject_all = False

    def _accept(self, controller: str, goal: Any) -> GoalResponse:
        if self.reject_all:
            return self._reject(controller, "this fake robot refuses every goal (--reject-goals)")
        return super()._accept(controller, goal)


class FakeRobot:
    """A fake ros2_control robot serving on ``context``.

    Args:
        spec: the robot (see :func:`~multiros.hardware.robot_spec.load_robot_spec`).
        context: an initialised ROS context (Zenoh for other processes to see it).
        rate: ``joint_states`` rate in Hz.
        update_rate: control-loop rate in Hz (at least ``rate``; default ``max(rate, 100)``).
        time_constant: first-order lag of the joints in seconds (default: the gap's ``time_constant``
            when > 0, else :data:`~multiros.hardware.fake_hardware.DEFAULT_TIME_CONSTANT`).
        activate: controllers to activate at start (default: every controller of the YAML whose
            joints are free, in file order); the others are loaded and inactive.
        stall_after: stop publishing ``joint_states`` this many seconds after :meth:`start`.
        reject_goals: refuse every FollowJointTrajectory goal.
        node_name: the node's name (ros2_control's is ``controller_manager``).
        joint_states_topic: where ``joint_states`` go (relative to the namespace unless absolute;
            default ``<ns>/joint_states``).
        gap: a reality gap (:class:`~multiros.hardware.gap.GapProfile`); with one (``none`` included)
            the truth is published on ``<ns>/<node_name>/ground_truth/joint_states``.
        gap_seed: seeds the gap's random parts (offsets, noise, drops, late messages, jitter).
        hardware: the joints to serve instead of a :class:`~multiros.hardware.fake_hardware.FakeHardware`
            of ``spec`` (``time_constant`` is then unused): an object with its "world" view, e.g. a
            :class:`~multiros.hardware.physics_hardware.PhysicsHardware` built with the same gap and seed.
    """

    def __init__(self, spec: RobotSpec, context: Context, *, rate: float = DEFAULT_RATE,
                 update_rate: float | None = None, time_constant: float | None = None,
                 activate: Sequence[str] | None = None, stall_after: float | None = None,
                 reject_goals: bool = False, node_name: str = "controller_manager",
                 joint_states_topic: str | None = None, gap: GapProfile | None = None,
                 gap_seed: int | None = 0, hardware: Any = None) -> None:
        if not rate > 0 or (update_rate is not None and not update_rate > 0):
            raise ValueError(f"rate ({rate}) and update_rate ({update_rate}) must be positive (Hz)")
        if stall_after is not None and not stall_after >= 0:
            raise ValueError(f"stall_after must be >= 0 seconds, got {stall_after}")
        self.spec = spec
        self.ns = spec.namespace
        self.rate = float(rate)
        self.update_rate = max(float(update_rate or max(rate, 100.0)), self.rate)
        self.stall_after = stall_after
        self.hardware = FakeHardware(spec, time_constant=time_constant, gap=gap, seed=gap_seed) \
            if hardware is None else hardware
        self.gap = gap
        self._sensing = StateGap(gap, 1.0 / self.rate, gap_generators(gap_seed)[1]) \
            if gap is not None and gap.acts_on_messages else None
        self._late: deque[tuple[float, Any]] = deque()  # (due, message): late joint_states, in due order
        self.dropped = 0  # joint_states messages dropped on purpose (--gap)
        self.active_controllers = self.hardware.start_controllers(list(activate) if activate is not None else None)
        self.node = Node(node_name, namespace=self.ns or None, context=context)
        self._names = spec.published_joints
        topic = joint_states_topic or "joint_states"
        self.joint_states_topic = topic if topic.startswith("/") else f"{self.ns}/{topic}"
        self._joint_pub = self.node.create_publisher(JointState, self.joint_states_topic, 10)
        self.truth_topic = f"{self.ns}/{node_name}/{TRUTH_TOPIC}" if gap is not None else None
        self._truth_pub = self.node.create_publisher(JointState, self.truth_topic, 10) \
            if self.truth_topic is not None else None
        self._actions = _Actions(self.node, self.hardware, spec.name, self.ns, self.hardware.lock)
        self._actions.reject_all = bool(reject_goals)
        self.controllers = ControllerInterfaces(self.node, self.hardware, spec.name, self.ns, self.hardware.lock,
                                                self._actions)
        with self.hardware.lock:
            self.controllers.subscribe_all()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._executor: SingleThreadedExecutor | None = None
        self._spin_thread: threading.Thread | None = None
        self.published = 0  # joint_states messages sent

    # -- loop --------------------------------------------------------------------------------
    def start(self) -> None:
        """Start the command topics, the control loop and ``joint_states``, then the controller
        manager's services: once they answer, everything is served."""
        if self._thread is not None:
            return
        self._executor = SingleThreadedExecutor(context=self.node.context)
        self._executor.add_node(self.node)
        self._spin_thread = threading.Thread(target=self._executor.spin, name="uniros-fake-robot-topics",
                                             daemon=True)
        self._spin_thread.start()
        self._thread = threading.Thread(target=self._loop, name="uniros-fake-robot", daemon=True)
        self._thread.start()
        self.controllers.serve()

    def _loop(self) -> None:
        tick, pub_period = 1.0 / self.update_rate, 1.0 / self.rate
        start = last = time.monotonic()
        next_tick, next_pub = start, start
        pub_at = next_pub  # with --gap's jitter: next_pub moved within its slot
        jitter = self._sensing is not None and self._sensing.profile.jitter > 0
        stall_at = start + self.stall_after if self.stall_after is not None else float("inf")
        stalled = False
        while True:
            # The loop wakes for its tick; with a gap also for a jittered publish or a late message due.
            wake = min(next_tick, pub_at) if jitter and not stalled else next_tick
            if self._late:
                wake = min(wake, self._late[0][0])
            if self._stop.wait(max(0.0, wake - time.monotonic())):
                break
            now = time.monotonic()
            try:
                self.hardware.update(now - last)
                self._actions.on_step()
                if now >= stall_at and not stalled:
                    stalled = True
                    self._late.clear()
                    _logger.warning("%s/joint_states: stalled on purpose (--stall-after %g s)", self.ns,
                                    self.stall_after)
                if not stalled and now >= pub_at:
                    self._publish()
                    next_pub += pub_period
                    if next_pub <= now:  # fell behind: keep the rate, skip the missed messages
                        next_pub = now + pub_period
                    pub_at = next_pub + self._sensing.jitter() if jitter and self._sensing is not None else next_pub
                while self._late and self._late[0][0] <= now:
                    self._joint_pub.publish(self._late.popleft()[1])
                    self.published += 1
            except Exception:  # noqa: BLE001 - a transport hiccup must not kill the robot
                _logger.exception("fake robot control loop")
            last = now
            if wake == next_tick:
                next_tick += tick
                if next_tick <= now:
                    next_tick = now + tick

    def _publish(self) -> None:
        positions, velocities, efforts = self.hardware.published_state()
        captured = time.time()
        if self._truth_pub is not None:
            truth = JointState()
            _stamp(truth, captured)
            truth.name = self._names
            truth.position, truth.velocity, truth.effort = self.hardware.true_state()
            self._truth_pub.publish(truth)
        fate = StateGap.NOW
        if self._sensing is not None:
            fate = self._sensing.fate()
            if fate == StateGap.DROP:
                self.dropped += 1
                return
            positions = self._sensing.noisy(positions)
        msg = JointState()
        _stamp(msg, captured)
        msg.name = self._names
        msg.position, msg.velocity, msg.effort = positions, velocities, efforts
        if fate == StateGap.LATE and self._sensing is not None:
            self._late.append((time.monotonic() + self._sensing.late_by, msg))
            return
        self._joint_pub.publish(msg)
        self.published += 1

    # -- teardown ----------------------------------------------------------------------------
    def stop(self) -> None:
        """Stop the control loop (the joints' motion and ``joint_states``); the topics and services stay
        until :meth:`destroy`. Whoever closes the hardware the loop steps calls this first."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def destroy(self) -> None:
        """Stop the loop, then destroy every topic, service and action."""
        self.stop()
        if self._executor is not None:
            self._executor.shutdown()
            if self._spin_thread is not None:
                self._spin_thread.join(timeout=2.0)
        self.controllers.destroy()
        self.node.destroy_node()


# ------------------------------------------------------------------------------------------ CLI
def build_parser() -> argparse.ArgumentParser:
    """The command line of ``uniros-fake-robot`` (the upper layer adds ``--arm`` to it)."""
    parser = argparse.ArgumentParser(
        prog="uniros-fake-robot",
        description="A fake ros2_control robot (not a simulator): joint_states at a fixed rate, a controller "
                    "manager, forward command and joint trajectory controllers, joints following commands "
                    "with a first-order lag. For trying a Real env with no robot. It logs 'ready' once serving.",
    )
    parser.add_argument("--robot", choices=sorted(PRESETS),
                        help="a shipped robot: its description, controllers, namespace and controller names")
    parser.add_argument("--description", help="URDF/xacro file or package:// URI (?name=value adds xacro args)")
    parser.add_argument("--xacro-arg", action="append", default=[], metavar="NAME:=VALUE",
                        help="xacro argument (NAME=VALUE too)")
    parser.add_argument("--controllers-file", help="ros2_control controllers YAML (file or package:// URI); "
                                                   "default: the preset's, or the one the description names")
    parser.add_argument("--namespace", help="ROS namespace (default: the preset's; rx200 -> /rx200, irb120 -> none)")
    parser.add_argument("--controller-name", action="append", default=[], metavar="YAML_NAME=NAME",
                        help="serve a controller of the YAML under another name (repeatable)")
    parser.add_argument("--activate", help="comma-separated controllers to activate at start (default: every "
                                           "controller whose joints are free, in YAML order)")
    parser.add_argument("--initial", action="append", default=[], metavar="JOINT=POSITION",
                        help="start position of a joint (default: the description's initial_value, else 0, "
                             "clamped to the limits)")
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE, help="joint_states rate in Hz (%(default)s)")
    parser.add_argument("--update-rate", type=float, default=None, help="control loop rate in Hz "
                                                                        "(default max(rate, 100))")
    parser.add_argument("--time-constant", type=float, default=None,
                        help=f"first-order lag of the joints in seconds (default: the --gap profile's time_constant "
                             f"when > 0, else {DEFAULT_TIME_CONSTANT})")
    parser.add_argument("--gap", metavar="PROFILE", default=None,
                        help=f"a reality gap: {', '.join(PROFILES)} or a YAML file of gap keys (command latency, lag, "
                             "backlash, droop, calibration offsets, joint noise, dropped/late joint_states, rate "
                             "jitter); the truth goes to <ns>/controller_manager/ground_truth/joint_states")
    parser.add_argument("--gap-set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one key of the --gap profile (repeatable), e.g. droop=0.05 or droop_joints=1,2")
    parser.add_argument("--gap-seed", type=int, default=0, metavar="N",
                        help="seed of the gap's random parts: offsets, noise, drops, late messages, jitter (0)")
    parser.add_argument("--stall-after", type=float, default=None, metavar="SEC",
                        help="fault: stop publishing joint_states SEC seconds after start")
    parser.add_argument("--reject-goals", action="store_true", help="fault: refuse every trajectory goal")
    parser.add_argument("--transport", default=None, choices=["zenoh", "rclpy"],
                        help="ROS transport (default: $UNIROS_TRANSPORT, else rclpy when rclpy can be imported, "
                             "else zenoh)")
    parser.add_argument("--router", default=None,
                        help="Zenoh router: 'auto' (default: the one at $UNIROS_ZENOH_ROUTER or "
                             "tcp/127.0.0.1:7447, started there if none listens), 'embedded', 'none', or an "
                             "endpoint such as tcp/127.0.0.1:7448")
    add_child_options(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros-fake-robot``: serve a fake robot until interrupted (or the owner is gone)."""
    parser = build_parser()
    own, ros_args = split_ros_arguments(sys.argv[1:] if argv is None else list(argv))
    opts = parser.parse_args(own)
    stop = start_child_program(opts)
    if not opts.robot and not opts.description:
        parser.error(f"give --robot (one of {', '.join(sorted(PRESETS))}) or --description")
    try:
        spec = load_robot_spec(
            opts.robot, description=opts.description,
            xacro_args=parse_xacro_args(opts.xacro_arg),
            controllers_file=opts.controllers_file, namespace=opts.namespace,
            renames=parse_assignments(opts.controller_name, "--controller-name"),
            initial_positions={k: float(v) for k, v in parse_assignments(opts.initial, "--initial").items()},
        )
    except (ValueError, OSError, SimError) as exc:  # bad option, missing file, xacro/URDF error: exit 2
        parser.error(f"cannot load the robot: {exc}")
    return serve(spec, opts, parser, stop, ros_args=ros_args)


def gap_from_options(opts: argparse.Namespace) -> GapProfile | None:
    """The gap of ``--gap`` and ``--gap-set`` (``--gap-set`` alone starts from ``none``); ``None`` without
    either. Raises :class:`~multiros.hardware.gap.GapProfileError` (one line)."""
    overrides = parse_gap_assignments(opts.gap_set)
    if opts.gap is None and not overrides:
        return None
    return load_gap_profile(opts.gap or "none", overrides)


def serve(spec: RobotSpec, opts: argparse.Namespace, parser: argparse.ArgumentParser, stop: threading.Event, *,
          joint_states_topic: str | None = None,
          attach: Callable[[FakeRobot], Callable[[], None] | None] | None = None,
          ros_args: Sequence[str] = (),
          hardware: Callable[[GapProfile | None, int], Any] | None = None) -> int:
    """Serve ``spec`` with the options of :func:`build_parser` until ``stop`` is set.

    ``ros_args`` are the ``--ros-args ...`` of the command line, for rcl (enclave, remaps).

    ``attach`` (the upper layer's) adds interfaces to the robot before it starts serving and returns
    what closes them (or ``None``); a ``ValueError`` from it is a bad robot: exit 2.

    ``hardware(gap, gap_seed)`` (the upper layer's) makes the joints to serve (``FakeRobot``'s ``hardware``);
    a ``ValueError`` from it is a bad robot: exit 2.
    """
    try:
        gap = gap_from_options(opts)
    except GapProfileError as exc:
        parser.exit(2, f"uniros-fake-robot: {exc}\n")
    opts.transport = wire_transport(opts.transport)
    options: dict[str, Any] = {"router": opts.router} if opts.router and opts.transport == "zenoh" else {}
    try:
        ctx = Context(transport=opts.transport, env=discovery_environment(), **options).init(list(ros_args))
    except TransportError as exc:
        parser.exit(2, f"uniros-fake-robot: {exc}\n")
    robot = None
    detach = None
    try:
        try:
            joints = hardware(gap, opts.gap_seed) if hardware is not None else None
            robot = FakeRobot(spec, ctx, rate=opts.rate, update_rate=opts.update_rate,
                              time_constant=opts.time_constant,
                              activate=opts.activate.split(",") if opts.activate else None,
                              stall_after=opts.stall_after, reject_goals=opts.reject_goals,
                              joint_states_topic=joint_states_topic, gap=gap, gap_seed=opts.gap_seed,
                              hardware=joints)
            detach = attach(robot) if attach is not None else None
        except (ValueError, ControllerError, TransportError) as exc:
            _logger.error("%s", exc)
            return 2
        robot.start()
        _logger.info("fake robot %s ready: namespace '%s', joints %s, active controllers %s (transport %s)",
                     spec.name, spec.namespace or "/", spec.published_joints, robot.active_controllers,
                     opts.transport)
        while not stop.wait(0.5):
            pass
    finally:
        if robot is not None:
            robot.stop()  # the loop steps the hardware: it stops before detach closes that hardware
        if detach is not None:
            detach()
        if robot is not None:
            robot.destroy()
        ctx.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
