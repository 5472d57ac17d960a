"""The ROS graph as a list of endpoint records, and the queries rclpy answers from it.

Both transports describe the graph the same way: the in-process registry lists its entities,
the Zenoh transport parses rmw_zenoh liveliness tokens into the same records.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

__all__ = ["Endpoint", "NODE", "PUBLISHER", "SUBSCRIPTION", "SERVICE", "CLIENT", "GraphQueries"]

NODE, PUBLISHER, SUBSCRIPTION, SERVICE, CLIENT = "NN", "MP", "MS", "SS", "SC"


class Endpoint(NamedTuple):
    """One graph entity: a node (``kind == NODE``) or a node's endpoint."""

    kind: str
    node_name: str
    namespace: str
    name: str = ""
    type_name: str = ""
    qos: object = None
    origin: str = ""  # session id for wire entities, "" for this context's own
    #: The entity's identity as its messages carry it (:attr:`Publisher.gid`: rmw_zenoh's attachment
    #: GID over Zenoh); ``b""`` where the transport gives none (rclpy).
    gid: bytes = b""


class GraphQueries:
    """rclpy's graph queries over a list of endpoints."""

    def __init__(self, endpoints: Iterable[Endpoint]) -> None:
        self.endpoints = list(endpoints)

    def node_names_and_namespaces(self) -> list[tuple[str, str]]:
        seen = {(e.node_name, e.namespace) for e in self.endpoints if e.kind == NODE}
        return sorted(seen)

    def _names_and_types(self, kinds: tuple[str, ...]) -> list[tuple[str, list[str]]]:
        table: dict[str, set[str]] = {}
        for e in self.endpoints:
            if e.kind in kinds:
                table.setdefault(e.name, set()).add(e.type_name)
        return [(name, sorted(types)) for name, types in sorted(table.items())]

    def topic_names_and_types(self) -> list[tuple[str, list[str]]]:
        return self._names_and_types((PUBLISHER, SUBSCRIPTION))

    def service_names_and_types(self) -> list[tuple[str, list[str]]]:
        return self._names_and_types((SERVICE, CLIENT))

    def count(self, kind: str, name: str) -> int:
        return sum(1 for e in self.endpoints if e.kind == kind and e.name == name)

    def endpoints_of(self, kind: str, name: str) -> list[Endpoint]:
        """The endpoints of ``kind`` called ``name`` (e.g. every publisher of a topic)."""
        return [e for e in self.endpoints if e.kind == kind and e.name == name]

    def by_node(self, kind: str, node_name: str, namespace: str) -> list[tuple[str, list[str]]]:
        table: dict[str, set[str]] = {}
        for e in self.endpoints:
            if e.kind == kind and e.node_name == node_name and e.namespace == namespace:
                table.setdefault(e.name, set()).add(e.type_name)
        return [(name, sorted(types)) for name, types in sorted(table.items())]


def type_name_of(cls: object) -> str:
    """The ROS type name of a message/service class (``_type``), or ``module/QualName`` for any other class."""
    name = getattr(cls, "_type", None)
    if isinstance(name, str):
        return name
    return f"{getattr(cls, '__module__', '?')}/{getattr(cls, '__qualname__', type(cls).__name__)}"
