"""Goal-env pass-through for wrappers.

gymnasium >= 1.0 wrappers no longer forward unknown attributes, yet SB3's ``check_env`` calls
``env.compute_reward`` on the object it is given and ``HerReplayBuffer`` reaches it through
``get_wrapper_attr``. Every uniros wrapper therefore exposes the three goal functions and hands
them to the wrapped env; a wrapper that changes the goal representation overrides them.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym


class GoalPassthrough:
    """Mixin for ``gym.Wrapper`` subclasses: ``compute_reward/terminated/truncated`` of the inner env."""

    env: gym.Env

    def _inner_goal_fn(self, name: str) -> Any:
        try:
            return self.env.get_wrapper_attr(name)
        except AttributeError:
            raise AttributeError(
                f"{type(self).__name__}: the wrapped env {self.env.unwrapped!r} has no {name}(); "
                "it is not a goal-conditioned env"
            ) from None

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The wrapped goal env's vectorised ``compute_reward``."""
        return self._inner_goal_fn("compute_reward")(achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The wrapped goal env's ``compute_terminated``."""
        return self._inner_goal_fn("compute_terminated")(achieved_goal, desired_goal, info)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The wrapped goal env's ``compute_truncated``."""
        return self._inner_goal_fn("compute_truncated")(achieved_goal, desired_goal, info)
