"""uniros-fake-robot: a fake ros2_control robot in another process, reached over Zenoh.

Each child joins a private router on a free loopback port (never 7447) and is stopped by PID.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from multiros.hardware import FakeHardware, load_robot_spec
from multiros.hardware.process import FakeRobotError, FakeRobotProcess
from multiros.ros import Context, Node
from multiros.ros.action import STATUS_ABORTED, STATUS_CANCELED, STATUS_SUCCEEDED, ActionClient
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_action, get_message, get_service
from multiros.ros.processes import child_environment
from multiros.sim.controllers import JointMode
from multiros.sim.launch import private_context

JointState = get_message("sensor_msgs/msg/JointState")
Float64MultiArray = get_message("std_msgs/msg/Float64MultiArray")
JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
Point = get_message("trajectory_msgs/msg/JointTrajectoryPoint")
Tolerance = get_message("control_msgs/msg/JointTolerance")
ListControllers = get_service("controller_manager_msgs/srv/ListControllers")
SwitchController = get_service("controller_manager_msgs/srv/SwitchController")
FollowJointTrajectory = get_action("control_msgs/action/FollowJointTrajectory")
FJT = FollowJointTrajectory.Result
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]
_CWD = tempfile.gettempdir()  # children import the installed package, as a user's would


# ------------------------------------------------------------------------------ in-process units
def test_presets_read_the_shipped_descriptions_and_vendor_controller_names():
    rx = load_robot_spec("rx200")
    assert rx.namespace == "/rx200"
    assert [j.name for j in rx.joints] == [*ARM, "left_finger"]
    assert rx.published_joints[-1] == "right_finger"  # mimic of left_finger
    shoulder = rx.joints[1]
    assert shoulder.velocity == pytest.approx(1.0) and shoulder.lower < 0 < shoulder.upper
    assert rx.joints[-1].initial == pytest.approx(0.0195)  # the description's initial_value
    irb = load_robot_spec("irb120")
    assert irb.namespace == "" and [j.name for j in irb.joints] == [f"joint_{i}" for i in range(1, 7)]
    cm = irb.controllers["controller_manager"]["ros__parameters"]
    assert "joint_trajectory_controller" in cm and "arm120_controller" not in cm
    assert "joint_trajectory_controller" in irb.controllers
    renamed = load_robot_spec("rx200", renames={"arm_controller": "my_arm"}, namespace="robot",
                              initial_positions={"waist": 0.5})
    assert renamed.namespace == "/robot" and renamed.joints[0].initial == 0.5
    assert "my_arm" in renamed.controllers["controller_manager"]["ros__parameters"]


def test_a_gripper_drive_left_out_of_ros2_control_is_commandable_and_its_mimic_follows():
    """As in the simulation (urdf_model.Robot.mimic_leaders): the vendor's arm block without the gripper."""
    urdf = Path(__file__).parents[1] / "sim" / "data" / "gripper_drive_outside_ros2_control.urdf"
    spec = load_robot_spec(description=str(urdf))
    assert [j.name for j in spec.joints] == ["wrist", "drive"]
    assert spec.joints[1].upper == pytest.approx(0.04)


@pytest.mark.parametrize("kwargs, match", [
    ({"robot": "ur5"}, "unknown robot preset"),
    ({"robot": None}, "no robot description"),
    ({"robot": "rx200", "renames": {"nope": "x"}}, "cannot rename controller 'nope'"),
    ({"robot": "rx200", "initial_positions": {"nope": 1.0}}, "unknown joints"),
])
def test_bad_specs_say_what_is_wrong(kwargs, match):
    robot = kwargs.pop("robot")
    with pytest.raises(ValueError, match=match):
        load_robot_spec(robot, **kwargs)


