"""The training layer's errors: each message says what is wrong and what to do.

``uniros`` (the CLI) prints them in one or two lines and exits with code 2.
"""

from __future__ import annotations


class TrainingError(Exception):
    """A training run cannot go on: the message says what is wrong and what to do."""


class TrainingConfigError(TrainingError, ValueError):
    """A training YAML is missing, malformed, or has an unknown, misspelt or mistyped key."""


class RunDirError(TrainingError, ValueError):
    """A run directory is missing, incomplete, in use, unsafe to write, or would be overwritten."""


class DiskFullError(TrainingError, OSError):
    """A run could not write a file: the disk (or the user's quota) is full."""


__all__ = ["DiskFullError", "RunDirError", "TrainingConfigError", "TrainingError"]
