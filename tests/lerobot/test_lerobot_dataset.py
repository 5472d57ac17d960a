"""LeRobot's ``LeRobotDataset`` reads what ``uniros record`` wrote: 20 RX200 pick-and-place episodes of the
scripted policy, and 20 driven through the teleop interface by a script publishing ``sensor_msgs/Joy`` on a
private Zenoh graph, every frame equal to what the env gave and the policy took (issue 53's goal;
docs/lerobot.md).

Run by ``.ci/lerobot`` in ``.venv-lerobot``; skipped where LeRobot is not installed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytestmark = pytest.mark.slow  # 1,000 simulation steps

ENV_ID = "RX200PnPGoalSim-v0"
EPISODES = 20


class _Tape(gym.Wrapper):  # type: ignore[type-arg]
    """Keeps every observation the policy saw and every action and reward, to compare the dataset against."""

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        self.obs: list[Any] = []
        self.actions: list[np.ndarray] = []
        self.rewards: list[float] = []
        self.episode_of: list[int] = []
        self._episode = -1

    def reset(self, **kwargs: Any) -> Any:
        obs, info = self.env.reset(**kwargs)
        self._episode += 1
        self._last = obs
        return obs, info

    def step(self, action: Any) -> Any:
        self.obs.append(self._last)
        self.episode_of.append(self._episode)
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.actions.append(np.asarray(action, dtype=np.float32))
        self.rewards.append(float(reward))
        self._last = obs
        return obs, reward, terminated, truncated, info


def _assert_lerobot_reads_every_frame(out: Path, env: _Tape) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset(f"uniros/{out.name}", root=out)
    assert ds.num_episodes == EPISODES and len(ds) == len(env.actions) and ds.fps == 25
    for i in range(len(ds)):
        item, seen = ds[i], env.obs[i]
        np.testing.assert_array_equal(item["observation.state"].numpy(), seen["observation"])
        np.testing.assert_array_equal(item["observation.achieved_goal"].numpy(), seen["achieved_goal"])
        np.testing.assert_array_equal(item["observation.desired_goal"].numpy(), seen["desired_goal"])
        np.testing.assert_array_equal(item["observation.environment_state"].numpy(),  # what LeRobot's eval passes
                                      np.concatenate([seen["achieved_goal"], seen["desired_goal"]]).astype(np.float32))
        np.testing.assert_array_equal(item["action"].numpy(), env.actions[i])
        assert float(item["next.reward"]) == np.float32(env.rewards[i])
        assert int(item["episode_index"]) == env.episode_of[i]
        assert item["task"] == "pick up the cube and place it at the goal"


def test_lerobot_reads_20_scripted_pick_and_place_episodes_every_frame_equal(lerobot_path: str,
                                                                             tmp_path: Path) -> None:
    from uniros.recording import record
    from uniros.run_envs import make_env

    out = tmp_path / "rx200_pnp"
    env = _Tape(make_env(ENV_ID))
    policy = env.unwrapped.task.scripted_policy()
    try:
        result = record(env, policy, EPISODES, out, env_id=ENV_ID, seed=0, progress=False, reset=policy.reset)
    finally:
        env.close()
    assert result["episodes"] == EPISODES and result["frames"] == len(env.actions)
    _assert_lerobot_reads_every_frame(out, env)


def test_lerobot_reads_20_pick_and_place_episodes_driven_by_joy_messages(lerobot_path: str, tmp_path: Path) -> None:
    """The teleop interface (:class:`uniros.teleop.TeleopInput` fed by :func:`uniros.teleop.subscribe`, as
    ``uniros teleop`` and ``uniros record --policy teleop`` use it) driven by a script: each step, the script
    reads the observation, moves the pad's sticks as the scripted policy would (left x/y, right z; A closes,
    B opens) and publishes one Joy message; the step takes the teleop policy's action once that message has
    arrived. The recorded actions are the pad's (its dead zone included), and LeRobot reads every frame."""
    import argparse
    import threading
    import time

    from multiros.ros import Node
    from multiros.ros.executors import SingleThreadedExecutor
    from multiros.ros.interfaces import get_message
    from multiros.ros.processes import private_context
    from uniros.recording import record
    from uniros.run_envs import make_env
    from uniros.teleop import TeleopInput, TeleopPolicy, subscribe

    ctx = private_context()
    executor = SingleThreadedExecutor(context=ctx)
    env = _Tape(make_env(ENV_ID))
    try:
        script = env.unwrapped.task.scripted_policy()
        source = TeleopInput()
        person = TeleopPolicy(source, env.action_space)
        executor.add_node(subscribe(ctx, source, argparse.Namespace(joy="/joy", joy_map="", twist=None)))
        spinner = threading.Thread(target=executor.spin, name="teleop-test-spin", daemon=True)
        spinner.start()
        Joy = get_message("sensor_msgs/msg/Joy")
        pad = Node("joy_script", context=ctx).create_publisher(Joy, "/joy", 10)
        sticks: list[list[float]] = []

        def driven(obs: Any) -> np.ndarray:
            want = script(obs)
            msg = Joy()
            msg.axes = [float(want[1]), float(want[0]), 0.0, 0.0, float(want[2])]  # the default JoyMapping
            msg.buttons = [1, 0] if want[3] < 0 else [0, 1]
            heard, deadline = source.messages, time.monotonic() + 10.0
            while source.messages == heard:  # published again every 0.2 s until it arrives (discovery)
                assert time.monotonic() < deadline, "the Joy message never reached the teleop input"
                pad.publish(msg)
                again = time.monotonic() + 0.2
                while source.messages == heard and time.monotonic() < again:
                    time.sleep(0.001)
            sticks.append([msg.axes[1], msg.axes[0], msg.axes[4], -1.0 if msg.buttons[0] else 1.0])
            return person(obs)

        out = tmp_path / "rx200_pnp_teleop"
        result = record(env, driven, EPISODES, out, env_id=ENV_ID, seed=0, progress=False, reset=script.reset)
    finally:
        env.close()
        executor.shutdown()
        ctx.try_shutdown()
    assert result["episodes"] == EPISODES and result["frames"] == len(env.actions) == len(sticks)
    pad_actions = np.asarray(sticks, dtype=np.float32)
    pad_actions[:, :3][np.abs(pad_actions[:, :3].astype(np.float64)) < 0.1] = 0.0  # the input's dead zone
    np.testing.assert_array_equal(np.asarray(env.actions), pad_actions)
    assert result["success_rate"] >= 0.8, result  # the pad's dead zone costs the script little
    _assert_lerobot_reads_every_frame(out, env)
