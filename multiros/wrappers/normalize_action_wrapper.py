"""``NormalizeActionWrapper``: the agent acts in ``[-1, 1]``, the env receives its own units.

Same name and behaviour as FRobs_RL's and MultiROS' wrapper (``low + (a + 1) (high - low) / 2``,
then clipped to the env's bounds), except that the wrapped env's ``action_space`` is left
untouched (FRobs_RL overwrote it in place) and infinite bounds are refused instead of producing NaN.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from multiros.wrappers._goal import GoalPassthrough
from multiros.wrappers._spaces import BoxScaler


class NormalizeActionWrapper(GoalPassthrough, gym.ActionWrapper):
    """Expose ``Box(-1, 1)`` as the action space and rescale actions to the env's ``Box``.

    Args:
        env: an env whose action space is a ``Box`` with finite bounds.

    Raises:
        TypeError: the action space is not a ``Box``.
        ValueError: some action bounds are infinite.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.ActionWrapper.__init__(self, env)
        self.scaler = BoxScaler(env.action_space, "action space")
        self.action_space = self.scaler.normalized_space()

    def action(self, action: Any) -> np.ndarray:
        """Normalised action -> env action (clipped to the env's bounds, in its dtype)."""
        return self.denormalize_action(action)

    def reverse_action(self, action: Any) -> np.ndarray:
        """Env action -> normalised action (exact inverse of :meth:`action` inside the bounds)."""
        return self.normalize_action(action)

    def denormalize_action(self, action: Any) -> np.ndarray:
        """MultiROS name of :meth:`action`."""
        inner = self.env.action_space
        value = self.scaler.denormalize(action).astype(inner.dtype, copy=False)
        return np.clip(value, inner.low, inner.high)

    def normalize_action(self, action: Any) -> np.ndarray:
        """Env action -> ``[-1, 1]`` (in the normalised space's dtype)."""
        return self.scaler.normalize(action).astype(self.action_space.dtype, copy=False)
