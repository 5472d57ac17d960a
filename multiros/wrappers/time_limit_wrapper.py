"""``TimeLimitWrapper(env, max_steps=...)``: FRobs_RL's episode limit, gymnasium-correct.

After ``max_steps`` steps since the last reset, ``step`` returns ``truncated=True`` and its info
carries:

* ``"is_success"``: always present; the env's value when it set one, else ``False``;
* ``"TimeLimit.truncated"``: ``True`` when the episode was cut by the limit and did not also
  terminate on this step (the classic gym key; SB3 uses it for bootstrapping);
* ``"time_limit_reached"``: ``True`` (the FRobs_RL / MultiROS key).

Differences to FRobs_RL, deliberate: FRobs_RL also set ``terminated=True`` on a timeout, which
tells value-based learners the timeout state is terminal and biases bootstrapping; here
``terminated`` is the env's own value. FRobs_RL overwrote ``is_success`` with ``0.0`` on a
timeout (even when the last step succeeded); here the env's value is kept and only a missing one
is filled in. MultiROS' ``max_episode_steps`` keyword is accepted as a synonym of ``max_steps``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from multiros.wrappers._goal import GoalPassthrough


class TimeLimitWrapper(GoalPassthrough, gym.Wrapper):
    """Truncate episodes after ``max_steps`` steps.

    Args:
        env: the env to limit.
        max_steps: steps per episode (FRobs_RL name; default 100 as there).
        max_episode_steps: MultiROS name of ``max_steps``; give one of them.

    Raises:
        ValueError: the limit is not a positive integer, or both names are given with different values.
    """

    def __init__(self, env: gym.Env, max_steps: int | None = None, *, max_episode_steps: int | None = None) -> None:
        gym.Wrapper.__init__(self, env)
        if max_steps is not None and max_episode_steps is not None and max_steps != max_episode_steps:
            raise ValueError(f"give max_steps ({max_steps}) or max_episode_steps ({max_episode_steps}), not both")
        limit = max_steps if max_steps is not None else max_episode_steps
        limit = 100 if limit is None else limit
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise ValueError(f"max_steps must be an integer >= 1, got {limit!r}")
        self.max_steps = limit
        self.elapsed_steps = 0

    @property
    def max_episode_steps(self) -> int:
        """MultiROS name of :attr:`max_steps`."""
        return self.max_steps

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        self.elapsed_steps = 0
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.elapsed_steps += 1
        if self.elapsed_steps >= self.max_steps:
            info = dict(info)
            info.setdefault("is_success", False)
            info["TimeLimit.truncated"] = not terminated
            info["time_limit_reached"] = True
            truncated = True
        return obs, reward, terminated, truncated, info
