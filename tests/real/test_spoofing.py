"""A hostile process on the robot's graph forges ``joint_states``: what reaches the robot stays
within the safety rules, watched on the robot side (issues 28 and 38).

* A forging publisher that is in the graph (a second ROS node on the robot's ``joint_states``) is
  refused by name, at start-up, when it appears mid-episode, and at a reset; nothing more is sent.
* A forging peer outside the graph (a raw Zenoh session putting well-formed samples on the topic's
  key, no liveliness token; given the private graph's credentials, as a process of the same user
  could read them) cannot steer the commands: its messages carry another identity than the driver
  the env pinned and are dropped; one that copies the driver's identity meets the plausibility
  checks (states outside the joint limits or moving faster than the robot can are dropped), and
  every command stays within the cap of the env's own previous command.
* A reset move takes the time its speed needs, whatever the states claim: the first one (no
  command sent yet) is timed from the furthest the arm can be.
* A partial message (one joint) is checked like a whole one and cannot stall the env.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import uniros
from multiros.envs.real import RobotConnectionError
from multiros.envs.real.robot_link import JointState, JointTrajectory
from multiros.ros import Node
from multiros.ros.interfaces import serialize_message, type_hash
from multiros.ros.transport.zenoh import wire
from rl_environments.arm_registry import arm_of

from .conftest import RESET_SPEED, StandIn, TopicRecorder

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

TOPIC = "/rx200/joint_states"
TRAJ_TOPIC = "/rx200/arm_controller/joint_trajectory"
CAP = 0.15
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]
INIT = [float(v) for v in arm_of("RX200").reach["init_joint_pos"]]


def _make(ctx: Any, **kw: Any) -> Any:
    kw.setdefault("startup_timeout", 10.0)
    kw.setdefault("reset_joint_speed", RESET_SPEED)  # the pacing tests set their own
    return uniros.make("RX200ReacherReal-v0", context=ctx, delta_action=False, max_joint_delta=CAP, **kw)


def _home() -> Any:
    return JointState(name=list(ARM), position=list(INIT), velocity=[0.0] * 5)


def _driver_gid(ctx: Any) -> bytes:
    """The identity the graph lists for the robot's one joint_states publisher."""
    node = Node(f"gid_probe_{os.getpid()}_{time.monotonic_ns()}", context=ctx)
    try:
        assert ctx.wait_for(lambda: node.count_publishers(TOPIC) == 1, 30.0)
        return node.get_publishers_info_by_topic(TOPIC)[0].gid
    finally:
        node.destroy_node()


class Forger:
    """Publishes a forged ``joint_states`` every ``period`` s on a thread of its own (it depends on
    no subscription of its own being served): ``forge(base())``, ``base`` the state to forge from.
    Through a ROS node in the graph, or (``raw``) as a bare Zenoh put on the topic's key, outside
    the graph, carrying ``gid`` as its identity (default: one of its own)."""

    def __init__(self, ctx: Any, forge: Callable[[Any], Any], *, base: Callable[[], Any] = _home,
                 raw: bool = False, gid: bytes | None = None, period: float = 0.01, wait_matched: bool = True,
                 topic: str = TOPIC) -> None:
        self.forge, self.base, self.period = forge, base, period
        self.sent = 0
        self._cond = threading.Condition()
        self.node = None if raw else Node(f"forger_{os.getpid()}_{time.monotonic_ns()}", context=ctx)
        self.pub = None if self.node is None else self.node.create_publisher(JointState, topic, 10)
        self.session = None
        self.gid = bytes(16) if gid is None else gid
        if raw:
            from raw_zenoh import open_peer_session

            from multiros.ros.processes import private_graph_credentials

            # The graph is private: another user's process gets no connection at all. This forger
            # stands for one that can connect (the user's own, or a shared graph's peer).
            # A client: its samples go through the router, the way the env's own driver's do. (A peer
            # would also set up direct links to the other peers, gossip-found; on a loaded machine
            # the samples of a peer whose links were still forming went nowhere for 30 s, issue 37.)
            self.session = open_peer_session(ctx.transport.settings.router_endpoint,
                                             credentials=private_graph_credentials(ctx), mode="client")
            key = wire.topic_key(ctx.domain_id, topic, "sensor_msgs::msg::dds_::JointState_",
                                 type_hash("sensor_msgs/msg/JointState"))
            self.zpub = self.session.declare_publisher(key)
            # Start once the router has told it a subscriber matches (the env's), not before.
            matched = threading.Event()
            self._listener = self.zpub.declare_matching_listener(lambda st: st.matching and matched.set())
            if self.zpub.matching_status.matching:
                matched.set()
            if wait_matched and not matched.wait(30.0):
                self._close_session()
                raise AssertionError("the forger's publisher never matched the env's subscription")
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        seq = 1 << 40  # far from the driver's own sequence numbers
        while not self._stop.wait(self.period):
            fake = self.forge(self.base())
            fake.header.frame_id = "forged"
            if self.pub is not None:
                self.pub.publish(fake)
            else:
                assert self.session is not None
                self.zpub.put(serialize_message(fake),
                              attachment=wire.encode_attachment(seq + self.sent, time.time_ns(), self.gid))
            with self._cond:
                self.sent += 1
                self._cond.notify_all()

    def wait_sent(self, n: int, timeout: float = 30.0) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: self.sent >= n, timeout)

    def close(self) -> None:
        self._stop.set()
        self.thread.join(timeout=5.0)
        if self.node is not None:
            self.node.destroy_node()
        self._close_session()

    def _close_session(self) -> None:
        if self.session is not None:
            self._listener.undeclare()
            self.zpub.undeclare()
            self.session.close()
            self.session = None


