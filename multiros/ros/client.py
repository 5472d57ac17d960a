"""``Client``: created by ``Node.create_client``.

``call`` first looks for a server in the same context and calls it directly (the training hot
path: one dict lookup, one uncontended lock, the callback); otherwise it goes over the
transport. Every wait is bounded: ``timeout_sec=None`` means the context's
``default_timeout_sec`` (10 s unless configured), not "forever" as in rclpy.
"""

from __future__ import annotations

import itertools
import time
from typing import TYPE_CHECKING, Any

from multiros.ros.exceptions import ServiceCallError, ServiceTimeoutError
from multiros.ros.graph import type_name_of
from multiros.ros.qos import QoSProfile
from multiros.ros.registry import type_key
from multiros.ros.task import Future

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["Client"]

_client_ids = itertools.count(1)


class Client:
    """Calls one service. Users should not construct this class; call ``Node.create_client``."""

    def __init__(self, node: Node, srv_type: Any, srv_name: str, qos_profile: QoSProfile) -> None:
        self.node = node
        self.context = node.context
        self.srv_type = srv_type
        self.type_name = type_name_of(srv_type)
        self.srv_name = srv_name
        self.qos_profile = qos_profile
        self._services = node.context.registry.services
        # In-process servers match on name and type hash, as on the Zenoh wire.
        self._key = (srv_name, type_key(srv_type))
        self._wire: Any = None  # transport handle: call(), call_async(), service_is_ready(), close()
        #: who this client is to a server in the same context (``multiros.ros.service.current_caller``)
        self.caller_id = f"inproc:{node.get_fully_qualified_name()}#{next(_client_ids)}"

    @property
    def service_name(self) -> str:
        return self.srv_name

    def service_is_ready(self) -> bool:
        """Whether a server is known (in this context or, with Zenoh, in the graph)."""
        if self._key in self._services:
            return True
        wire = self._wire
        return wire is not None and wire.service_is_ready()

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        """Wait until a server is available; returns ``False`` after ``timeout_sec``.

        ``None`` waits up to the context's ``default_timeout_sec``.
        """
        timeout = self.context.default_timeout_sec if timeout_sec is None else timeout_sec
        return self.context.wait_for(self.service_is_ready, timeout)

    def call(self, request: Any, timeout_sec: float | None = None) -> Any:
        """Call the service and return its response.

        Raises:
            ServiceTimeoutError: no server appeared or no reply came within ``timeout_sec``
                (a ``TimeoutError``).
            ServiceCallError: the server raised or replied with an error, or went away.
        """
        srv = self._services.get(self._key)
        if srv is not None:
            return srv._call_wait(request, self._timeout(timeout_sec), self.caller_id)
        return self._call_remote(request, timeout_sec)

    def _timeout(self, timeout_sec: float | None) -> float:
        return self.context.default_timeout_sec if timeout_sec is None else float(timeout_sec)

    def _call_remote(self, request: Any, timeout_sec: float | None) -> Any:
        timeout = self._timeout(timeout_sec)
        start = time.monotonic()
        if not self.wait_for_service(timeout):
            raise ServiceTimeoutError(self.srv_name, timeout, "no server available")
        remaining = max(0.0, timeout - (time.monotonic() - start))
        srv = self._services.get(self._key)
        if srv is not None:
            return srv._call_wait(request, remaining, self.caller_id)
        return self._wire.call(request, remaining, timeout)

    def call_async(self, request: Any, *, timeout_sec: float | None = None) -> Future:
        """Send the request and return a ``Future`` for the response.

        With a server in the same context the future is already done when this returns (unless
        the server defers its response). ``timeout_sec`` bounds a call over the wire (default:
        the context's ``default_timeout_sec``); the future then fails with ``ServiceTimeoutError``.
        """
        future = Future(self.context.notify)
        srv = self._services.get(self._key)
        if srv is not None:
            try:
                response = srv._call(request, self.caller_id)
            except ServiceCallError as exc:
                future.set_exception(exc)
                return future
            if isinstance(response, Future):
                name = self.srv_name
                response.add_done_callback(lambda done: _chain(done, future, name))
            else:
                future.set_result(response)
            return future
        wire = self._wire
        if wire is None:
            future.set_exception(
                ServiceCallError(self.srv_name, "no server available in this context; call wait_for_service() first")
            )
            return future
        wire.call_async(request, future, self._timeout(timeout_sec))
        return future

    def remove_pending_request(self, future: Future) -> None:
        """Forget a pending request (its future is cancelled)."""
        future.cancel()

    def destroy(self) -> None:
        """Same as ``Node.destroy_client(self)``."""
        self.node.destroy_client(self)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.destroy()


def _chain(source: Future, target: Future, name: str) -> None:
    """Complete ``target`` as ``source`` completed (a deferred in-process response)."""
    exc = source.exception()
    if exc is not None:
        target.set_exception(exc)
    elif source.cancelled():
        target.set_exception(ServiceCallError(name, "the server gave up on the request"))
    else:
        target.set_result(source.result())
