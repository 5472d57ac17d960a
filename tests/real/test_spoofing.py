"""A hostile process on the robot's graph forges ``joint_states``: what reaches the robot stays
within the safety rules, watched on the robot side (issue 28, item 1).

* A forging publisher that is in the graph (a second ROS node on the robot's ``joint_states``) is
  refused by name, at start-up and when it appears mid-episode; nothing more is sent.
* A forging peer outside the graph (a raw Zenoh session putting well-formed samples on the topic's
  key, no liveliness token; given the private graph's credentials, as a process of the same user
  could read them) cannot steer the commands: states outside the joint limits or moving
  faster than the robot can are dropped, and every command stays within the cap of the env's own
  previous command.
* A reset move takes the time its speed needs, whatever the states claim.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Any

import numpy as np
import pytest

import uniros
from multiros.envs.real import RobotConnectionError
from multiros.envs.real.robot_link import JointState, JointTrajectory
from multiros.ros import Node
from multiros.ros.interfaces import serialize_message, type_hash
from multiros.ros.transport.zenoh import wire

from .conftest import StandIn, TopicRecorder

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

TOPIC = "/rx200/joint_states"
TRAJ_TOPIC = "/rx200/arm_controller/joint_trajectory"
CAP = 0.15


def _make(ctx: Any, **kw: Any) -> Any:
    kw.setdefault("startup_timeout", 10.0)
    return uniros.make("RX200ReacherReal-v0", context=ctx, delta_action=False, max_joint_delta=CAP, **kw)


class Forger:
    """After every true ``joint_states`` message, publishes a forged copy (``forge(msg)``): through a
    ROS node in the graph, or (``raw``) as a bare Zenoh put on the topic's key, outside the graph."""

    def __init__(self, ctx: Any, forge: Any, *, raw: bool = False) -> None:
        from multiros.ros.executors import SingleThreadedExecutor

        self.forge = forge
        self.sent = 0
        self.node = Node(f"forger_{os.getpid()}_{time.monotonic_ns()}", context=ctx)
        self.pub = None if raw else self.node.create_publisher(JointState, TOPIC, 10)
        self.session = None
        if raw:
            from raw_zenoh import open_peer_session

            from multiros.ros.processes import private_graph_credentials

            # The graph is private: another user's process gets no connection at all. This forger
            # stands for one that can connect (the user's own, or a shared graph's peer).
            self.session = open_peer_session(ctx.transport.settings.router_endpoint,
                                             credentials=private_graph_credentials(ctx))
            self.key = wire.topic_key(ctx.domain_id, TOPIC, "sensor_msgs::msg::dds_::JointState_",
                                      type_hash("sensor_msgs/msg/JointState"))
        self.sub = self.node.create_subscription(JointState, TOPIC, self._on, 10)
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on(self, msg: Any) -> None:
        if "forged" in msg.header.frame_id:
            return
        fake = self.forge(msg)
        fake.header.frame_id = "forged"
        if self.pub is not None:
            self.pub.publish(fake)
        else:
            assert self.session is not None
            self.session.put(self.key, serialize_message(fake), attachment=wire.encode_attachment(self.sent, 0,
                                                                                                  bytes(16)))
        self.sent += 1

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=2.0)
        self.node.destroy_node()
        if self.session is not None:
            self.session.close()


def _shifted(offset: float | None = None, value: float | None = None) -> Any:
    def forge(msg: Any) -> Any:
        fake = JointState(name=list(msg.name), position=list(msg.position), velocity=list(msg.velocity),
                          effort=list(msg.effort))
        i = list(msg.name).index("waist")
        fake.position[i] = value if value is not None else msg.position[i] + offset
        return fake
    return forge


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
        forger = Forger(graph, _shifted(offset=1.0))  # appears mid-episode
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


@pytest.mark.parametrize(("offset", "value", "reason"), [(1.0, None, "jumped"), (None, 1e5, "outside its limits")])
def test_forged_states_outside_the_graph_cannot_steer_commands(graph, standin: StandIn, offset, value,
                                                               reason: str) -> None:
    recorder = TopicRecorder(graph, JointTrajectory, TRAJ_TOPIC)
    env = _make(graph, environment_loop_rate=20.0)
    forger = Forger(graph, _shifted(offset=offset, value=value), raw=True)
    try:
        env.reset(seed=0)
        states = env.unwrapped.link.states
        assert graph.wait_for(lambda: forger.sent > 5 and states.malformed_count > 0, 30.0)
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
        forger.close()
        env.close()
        recorder.close()


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