def _shifted(offset: float | None = None, value: float | None = None) -> Callable[[Any], Any]:
    def forge(msg: Any) -> Any:
        fake = JointState(name=list(msg.name), position=list(msg.position), velocity=list(msg.velocity),
                          effort=list(msg.effort))
        i = list(msg.name).index("waist")
        fake.position[i] = value if value is not None else msg.position[i] + offset
        return fake
    return forge


def _observed(env: Any) -> Callable[[], Any]:
    """The env's own view of the arm, to forge from (the true state, as a forger hearing it would)."""
    def base() -> Any:
        s = env.unwrapped.link.states.sample(ARM)
        return JointState(name=list(ARM), position=[float(v) for v in s.position], velocity=[0.0] * 5)
    return base


def test_a_second_publisher_is_refused_by_name(graph, standin: StandIn) -> None:
    forger = Forger(graph, _shifted(offset=1.0))
    try:
        assert graph.wait_for(lambda: forger.node.count_publishers(TOPIC) >= 2, 30.0)
        with pytest.raises(RobotConnectionError, match=rf"2 publishers on {TOPIC}.*{forger.node.get_name()}"):
            _make(graph, startup_timeout=3.0)  # a second publisher that persists through start-up
    finally:
        forger.close()
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    env = _make(graph)
    forger = None
    try:
        assert "rx200" in env.unwrapped.robot_driver or env.unwrapped.robot_driver
        env.reset(seed=0)
        env.step(env.unwrapped.joint_positions(env.unwrapped.arm_joints).astype(np.float32))
        sent = env.unwrapped.commands_sent
        forger = Forger(graph, _shifted(offset=1.0), base=_observed(env))  # appears mid-episode
        assert graph.wait_for(lambda: env.unwrapped.node.count_publishers(TOPIC) >= 2, 30.0)
        with pytest.raises(RobotConnectionError, match="2 publishers"):
            env.step(env.action_space.high)
        assert env.unwrapped.commands_sent == sent  # nothing more left the process
        assert recorder.wait_count(sent) and len(recorder.messages) <= sent
    finally:
        env.close()
        if forger is not None:
            forger.close()
        recorder.close()


def test_a_reset_applies_the_one_driver_rule(graph, standin: StandIn) -> None:
    """Issue 38: a reset heard whoever published; it now refuses a second publisher as steps do."""
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    env = _make(graph, startup_timeout=2.0, reset_joint_speed=2.0)
    forger = None
    try:
        env.reset(seed=0)
        sent = env.unwrapped.commands_sent
        forger = Forger(graph, _shifted(offset=0.0), base=_observed(env))
        assert graph.wait_for(lambda: env.unwrapped.node.count_publishers(TOPIC) >= 2, 30.0)
        with pytest.raises(RobotConnectionError, match=rf"2 publishers on {TOPIC}.*{forger.node.get_name()}"):
            env.reset()
        assert env.unwrapped.commands_sent == sent and recorder.wait_count(sent) and len(recorder.messages) <= sent
        forger.close()
        forger = None
        assert graph.wait_for(lambda: env.unwrapped.node.count_publishers(TOPIC) == 1, 30.0)
        env.reset()  # the driver alone again: the reset goes on
        assert env.unwrapped.commands_sent > sent
    finally:
        env.close()
        if forger is not None:
            forger.close()
        recorder.close()


