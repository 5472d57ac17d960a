"""Ctrl-C and SIGTERM during training: stop at the next env step, save, and say so.

The trainer (:mod:`uniros.trainer`) asks for a stop with :func:`stop_at_next_step` around
``model.learn``, writes its checkpoint inside :func:`signals_deferred`, and raises
:class:`TrainingInterrupted`; ``uniros train`` turns SIGTERM into an interrupt with
:func:`sigterm_as_interrupt`.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any

from uniros.errors import TrainingError
from uniros.run_dir import Checkpoint


class TrainingInterrupted(TrainingError, KeyboardInterrupt):
    """Training stopped on Ctrl-C or SIGTERM; a checkpoint was saved (``checkpoint``) when possible."""

    def __init__(self, message: str, signum: int, checkpoint: Checkpoint | None) -> None:
        super().__init__(message)
        self.signum = signum
        self.checkpoint = checkpoint

    @property
    def exit_code(self) -> int:
        """128 + the signal number (130 for Ctrl-C, 143 for SIGTERM), as shells report it."""
        return 128 + int(self.signum)


class _Signal(KeyboardInterrupt):
    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def _signal_handler(handler: Callable[[int, Any], None], signals: tuple[int, ...]) -> Iterator[None]:
    """Within the block, ``handler`` handles ``signals`` (only the main thread can set handlers;
    elsewhere the block runs with the handlers as they are)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield
    finally:
        for s, old in previous.items():
            signal.signal(s, old)


def _raise_signal(signum: int, frame: Any) -> None:
    raise _Signal(signum)


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM interrupts like Ctrl-C (raises ``KeyboardInterrupt`` with ``signum``)."""
    with _signal_handler(_raise_signal, (signal.SIGTERM,)):
        yield


class StopRequest:
    """The signal that asked training to stop, once one has."""

    def __init__(self) -> None:
        self.signum: int | None = None


@contextlib.contextmanager
def stop_at_next_step() -> Iterator[StopRequest]:
    """Within the block, the first Ctrl-C or SIGTERM asks training to stop; a second one interrupts at once.

    The request is honoured at the next env step, where the model is whole. Raising from the handler
    instead lands anywhere, mid optimizer update included, and a checkpoint saved then can hold Adam
    state with ``step`` but no ``exp_avg``, which fails on resume.
    """
    request = StopRequest()

    def handler(signum: int, frame: Any) -> None:
        if request.signum is not None:
            _raise_signal(signum, frame)
        request.signum = signum

    with _signal_handler(handler, (signal.SIGINT, signal.SIGTERM)):
        yield request


@contextlib.contextmanager
def signals_deferred() -> Iterator[list[int]]:
    """Within the block, Ctrl-C and SIGTERM are noted, not raised (a save in progress completes)."""
    pending: list[int] = []
    with _signal_handler(lambda signum, frame: pending.append(signum), (signal.SIGINT, signal.SIGTERM)):
        yield pending
