"""Joint arrays by name: the accessors the simulated and the real env cores share."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from multiros.envs.errors import EnvError

__all__ = ["JointStateAccess"]


class JointStateAccess:
    """``joint_positions``/``joint_velocities``/``joint_efforts`` of ``robot_state``: all joints, or
    the ones named, in that order.

    The host class provides ``robot_state`` (``position``, ``velocity``, ``effort`` arrays),
    ``joint_names`` and ``robot_name``, and calls :meth:`_set_joint_order` whenever the order of the
    joint arrays is known or changes.
    """

    robot_state: Any
    robot_name: str
    joint_names: tuple[str, ...]

    def _set_joint_order(self, names: Sequence[str]) -> None:
        self._joint_index: dict[str, int] = {name: i for i, name in enumerate(names)}
        self._select_cache: dict[tuple[str, ...], np.ndarray] = {}

    def joint_positions(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Joint positions after the last step or reset (all joints, or ``names`` in that order)."""
        return self._select(self.robot_state.position, names)

    def joint_velocities(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Joint velocities after the last step or reset."""
        return self._select(self.robot_state.velocity, names)

    def joint_efforts(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Joint efforts after the last step or reset."""
        return self._select(self.robot_state.effort, names)

    def _select(self, values: np.ndarray, names: Sequence[str] | None) -> np.ndarray:
        if names is None:
            return values.copy()
        return values[self._joint_indices(names)]

    def _joint_indices(self, names: Sequence[str]) -> np.ndarray:
        """Where the joints ``names`` sit in the joint arrays (EnvError for an unknown joint)."""
        key = tuple(names)
        idx = self._select_cache.get(key)
        if idx is None:
            try:
                idx = self._select_cache[key] = np.array([self._joint_index[n] for n in key], dtype=np.intp)
            except KeyError as exc:
                raise EnvError(f"robot {self.robot_name!r} has no joint {exc.args[0]!r}; joints: "
                               f"{self.joint_names}") from None
        return idx