@pytest.mark.parametrize("identity", ["own", "driver"])
@pytest.mark.parametrize(("offset", "value", "reason"), [(1.0, None, "jumped"), (None, 1e5, "outside its limits")])
def test_forged_states_outside_the_graph_cannot_steer_commands(graph, standin: StandIn, offset, value,
                                                               reason: str, identity: str) -> None:
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    env = _make(graph, environment_loop_rate=20.0)
    forger = None
    try:
        env.reset(seed=0)
        states = env.unwrapped.link.states
        # Its own identity (the forger of issue 38), or a copy of the driver's (public in the graph).
        gid = states.driver if identity == "driver" else None
        assert identity == "own" or gid == _driver_gid(graph)
        forger = Forger(graph, _shifted(offset=offset, value=value), base=_observed(env), raw=True, gid=gid)
        assert forger.wait_sent(6)  # event-driven: the forger's own thread, no subscription of its own
        if identity == "own":
            assert graph.wait_for(lambda: states.foreign_count > 0, 30.0), states.sources(5.0)
            assert "other than the driver" in states.describe_problem(ARM)
        else:
            assert graph.wait_for(lambda: states.malformed_count > 0, 30.0)
            assert reason in (states.last_error or "")
        start = len(recorder.messages)
        sent_before = env.unwrapped.commands_sent
        previous = env.unwrapped.last_command
        far = env.action_space.high.copy()  # every joint asks for its upper limit, far away
        for _ in range(8):
            env.step(far)
            command = env.unwrapped.last_command
            assert np.all(np.abs(command - previous) <= CAP + 1e-9)  # within the cap of the env's own last command
            previous = command
        n = env.unwrapped.commands_sent - sent_before
        assert recorder.wait_count(start + n)
        received = [np.asarray(m.points[0].positions) for m in recorder.messages[start:start + n]]
        for a, b in zip(received, received[1:]):
            assert np.all(np.abs(b - a) <= CAP + 1e-9)  # what the robot got never jumps beyond the cap
        waist = env.unwrapped.joint_positions(["waist"])[0]
        assert abs(waist) < 3.2  # the env never saw a forged waist
    finally:
        if forger is not None:
            forger.close()
        env.close()
        recorder.close()


@pytest.mark.parametrize("identity", ["own", "driver", "only"])
def test_the_first_reset_is_slow_whatever_the_states_say(graph, standin: StandIn, identity: str) -> None:
    """Issue 38: a forger said the arm was at its initial pose while it was 1 rad away, and the first
    reset (no command sent yet) commanded the whole move in 0.1 s (20x reset_joint_speed).

    ``own``: the forger's own identity; ``driver``: a copy of the driver's; ``only``: the env hears
    nothing but the forged states (on a topic of the forger's: the worst case, whatever the checks)."""
    speed = 1.0
    env = _make(graph, reset_joint_speed=4.0)
    try:  # put the arm about 1 rad of waist away from its initial pose
        env.reset(seed=0)
        for _ in range(100):  # the cap holds from the measured state too: a lagging arm takes more steps
            if env.unwrapped.last_command[0] - INIT[0] >= 1.05:
                break
            env.step(np.r_[env.unwrapped.last_command[0] + CAP, INIT[1:]].astype(np.float32))
        away = env.unwrapped.last_command.copy()
        for _ in range(100):  # and let it arrive there
            if abs(env.unwrapped.joint_positions(["waist"])[0] - away[0]) < 0.01:
                break
            env.step(away.astype(np.float32))
    finally:
        env.close()
    assert abs(away[0] - INIT[0]) >= 1.05 - 1e-6
    gid = _driver_gid(graph) if identity == "driver" else None
    at_init = _shifted(value=INIT[0])  # the forged states: every joint at the initial pose
    # It forges before the env exists (no subscriber to match yet): the env hears it from its start.
    topic = f"/forged_{os.getpid()}/joint_states" if identity == "only" else TOPIC
    forger = Forger(graph, at_init, raw=identity != "only", gid=gid, period=0.002, wait_matched=False, topic=topic)
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    env = None
    try:
        env = _make(graph, reset_joint_speed=speed, joint_states_topic=topic)
        states = env.unwrapped.link.states
        if identity == "own":  # heard, and dropped as another publisher's
            assert graph.wait_for(lambda: states.foreign_count > 0, 30.0)
        elif identity == "only":  # the env sees the arm at its initial pose
            assert abs(states.sample(ARM).position[0] - INIT[0]) < 1e-9
        else:  # heard: taken for the robot's, or dropped as a jump from it
            assert graph.wait_for(lambda: states.malformed_count > 0 or abs(
                states.sample(ARM).position[0] - INIT[0]) < 1e-9, 30.0)
        start = len(recorder.messages)
        env.reset(seed=0)
        assert recorder.wait_count(start + 1)
        move = recorder.messages[start]
        duration = move.points[0].time_from_start.sec + move.points[0].time_from_start.nanosec * 1e-9
        true_distance = float(np.max(np.abs(np.asarray(move.points[0].positions) - away)))
        assert true_distance > 1.0 - 1e-6  # the robot really had that far to go
        assert true_distance / duration <= 1.5 * speed  # the goal: at most 1.5x reset_joint_speed
        assert duration >= float(np.max(env.unwrapped.safety.worst_case_distance(INIT))) / speed - 1e-6
    finally:
        if env is not None:
            env.close()
        forger.close()
        recorder.close()


