"""Executors: run subscription and timer callbacks of the nodes they were given.

Service callbacks do not need an executor (see ``service.py``); futures complete on their own
(see ``task.py``). Each callback runs under its node's callback lock, so one node's callbacks
never run concurrently, also with ``MultiThreadedExecutor``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from multiros.ros.context import Context, get_default_context
from multiros.ros.task import Future

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["Executor", "SingleThreadedExecutor", "MultiThreadedExecutor"]

_log = logging.getLogger(__name__)
_MAX_WAIT = 1.0  # re-check shutdown at least this often while idle


class Executor:
    """Base executor; ``spin_once`` runs at most one callback."""

    def __init__(self, *, context: Context | None = None) -> None:
        self.context = context if context is not None else get_default_context()
        self._nodes: list[Node] = []
        self._lock = threading.Lock()
        self._shutdown = False
        self._rr = 0

    def add_node(self, node: Node) -> bool:
        """Spin ``node`` too; returns ``False`` if it was already added."""
        with self._lock:
            if node in self._nodes:
                return False
            self._nodes.append(node)
        self.context.notify()
        return True

    def remove_node(self, node: Node) -> None:
        with self._lock:
            if node in self._nodes:
                self._nodes.remove(node)

    def get_nodes(self) -> list[Node]:
        return list(self._nodes)

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Stop spinning (wakes a blocked ``spin``)."""
        self._shutdown = True
        self.context.notify()
        return True

    def _running(self) -> bool:
        return not self._shutdown and self.context.ok()

    def _next_task(self) -> tuple[Callable[[], None] | None, float | None]:
        """Claim one ready callback; also return seconds until the next timer is due."""
        now = time.monotonic_ns()
        next_due: int | None = None
        with self._lock:
            nodes = self._nodes
            n = len(nodes)
            for k in range(n):
                node = nodes[(self._rr + k) % n]
                if node._destroyed:
                    continue
                for timer in node.timers:
                    if timer._claim(now):
                        self._rr = (self._rr + k + 1) % n
                        return _bind(node, timer.callback, None, False), 0.0
                    left = timer.time_until_next_call()
                    if left is not None and (next_due is None or left < next_due):
                        next_due = left
                for sub in node.subscriptions:
                    ok, msg = sub._take()
                    if ok:
                        self._rr = (self._rr + k + 1) % n
                        return _bind(node, sub.callback, msg, True), 0.0
        return None, (None if next_due is None else next_due / 1e9)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Run one ready callback, waiting up to ``timeout_sec`` (``None``: until one is ready)."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        ctx = self.context
        while self._running():
            gen = ctx.generation
            task, next_due = self._next_task()
            if task is not None:
                task()
                return
            wait = _MAX_WAIT if next_due is None else min(next_due, _MAX_WAIT)
            if deadline is not None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return
                wait = min(wait, remaining)
            ctx.wait_changed(gen, wait)

    def spin(self) -> None:
        """Run callbacks until ``shutdown()`` or the context shuts down."""
        while self._running():
            self.spin_once(_MAX_WAIT)

    def spin_until_future_complete(self, future: Future, timeout_sec: float | None = None) -> None:
        """Run callbacks until ``future`` is done or ``timeout_sec`` passed."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not future.done() and self._running():
            if deadline is None:
                self.spin_once(_MAX_WAIT)
                continue
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            self.spin_once(remaining)

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()


def _bind(node: Node, callback: Callable, arg: object, with_arg: bool) -> Callable[[], None]:
    lock = node._callback_lock

    def run() -> None:
        with lock:
            try:
                if with_arg:
                    callback(arg)
                else:
                    callback()
            except Exception:
                # rclpy lets the exception escape spin(); we do too, after logging which node.
                node.get_logger().exception("callback of node %s raised", node.get_fully_qualified_name())
                raise

    return run


class SingleThreadedExecutor(Executor):
    """Runs every callback in the thread that calls ``spin*``."""


class MultiThreadedExecutor(Executor):
    """Runs callbacks on ``num_threads`` worker threads while ``spin`` blocks the caller.

    Callbacks of different nodes run in parallel; one node's callbacks stay serialized by its
    callback lock.
    """

    def __init__(self, num_threads: int | None = None, *, context: Context | None = None) -> None:
        super().__init__(context=context)
        self.num_threads = num_threads or 2

    def spin(self) -> None:
        base_spin = super().spin
        workers = [
            threading.Thread(target=base_spin, name=f"ros-executor-{i}", daemon=True)
            for i in range(self.num_threads)
        ]
        for w in workers:
            w.start()
        try:
            for w in workers:
                while w.is_alive():
                    w.join(_MAX_WAIT)
        finally:
            self.shutdown()
            for w in workers:
                w.join(_MAX_WAIT * 2)
