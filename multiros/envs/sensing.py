"""What a simulated robot's sensors add to the truth: joint noise, calibration offsets, a tracker's noise
and latency.

Domain randomisation's sensing part (:mod:`rl_environments.randomization` draws it per episode). A
:class:`SensorModel` is applied where a simulated robot's state enters the env, once per step, to the
fresh arrays of the node's reply (single and batched steps alike: :class:`~multiros.envs.sim_connection.
SimConnection` calls it), so every reader of the state (the observation, the task's delta commands, the
scores) sees what a real robot's encoders and tracker would report.

A calibration offset is the encoder's error: it reads ``true + offset``. A real servo closes its loop
on that same reading, so a command lands ``offset`` away from where the model puts it: the connection
takes the offsets off the arm's commands and reset poses (:meth:`SensorModel.to_model`), which keeps
commands and readings in the encoder's frame while the arm itself (its frames, the end effector) stands
where the truth is.

A tracker's latency: the object's position a reading reports is the truest one at least ``frame_latency``
seconds older than the state (simulation time; the oldest kept before that much has passed). The
connection starts each episode's history afresh once the task has placed the object.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["SensorModel"]


@dataclass
class SensorModel:
    """Noise and offsets for one robot's readings.

    Attributes:
        joints: indices, in the robot's joint state, of the joints read with offsets and noise.
        offsets: rad added to those joints (this episode's calibration error).
        joint_noise: rad, standard deviation of Gaussian noise per reading.
        frames: indices of the frames a tracker reports (the task's object), ``()`` for none.
        frame_noise: m, standard deviation of Gaussian noise on those frames' positions.
        rng: the noise's generator (the env's, seeded with it).
        frame_latency: s, how old the tracker's reading of those frames is.
    """

    joints: np.ndarray
    offsets: np.ndarray
    joint_noise: float = 0.0
    frames: tuple[int, ...] = ()
    frame_noise: float = 0.0
    rng: np.random.Generator = field(default_factory=np.random.default_rng)
    frame_latency: float = 0.0
    _history: deque[tuple[float, np.ndarray]] = field(default_factory=deque, repr=False)

    def forget(self) -> None:
        """Drop the tracker's history (the object was placed: the next reading is its new place)."""
        self._history.clear()

    def to_model(self, joints: Sequence[int], reading: np.ndarray) -> np.ndarray:
        """Positions of ``joints`` (indices in the joint state) as the encoders read them, in the model's
        frame: the offsets taken off (a new array)."""
        offset = dict(zip(self.joints.tolist(), self.offsets.tolist()))
        return np.asarray(reading, dtype=np.float64) - np.array([offset.get(int(j), 0.0) for j in joints])

    def apply(self, position: np.ndarray, frame_positions: np.ndarray, time: float = 0.0) -> None:
        """Add offsets and noise, in place, to one robot's joint positions ``(n,)`` and frame positions
        ``(f, 3)`` read at simulation ``time`` (the tracker's latency counts in it)."""
        joints = self.joints
        if joints.size:
            reading = position[joints] + self.offsets
            if self.joint_noise > 0:
                reading += self.rng.normal(0.0, self.joint_noise, joints.size)
            position[joints] = reading
        if self.frames and self.frame_latency > 0 and frame_positions.size:
            self._delay(frame_positions, time)
        if self.frames and self.frame_noise > 0 and frame_positions.size:
            idx = list(self.frames)
            frame_positions[idx] += self.rng.normal(0.0, self.frame_noise, (len(idx), 3))

    def _delay(self, frame_positions: np.ndarray, time: float) -> None:
        """Put the tracked frames' reading from ``frame_latency`` ago in place of the true one."""
        idx = list(self.frames)
        history = self._history
        if history and time < history[-1][0]:  # the clock went back: a new timeline
            history.clear()
        if history and time == history[-1][0]:  # a second reading at one time (a refresh without steps)
            history.pop()
        history.append((time, frame_positions[idx].copy()))
        due = time - self.frame_latency
        while len(history) > 1 and history[1][0] <= due:
            history.popleft()
        frame_positions[idx] = history[0][1]
