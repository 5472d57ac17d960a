"""``Service``: created by ``Node.create_service``.

Execution model: a call from a client in the same context runs the callback synchronously in
the caller's thread (no queue, no serialization, no copy of the request); a call arriving over
the wire runs it on the transport's receive thread and replies from there. Either way the
node's callback lock is held, so a node's callbacks never run concurrently, unless the service
belongs to a :class:`~multiros.ros.callback_groups.ReentrantCallbackGroup` (no lock) or a
``MutuallyExclusiveCallbackGroup`` (that group's lock). Services therefore answer without anyone
spinning the server node.

Deferred responses: a callback may return a ``Future`` instead of the response (the action
server's ``get_result`` does, to answer when the goal ends). The node lock is released at once;
the reply goes out when the future completes (an in-process caller waits on it, within its
timeout; over Zenoh the query is kept open and answered then).

Who is calling: during a callback, :func:`current_caller` names the client that sent the request,
for accounting (a node's per-client quotas), never for authority: over the wire the identity is
whatever the peer put there. ``inproc:<node>#<n>`` for a client in the same context (one per
``Client`` object), ``zenoh:<gid hex>`` for the GID in an rmw_zenoh request's attachment,
``dds:<guid hex>`` for the writer GUID of a request over rclpy; ``None`` where the transport does
not tell (callers then share one anonymous identity). The prefixes keep one transport's callers
from posing as another's.

Bounded requests: :meth:`Service.bound_requests` names the most bytes (CDR) a request may have, and
for a request type whose first field is a sequence, the most elements it may hold. A transport that
sees a request's encoded bytes before decoding them (rclpy's) does not decode a larger one: the
service's ``refuse`` answers it (a response saying why) or, without one, it is dropped with a throttled
warning, so a flood of huge or many-item requests costs the node no decoding and no callback.
"""

from __future__ import annotations

import contextvars
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from multiros.ros.callback_groups import CallbackGroup
from multiros.ros.exceptions import ServiceCallError, ServiceTimeoutError
from multiros.ros.graph import type_name_of
from multiros.ros.qos import QoSProfile
from multiros.ros.task import Future

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["Service", "current_caller"]

_caller: contextvars.ContextVar[str | None] = contextvars.ContextVar("multiros_service_caller", default=None)


def current_caller() -> str | None:
    """The client whose request the running service callback serves (see the module docstring);
    ``None`` outside a callback or where the transport does not know it."""
    return _caller.get()


class Service:
    """Serves requests with ``callback(request, response) -> response``."""

    def __init__(
        self, node: Node, srv_type: Any, srv_name: str, callback: Callable[[Any, Any], Any],
        qos_profile: QoSProfile, callback_group: CallbackGroup | None = None,
    ) -> None:
        self.node = node
        self.srv_type = srv_type
        self.type_name = type_name_of(srv_type)
        self.srv_name = srv_name
        self.callback = callback
        self.qos_profile = qos_profile
        self._response_cls = srv_type.Response
        self._lock = node._callback_lock if callback_group is None else callback_group.lock
        self._wire: Any = None
        self.max_request_bytes: int | None = None
        self.max_request_items: int | None = None
        self._refuse: Callable[[str, Any], Any] | None = None

    def bound_requests(self, max_bytes: int, refuse: Callable[[str, Any], Any] | None = None, *,
                       max_items: int | None = None) -> None:
        """Requests of more than ``max_bytes`` bytes (CDR), or (``max_items``, for a request type whose first
        field is a sequence) more than ``max_items`` elements in it, are not decoded where the transport can
        tell (see the module docstring): ``refuse(why, response) -> response`` answers them (``why``: "a
        request of 300,000 bytes; at most 262,144"), or they are dropped."""
        if max_bytes < 1:
            raise ValueError(f"service '{self.srv_name}': max_bytes must be >= 1, not {max_bytes}")
        if max_items is not None and max_items < 0:
            raise ValueError(f"service '{self.srv_name}': max_items must be >= 0, not {max_items}")
        self.max_request_bytes = int(max_bytes)
        self.max_request_items = None if max_items is None else int(max_items)
        self._refuse = refuse

    def over_bound(self, data: bytes | bytearray | memoryview) -> str | None:
        """Why the CDR bytes of a request are over this service's bounds (never decoded), or None."""
        from multiros.ros.interfaces import first_sequence_length

        limit = self.max_request_bytes
        if limit is not None and len(data) > limit:
            return f"a request of {len(data):,} bytes; at most {limit:,}"
        most = self.max_request_items
        if most is not None:
            items = first_sequence_length(data)
            if items is not None and items > most:
                return f"a request of {items:,} items; at most {most:,}"
        return None

    def _refused(self, why: str) -> Any:
        """The answer to a request over the bounds (``why``: :meth:`over_bound`'s): the refusal's
        response, or None (dropped)."""
        if self._refuse is None:
            return None
        try:
            return self._refuse(why, self._response_cls())
        except Exception as exc:
            raise ServiceCallError(self.srv_name, f"refusing an oversize request raised {type(exc).__name__}: "
                                                  f"{exc}") from exc

    @property
    def service_name(self) -> str:
        return self.srv_name

    def _call(self, request: Any, caller: str | None = None) -> Any:
        """Run the callback under the node lock, with :func:`current_caller` answering ``caller``;
        wrap its failures in ``ServiceCallError``.

        Returns the response, or a ``Future`` of it when the callback deferred its answer.
        """
        lock = self._lock
        if lock is not None:
            lock.acquire()
        token = _caller.set(caller)
        try:
            response = self.callback(request, self._response_cls())
        except Exception as exc:
            raise ServiceCallError(
                self.srv_name, f"the service callback raised {type(exc).__name__}: {exc}"
            ) from exc
        finally:
            _caller.reset(token)
            if lock is not None:
                lock.release()
        if response is None:
            raise ServiceCallError(self.srv_name, "the service callback returned None; it must return the response")
        return response

    def _call_wait(self, request: Any, timeout_sec: float, caller: str | None = None) -> Any:
        """``_call`` that waits up to ``timeout_sec`` for a deferred response.

        Raises:
            ServiceTimeoutError: a deferred response did not come in time.
            ServiceCallError: the callback failed.
        """
        response = self._call(request, caller)
        if not isinstance(response, Future):
            return response
        if not response.wait(timeout_sec):
            raise ServiceTimeoutError(self.srv_name, timeout_sec, "the deferred response did not come")
        return response.result()

    def destroy(self) -> None:
        """Same as ``Node.destroy_service(self)``."""
        self.node.destroy_service(self)
