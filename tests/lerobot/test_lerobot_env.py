"""The gym side of the LeRobot plugin (:mod:`uniros.lerobot_env`), without LeRobot: the observation
layout LeRobot's ``preprocess_observation`` reads, the task text, ``is_success`` and the features."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from uniros.lerobot_env import (
    NAMESPACE,
    LeRobotEnv,
    LeRobotLayoutError,
    control_fps,
    lerobot_features,
    make_lerobot_env,
    register_ids,
)


class _Fake(gym.Env):  # type: ignore[type-arg]
    """An env of a given observation space, whose observations are samples of it."""

    metadata = {"render_fps": 30}

    def __init__(self, space: spaces.Space) -> None:  # type: ignore[type-arg]
        self.observation_space, self.action_space = space, spaces.Box(-1, 1, (2,), np.float32)

    def reset(self, *, seed=None, options=None):  # type: ignore[no-untyped-def]
        super().reset(seed=seed)
        self.observation_space.seed(seed)
        self.last = self.observation_space.sample()
        return self.last, {}

    def step(self, action):  # type: ignore[no-untyped-def]
        self.last = self.observation_space.sample()
        return self.last, 0.5, False, False, {"is_success": np.bool_(True)}


def _box(n: int) -> spaces.Box:
    return spaces.Box(-1.0, 1.0, (n,), np.float64)


def test_a_goal_env_with_a_camera_is_laid_out_as_lerobot_reads_it() -> None:
    image = spaces.Box(0, 255, (8, 6, 3), np.uint8)
    inner = _Fake(spaces.Dict({"observation": _box(5), "desired_goal": _box(3), "achieved_goal": _box(3),
                               "rgb": image}))
    env = LeRobotEnv(inner, "Fake-v0")
    obs, info = env.reset(seed=3)
    assert set(obs) == {"agent_pos", "environment_state", "pixels"} and info["is_success"] is False
    assert env.observation_space.contains(obs)
    raw = inner.last
    np.testing.assert_array_equal(obs["agent_pos"], raw["observation"].astype(np.float32))
    np.testing.assert_array_equal(obs["environment_state"],
                                  np.r_[raw["achieved_goal"], raw["desired_goal"]].astype(np.float32))
    np.testing.assert_array_equal(obs["pixels"]["rgb"], raw["rgb"])
    obs, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
    assert info["is_success"] is True and reward == 0.5 and env.observation_space.contains(obs)
    feats, fmap = lerobot_features(env)
    assert feats == {"action": ("ACTION", (2,)), "agent_pos": ("STATE", (5,)), "environment_state": ("ENV", (6,)),
                     "pixels/rgb": ("VISUAL", (8, 6, 3))}
    assert fmap == {"action": "action", "agent_pos": "observation.state",
                    "environment_state": "observation.environment_state", "pixels/rgb": "observation.images.rgb"}
    assert env.metadata["render_fps"] == 30 and env.task_description == "Fake-v0"


def test_a_plain_box_env_is_its_state_alone() -> None:
    env = LeRobotEnv(_Fake(_box(4)), "Plain-v0")
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"agent_pos"} and obs["agent_pos"].dtype == np.float32
    assert lerobot_features(env)[0] == {"action": ("ACTION", (2,)), "agent_pos": ("STATE", (4,))}


@pytest.mark.parametrize(("space", "message"), [
    (spaces.Dict({"observation": _box(3), "depth": spaces.Box(0, 1, (4, 4), np.float32)}), "'depth'"),
    (spaces.Discrete(3), "Discrete observation space"),
    (spaces.Dict({"achieved_goal": _box(3)}), "neither a state vector nor a camera image"),
])
def test_observations_lerobot_cannot_take_are_refused_in_one_line(space: spaces.Space, message: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(LeRobotLayoutError, match=message) as err:
        LeRobotEnv(_Fake(space), "Bad-v0")
    assert "\n" not in str(err.value)


def test_uniros_ids_are_registered_in_lerobots_namespace_and_made_through_gym() -> None:
    ids = register_ids()
    name = f"{NAMESPACE}/RX200PnPGoalSim-v0"
    assert name in ids and name in gym.registry
    env = gym.make(name, disable_env_checker=True, episode_length=7)
    try:
        assert isinstance(env, LeRobotEnv)  # nothing of gym.make's outside it: LeRobot reads its attributes
        assert env._max_episode_steps == 7 and env.task_description == "pick up the cube and place it at the goal"
        assert control_fps(env.env) == 25 and env.metadata["render_fps"] == 25
        obs, _ = env.reset(seed=1)
        assert obs["agent_pos"].shape == env.env.observation_space["observation"].shape
        steps = 0
        truncated = False
        while not truncated:
            obs, _, _, truncated, info = env.step(env.action_space.sample())
            steps += 1
            assert isinstance(info["is_success"], bool)
        assert steps == 7
    finally:
        env.close()


def test_the_reach_env_steps_at_its_control_period() -> None:
    env = make_lerobot_env("RX200ReacherGoalSim-v0")
    try:
        assert control_fps(env.env) == 10  # 0.1 s a step
    finally:
        env.close()
