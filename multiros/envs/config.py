"""Small typed records for the base environments' constructor knobs.

MultiROS passes every knob as a loose keyword (``sim_step_mode=1``, ``reset_mode="world"``,
``robot_ori_w=0.0``); here each knob is validated once, with a message that names it, and the
MultiROS/FRobs_RL spellings are accepted and translated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

StepMode = Literal["lockstep", "pause_unpause", "realtime"]
ResetMode = Literal["world", "simulation"]
SimMode = Literal["composed", "process", "existing"]

# MultiROS: sim_step_mode 1 = unpause/act/pause, 2 = act then step N; FRobs_RL: step_mode 1 = services,
# 2 = step function. Both "2"s are our lockstep.
_STEP_MODE_ALIASES: dict[object, StepMode] = {
    1: "pause_unpause",
    2: "lockstep",
    "lockstep": "lockstep",
    "step": "lockstep",
    "pause_unpause": "pause_unpause",
    "unpause_pause": "pause_unpause",
    "realtime": "realtime",
    "real_time": "realtime",
}
# MultiROS: "world" or anything else = simulation; FRobs_RL: 1 = reset_world, 2 = reset_simulation.
_RESET_MODE_ALIASES: dict[object, ResetMode] = {
    1: "world",
    2: "simulation",
    "world": "world",
    "simulation": "simulation",
}


def parse_step_mode(value: object) -> StepMode:
    """Normalise a step mode (``"lockstep"``, ``"pause_unpause"``, ``"realtime"``, or MultiROS' 1/2)."""
    try:
        return _STEP_MODE_ALIASES[value]
    except (KeyError, TypeError):
        raise ValueError(
            f"step_mode {value!r} is not one of 'lockstep' (or 2), 'pause_unpause' (or 1), 'realtime'"
        ) from None


def parse_reset_mode(value: object) -> ResetMode:
    """Normalise a reset mode (``"world"``/1 keeps sim time, ``"simulation"``/2 resets it)."""
    try:
        return _RESET_MODE_ALIASES[value]
    except (KeyError, TypeError):
        raise ValueError(f"reset_mode {value!r} is not one of 'world' (or 1), 'simulation' (or 2)") from None


@dataclass(frozen=True)
class SpawnPose:
    """Where the robot is spawned: a world position and a ``(w, x, y, z)`` quaternion.

    The default orientation is the identity. A zero quaternion (MultiROS' old default) is refused.
    """

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        pos = np.asarray(self.position, dtype=float)
        quat = np.asarray(self.orientation, dtype=float)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValueError(f"robot position must be 3 finite numbers, got {self.position!r}")
        if quat.shape != (4,) or not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-9:
            raise ValueError(
                f"robot orientation must be a non-zero quaternion (w, x, y, z), got {self.orientation!r}; "
                "robot_ori_w=1.0 with x=y=z=0 is the identity (MultiROS defaulted to all zeros, which is invalid)"
            )


@dataclass(frozen=True)
class StepConfig:
    """How one env step advances the simulation.

    Attributes:
        mode: ``"lockstep"`` (one round trip: commands + ``num_sim_steps`` physics steps, the fast
            deterministic default), ``"pause_unpause"`` (MultiROS: unpause, act, wait
            ``action_cycle_time`` of wall time, pause) or ``"realtime"`` (physics runs free; act, then
            wait ``action_cycle_time``).
        num_sim_steps: physics steps per env step in lockstep mode.
        action_cycle_time: seconds between acting and observing in the other modes.
    """

    mode: StepMode = "lockstep"
    num_sim_steps: int = 20
    action_cycle_time: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.num_sim_steps, (int, np.integer)) or self.num_sim_steps < 1:
            raise ValueError(f"num_sim_steps must be an integer >= 1, got {self.num_sim_steps!r}")
        if not np.isfinite(self.action_cycle_time) or self.action_cycle_time < 0:
            raise ValueError(f"action_cycle_time must be >= 0 seconds, got {self.action_cycle_time!r}")
        if self.mode != "lockstep" and self.action_cycle_time <= 0:
            raise ValueError(
                f"step_mode {self.mode!r} needs action_cycle_time > 0 (seconds between acting and observing)"
            )
