"""The errors every env layer raises (simulated and real)."""

from __future__ import annotations

from gymnasium.error import ResetNeeded

__all__ = ["EnvError", "ResetError", "StepAfterFailedReset"]


class EnvError(RuntimeError):
    """A problem in an environment's set-up or episode logic that the user can fix."""


class ResetError(EnvError):
    """A reset could not bring the robot to its initial pose within the allowed attempts."""


class StepAfterFailedReset(EnvError, ResetNeeded):
    """``step()`` after a ``reset()`` that raised: the episode has no start state (call reset again).

    Also a ``gymnasium.error.ResetNeeded``, the error gymnasium raises for a step before any reset.
    """
