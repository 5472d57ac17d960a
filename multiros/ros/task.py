"""``Future``: the result of ``Client.call_async``, shaped like ``rclpy.task.Future``.

Done-callbacks run in the thread that completes the future (for in-process services that is
the caller's thread, for Zenoh replies the Zenoh callback thread), not in an executor.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

__all__ = ["Future"]


class Future:
    """A value that becomes available later.

    Args:
        notify: called after the future completes (the context uses it to wake executors).
    """

    __slots__ = ("_result", "_exception", "_done", "_cancelled", "_event", "_callbacks", "_notify", "_lock")

    def __init__(self, notify: Callable[[], None] | None = None) -> None:
        self._result: Any = None
        self._exception: BaseException | None = None
        self._done = False
        self._cancelled = False
        self._event: threading.Event | None = None
        self._callbacks: list[Callable[[Future], None]] = []
        self._notify = notify
        self._lock = threading.Lock()

    def done(self) -> bool:
        """Whether a result, an exception or a cancellation is set."""
        return self._done

    def cancelled(self) -> bool:
        """Whether ``cancel()`` was called before completion."""
        return self._cancelled

    def cancel(self) -> None:
        """Give up on the result; later ``set_result`` calls are ignored."""
        self._complete(None, None, cancelled=True)

    def result(self) -> Any:
        """The result, or ``None`` while pending; re-raises a stored exception."""
        if self._exception is not None:
            raise self._exception
        return self._result

    def exception(self) -> BaseException | None:
        """The stored exception, if any."""
        return self._exception

    def set_result(self, result: Any) -> None:
        """Complete with ``result`` (ignored if already done)."""
        self._complete(result, None)

    def set_exception(self, exception: BaseException) -> None:
        """Complete with an exception (ignored if already done)."""
        self._complete(None, exception)

    def add_done_callback(self, callback: Callable[[Future], None]) -> None:
        """Call ``callback(future)`` on completion (at once if already done)."""
        with self._lock:
            if not self._done:
                self._callbacks.append(callback)
                return
        callback(self)

    def wait(self, timeout_sec: float | None) -> bool:
        """Block until done or ``timeout_sec`` passed; returns ``done()``."""
        if self._done:
            return True
        with self._lock:
            if self._done:
                return True
            if self._event is None:
                self._event = threading.Event()
            event = self._event
        event.wait(timeout_sec)
        return self._done

    def _complete(self, result: Any, exception: BaseException | None, cancelled: bool = False) -> None:
        with self._lock:
            if self._done:
                return
            self._result, self._exception, self._cancelled = result, exception, cancelled
            self._done = True
            callbacks, self._callbacks = self._callbacks, []
            event = self._event
        if event is not None:
            event.set()
        for cb in callbacks:
            cb(self)
        if self._notify is not None:
            self._notify()

    def __await__(self):  # pragma: no cover - convenience for asyncio-style code
        while not self._done:
            yield
        return self.result()