def test_hardware_lag_velocity_limit_and_position_limits():
    hw = FakeHardware(load_robot_spec("rx200"), time_constant=0.1, clock=lambda: 1000.0)
    hw.start_controllers()
    hw.cm.switch(["arm_position_controller"], ["arm_controller"], time=1000.0)
    assert hw.hw.mode[0] == int(JointMode.POSITION)
    hw.cm.set_command("arm_position_controller", [0.1, 0.0, 0.0, 0.0, 100.0], 1000.0)
    for _ in range(10):
        hw.update(0.01)
    assert hw.hw.position[0] == pytest.approx(0.1 * (1.0 - math.exp(-1.0)), rel=1e-6)  # one time constant
    for _ in range(1000):
        hw.update(0.01)
    assert hw.hw.position[4] == pytest.approx(hw.hw.upper[4])  # clamped to the URDF limit
    hw.cm.set_command("arm_position_controller", [1.0, 1.5, 0.0, 0.0, 0.0], 1000.0)
    hw.update(0.01)
    assert hw.hw.velocity[1] == pytest.approx(1.0)  # shoulder: URDF velocity limit 1 rad/s
    positions, _, _ = hw.published_state()
    assert positions[6] == pytest.approx(-positions[5])  # right_finger mimics left_finger


def test_serve_stops_the_control_loop_before_the_upper_layer_closes_its_hardware(monkeypatch):
    """The physics stand-in's world is closed by what ``attach`` returns; the loop that steps it must have
    stopped by then (a loop stepping a closed world logged AttributeError tracebacks at shutdown)."""
    from multiros.hardware import fake_robot as fr

    spec = load_robot_spec("rx200")
    stop = threading.Event()
    stepped_closed = threading.Event()

    class ClosingHardware(FakeHardware):
        closed = False
        updates = 0

        def update(self, dt: float, now: float | None = None) -> None:
            if self.closed:
                stepped_closed.set()
            self.updates += 1
            if self.updates == 20:  # the loop runs: stop serving
                stop.set()
            super().update(dt, now)

    made: list[ClosingHardware] = []

    def hardware(gap, seed):
        made.append(ClosingHardware(spec, gap=gap, seed=seed))
        return made[-1]

    closes: list[bool] = []

    def attach(robot):
        def detach() -> None:
            made[-1].closed = True
            # the loop ticks at update_rate (100 Hz by default): a running one steps the closed hardware
            # within a tick; a stopped one never does
            closes.append(stepped_closed.wait(0.3))
        return detach

    class PrivateContext:  # serve's Context(...).init(...): a private graph of this test's own
        def __init__(self, **kwargs):
            pass

        def init(self, args):
            return private_context()

    monkeypatch.setattr(fr, "Context", PrivateContext)
    opts = fr.build_parser().parse_args(["--robot", "rx200", "--transport", "zenoh", "--log-level", "WARNING"])
    assert fr.serve(spec, opts, fr.build_parser(), stop, attach=attach, hardware=hardware) == 0
    assert made[-1].updates >= 20
    assert closes == [False], "the control loop stepped the hardware after it was closed"


# ------------------------------------------------------------------------------ over the wire
class Probe:
    """A client node on the fake robot's graph: joint_states recorder, services, actions."""

    def __init__(self, ctx: Context, ns: str = "/rx200") -> None:
        self.ns = ns
        self.node = Node(f"probe_{os.getpid()}_{id(self):x}", context=ctx)
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        self.lock = threading.Lock()
        self.states: list[tuple[float, object]] = []
        self.node.create_subscription(JointState, f"{ns}/joint_states", self._on_state, 200)
        self.list_client = self.node.create_client(ListControllers, f"{ns}/controller_manager/list_controllers")
        self.switch_client = self.node.create_client(SwitchController, f"{ns}/controller_manager/switch_controller")
        self.gripper = self.node.create_publisher(Float64MultiArray, f"{ns}/gripper_controller/commands", 10)
        self.arm_topic = self.node.create_publisher(JointTrajectory, f"{ns}/arm_controller/joint_trajectory", 10)
        self.action = ActionClient(self.node, FollowJointTrajectory, f"{ns}/arm_controller/follow_joint_trajectory")

    def _on_state(self, msg) -> None:
        with self.lock:
            self.states.append((time.time(), msg))

    def clear(self) -> None:
        with self.lock:
            self.states.clear()

    def wait_states(self, count: int, timeout: float = 10.0) -> list:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if len(self.states) >= count:
                    return list(self.states)
            time.sleep(0.01)
        raise AssertionError(f"fewer than {count} joint_states within {timeout} s (got {len(self.states)})")

    def position(self, joint: str) -> float:
        _, msg = self.wait_states(1)[-1]
        return float(msg.position[list(msg.name).index(joint)])

    def controllers(self) -> dict[str, str]:
        response = self.list_client.call(ListControllers.Request(), timeout_sec=5.0)
        return {c.name: c.state for c in response.controller}

    def switch(self, activate=(), deactivate=(), strict=True):
        req = SwitchController.Request(activate_controllers=list(activate), deactivate_controllers=list(deactivate),
                                       strictness=SwitchController.Request.STRICT if strict
                                       else SwitchController.Request.BEST_EFFORT)
        return self.switch_client.call(req, timeout_sec=5.0)

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=5.0)
        self.node.destroy_node()


