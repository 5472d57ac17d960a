"""The transport seam: what a transport adds to the in-process routing of a ``Context``.

The context's ``LocalRegistry`` always connects entities of the same context directly. A
transport makes them visible and reachable beyond it: it returns one handle per entity
(``None`` when it has nothing to add) and answers graph queries. ``inproc``, ``zenoh`` and
``rclpy`` implement this class.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from multiros.ros.client import Client
    from multiros.ros.context import Context
    from multiros.ros.graph import Endpoint
    from multiros.ros.node import Node
    from multiros.ros.publisher import Publisher
    from multiros.ros.service import Service
    from multiros.ros.subscription import Subscription
    from multiros.ros.task import Future

__all__ = ["Transport", "Handle", "PublisherHandle", "ClientHandle"]


class Handle(Protocol):
    """A transport-side entity; ``close()`` undeclares it (idempotent)."""

    def close(self) -> None: ...


class PublisherHandle(Handle, Protocol):
    def publish(self, msg: Any) -> None: ...


class ClientHandle(Handle, Protocol):
    def service_is_ready(self) -> bool: ...

    def call(self, request: Any, timeout_sec: float, total_timeout_sec: float) -> Any: ...

    def call_async(self, request: Any, future: Future, timeout_sec: float) -> None: ...


class Transport(ABC):
    """One transport instance per ``Context``."""

    name: str = ""
    #: The transport delivers topic messages between entities of its own context (rclpy cannot
    #: drop a process's own publications): the registry then leaves topics to it.
    delivers_local_topics: bool = False
    #: whether nodes serve their parameters (rcl_interfaces services) on it: where ROS tools reach them
    serves_parameters: bool = False
    #: Longest a ``Context.wait_for`` sleeps between checks of its predicate; a transport that
    #: announces no graph changes (``Context.notify``) sets it short.
    poll_sec: float = 1.0

    def __init__(self, context: Context) -> None:
        self.context = context

    @abstractmethod
    def open(self) -> None:
        """Start sessions/threads. Raises ``TransportError`` naming what failed."""

    @abstractmethod
    def close(self) -> None:
        """Stop everything ``open`` started; idempotent, safe at interpreter exit."""

    def add_node(self, node: Node) -> Handle | None:
        return None

    def add_publisher(self, pub: Publisher) -> PublisherHandle | None:
        return None

    def add_subscription(self, sub: Subscription) -> Handle | None:
        return None

    def add_service(self, srv: Service) -> Handle | None:
        return None

    def add_client(self, cli: Client) -> ClientHandle | None:
        return None

    def reach(self) -> str:
        """How this transport reaches other programs, for messages (``the Zenoh router ...``)."""
        return f"the {self.name or type(self).__name__} transport (this process only)"

    def graph_version(self) -> int | None:
        """A number that changes whenever :meth:`count` may answer differently; ``None`` when the
        transport keeps none (callers then ask :meth:`count` every time)."""
        return None

    def count(self, kind: str, name: str) -> int:
        """How many graph entities of ``kind`` are called ``name``.

        Publishers ask this on every publish-if-anyone-listens check, so transports answer it from
        an index instead of listing the whole graph.
        """
        return sum(1 for e in self.endpoints() if e.kind == kind and e.name == name)

    @abstractmethod
    def endpoints(self) -> list[Endpoint]:
        """Every graph entity this transport knows (including this context's own)."""
