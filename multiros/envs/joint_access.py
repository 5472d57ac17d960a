"""Joint arrays by name: the accessors every env core offers its hooks."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from multiros.envs.errors import EnvError

if TYPE_CHECKING:
    from multiros.robot_state import RobotState

__all__ = ["JointStateAccess"]


class JointStateAccess:
    """``joint_positions``/``joint_velocities``/``joint_efforts`` of ``robot_state``: all joints, or
    the ones named, in that order. The host class provides ``robot_state`` and ``robot_name``."""

    if TYPE_CHECKING:
        robot_name: str

        @property
        def robot_state(self) -> RobotState: ...

    _joint_index_cache: dict[tuple[tuple[str, ...], tuple[str, ...]], np.ndarray]

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
        """Where the joints ``names`` sit in the joint arrays (EnvError for an unknown joint); cached
        per order of the state's joints."""
        order = self.robot_state.names
        key = (order, tuple(names))
        cache = self.__dict__.get("_joint_index_cache")
        if cache is None:
            cache = self._joint_index_cache = {}
        idx = cache.get(key)
        if idx is None:
            where = {name: i for i, name in enumerate(order)}
            try:
                idx = np.array([where[n] for n in key[1]], dtype=np.intp)
            except KeyError as exc:
                raise EnvError(f"robot {self.robot_name!r} has no joint {exc.args[0]!r}; joints: {order}") from None
            if len(cache) >= 64:  # a few name lists per env; never grow without end
                cache.clear()
            cache[key] = idx
        return idx