@pytest.fixture(scope="module")
def graph() -> Iterator[Context]:
    ctx = private_context()
    yield ctx
    ctx.try_shutdown()


@pytest.fixture(scope="module")
def rx200(graph) -> Iterator[FakeRobotProcess]:
    with FakeRobotProcess("rx200", context=graph, args=["--log-level", "WARNING"], cwd=_CWD) as proc:
        yield proc


@pytest.fixture
def probe(graph, rx200) -> Iterator[Probe]:
    p = Probe(graph)
    assert p.list_client.wait_for_service(10.0) and p.action.wait_for_server(10.0)
    yield p
    p.close()


def _wait_for(predicate, timeout: float = 10.0, what: str = "condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.02)
    raise AssertionError(f"{what} not reached within {timeout} s")


def _goal(positions, seconds: float, joints=ARM, goal_tol: float = 0.0):
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = list(joints)
    point = Point(positions=np.asarray(positions, dtype=float))
    point.time_from_start.sec, point.time_from_start.nanosec = int(seconds), int(round((seconds % 1) * 1e9))
    goal.trajectory.points = [point]
    if goal_tol:
        goal.goal_tolerance = [Tolerance(name=j, position=goal_tol) for j in joints]
    goal.goal_time_tolerance.sec = 2
    return goal


def _send(probe: Probe, goal, feedback=None):
    sent = probe.action.send_goal_async(goal, feedback_callback=feedback)
    assert sent.wait(5.0)
    return sent.result()


def _arm(probe: Probe) -> np.ndarray:
    _, msg = probe.wait_states(1)[-1]
    names = list(msg.name)
    return np.array([msg.position[names.index(j)] for j in ARM])


@pytest.mark.multiprocess
def test_joint_states_at_a_fixed_rate_with_wall_clock_stamps(probe):
    probe.clear()
    start = time.time()
    time.sleep(1.0)
    states = probe.wait_states(1)
    received = [s for s in states if s[0] <= start + 1.0]
    assert 60 <= len(received) <= 120, f"{len(received)} joint_states in 1 s at --rate 100"
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for _, m in states]
    assert all(b > a for a, b in zip(stamps, stamps[1:])), "stamps must increase"
    assert all(abs(t - s) < 0.5 for (t, _), s in zip(states, stamps)), "stamps are the wall clock"
    assert list(states[-1][1].name) == [*ARM, "left_finger", "right_finger"]


@pytest.mark.multiprocess
def test_a_forward_command_is_followed_with_a_first_order_lag(probe):
    start = probe.position("left_finger")
    target = 0.030 if start < 0.025 else 0.020
    probe.clear()
    probe.gripper.publish(Float64MultiArray(data=[target]))
    _wait_for(lambda: abs(probe.position("left_finger") - target) < 1e-4, what="the gripper reaching its target")
    samples = []
    for _, msg in probe.wait_states(1):
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        frac = (msg.position[5] - start) / (target - start)
        if 0.15 < frac < 0.9:
            samples.append((stamp, frac))
    assert len(samples) >= 5, "too few samples on the way to the target"
    # tau from pairs of samples, independent of when the command took effect
    taus = [(t2 - t1) / math.log((1 - f1) / (1 - f2)) for (t1, f1), (t2, f2) in zip(samples, samples[3:])]
    assert 0.06 < float(np.median(taus)) < 0.16, f"time constant {np.median(taus):.3f} s, expected ~0.1 s"
    assert probe.position("right_finger") == pytest.approx(-target, abs=1e-4)


