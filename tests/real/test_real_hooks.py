"""RealBaseEnv/RealGoalEnv in one process: RealROS knobs and hook names, prompts, the arm interface."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from gymnasium import spaces

import uniros
from multiros.envs import RealBaseEnv as ExportedBase
from multiros.envs.real import RobotConnectionError
from multiros.envs.real.robot_link import JointState
from multiros.envs.RealBaseEnv import RealBaseEnv
from multiros.envs.RealGoalEnv import RealGoalEnv
from multiros.ros import Context, Node
from rl_environments.arm_env import ArmRealEnv, ArmRealGoalEnv, ArmSimGoalEnv
from rl_environments.arm_envs import RX200ReacherGoalEnv, RX200ReacherGoalRealEnv


@pytest.fixture
def joint_states() -> Iterator[Context]:
    """An in-process graph where a test node publishes ``/toy/joint_states`` at 100 Hz."""
    with Context(transport="inproc", env={}) as ctx:
        node = Node("toy_robot", context=ctx)
        pub = node.create_publisher(JointState, "/toy/joint_states", 10)
        stop = threading.Event()

        def run() -> None:
            while not stop.wait(0.01):
                pub.publish(JointState(name=["a", "b"], position=[0.1, 0.2], velocity=[0.0, 0.0]))

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        try:
            yield ctx
        finally:
            stop.set()
            thread.join(timeout=2.0)


class ToyRealEnv(RealBaseEnv):
    """A RealROS-style task written with RealROS' hook names."""

    def __init__(self, **kw) -> None:
        super().__init__(namespace="/toy", **kw)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = spaces.Box(-10.0, 10.0, (2,), np.float32)
        self.sent: list[np.ndarray] = []
        self.init_options = None

    def _send_action(self, action) -> None:
        self.sent.append(action)

    def _get_observation(self):
        return self.joint_positions(["a", "b"]).astype(np.float32)

    def _get_reward(self, info) -> float:
        info["seen"] = True
        return -1.0

    def _compute_terminated(self, info) -> bool:
        return False

    def _set_init_params(self, options) -> None:
        self.init_options = options


def test_realros_hook_names_prompts_and_loop(joint_states: Context, caplog: pytest.LogCaptureFixture) -> None:
    assert ExportedBase is RealBaseEnv is uniros.RealBaseEnv and RealGoalEnv is uniros.RealGoalEnv
    with caplog.at_level(logging.WARNING):
        env = ToyRealEnv(context=joint_states, reset_env_prompt=True, close_env_prompt=True, kill_rosmaster=True,
                         environment_loop_rate=50.0)
        obs, info = env.reset(seed=3, options={"x": 1})
        np.testing.assert_allclose(obs, [0.1, 0.2], rtol=1e-6)
        assert env.init_options == {"x": 1} and info["state_age_sec"] < 0.5
        obs, reward, terminated, truncated, info = env.step(np.array([0.5, -0.5], np.float32))
        assert reward == -1.0 and info["seen"] and len(env.sent) == 1 and info["cycle_time_sec"] >= 0.02 - 1e-3
        env.close()
    text = caplog.text
    assert "ignores kill_rosmaster" in text and "not waiting for the operator" in text  # stdin is not a terminal


def test_knobs_that_would_launch_a_robot_are_refused() -> None:
    with pytest.raises(ValueError, match="start the robot's ROS 2 driver yourself"):
        RealBaseEnv(load_robot=True)
    with pytest.raises(TypeError, match="unexpected keyword"):
        RealBaseEnv(no_such_knob=1)
    with pytest.raises(ValueError, match="cannot render"):
        RealBaseEnv(render_mode="rgb_array")


def test_no_robot_is_a_clear_error_within_the_startup_timeout() -> None:
    with Context(transport="inproc", env={}) as ctx, pytest.raises(RobotConnectionError, match="no joint_states"):
        ArmRealEnv(arm="IRB120", task="reach", context=ctx, startup_timeout=0.2)


def test_the_names_of_earlier_releases_are_the_arm_envs_with_their_arm_and_task() -> None:
    assert issubclass(RX200ReacherGoalEnv, ArmSimGoalEnv) and issubclass(RX200ReacherGoalRealEnv, ArmRealGoalEnv)
    assert (RX200ReacherGoalEnv.ARM, RX200ReacherGoalEnv.TASK) == ("RX200", "reach") == (
        RX200ReacherGoalRealEnv.ARM, RX200ReacherGoalRealEnv.TASK)
    assert RX200ReacherGoalEnv.step is RX200ReacherGoalRealEnv.step  # one step, both sides
    from rl_environments import arm_envs

    with pytest.raises(AttributeError, match="compose the arm with a task"):
        arm_envs.IRB120RobotRealEnv  # noqa: B018 - an arm without a task is no env class any more


def test_the_env_hears_only_the_publisher_it_checked(joint_states: Context) -> None:
    """Issue 38: joint_states count only from the identity of the one publisher in the graph; a
    message of another identity (a process outside the graph) is dropped and named."""
    env = ToyRealEnv(context=joint_states)
    try:
        states = env.link.states
        [driver] = env.node.get_publishers_info_by_topic("/toy/joint_states")
        assert driver.gid and states.driver == driver.gid
        env.link._sub._enqueue(JointState(name=["a", "b"], position=[5.0, 5.0]), bytes(16))  # as the wire would
        assert joint_states.wait_for(lambda: states.foreign_count == 1, 5.0)
        assert "other than the driver (identity 000000000000" in states.describe_problem(["a", "b"])
        env.reset(seed=0)  # the same driver: nothing to decide again
        np.testing.assert_allclose(env.joint_positions(["a", "b"]), [0.1, 0.2])
    finally:
        env.close()


def test_several_identities_behind_one_publisher_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """One publisher in the graph, two identities heard, neither the graph's: a process outside the
    graph publishes too, and the env cannot tell which is the robot. With one identity heard (an
    rmw_zenoh driver, whose GIDs are another hash of its token) that one is pinned."""
    real = Node.get_publishers_info_by_topic
    monkeypatch.setattr(Node, "get_publishers_info_by_topic",
                        lambda self, topic: [e._replace(gid=b"\xff" * 16) for e in real(self, topic)])
    for identities, refused in ((2, True), (1, False)):
        with Context(transport="inproc", env={}) as ctx:
            node = Node("toy_robot", context=ctx)
            pub = node.create_publisher(JointState, "/toy/joint_states", 10)
            gids = [bytes([k + 1]) * 16 for k in range(identities)]
            stop = threading.Event()

            def run(pub: Any, gids: list[bytes], stop: threading.Event) -> None:
                k = 0
                while not stop.wait(0.005):
                    pub._local_gid = gids[k % len(gids)]  # the identity its messages carry
                    pub.publish(JointState(name=["a", "b"], position=[0.1, 0.2], velocity=[0.0, 0.0]))
                    k += 1

            thread = threading.Thread(target=run, args=(pub, gids, stop), daemon=True)
            thread.start()
            try:
                if refused:
                    with pytest.raises(RobotConnectionError, match="2 publisher identities while the graph has one"):
                        ToyRealEnv(context=ctx, startup_timeout=3.0)
                else:
                    env = ToyRealEnv(context=ctx, startup_timeout=3.0)
                    assert env.link.states.driver == gids[0]
                    env.close()
            finally:
                stop.set()
                thread.join(timeout=2.0)
