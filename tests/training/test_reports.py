"""Evaluation on seeded episodes with Wilson intervals, and the run's video: real-time speed, several
episodes, the goal marker on a fixed trajectory."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from uniros.evaluation import EVAL_SEED, evaluate, format_success, wilson_interval


def test_wilson_interval_known_values():
    # Values from the closed form (Wilson 1927), z = 1.96.
    assert wilson_interval(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson_interval(20, 20) == pytest.approx((0.8389, 1.0), abs=1e-4)
    assert wilson_interval(45, 50) == pytest.approx((0.7864, 0.9565), abs=1e-4)
    assert all(v != v for v in wilson_interval(0, 0))
    assert format_success(0.9, 50) == "0.90 [0.79, 0.96]"
    assert format_success(float("nan"), 20) == "n/a"


class _Zero:
    """A policy that always sends zeros (the arm holds its pose)."""

    def __init__(self, space):
        self.space = space

    def predict(self, obs, deterministic=True):
        return np.zeros(self.space.shape, self.space.dtype), None


class _Seeded:
    """A deterministic policy whose actions depend on the observation."""

    def predict(self, obs, deterministic=True):
        return np.tanh(np.asarray(obs)[:1] * 3).astype(np.float32), None


def test_evaluation_episodes_are_seeded_one_by_one():
    """Episode i starts with seed + i: the first k of n episodes are the k-episode evaluation, and a
    repeat gives the same figures (what makes training's final evaluation and uniros eval agree)."""
    env = gym.make("Pendulum-v1")
    try:
        five = evaluate(_Seeded(), env, 5)
        assert evaluate(_Seeded(), env, 5) == five
        firsts = [evaluate(_Seeded(), env, 1, seed=EVAL_SEED + i)["mean_return"] for i in range(5)]
        assert np.mean(firsts) == pytest.approx(five["mean_return"])
        assert five["episodes"] == 5 and five["successes"] == 0 and five["ci_high"] == pytest.approx(0.4345, abs=1e-4)
    finally:
        env.close()


def test_the_video_plays_several_episodes_at_real_time_with_the_goal_shown(tmp_path):
    import imageio.v2 as imageio

    import uniros
    from uniros.reports import record_video

    def make(**kwargs):
        return uniros.make("RX200ReacherGoalSim-v0", ee_action_type=True, max_episode_steps=10, **kwargs)

    probe = make()
    zero = _Zero(probe.action_space)
    probe.close()
    n = record_video(zero, make, tmp_path / "v.mp4", episodes=2, seed=EVAL_SEED)
    assert n == 2 * (1 + 10 + 5)  # per episode: the reset frame, 10 steps, the end held 0.5 s
    reader = imageio.get_reader(str(tmp_path / "v.mp4"))
    assert reader.get_meta_data()["fps"] == 10  # one frame per 100 ms step: robot time
    frames = [np.asarray(f, dtype=int) for f in reader]
    green = [int(((f[..., 1] - np.maximum(f[..., 0], f[..., 2])) > 60).sum()) for f in frames]
    assert min(green) > 20, "the goal marker is missing from frames of a still arm"
    assert abs(green[0] - green[16]) > 5  # the second episode has another goal