@pytest.mark.multiprocess
def test_list_and_switch_follow_ros2_control_semantics(probe):
    assert probe.controllers() == {"joint_state_broadcaster": "active", "arm_controller": "active",
                                   "arm_position_controller": "inactive", "gripper_controller": "active"}
    clash = probe.switch(activate=["arm_position_controller"])
    assert not clash.ok and "already claimed" in clash.message and "arm_controller" in clash.message
    unknown = probe.switch(activate=["nope"])
    assert not unknown.ok and "not loaded" in unknown.message
    assert probe.switch(activate=["nope"], strict=False).ok  # best effort skips what it cannot do
    swapped = probe.switch(activate=["arm_position_controller"], deactivate=["arm_controller"])
    assert swapped.ok
    assert probe.controllers()["arm_position_controller"] == "active"
    assert probe.controllers()["arm_controller"] == "inactive"
    goal = _send(probe, _goal([0.1] * 5, 0.5))
    assert not goal.accepted  # an inactive trajectory controller refuses goals
    assert probe.switch(activate=["arm_controller"], deactivate=["arm_position_controller"]).ok
    assert probe.controllers()["arm_controller"] == "active"


@pytest.mark.multiprocess
def test_trajectory_goal_succeeds_with_feedback_and_bad_goals_are_rejected(probe):
    target = [0.3, 0.2, -0.2, 0.1, 0.0]
    feedback = []
    handle = _send(probe, _goal(target, 0.5, goal_tol=0.02), feedback.append)
    assert handle.accepted
    # The client drops a goal's feedback callback once the result arrives: wait (bounded) for the
    # feedback the trajectory sends, which a loaded machine delivers late, before asking for it.
    deadline = time.monotonic() + 10.0
    while not feedback and time.monotonic() < deadline:
        time.sleep(0.01)
    response = handle.get_result(timeout_sec=10.0)
    assert response.status == STATUS_SUCCEEDED and response.result.error_code == FJT.SUCCESSFUL
    assert np.max(np.abs(_arm(probe) - target)) < 0.03  # the last joint_states may be 10 ms old
    assert feedback and list(feedback[-1].feedback.joint_names) == ARM
    assert not _send(probe, _goal([0.1, 0.1], 0.5, joints=["waist", "nope"])).accepted
    nan_goal = _goal([0.1] * 5, 0.5)
    nan_goal.trajectory.points[0].positions = np.array([0.1, np.nan, 0.1, 0.1, 0.1])
    assert not _send(probe, nan_goal).accepted
    # A goal that cannot reach its tolerance aborts with GOAL_TOLERANCE_VIOLATED.
    tight = _goal([0.0] * 5, 0.2, goal_tol=1e-9)
    tight.goal_time_tolerance.sec, tight.goal_time_tolerance.nanosec = 0, 50_000_000
    response = _send(probe, tight).get_result(timeout_sec=10.0)
    assert response.status == STATUS_ABORTED and response.result.error_code == FJT.GOAL_TOLERANCE_VIOLATED


@pytest.mark.multiprocess
def test_cancel_holds_the_position_and_a_new_goal_preempts(probe):
    assert _send(probe, _goal([0.0] * 5, 0.3, goal_tol=0.05)).get_result(timeout_sec=10.0).status == STATUS_SUCCEEDED
    handle = _send(probe, _goal([1.0, 0.8, 0.8, 0.8, 0.8], 4.0))
    _wait_for(lambda: _arm(probe)[0] > 0.1, what="the arm moving")
    assert handle.cancel_goal(timeout_sec=5.0).return_code == 0
    assert handle.get_result(timeout_sec=5.0).status == STATUS_CANCELED
    _wait_for(lambda: np.max(np.abs(probe.wait_states(1)[-1][1].velocity)) < 1e-4,
              what="the arm at rest after the cancel")
    held = _arm(probe)
    assert 0.05 < held[0] < 0.9
    time.sleep(0.5)
    assert np.max(np.abs(_arm(probe) - held)) < 0.01, "after a cancel the arm holds where it was"
    first = _send(probe, _goal([0.2] * 5, 3.0))
    second = _send(probe, _goal([-0.1] * 5, 0.5, goal_tol=0.05))
    result = first.get_result(timeout_sec=5.0)
    assert result.status == STATUS_ABORTED and "preempted" in result.result.error_string
    assert second.get_result(timeout_sec=10.0).status == STATUS_SUCCEEDED


