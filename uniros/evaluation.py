"""Evaluating a policy on seeded episodes, and success rates with a confidence interval.

Every evaluation in uniros plays the same episodes: episode ``i`` starts with
``env.reset(seed=EVAL_SEED + i)``. The evaluations during training use the first
``eval_episodes`` of them, the final evaluation of ``uniros train`` and ``uniros eval`` (default
``--seed``) the first ``--episodes``, so one model gets one figure wherever it is measured (the
env and the deterministic policy are reproducible from a seed). Since the best model is chosen on
the training evaluations' episodes, its figure on those is optimistic; ``uniros eval --seed S``
plays other episodes.

A success rate over n episodes is an estimate: :func:`wilson_interval` gives its 95 % Wilson
score interval (good at rates near 0 and 1 and for small n, unlike the normal approximation), and
:func:`format_success` prints both, as ``0.90 [0.79, 0.96]``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Episode ``i`` of every evaluation starts with ``env.reset(seed=EVAL_SEED + i)``.
EVAL_SEED = 1_000_000


def wilson_interval(successes: int, episodes: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95 % by default); ``(nan, nan)`` for 0 episodes."""
    if episodes <= 0:
        return float("nan"), float("nan")
    p = successes / episodes
    denom = 1 + z * z / episodes
    centre = (p + z * z / (2 * episodes)) / denom
    half = z * math.sqrt(p * (1 - p) / episodes + z * z / (4 * episodes * episodes)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def format_success(rate: float, episodes: int) -> str:
    """``0.90 [0.79, 0.96]``: a success rate over ``episodes`` episodes and its 95 % interval."""
    if rate != rate or episodes <= 0:
        return "n/a"
    low, high = wilson_interval(round(rate * episodes), episodes)
    return f"{rate:.2f} [{low:.2f}, {high:.2f}]"


def evaluate(
    model: Any, env: Any, episodes: int, *, seed: int | None = EVAL_SEED, normalizer: Any = None
) -> dict[str, float]:
    """Run ``episodes`` deterministic episodes; success = the final ``info["is_success"]``.

    Episode ``i`` is reset with ``seed + i`` (``seed=None``: the env's own stream). ``normalizer``
    (a ``VecNormalize``) normalises observations as during training, without updating its
    statistics.

    Returns:
        ``success_rate``, ``successes``, ``episodes``, ``ci_low``/``ci_high`` (95 % Wilson),
        ``mean_return``, ``std_return``, ``mean_length``.
    """
    successes, returns, lengths = [], [], []
    for i in range(episodes):
        obs, info = env.reset(seed=None if seed is None else seed + i)
        done, total, steps = False, 0.0, 0
        while not done:
            policy_obs = obs if normalizer is None else normalizer.normalize_obs(obs)
            action, _ = model.predict(policy_obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            steps += 1
            done = terminated or truncated
        successes.append(bool(info.get("is_success", False)))
        returns.append(total)
        lengths.append(steps)
    wins = int(sum(successes))
    low, high = wilson_interval(wins, episodes)
    return {
        "success_rate": wins / episodes if episodes else float("nan"),
        "successes": float(wins),
        "episodes": float(episodes),
        "ci_low": low,
        "ci_high": high,
        "mean_return": float(np.mean(returns)) if returns else float("nan"),
        "std_return": float(np.std(returns)) if returns else float("nan"),
        "mean_length": float(np.mean(lengths)) if lengths else float("nan"),
    }


__all__ = ["EVAL_SEED", "evaluate", "format_success", "wilson_interval"]
