"""The training layer's errors: each message says what is wrong and what to do.

``uniros`` (the CLI) prints them in one or two lines and exits with code 2.
"""

from __future__ import annotations


class TrainingError(Exception):
    """A training run cannot go on: the message says what is wrong and what to do."""


class TrainingConfigError(TrainingError, ValueError):
    """A training YAML is missing, malformed, or has an unknown, misspelt or mistyped key."""


__all__ = ["TrainingConfigError", "TrainingError"]
