"""``Context``: what ``init()`` creates. It owns the transport, the domain id, the in-process
registry and (with Zenoh) the session and the embedded router.

Two contexts in one process share nothing: tests and vectorised envs create one each.
"""

from __future__ import annotations

import logging
import os
import threading
import time
import weakref
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from multiros.ros.exceptions import NotInitializedException
from multiros.ros.graph import GraphQueries
from multiros.ros.names import RosArguments, parse_ros_arguments, split_ros_arguments
from multiros.ros.registry import LocalRegistry

if TYPE_CHECKING:
    from multiros.ros.node import Node
    from multiros.ros.transport.base import Transport

__all__ = ["Context", "get_default_context", "TRANSPORT_ENV", "DEFAULT_TIMEOUT_SEC"]

_log = logging.getLogger(__name__)

TRANSPORT_ENV = "UNIROS_TRANSPORT"
DEFAULT_TIMEOUT_SEC = 10.0  # rmw_zenoh's queries_default_timeout


class Context:
    """Holds everything one ROS "process view" needs; usable as a context manager.

    Args:
        transport: ``"inproc"`` (default; no network), ``"zenoh"`` or ``"rclpy"`` (the installed
            rclpy, on whatever middleware it loads); default from ``$UNIROS_TRANSPORT``.
        domain_id: ROS domain; default ``$ROS_DOMAIN_ID`` read once here, else 0.
        default_timeout_sec: bound for waits given ``timeout_sec=None``.
        env: environment to read settings from (default ``os.environ``; never written).
        **transport_options: passed to the transport (Zenoh: ``router``, ``router_endpoint``,
            ``attachment_format``, ``codec``, ``lazy_publish``; see ``ZenohSettings``).

    Raises:
        ValueError: bad domain id.
    """

    def __init__(
        self,
        *,
        transport: str | None = None,
        domain_id: int | None = None,
        default_timeout_sec: float = DEFAULT_TIMEOUT_SEC,
        env: Mapping[str, str] | None = None,
        **transport_options: Any,
    ) -> None:
        self.env: dict[str, str] = dict(os.environ if env is None else env)
        self.transport_name = (transport or self.env.get(TRANSPORT_ENV) or "inproc").strip().lower()
        self.domain_id = _domain_id(domain_id, self.env)
        self.default_timeout_sec = float(default_timeout_sec)
        self.transport_options = transport_options
        self.registry = LocalRegistry()
        self.arguments = RosArguments()
        self.ros_argv: list[str] = []  # the --ros-args sections of init's args, for rcl (the rclpy transport)
        self._transport: Transport | None = None
        self._cond = threading.Condition()
        self._generation = 0
        self._ok = False
        self._nodes: list[Node] = []
        self._shutdown_callbacks: list[Callable[[], None]] = []
        self._finalizer: weakref.finalize | None = None
        self._default_executor: Any = None
        self._poll_sec = 1.0

    # -- lifecycle ---------------------------------------------------------------------------
    def init(self, args: Sequence[str] | None = None, *, domain_id: int | None = None) -> Context:
        """Parse global ``--ros-args`` and open the transport.

        Raises:
            RuntimeError: already initialised.
            TransportError: the transport could not be opened.
        """
        if self._ok:
            raise RuntimeError("context is already initialised; call shutdown() first")
        if domain_id is not None:
            self.domain_id = _domain_id(domain_id, self.env)
        self.arguments = parse_ros_arguments(list(args) if args else None)
        self.ros_argv = split_ros_arguments(list(args) if args else [])[1]
        from multiros.ros.transport import make_transport

        transport = make_transport(self.transport_name, self)
        transport.open()
        self.registry.leave_topics_to_transport(transport.delivers_local_topics)
        self._poll_sec = float(transport.poll_sec)
        self._transport = transport
        # Close the transport at interpreter exit or when the context is garbage-collected.
        self._finalizer = weakref.finalize(self, transport.close)
        self._ok = True
        return self

    def ok(self) -> bool:
        """Whether the context is initialised and not shut down."""
        return self._ok

    @property
    def transport(self) -> Transport:
        if self._transport is None:
            raise NotInitializedException("the context")
        return self._transport

    def reach(self) -> str:
        """How this context reaches other programs, for messages (``Zenoh router tcp/...``, ``ROS 2
        middleware rmw_fastrtps_cpp``): its transport's own words."""
        return self._transport.reach() if self._transport is not None else f"the {self.transport_name} transport"

    def shutdown(self) -> None:
        """Destroy all nodes, close the transport (session, router, threads) and wake waiters.

        Raises:
            RuntimeError: the context was not initialised.
        """
        if not self._ok:
            raise RuntimeError("context is not initialised or already shut down")
        self.try_shutdown()

    def try_shutdown(self) -> None:
        """``shutdown()`` that does nothing if already shut down."""
        if not self._ok:
            return
        self._ok = False
        for cb in list(self._shutdown_callbacks):
            try:
                cb()
            except Exception:  # noqa: BLE001 - shutdown must finish
                _log.exception("on_shutdown callback failed")
        for node in list(self._nodes):
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001
                _log.exception("destroying node %s failed", node)
        if self._finalizer is not None:
            self._finalizer()  # closes the transport exactly once
        self.notify()

    def on_shutdown(self, callback: Callable[[], None]) -> None:
        """Call ``callback()`` when the context shuts down."""
        self._shutdown_callbacks.append(callback)

    def __enter__(self) -> Context:
        if not self._ok:
            self.init()
        return self

    def __exit__(self, *exc: object) -> None:
        self.try_shutdown()

    # -- nodes and graph ---------------------------------------------------------------------
    def _add_node(self, node: Node) -> None:
        self._nodes.append(node)
        self.registry.add_node(node)
        self.notify()

    def _remove_node(self, node: Node) -> None:
        if node in self._nodes:
            self._nodes.remove(node)
        self.registry.remove_node(node)
        self.notify()

    @property
    def nodes(self) -> list[Node]:
        return list(self._nodes)

    def graph(self) -> GraphQueries:
        """The ROS graph as this context sees it (own entities and, with Zenoh, the wire)."""
        return GraphQueries(self.transport.endpoints())

    # -- waking ------------------------------------------------------------------------------
    def notify(self) -> None:
        """Wake everyone waiting on this context (new message, new server, graph change, ...)."""
        with self._cond:
            self._generation += 1
            self._cond.notify_all()

    def wait_for(self, predicate: Callable[[], bool], timeout_sec: float) -> bool:
        """Wait until ``predicate()`` holds; re-checked on every ``notify()``. Returns its last value."""
        deadline = time.monotonic() + max(0.0, timeout_sec)
        while True:
            with self._cond:
                gen = self._generation
            if predicate():
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not self._ok:
                return predicate()
            with self._cond:
                if self._generation == gen:
                    self._cond.wait(min(remaining, self._poll_sec))

    def wait_changed(self, generation: int, timeout_sec: float) -> None:
        """Block until ``notify()`` was called after ``generation`` was read, or ``timeout_sec`` passed."""
        with self._cond:
            if self._generation == generation:
                self._cond.wait(timeout_sec)

    @property
    def generation(self) -> int:
        return self._generation

    def __repr__(self) -> str:
        state = "ok" if self._ok else "shut down"
        return f"Context(transport={self.transport_name!r}, domain_id={self.domain_id}, {state})"


def _domain_id(value: int | None, env: Mapping[str, str]) -> int:
    if value is None:
        raw = env.get("ROS_DOMAIN_ID", "").strip()
        if not raw:
            return 0
        try:
            value = int(raw)
        except ValueError:
            raise ValueError(f"ROS_DOMAIN_ID={raw!r} is not an integer; unset it or use 0-232") from None
    if not 0 <= int(value) <= 232:
        raise ValueError(f"ROS domain id {value} is out of range; use 0-232")
    return int(value)


class _DefaultContextHolder:
    # The one convenience global, as in rclpy: init()/shutdown() without an explicit context.
    context: Context | None = None
    lock = threading.Lock()


def get_default_context(*, create: bool = True) -> Context:
    """The default context used when ``context=`` is omitted."""
    with _DefaultContextHolder.lock:
        if _DefaultContextHolder.context is None and create:
            _DefaultContextHolder.context = Context()
        if _DefaultContextHolder.context is None:
            raise NotInitializedException("the default context")
        return _DefaultContextHolder.context


def _set_default_context(context: Context) -> None:
    with _DefaultContextHolder.lock:
        _DefaultContextHolder.context = context

