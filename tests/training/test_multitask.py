"""MultiTaskEnv / MultiTaskGoalEnv: one env per episode, padding, and HER's compute_reward routed per sample."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import uniros
from uniros.multitask import MultiTaskEnv, MultiTaskGoalEnv

RX200 = "RX200ReacherGoalSim-v0"
IRB120 = "ABBIRB120ReacherGoalEnv-v0"


@pytest.fixture(scope="module")
def mixed():
    """RX200 (obs 18, action 5) with a sparse reward and IRB120 (obs 15, action 6) with a dense one."""
    env = MultiTaskGoalEnv([RX200, IRB120], [{"reward_type": "sparse"}, {"reward_type": "dense"}],
                           selection="round_robin")
    yield env
    env.close()


def _batch(env: MultiTaskGoalEnv, episodes: int = 4, steps: int = 6):
    """Padded (achieved, desired) pairs and their task ids, from a few short episodes of each env."""
    achieved, desired, ids = [], [], []
    env.action_space.seed(1)
    for ep in range(episodes):
        obs, info = env.reset(seed=100 if ep == 0 else None)  # a seeded reset restarts the round robin
        for _ in range(steps):
            obs, _, _, _, info = env.step(env.action_space.sample())
            achieved.append(obs["achieved_goal"])
            desired.append(obs["desired_goal"])
            ids.append(info["task_id"])
    return np.array(achieved), np.array(desired), np.array(ids)


def test_exported_from_uniros():
    assert uniros.MultiTaskEnv is MultiTaskEnv and uniros.MultiTaskGoalEnv is MultiTaskGoalEnv


def test_spaces_are_padded_to_the_largest_and_carry_the_task_id(mixed):
    space = mixed.observation_space
    assert space["observation"].shape == (18,) and mixed.action_space.shape == (6,)
    assert space["achieved_goal"].shape == (4,) and space["desired_goal"].shape == (4,)  # xyz + task id
    assert space["desired_goal"].high[-1] == 1.0 and space["desired_goal"].low[-1] == 0.0
    seen = []
    for _ in range(4):  # round robin: 0, 1, 0, 1
        obs, info = mixed.reset()
        seen.append(info["task_id"])
        assert obs in space
        assert obs["achieved_goal"][-1] == info["task_id"] == obs["desired_goal"][-1]
        if info["task_id"] == 1:
            assert np.all(obs["observation"][15:] == 0.0)  # IRB120's 15 entries, zero-padded
        obs, reward, terminated, truncated, info = mixed.step(mixed.action_space.sample())
        assert obs in space and info["task_name"] == [RX200, IRB120][info["task_id"]]
    assert seen == [0, 1, 0, 1]


def test_her_batches_are_routed_to_the_env_of_each_sample(mixed):
    achieved, desired, ids = _batch(mixed)
    assert set(ids.tolist()) == {0, 1}
    rng = np.random.default_rng(0)
    order = rng.permutation(len(ids))  # mixed, like a HER batch
    achieved, desired, ids = achieved[order], desired[order], ids[order]
    # HER relabelling: some desired goals replaced by achieved goals of the same episode (same task)
    desired[::3] = achieved[::3] + rng.normal(0.0, 0.01, achieved[::3].shape) * np.r_[1, 1, 1, 0]
    expected = np.empty(len(ids))
    for k in range(2):
        rows = ids == k
        sub = mixed.envs[k].unwrapped
        expected[rows] = sub.compute_reward(achieved[rows, :3], desired[rows, :3], [{}] * int(rows.sum()))
    got = mixed.compute_reward(achieved, desired, [{} for _ in ids])  # SB3's default: empty infos
    assert np.allclose(got, expected)
    assert set(np.unique(got[ids == 0])) <= {-1.0, 0.0}  # sparse RX200
    assert np.all(got[ids == 1] <= 0) and len(np.unique(got[ids == 1])) > 2  # dense IRB120 (distances)
    # Infos with task ids (SB3 with copy_info_dict=True) take precedence and agree.
    assert np.allclose(mixed.compute_reward(achieved, desired, [{"task_id": int(k)} for k in ids]), expected)
    # A single sample, as the env's own step computes it.
    single = mixed.compute_reward(achieved[0], desired[0], {"task_id": int(ids[0])})
    assert single == pytest.approx(expected[0])
    terminated = mixed.compute_terminated(achieved, desired, [{}] * len(ids))
    assert terminated.dtype == bool and terminated.shape == ids.shape


def test_without_the_goal_entry_routing_needs_infos():
    env = MultiTaskGoalEnv([RX200, RX200], [{"reward_type": "sparse"}, {"reward_type": "dense"}],
                           task_id_in_goal=False)
    try:
        assert env.observation_space["desired_goal"].shape == (3,)
        obs, info = env.reset(seed=0, options={"task_id": 1})
        assert info["task_id"] == 1
        ag, dg = np.stack([obs["achieved_goal"]] * 2), np.stack([obs["desired_goal"]] * 2)
        rewards = env.compute_reward(ag, dg, [{"task_id": 0}, {"task_id": 1}])
        assert rewards[0] in (-1.0, 0.0) and rewards[1] == pytest.approx(-np.linalg.norm(ag[1] - dg[1]))
        with pytest.raises(ValueError, match="copy_info_dict"):
            env.compute_reward(ag, dg, [{}, {}])
    finally:
        env.close()


def test_selection_is_seeded_weighted_or_forced():
    env = MultiTaskGoalEnv([RX200, RX200], [{}, {"reward_type": "dense"}])
    try:
        picks = [env.reset(seed=s)[1]["task_id"] for s in range(12)]
        assert picks == [env.reset(seed=s)[1]["task_id"] for s in range(12)]  # same seeds, same picks
        assert set(picks) == {0, 1}
        first = env.reset(seed=5)[0]
        again = env.reset(seed=5)[0]
        assert all(np.array_equal(first[k], again[k]) for k in first)  # the chosen env is seeded too
        assert env.reset(options={"task_id": 1})[1]["task_id"] == 1
        with pytest.raises(ValueError, match="not an env index"):
            env.reset(options={"task_id": 2})
    finally:
        env.close()
    weighted = MultiTaskGoalEnv([RX200, RX200], weights=[0.0, 1.0])
    try:
        assert {weighted.reset(seed=s)[1]["task_id"] for s in range(5)} == {1}
    finally:
        weighted.close()


def test_gymnasium_and_sb3_checkers_pass(mixed):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    check_env(mixed, skip_render_check=True)
    sb3_check_env(mixed, warn=True)
    plain = MultiTaskEnv(["RX200ReacherSim-v0", "ABBIRB120ReacherEnv-v0"])
    try:
        assert plain.observation_space.shape == (22,) and plain.action_space.shape == (6,)
        check_env(plain, skip_render_check=True)
        sb3_check_env(plain, warn=True)
        obs, info = plain.reset(seed=3)
        assert obs in plain.observation_space and info["task_id"] in (0, 1)
    finally:
        plain.close()


class _Counting(gym.Env):
    observation_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, fail_close: bool = False) -> None:
        self.closed = 0
        self.fail_close = fail_close
        self.actions = []

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(2, np.float32), {}

    def step(self, action):
        self.actions.append(np.asarray(action))
        return np.zeros(2, np.float32), 0.0, False, False, {}

    def close(self):
        self.closed += 1
        if self.fail_close:
            raise OSError("robot unreachable")


def test_close_closes_every_env_once_even_when_one_fails():
    a, b, c = _Counting(), _Counting(fail_close=True), _Counting()
    env = MultiTaskEnv([a, lambda: b, c])
    with pytest.raises(RuntimeError, match="1 env"):
        env.close()
    env.close()
    assert (a.closed, b.closed, c.closed) == (1, 1, 1)


def test_actions_are_cut_to_the_env_and_clipped():
    small = _Counting()
    wide = _Counting()
    wide.action_space = spaces.Box(-2.0, 2.0, (3,), np.float32)
    env = MultiTaskEnv([small, wide], selection="round_robin")
    assert env.action_space.shape == (3,) and env.action_space.high.tolist() == [2.0, 2.0, 2.0]
    env.reset()
    env.step(np.array([1.5, 0.3, -0.2], np.float32))
    assert small.actions[-1].tolist() == [1.0]  # first entry, clipped to the small env's bounds
    env.reset()
    env.step(np.array([1.5, 0.3, -0.2], np.float32))
    assert wide.actions[-1].tolist() == pytest.approx([1.5, 0.3, -0.2])
    with pytest.raises(ValueError, match="one per env"):
        MultiTaskEnv([small], [{}, {}])
    with pytest.raises(TypeError, match="goal envs"):
        MultiTaskGoalEnv([small])
    env.close()


@pytest.mark.slow
def test_sb3_her_sac_trains_over_both_envs():
    """A few hundred HER+SAC steps with SB3's default HerReplayBuffer (empty infos): episodes of
    both envs land in one buffer and relabelled rewards come from the right env."""
    from stable_baselines3 import SAC, HerReplayBuffer

    env = MultiTaskGoalEnv([RX200, IRB120], [{"reward_type": "sparse"}, {"reward_type": "dense"}],
                           selection="round_robin")
    try:
        model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                    replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
                    learning_starts=100, batch_size=64, train_freq=1, gradient_steps=1, seed=0, verbose=0,
                    device="cpu")
        model.learn(total_timesteps=300)
        buffer = model.replay_buffer
        stored = buffer.observations["desired_goal"][: buffer.pos, 0, -1]
        assert set(np.rint(stored).tolist()) == {0.0, 1.0}  # episodes of both envs
        samples = buffer.sample(256)
        ag = samples.next_observations["achieved_goal"].numpy()
        dg = samples.observations["desired_goal"].numpy()
        rewards = samples.rewards.numpy().reshape(-1)
        expected = env.compute_reward(ag, dg, [{} for _ in rewards])
        assert np.allclose(rewards, expected, atol=1e-5)
        action, _ = model.predict(env.reset(seed=1)[0], deterministic=True)
        assert action.shape == (6,)
    finally:
        env.close()
