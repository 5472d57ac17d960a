"""Spin, then block: how each side of a worker vector env waits for the other's message.

A process with a core of its own polls its socket for :data:`SPIN_WAIT_SEC` before it sleeps: a sleeping
process's wake-up costs more than an answer's usual wait (:func:`_spin_wait` gives each side its
value). Beside other programs on the same cores a spinning process takes a core from one that has
work, so a process that steps a share polls only while its thread seldom waits for a core
(:class:`RunQueueDelay`, the kernel's run-queue delay, below :data:`QUEUED_TO_SPIN`). The socket's poll
is registered once (:func:`_poller`): :func:`_spin` polls, :func:`_wait_for` sleeps.
"""

from __future__ import annotations

import math
import os
import select
import threading
import time
from multiprocessing.connection import Connection
from typing import Any

from multiros.envs.batch import usable_cores

__all__ = ["QUEUED_TO_SPIN", "SPIN_WAIT_SEC", "RunQueueDelay"]

#: How long a process with a core of its own polls for the other side's message before it sleeps
#: (spin, then block): a sleeping process's wake-up costs more than the answer's usual wait.
SPIN_WAIT_SEC = 200e-6
#: A share spins only while its thread waits less than this for a core per vector step (the kernel's
#: run-queue delay, a running mean; Linux): above it another program shares the cores, and a spinning
#: process takes the core from a process that has work. make_vec(8) on 2 cores: 5-90 us a step alone,
#: 200-1,100 us beside a second one.
QUEUED_TO_SPIN = 200e-6


class RunQueueDelay:
    """How long the thread that samples it waited for a core (runnable, not running) between two
    samples, a running mean (``per_step``, seconds), from the kernel's ``/proc/thread-self/schedstat``.

    Beside other programs on the same cores a process that was woken waits for a core; a process that
    spins keeps one from them. No standard module reads this (``os.sched_*`` and ``resource`` give CPU
    time and switch counts, not the wait), so it is read here: one ``pread`` of an open file, about
    1 us. The file is opened again for another thread (by its kernel id, in this process: a fork's
    child opens its own). Where the file is missing (not Linux) ``per_step`` stays 0.
    """

    WEIGHT = 1 / 16  # of each sample in the running mean

    def __init__(self) -> None:
        self.per_step = 0.0
        self._fd: int | None = None
        self._thread: tuple[int, int] | None = None  # (process id, kernel thread id) the file is of
        self._last: int | None = None
        self._missing = False  # no such file here: never asked again

    def sample(self) -> None:
        if self._missing:
            return
        thread = (os.getpid(), threading.get_native_id())
        if thread != self._thread:  # (re)open for the thread that steps now
            self.close()
            try:
                self._fd = os.open("/proc/thread-self/schedstat", os.O_RDONLY)
            except FileNotFoundError:
                self._missing = True
                return
            except OSError:
                return
            self._thread = thread
        fd = self._fd
        if fd is None:
            return
        try:
            waited = int(os.pread(fd, 64, 0).split()[1])  # "cpu_ns run_delay_ns timeslices"
        except (OSError, ValueError, IndexError):
            self.close()  # the next sample opens it again
            return
        if self._last is not None:
            self.per_step += ((waited - self._last) * 1e-9 - self.per_step) * self.WEIGHT
        self._last = waited

    def close(self) -> None:
        fd, self._fd, self._last, self._thread = self._fd, None, None, None
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass


def _spin_wait(value: float | None, shares: int, in_parent: bool) -> float:
    """The ``spin_wait_sec`` of a side of a vector env of ``shares`` shares (``in_parent``: a side that
    steps a share; a worker's always does): ``value`` checked, else the default (:data:`SPIN_WAIT_SEC`
    where that side steps a share and every share has a core, else 0: a process that polls while
    another needs its core only delays it)."""
    if value is None:
        return SPIN_WAIT_SEC if in_parent and shares <= usable_cores() else 0.0
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 0.01:
        raise ValueError(f"spin_wait_sec must be a number of seconds from 0 to 0.01, got {value!r}")
    return float(value)


def _poller(conn: Connection) -> Any:
    """A ``select.poll`` of ``conn``'s socket (registered once: a poll of it then costs a microsecond)."""
    poller = select.poll()
    poller.register(conn.fileno(), select.POLLIN)
    return poller


def _wait_for(poller: Any, seconds: float) -> bool:
    """Sleep until a message (or the socket's end) is there or ``seconds`` have passed; whether it is.
    The poll is registered once: ``multiprocessing.connection.wait`` makes and fills a selector each
    call (at N = 128 with 15 workers, a tenth of this process's exchange)."""
    return bool(poller.poll(max(0, math.ceil(seconds * 1000))))


def _spin(poller: Any, seconds: float) -> bool:
    """Poll until a message (or the socket's end) is there or ``seconds`` have passed; whether it is."""
    end = time.perf_counter() + seconds
    while not poller.poll(0):
        if time.perf_counter() >= end:
            return False
    return True
