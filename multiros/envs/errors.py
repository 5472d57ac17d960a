"""The errors every env layer raises (simulated and real)."""

from __future__ import annotations

__all__ = ["EnvError", "ResetError"]


class EnvError(RuntimeError):
    """A problem in an environment's set-up or episode logic that the user can fix."""


class ResetError(EnvError):
    """A reset could not bring the robot to its initial pose within the allowed attempts."""