def test_a_partial_message_cannot_stall_the_env(graph, standin: StandIn) -> None:
    """Issue 38: ``{name: [waist], position: [1e5]}`` was cached unchecked and every true message after
    it dropped as a jump: StaleStateError on every step for ~6 h. Now it is refused, and so is a
    partial message within the limits that jumps; the env steps on."""
    topic = f"/partial_{os.getpid()}/joint_states"
    node = Node(f"js_driver_{os.getpid()}_{time.monotonic_ns()}", context=graph)
    pub = node.create_publisher(JointState, topic, 10)
    stop = threading.Event()
    extra: list[Any] = []

    def run() -> None:  # the driver: the home pose at 50 Hz, and whatever the test slips in
        while not stop.wait(0.02):
            while extra:
                pub.publish(extra.pop(0))
            pub.publish(_home())

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        env = _make(graph, joint_states_topic=topic, joint_state_timeout=0.3, reset_joint_speed=4.0)
        try:
            env.reset(seed=0)
            states = env.unwrapped.link.states
            for partial, reason in (([1e5], "waist at 1e+05 is outside its limits"), ([1.0], "waist jumped")):
                dropped = states.malformed_count
                extra.append(JointState(name=["waist"], position=partial))
                assert graph.wait_for(lambda d=dropped: states.malformed_count > d, 30.0)
                assert reason in (states.last_error or "")
                t0 = time.monotonic()
                while time.monotonic() - t0 < 3 * 0.3:  # steps go on, well past joint_state_timeout
                    env.step(np.asarray(INIT, dtype=np.float32))
                    assert env.unwrapped.joint_positions(["waist"])[0] == pytest.approx(INIT[0])
        finally:
            env.close()
    finally:
        stop.set()
        thread.join(timeout=5.0)
        node.destroy_node()


def test_a_reset_move_takes_the_time_its_speed_needs(graph, standin: StandIn) -> None:
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    speed = 0.5
    env = _make(graph, reset_joint_speed=speed)
    try:
        env.reset(seed=0)
        home = env.unwrapped.last_command.copy()
        for _ in range(4):  # 0.6 rad of waist away from the initial pose
            env.step(np.r_[env.unwrapped.last_command[0] + CAP, home[1:]].astype(np.float32))
        away = env.unwrapped.last_command.copy()
        start = len(recorder.messages)
        t0 = time.monotonic()
        env.reset()
        took = time.monotonic() - t0
        assert recorder.wait_count(start + 1)
        move = recorder.messages[start]
        duration = move.points[0].time_from_start.sec + move.points[0].time_from_start.nanosec * 1e-9
        need = float(np.max(np.abs(away - home))) / speed
        assert duration >= need - 1e-6 and took >= need - 0.05
    finally:
        env.close()
        recorder.close()