@pytest.mark.multiprocess
def test_malformed_commands_are_ignored_and_the_robot_stays_alive(probe):
    _wait_for(lambda: np.max(np.abs(probe.wait_states(1)[-1][1].velocity)) < 1e-4, what="the robot at rest")
    before = probe.position("left_finger")
    probe.gripper.publish(Float64MultiArray(data=[0.02, 0.03]))  # wrong length
    probe.gripper.publish(Float64MultiArray(data=[float("nan")]))
    bad = JointTrajectory(joint_names=ARM)
    bad.points = [Point(positions=np.array([0.1, np.inf, 0.1, 0.1, 0.1]))]
    probe.arm_topic.publish(bad)
    arm_before = _arm(probe)
    probe.clear()
    probe.wait_states(30)  # still publishing, 0.3 s later
    assert probe.position("left_finger") == pytest.approx(before, abs=1e-6)
    assert np.allclose(_arm(probe), arm_before, atol=1e-3)
    assert probe.controllers()["gripper_controller"] == "active"


@pytest.mark.multiprocess
def test_faults_stall_and_reject_goals(graph):
    args = ["--log-level", "ERROR", "--namespace", "faulty", "--stall-after", "0.5", "--reject-goals"]
    with FakeRobotProcess("rx200", context=graph, args=args, cwd=_CWD):
        probe = Probe(graph, ns="/faulty")
        try:
            assert probe.action.wait_for_server(10.0)
            assert not _send(probe, _goal([0.1] * 5, 0.5)).accepted
            time.sleep(0.7)  # past the stall
            probe.clear()
            time.sleep(0.5)
            assert probe.states == [], "joint_states must stop after --stall-after"
            assert probe.controllers()["arm_controller"] == "active"  # the services still answer
        finally:
            probe.close()


@pytest.mark.slow
@pytest.mark.multiprocess
def test_stopped_by_pid_and_with_its_owner(graph):
    robot = FakeRobotProcess("irb120", context=graph, args=["--log-level", "WARNING"], cwd=_CWD)
    probe = Probe(graph, ns="")
    try:
        assert probe.controllers()["joint_trajectory_controller"] == "active"
        probe.wait_states(5)
    finally:
        probe.close()
        robot.stop(timeout=30.0)  # a clean exit takes < 1 s; a loaded machine (CI at load 6) took > 5 s
    assert robot.process.returncode == 0  # SIGINT: a clean exit
    owner = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    child = subprocess.Popen([sys.executable, "-m", "multiros.hardware.fake_robot", "--robot", "irb120",
                              "--router", "none", "--owner-pid", str(owner.pid), "--log-level", "ERROR"],
                             env={**os.environ, **child_environment(graph)}, cwd=_CWD)
    try:
        owner.kill()
        owner.wait(timeout=10)
        assert child.wait(timeout=15) == 0
    finally:
        for proc in (owner, child):
            if proc.poll() is None:
                proc.send_signal(signal.SIGKILL)
                proc.wait(timeout=10)


@pytest.mark.multiprocess
def test_bad_command_lines_exit_with_a_reason(graph):
    with pytest.raises(FakeRobotError, match="exited with code 2"):
        FakeRobotProcess(None, context=graph, args=["--description", "/nonexistent/robot.urdf"], cwd=_CWD)
    out = subprocess.run([sys.executable, "-m", "multiros.hardware.fake_robot", "--robot", "rx200",
                          "--controller-name", "nope=x"], capture_output=True, text=True, timeout=60, cwd=_CWD)
    assert out.returncode == 2 and "cannot rename controller 'nope'" in out.stderr


def test_xacro_arguments_in_either_form_and_a_stray_colon_refused() -> None:
    from multiros.hardware.robot_spec import parse_xacro_args

    assert parse_xacro_args(["prefix:=left_", "hand=true", "ur_type := ur5e", "x="]) == {
        "prefix": "left_", "hand": "true", "ur_type": "ur5e", "x": ""}
    assert parse_xacro_args(["tcp:=a=b"]) == {"tcp": "a=b"}  # the first separator splits
    assert parse_xacro_args(["tcp=a:=b"]) == {"tcp": "a:=b"}
    for bad in ["prefix::=left_", "prefix", "=x", "a b=c", "1a=2"]:
        with pytest.raises(ValueError, match=r"--xacro-arg .* must look like NAME:=VALUE \(or NAME=VALUE\)"):
            parse_xacro_args([bad])
