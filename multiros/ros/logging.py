"""Node loggers (standard ``logging`` with rclpy's method names) and rate-limited warnings.

Node loggers: every node logs through the standard ``logging`` logger of its fully qualified
name (``/ns/node`` -> ``ros.ns.node``), so ``logging.getLogger("ros.mujoco_sim").setLevel(...)``
works as users expect. ``logging`` keeps every logger it ever created for the life of the process,
so a program that creates and destroys nodes with fresh names (an env per ``make``, named with a
counter) would keep one logger per node forever: :func:`get_logger` looks names up instead of
creating them, and :func:`release_logger` (called when a node is destroyed) drops a logger that
nothing configured.

Rate limits: anything that arrives from the wire can arrive a thousand times a second, and a
warning per bad sample floods the log. :class:`LogThrottle` logs the first ``burst`` occurrences
of one kind of warning, then at most one line per ``interval_sec`` saying how many were
suppressed since the last line (rclpy's ``throttle_duration_sec`` and ``skip_first``, combined).
"""

from __future__ import annotations

import logging as _logging
import threading
import time
from collections.abc import Callable

__all__ = ["LogThrottle", "RosLogger", "get_logger", "release_logger"]

_ROOT = "ros"
_lock = threading.Lock()
_users: dict[str, int] = {}  # logger name -> nodes using it now
_logging.getLogger(_ROOT)  # a logger, not a placeholder that would keep a reference to every node's logger


class RosLogger(_logging.LoggerAdapter):
    """A ``logging.Logger`` adapter that also answers rclpy's ``warn`` and ``fatal``."""

    def warn(self, msg: object, *args: object, **kwargs: object) -> None:  # noqa: D102
        self.warning(msg, *args, **kwargs)

    def fatal(self, msg: object, *args: object, **kwargs: object) -> None:  # noqa: D102
        self.critical(msg, *args, **kwargs)

    def get_child(self, name: str) -> RosLogger:
        """A logger for a sub-component (``node.sub``)."""
        return RosLogger(self.logger.getChild(name), {})


def _dotted(name: str) -> str:
    dotted = ".".join(p for p in name.split("/") if p)
    return f"{_ROOT}.{dotted}" if dotted else _ROOT


def get_logger(name: str, *, node: bool = False) -> RosLogger:
    """The logger for a ROS name (``/ns/node`` -> ``ros.ns.node``).

    ``node=True`` counts one more node using it, until :func:`release_logger`.
    """
    dotted = _dotted(name)
    with _lock:
        if node:
            _users[dotted] = _users.get(dotted, 0) + 1
        return RosLogger(_logging.getLogger(dotted), {})


def release_logger(name: str) -> None:
    """A node using the logger of ``name`` is gone: forget the logger if no node uses it any more
    and nobody configured it (no level, handler, filter or disabled flag of its own, no child
    logger), so that nodes with unique names leave nothing behind in ``logging``."""
    dotted = _dotted(name)
    with _lock:
        left = _users.get(dotted, 0) - 1
        if left > 0:
            _users[dotted] = left
            return
        _users.pop(dotted, None)
        manager = _logging.Logger.manager
        with _logging._lock:  # type: ignore[attr-defined]  # logging's own lock over loggerDict (3.10-3.13)
            logger = manager.loggerDict.get(dotted)
            if not isinstance(logger, _logging.Logger) or dotted == _ROOT:
                return
            if logger.level or logger.handlers or logger.filters or logger.disabled or not logger.propagate:
                return
            prefix = dotted + "."
            if any(key.startswith(prefix) for key in manager.loggerDict):
                return
            del manager.loggerDict[dotted]
            parent = dotted.rpartition(".")[0]
            while parent:  # a placeholder for a missing parent (``ros.ns`` of ``ros.ns.node``) maps its children
                holder = manager.loggerDict.get(parent)
                if isinstance(holder, _logging.PlaceHolder):
                    holder.loggerMap.pop(logger, None)
                    if not holder.loggerMap:
                        del manager.loggerDict[parent]
                parent = parent.rpartition(".")[0]


class LogThrottle:
    """Rate limit for one kind of repeated log line (see the module docstring).

    Args:
        burst: how many occurrences are logged in full before throttling starts.
        interval_sec: at most one line per interval afterwards, with the count suppressed since
            the previous line.
        clock: monotonic time source (tests pass their own).

    Thread-safe: callbacks of several transport threads may report at once.
    """

    def __init__(self, burst: int = 5, interval_sec: float = 10.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if burst < 0 or not interval_sec > 0:
            raise ValueError(f"burst must be >= 0 and interval_sec > 0, got {burst}, {interval_sec}")
        self.burst = int(burst)
        self.interval_sec = float(interval_sec)
        self._clock = clock
        self._lock = threading.Lock()
        self._seen = 0
        self._suppressed = 0
        self._next = 0.0

    @property
    def seen(self) -> int:
        """Occurrences reported so far, logged or not."""
        return self._seen

    def log(self, logger: _logging.Logger | _logging.LoggerAdapter, level: int, msg: str, *args: object) -> bool:
        """Log ``msg % args`` at ``level`` unless the rate limit holds it back; True when logged."""
        with self._lock:
            self._seen += 1
            last_in_full = self._seen == self.burst
            suppressed = 0
            if self._seen > self.burst:
                now = self._clock()
                if now < self._next:
                    self._suppressed += 1
                    return False
                suppressed, self._suppressed = self._suppressed, 0
                self._next = now + self.interval_sec
            elif last_in_full:
                self._next = self._clock() + self.interval_sec
        if suppressed:
            msg = f"{msg} ({suppressed} more like this since the last line were not logged)"
        elif last_in_full:
            msg = f"{msg} (more like this: at most one line per {self.interval_sec:g} s)"
        logger.log(level, msg, *args)
        return True
