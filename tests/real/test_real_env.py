"""Real envs against robot stand-ins in other processes, over a private Zenoh graph.

Both stand-ins (the simulation node in real-time mode, and ``uniros-fake-robot``) offer only what a
ros2_control robot offers; the env must work with either and call no simulation service. What
reaches the robot side is recorded from the test's own subscription to the command topic.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from typing import Any

import numpy as np
import pytest

import uniros
from multiros.envs.core import EnvError
from multiros.envs.real import (
    ControllerNotActiveError,
    RobotConnectionError,
    StaleStateError,
    TrajectoryGoalError,
    UnsafeCommandError,
)
from multiros.envs.real.robot_link import JointState, JointTrajectory
from multiros.ros import Client, Node
from multiros.ros.controller_manager import ControllerManagerClient
from multiros.sim.launch import private_context
from rl_environments.arm_registry import arm_of

from .conftest import StandIn, TopicRecorder, make_real

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

TRAJ_TOPIC = "/rx200/arm_controller/joint_trajectory"


@functools.lru_cache(maxsize=1)
def _sim_spaces() -> tuple[Any, Any]:
    env = uniros.make("RX200ReacherGoalSim-v0")
    try:
        return env.observation_space, env.action_space
    finally:
        env.close()


def _make(ctx, env_id: str = "RX200ReacherGoalReal-v0", **kw: Any) -> Any:
    kw.setdefault("startup_timeout", 10.0)
    return make_real(ctx, env_id, **kw)  # the watchdog's tests set joint_state_timeout


def _wait_publisher_matched(env: Any, subscribers: int = 2, timeout: float = 5.0) -> None:
    """Wait until the env's trajectory publisher sees the robot and the test's recorder."""
    link = env.unwrapped.link
    pub = link._publisher(JointTrajectory, link.trajectory_topic(env.unwrapped.arm_controller))
    assert env.unwrapped.context.wait_for(lambda: pub.get_subscription_count() >= subscribers, timeout)


def test_goal_env_runs_with_the_sim_spaces_and_no_simulation_service(graph, standin: StandIn, monkeypatch) -> None:
    obs_space, act_space = _sim_spaces()  # before the spies: the simulated env may call its node
    names: list[str] = []
    create_client = Node.create_client
    call_async = Client.call_async

    def spy_create(self, srv_type, srv_name, **kw):
        names.append(self.resolve_service_name(srv_name))
        return create_client(self, srv_type, srv_name, **kw)

    def spy_call(self, request, *args, **kw):
        names.append(self.srv_name)
        return call_async(self, request, *args, **kw)

    monkeypatch.setattr(Node, "create_client", spy_create)
    monkeypatch.setattr(Client, "call_async", spy_call)
    env = _make(graph, command_interface="action")
    try:
        assert not hasattr(env.unwrapped, "sim")
        assert env.observation_space == obs_space and env.action_space == act_space
        obs, info = env.reset(seed=1)
        assert obs_space.contains(obs) and 0 <= info["state_age_sec"] < 0.5
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert obs_space.contains(obs) and reward in (0.0, -1.0)
            assert 0 <= info["state_age_sec"] < 0.5 and info["safety"]["refused"] is False
        assert env.unwrapped.commands_sent == 4  # the move to the initial pose, then one per step
    finally:
        env.close()
    assert names, "the env made no service call at all"
    allowed = ("/rx200/controller_manager/", "/rx200/arm_controller/follow_joint_trajectory/_action/")
    assert all(n.startswith(allowed) for n in names), sorted(set(names))
    assert not any("mujoco_sim" in n for n in names)


def test_control_loop_rate(graph, standin: StandIn) -> None:
    env = _make(graph, "RX200ReacherReal-v0", environment_loop_rate=25.0)
    try:
        env.reset(seed=0)
        stamps = []
        for _ in range(15):
            _, _, _, _, info = env.step(np.zeros(5, dtype=np.float32))
            stamps.append(time.monotonic())
            assert info["cycle_time_sec"] >= 0.04 - 1e-3  # never faster than the loop
        periods = np.diff(stamps)
        # Loose upper bound on a shared machine: the loop does not drift by whole periods.
        assert np.median(periods) == pytest.approx(0.04, abs=0.015)
    finally:
        env.close()


def _check_command(env: Any, positions: np.ndarray, cap: float, floor: float) -> None:
    rules = env.unwrapped.safety
    assert np.all(positions >= rules.lower - 1e-9) and np.all(positions <= rules.upper + 1e-9)
    # The cap holds against the joint positions read just before sending (the arm moves in real
    # time, so a reading taken before env.step() may be tens of milliseconds older).
    measured = env.unwrapped.last_decision.measured
    assert np.max(np.abs(positions - measured)) <= cap + 1e-9
    ee = rules.ee_position(positions)
    assert ee[2] >= floor - 1e-6
    assert np.all(ee >= rules.workspace_min - 1e-6) and np.all(ee <= rules.workspace_max + 1e-6)


@pytest.mark.parametrize("mode", ["project", "refuse"])
def test_commands_beyond_the_rules_never_reach_the_robot(graph, standin: StandIn, mode: str) -> None:
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    cap, floor = 0.1, 0.12  # the home pose's end effector is at z 0.175
    env = _make(graph, "RX200ReacherReal-v0", delta_action=False, max_joint_delta=cap, floor_z=floor,
                workspace_mode=mode, environment_loop_rate=20.0)
    try:
        _wait_publisher_matched(env)
        env.reset(seed=0)
        sent_before = env.unwrapped.commands_sent
        # The reset's own commands may still be on their way: count them in before the steps.
        assert recorder.wait_count(sent_before)
        start = len(recorder.messages)
        high, low = env.action_space.high, env.action_space.low
        down = np.array([0.0, 1.5, 1.2, 0.0, 0.0], dtype=np.float32)  # reaches for the floor
        events: set[str] = set()
        refused = 0
        expected = []
        for action in [high, low, *[down] * 12]:
            _, _, _, _, info = env.step(action)
            events |= {k for k, v in info["safety"].items() if v is True}
            if info["safety"]["refused"]:
                refused += 1
            else:
                expected.append(env.unwrapped.last_command.copy())
                _check_command(env, env.unwrapped.last_command, cap, floor)
        n_sent = env.unwrapped.commands_sent - sent_before
        assert n_sent == len(expected)
        assert recorder.wait_count(start + n_sent)
        received = recorder.messages[start:]
        assert len(received) == n_sent  # nothing else reached the robot
        for msg, want in zip(received, expected):
            assert list(msg.joint_names) == list(env.unwrapped.arm_joints)
            np.testing.assert_allclose(msg.points[0].positions, want)
        assert {"joint_delta", "floor"} <= events
        if mode == "refuse":
            assert refused > 0
        ee_z = env.unwrapped.ee_position()[2]
        assert ee_z >= floor - 0.01  # the measured end effector stayed above the floor (tracking error)
    finally:
        env.close()
        recorder.close()


def test_nan_and_out_of_range_actions_are_errors_and_send_nothing(graph, standin: StandIn) -> None:
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    env = _make(graph)
    try:
        _wait_publisher_matched(env)
        env.reset(seed=0)
        sent = env.unwrapped.commands_sent
        assert recorder.wait_count(sent)  # the reset's own commands are in before counting
        start = len(recorder.messages)
        for bad in ([np.nan, 0, 0, 0, 0], [0, 0, np.inf, 0, 0], [2.0, 0, 0, 0, 0], [0, 0, 0, 0]):
            with pytest.raises(UnsafeCommandError, match="nothing was sent"):
                env.step(np.asarray(bad, dtype=np.float32))
        assert env.unwrapped.commands_sent == sent
        env.step(np.full(5, 0.5, dtype=np.float32))  # the next command is the first one the robot sees
        assert recorder.wait_count(start + 1)
        assert len(recorder.messages) == start + 1
        np.testing.assert_allclose(recorder.messages[-1].points[0].positions, env.unwrapped.last_command)
    finally:
        env.close()
        recorder.close()


def test_controller_not_active_and_trajectory_goal_rejected(graph, standin: StandIn) -> None:
    node = Node(f"cm_test_{os.getpid()}", context=graph)
    cm = ControllerManagerClient(node, "/rx200", timeout_sec=5.0)
    env = _make(graph, command_interface="action")
    try:
        env.reset(seed=0)
        cm.deactivate("arm_controller")
        with pytest.raises(ControllerNotActiveError, match="arm_controller"):
            _make(graph)
        with pytest.raises(TrajectoryGoalError, match="rejected"):
            env.step(np.zeros(3 + 2, dtype=np.float32))
        with pytest.raises(ControllerNotActiveError, match="arm_controller"):
            env.reset()
    finally:
        env.close()
        if cm.states().get("arm_controller") != "active":
            cm.activate("arm_controller")
        cm.close()
        node.destroy_node()


class _Publisher:
    """Publishes JointState messages from the test at 50 Hz; ``make`` builds each message."""

    def __init__(self, ctx, topic: str) -> None:
        self.node = Node(f"js_pub_{os.getpid()}_{time.monotonic_ns()}", context=ctx)
        self.pub = self.node.create_publisher(JointState, topic, 10)
        home = [float(v) for v in arm_of("RX200").reach["init_joint_pos"]]  # the reset finds it there
        self.make = lambda: JointState(name=["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"],
                                       position=list(home), velocity=[0.0] * 5)
        self.running = True
        self.stop_event = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop_event.wait(0.02):
            if self.running:
                self.pub.publish(self.make())

    def close(self) -> None:
        self.stop_event.set()
        self.thread.join(timeout=2.0)
        self.node.destroy_node()


@pytest.mark.parametrize(("field", "value", "reason"), [
    ("position", [0.0, 0.0, float("nan"), 0.0, 0.0], "NaN"),
    ("position", [0.0, 0.0], "5 names but 2 positions"),
])
def test_malformed_joint_states_are_clear_errors(graph, standin: StandIn, field: str, value: list, reason: str) -> None:
    topic = f"/test_{os.getpid()}/joint_states"
    pub = _Publisher(graph, topic)
    try:
        good = pub.make
        env = _make(graph, joint_states_topic=topic, joint_state_timeout=0.3)
        try:
            env.reset(seed=0)  # the published joints are the init pose: already there
            env.step(np.zeros(5, dtype=np.float32))

            def bad() -> Any:
                msg = good()
                setattr(msg, field, value)
                return msg

            pub.make = bad
            t0 = time.monotonic()
            with pytest.raises(StaleStateError, match=reason):
                for _ in range(50):
                    env.step(np.zeros(5, dtype=np.float32))
            assert time.monotonic() - t0 < 2.0
            with pytest.raises(EnvError, match="stopped after an error"):
                env.step(np.zeros(5, dtype=np.float32))
        finally:
            env.close()
        with pytest.raises(RobotConnectionError, match=reason):
            _make(graph, joint_states_topic=topic, startup_timeout=1.0)
    finally:
        pub.close()


def test_stale_joint_states_stop_the_env(graph, standin: StandIn) -> None:
    topic = f"/stale_{os.getpid()}/joint_states"
    pub = _Publisher(graph, topic)
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    try:
        env = _make(graph, joint_states_topic=topic, joint_state_timeout=0.3)
        try:
            _wait_publisher_matched(env)
            env.reset(seed=0)
            env.step(np.zeros(5, dtype=np.float32))
            pub.running = False
            t0 = time.monotonic()
            with pytest.raises(StaleStateError, match="stale"):
                for _ in range(50):
                    env.step(np.zeros(5, dtype=np.float32))
            assert time.monotonic() - t0 < 2.0
            sent = env.unwrapped.commands_sent
            assert recorder.wait_count(sent)
            with pytest.raises(EnvError):
                env.step(np.zeros(5, dtype=np.float32))
            assert env.unwrapped.commands_sent == sent and len(recorder.messages) <= sent
            pub.running = True  # the robot is back: a reset resumes
            env.reset()
            env.step(np.zeros(5, dtype=np.float32))
        finally:
            env.close()
    finally:
        recorder.close()
        pub.close()


@pytest.mark.parametrize("kind", ["sim", "fake"])
def test_robot_killed_mid_episode_then_back(kind: str) -> None:
    graph = private_context()  # of its own: the module's stand-ins would keep publishing
    try:
        _killed_then_back(graph, kind)
    finally:
        graph.try_shutdown()


def _killed_then_back(graph, kind: str) -> None:
    robot = StandIn(kind, graph)
    try:
        env = _make(graph, joint_state_timeout=0.3)
        try:
            env.reset(seed=0)
            env.step(env.action_space.sample())
            robot.kill()
            t0 = time.monotonic()
            with pytest.raises(StaleStateError, match="stale"):
                for _ in range(50):
                    env.step(env.action_space.sample())
            assert time.monotonic() - t0 < 2.0
        finally:
            env.close()
    finally:
        robot.stop()
    robot = StandIn(kind, graph)
    try:
        env = _make(graph)
        try:
            env.reset(seed=0)
            env.step(env.action_space.sample())
        finally:
            env.close()
    finally:
        robot.stop()
