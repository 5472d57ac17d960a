"""What a robot's state is, wherever it comes from: the simulation node or a real robot's driver.

:class:`RobotStates` holds the states of N robots alike (same joint order, same number of frames)
as rows of ``(N, ...)`` arrays; :class:`RobotState` is one robot's. A simulation node's step
returns the states of all the robots it stepped stacked (rows are views, no copy per robot); a real
robot's connection returns a batch of one. The envs and tasks read states only through these two
records, so simulated and real, single and batched, share one meaning of "the robot's state".

A leaf module (numpy only): the simulation layer (:mod:`multiros.sim`), the env layer and the real
robot side all import it, and it imports none of them.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["RobotState", "RobotStates", "EMPTY_FRAME_POSITIONS", "EMPTY_FRAME_ORIENTATIONS"]

EMPTY_FRAME_POSITIONS = np.empty((0, 3))
EMPTY_FRAME_ORIENTATIONS = np.empty((0, 4))
EMPTY_FRAME_POSITIONS.flags.writeable = False
EMPTY_FRAME_ORIENTATIONS.flags.writeable = False


@dataclass(slots=True)
class RobotState:
    """One robot's state after a step (simulation) or at its arrival (robot). Read it, do not change
    it: it may share its arrays with the states of the other robots of a step (a plain slotted
    dataclass, not a frozen one: made on every step of every env, and a frozen one costs twice).

    Attributes:
        sim_time: simulation time in seconds after the step; on a real robot the header stamp of
            the state (the robot's clock; 0 when it sends none).
        names: joint names, in the order of the joint arrays.
        position, velocity, effort: joint state arrays aligned with ``names``.
        frame_positions: ``(frames, 3)`` world positions of the frames the step asked for.
        frame_orientations: ``(frames, 4)`` world orientations, quaternions ``(w, x, y, z)``.
        received: local monotonic time the state arrived (a real robot's; ``None`` in simulation).
    """

    sim_time: float
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    frame_positions: np.ndarray = field(default_factory=lambda: EMPTY_FRAME_POSITIONS)
    frame_orientations: np.ndarray = field(default_factory=lambda: EMPTY_FRAME_ORIENTATIONS)
    received: float | None = None

    @property
    def stamp(self) -> float:
        """The state's time stamp (``sim_time``; a real robot's header stamp)."""
        return self.sim_time

    def age(self, now: float | None = None) -> float:
        """Seconds since the state arrived (0 for a simulated state, which is never stale)."""
        if self.received is None:
            return 0.0
        return (_time.monotonic() if now is None else now) - self.received


@dataclass(slots=True)
class RobotStates:
    """The states of N robots with the same joints and the same number of frames: row ``j`` is robot ``j``'s.

    Attributes:
        sim_time: simulation time after the step (one clock for the batch).
        names: the joint names every robot's arrays follow.
        position, velocity, effort: ``(N, joints)``.
        frame_positions: ``(N, frames, 3)``; frame_orientations: ``(N, frames, 4)`` ``(w, x, y, z)``.
    """

    sim_time: float
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    frame_positions: np.ndarray
    frame_orientations: np.ndarray

    def __len__(self) -> int:
        return len(self.position)

    def row(self, j: int) -> RobotState:
        """Robot ``j``'s state (its arrays are views of these)."""
        return RobotState(self.sim_time, self.names, self.position[j], self.velocity[j], self.effort[j],
                          self.frame_positions[j], self.frame_orientations[j])

    def batch_of_row(self, j: int) -> RobotStates:
        """Robot ``j``'s state as a batch of one (views of these arrays)."""
        k = slice(j, j + 1)
        return RobotStates(self.sim_time, self.names, self.position[k], self.velocity[k], self.effort[k],
                           self.frame_positions[k], self.frame_orientations[k])

    def put_row(self, j: int, state: RobotState) -> bool:
        """Make row ``j`` ``state`` (copied in); ``False``, changing nothing, when it is not alike."""
        if state.names != self.names or state.frame_positions.shape != self.frame_positions.shape[1:]:
            return False
        self.position[j], self.velocity[j], self.effort[j] = state.position, state.velocity, state.effort
        self.frame_positions[j], self.frame_orientations[j] = state.frame_positions, state.frame_orientations
        return True

    def rows(self) -> list[RobotState]:
        """Every robot's state, in order."""
        t, names = self.sim_time, self.names
        return [RobotState(t, names, p, v, e, fp, fo) for p, v, e, fp, fo in
                zip(self.position, self.velocity, self.effort, self.frame_positions, self.frame_orientations)]

    @classmethod
    def of(cls, states: list[RobotState]) -> RobotStates | None:
        """The states stacked, or ``None`` when they are not alike (joint names or frame counts differ)."""
        if not states:
            return None
        first = states[0]
        if any(s.names != first.names or len(s.frame_positions) != len(first.frame_positions) for s in states):
            return None
        return cls(first.sim_time, first.names, np.array([s.position for s in states]),
                   np.array([s.velocity for s in states]), np.array([s.effort for s in states]),
                   np.array([s.frame_positions for s in states]).reshape(len(states), -1, 3),
                   np.array([s.frame_orientations for s in states]).reshape(len(states), -1, 4))
