"""``Service``: created by ``Node.create_service``.

Execution model: a call from a client in the same context runs the callback synchronously in
the caller's thread (no queue, no serialization, no copy of the request); a call arriving over
the wire runs it on the transport's receive thread and replies from there. Either way the
node's callback lock is held, so a node's callbacks never run concurrently. Services therefore
answer without anyone spinning the server node.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from multiros.ros.exceptions import ServiceCallError
from multiros.ros.graph import type_name_of
from multiros.ros.qos import QoSProfile

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["Service"]


class Service:
    """Serves requests with ``callback(request, response) -> response``."""

    def __init__(
        self, node: Node, srv_type: Any, srv_name: str, callback: Callable[[Any, Any], Any],
        qos_profile: QoSProfile,
    ) -> None:
        self.node = node
        self.srv_type = srv_type
        self.type_name = type_name_of(srv_type)
        self.srv_name = srv_name
        self.callback = callback
        self.qos_profile = qos_profile
        self._response_cls = srv_type.Response
        self._lock = node._callback_lock
        self._wire: Any = None

    @property
    def service_name(self) -> str:
        return self.srv_name

    def _call(self, request: Any) -> Any:
        """Run the callback under the node lock; wrap its failures in ``ServiceCallError``."""
        with self._lock:
            try:
                response = self.callback(request, self._response_cls())
            except Exception as exc:
                raise ServiceCallError(
                    self.srv_name, f"the service callback raised {type(exc).__name__}: {exc}"
                ) from exc
        if response is None:
            raise ServiceCallError(self.srv_name, "the service callback returned None; it must return the response")
        return response

    def destroy(self) -> None:
        """Same as ``Node.destroy_service(self)``."""
        self.node.destroy_service(self)
