"""Exact, invertible affine maps between a bounded ``Box`` and ``[-1, 1]``.

Written by hand because gymnasium's ``RescaleAction`` covers actions only, clips, and has no
inverse, and its observation normalisers are running statistics, not bound-based maps.
All arithmetic is in float64; results are cast to the target space's dtype at the end.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces


class BoxScaler:
    """Maps values of a bounded ``Box`` to ``[-1, 1]`` and back.

    ``normalize(x) = 2 (x - low) / (high - low) - 1``; ``denormalize(y) = low + (y + 1) (high - low) / 2``.
    Dimensions whose ``low == high`` normalise to 0 and denormalise to ``low``.

    Args:
        space: a ``Box`` whose every bound is finite.
        what: how to name the space in error messages (e.g. ``"action space"``).

    Raises:
        TypeError: ``space`` is not a ``Box``.
        ValueError: some bounds are infinite (normalising them is undefined).
    """

    def __init__(self, space: spaces.Space, what: str) -> None:
        if not isinstance(space, spaces.Box):
            raise TypeError(f"{what} must be a gymnasium.spaces.Box to be normalised, got {space!r}")
        low = np.asarray(space.low, dtype=np.float64)
        high = np.asarray(space.high, dtype=np.float64)
        unbounded = ~(np.isfinite(low) & np.isfinite(high))
        if np.any(unbounded):
            where = np.argwhere(unbounded).tolist()
            raise ValueError(
                f"{what} {space} has unbounded dimensions at indices {where[:8]}"
                f"{' ...' if len(where) > 8 else ''}; give it finite low/high bounds before normalising"
            )
        self.space = space
        self.low = low
        self.high = high
        self.range = high - low
        self._degenerate = self.range <= 0
        self._safe_range = np.where(self._degenerate, 1.0, self.range)
        self.dtype = space.dtype if np.issubdtype(space.dtype, np.floating) else np.dtype(np.float32)

    def normalized_space(self) -> spaces.Box:
        """The ``[-1, 1]`` box of the same shape (dtype: the original's if floating, else float32)."""
        return spaces.Box(-1.0, 1.0, shape=self.space.shape, dtype=self.dtype)

    def normalize(self, x: np.ndarray) -> np.ndarray:
        """Values of the original space -> ``[-1, 1]`` (no clipping: out-of-bound values map outside)."""
        x = np.asarray(x, dtype=np.float64)
        y = 2.0 * (x - self.low) / self._safe_range - 1.0
        return np.where(self._degenerate, 0.0, y)

    def denormalize(self, y: np.ndarray) -> np.ndarray:
        """``[-1, 1]`` -> values of the original space (no clipping)."""
        y = np.asarray(y, dtype=np.float64)
        return self.low + (y + 1.0) * 0.5 * self.range
