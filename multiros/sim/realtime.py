"""The real-time runner: steps a :class:`~multiros.sim.world.World` in a background thread, paced
against the wall clock at a real-time factor (the simulation node's ``STATE_PLAYING`` mode).

Re-exported by :mod:`multiros.sim.world`.
"""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from multiros.sim.errors import UnstableSimulationError

if TYPE_CHECKING:
    from multiros.sim.world import World

__all__ = ["RealTimeRunner"]


class RealTimeRunner:
    """Runs a world's physics in a background thread at a real-time factor.

    Deadline-based: after each chunk the thread waits until ``start_wall + sim_elapsed / rtf``
    (not a fixed sleep); if it falls more than ``max_lag`` seconds behind it restarts the deadline
    rather than bursting to catch up.

    Args:
        world: the world to step.
        real_time_factor: 1.0 = wall clock, > 1 faster, <= 0 as fast as possible.
        chunk_steps: physics steps per chunk (the callback runs after each chunk).
        on_chunk: ``callback(world)`` after each chunk, with the lock held (publish /clock, joint states).
        on_error: ``callback(exc)`` for an exception raised by a chunk (the runner keeps running
            after UnstableSimulationError, stops after anything else).
        lock: the (reentrant) lock to hold while stepping, any object with ``acquire``/``release``
            (default: a new RLock), exposed as ``lock``; the node passes a
            :class:`~multiros.sim.fair_lock.FairLock`.
        max_lag: seconds behind the deadline before the pacing restarts from now.
    """

    def __init__(self, world: World, *, real_time_factor: float = 1.0, chunk_steps: int = 10,
                 on_chunk: Callable[[World], None] | None = None,
                 on_error: Callable[[BaseException], None] | None = None,
                 lock: Any = None, max_lag: float = 0.25) -> None:
        if chunk_steps < 1:
            raise ValueError(f"chunk_steps must be >= 1, got {chunk_steps}")
        self.world = world
        self.lock = lock if lock is not None else threading.RLock()
        self.chunk_steps = int(chunk_steps)
        self.on_chunk, self.on_error = on_chunk, on_error
        self.max_lag = max_lag
        self._rtf = float(real_time_factor)
        self._stop = threading.Event()
        self._rebase = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None
        self.measured_real_time_factor: float | None = None  # sim s per wall s over the last 2 s while playing

    @property
    def real_time_factor(self) -> float:
        """Settable while running; the deadline restarts from now."""
        return self._rtf

    @real_time_factor.setter
    def real_time_factor(self, value: float) -> None:
        self._rtf = float(value)
        self._rebase.set()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start the thread (no-op when running)."""
        if self.running:
            return
        self._stop.clear()
        self.error = None
        self._thread = threading.Thread(target=self._run, name="uniros-realtime", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop and join the thread within ``timeout`` seconds.

        Raises:
            TimeoutError: the thread did not stop in time (a callback is blocking).
        """
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
            if thread.is_alive():
                raise TimeoutError(f"real-time runner did not stop within {timeout} s; a chunk callback "
                                   f"is blocking")
        self._thread = None

    def _run(self) -> None:
        wall0, sim0 = _time.monotonic(), self.world.time
        window_wall, window_sim = wall0, sim0
        self.measured_real_time_factor = None
        while not self._stop.is_set():
            try:
                with self.lock:
                    if self._rebase.is_set() or self.world.time < sim0:  # rtf change or reset rewound time
                        self._rebase.clear()
                        wall0, sim0 = _time.monotonic(), self.world.time
                    try:
                        self.world.step(self.chunk_steps)
                    except UnstableSimulationError as exc:
                        if self.on_error is not None:
                            self.on_error(exc)
                    if self.on_chunk is not None:
                        self.on_chunk(self.world)
                    sim_elapsed = self.world.time - sim0
            except BaseException as exc:  # stop the loop, report, never die silently
                self.error = exc
                if self.on_error is not None:
                    self.on_error(exc)
                return
            now = _time.monotonic()
            if self.world.time < window_sim or self._rebase.is_set():
                window_wall, window_sim = now, self.world.time
            elif now - window_wall >= 2.0:
                self.measured_real_time_factor = (self.world.time - window_sim) / (now - window_wall)
                window_wall, window_sim = now, self.world.time
            rtf = self._rtf
            if rtf <= 0:
                wall0, sim0 = _time.monotonic(), self.world.time
                continue
            delay = wall0 + sim_elapsed / rtf - _time.monotonic()
            if delay < -self.max_lag:
                wall0, sim0 = _time.monotonic(), self.world.time
            elif delay > 0:
                self._stop.wait(delay)
