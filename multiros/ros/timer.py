"""Timers run by the executor on the monotonic clock (``Node.create_timer``)."""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["Timer"]


class Timer:
    """A periodic callback; created by ``Node.create_timer``, run during ``spin``.

    Periods are measured on the monotonic clock, so wall-clock jumps and sim time do not
    affect them. A late timer runs once and then keeps its phase (missed periods are skipped).
    """

    def __init__(self, callback: Callable[[], None], period_sec: float, node: object) -> None:
        if period_sec <= 0:
            raise ValueError(f"timer period must be > 0 s, got {period_sec}")
        self.callback = callback
        self.node = node
        self.timer_period_ns = int(period_sec * 1e9)
        self._next = time.monotonic_ns() + self.timer_period_ns
        self._canceled = False
        self._destroyed = False

    @property
    def timer_period_sec(self) -> float:
        return self.timer_period_ns / 1e9

    def cancel(self) -> None:
        """Stop calling the callback until ``reset()``."""
        self._canceled = True

    def is_canceled(self) -> bool:
        return self._canceled

    def reset(self) -> None:
        """Restart the period from now (and un-cancel)."""
        self._canceled = False
        self._next = time.monotonic_ns() + self.timer_period_ns

    def is_ready(self) -> bool:
        return not self._canceled and time.monotonic_ns() >= self._next

    def time_until_next_call(self) -> int | None:
        """Nanoseconds until the next call, or ``None`` if canceled."""
        if self._canceled:
            return None
        return max(0, self._next - time.monotonic_ns())

    def _claim(self, now_ns: int) -> bool:
        # Executors call this under their own lock, so a period is claimed by one thread only.
        if self._canceled or self._destroyed or now_ns < self._next:
            return False
        missed = (now_ns - self._next) // self.timer_period_ns
        self._next += (missed + 1) * self.timer_period_ns
        return True

    def destroy(self) -> None:
        self._destroyed = True
        self._canceled = True
