"""The in-process registry of one ``Context``: who publishes, subscribes and serves what.

It routes messages and service calls between nodes of the same context directly, with no
serialization and no thread hop (like rclcpp intra-process communication), whatever the
transport. The transport adds the wire on top.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any

from multiros.ros.graph import CLIENT, NODE, PUBLISHER, SERVICE, SUBSCRIPTION, Endpoint, type_name_of
from multiros.ros.qos import DurabilityPolicy, qos_compatible

if TYPE_CHECKING:
    from multiros.ros.client import Client
    from multiros.ros.node import Node
    from multiros.ros.publisher import Publisher
    from multiros.ros.service import Service
    from multiros.ros.subscription import Subscription

__all__ = ["LocalRegistry", "type_key"]

_log = logging.getLogger(__name__)


def type_key(interface_type: object) -> str:
    """What the two ends of a topic or service must share to be connected.

    For interface types (messages and services) the RIHS01 type hash, as in the Zenoh key, so the
    variants of one type from different ROS distributions stay apart in-process too; for any other
    class its name.
    """
    if getattr(interface_type, "_registry", None) is not None and (
            hasattr(interface_type, "Request") or hasattr(interface_type, "_type")):
        from multiros.ros.interfaces import type_hash

        return type_hash(interface_type)
    return type_name_of(interface_type)


class LocalRegistry:
    """Entities of one context, indexed by resolved name."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.version = 0  # changes with every entity added or removed (Transport.graph_version)
        self._topics_local = True  # False: the transport delivers topics within the context too
        self.nodes: list[Node] = []
        self.publishers: dict[str, list[Publisher]] = {}
        self.subscriptions: dict[str, list[Subscription]] = {}
        # (name, type key) -> first server; read without a lock on the service-call hot path
        # (dict.get is atomic). Variants of one service (one per type hash) live side by side.
        self.services: dict[tuple[str, str], Service] = {}
        self._service_lists: dict[str, list[Service]] = {}
        self.clients: dict[str, list[Client]] = {}
        # kind -> table, for count(): asked per robot per step by lazy publishers
        self._tables: dict[str, dict[str, list[Any]]] = {
            PUBLISHER: self.publishers, SUBSCRIPTION: self.subscriptions,
            SERVICE: self._service_lists, CLIENT: self.clients,
        }

    def leave_topics_to_transport(self, yes: bool) -> None:
        """Stop (or resume) delivering topic messages within the context: the transport does it."""
        with self._lock:
            self._topics_local = not yes
            for topic in self.publishers:
                self._rewire(topic)

    # -- nodes -------------------------------------------------------------------------------
    def add_node(self, node: Node) -> None:
        with self._lock:
            self.version += 1
            self.nodes.append(node)

    def remove_node(self, node: Node) -> None:
        with self._lock:
            self.version += 1
            if node in self.nodes:
                self.nodes.remove(node)

    # -- topics ------------------------------------------------------------------------------
    def add_publisher(self, pub: Publisher) -> None:
        with self._lock:
            self.version += 1
            self.publishers.setdefault(pub.topic_name, []).append(pub)
            self._rewire(pub.topic_name)

    def remove_publisher(self, pub: Publisher) -> None:
        with self._lock:
            self.version += 1
            pubs = self.publishers.get(pub.topic_name, [])
            if pub in pubs:
                pubs.remove(pub)
            pub._local_subs = ()

    def add_subscription(self, sub: Subscription) -> None:
        with self._lock:
            self.version += 1
            self.subscriptions.setdefault(sub.topic_name, []).append(sub)
            self._rewire(sub.topic_name)
            late = [
                p for p in self.publishers.get(sub.topic_name, [])
                if p._tl_cache is not None and sub in p._local_subs
            ]
        # A transient-local late joiner gets what each matching publisher still holds.
        if sub.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
            for pub in late:
                for msg in list(pub._tl_cache or ()):
                    sub._enqueue(msg, pub.gid)

    def remove_subscription(self, sub: Subscription) -> None:
        with self._lock:
            self.version += 1
            subs = self.subscriptions.get(sub.topic_name, [])
            if sub in subs:
                subs.remove(sub)
            self._rewire(sub.topic_name)

    def _rewire(self, topic: str) -> None:
        subs = self.subscriptions.get(topic, []) if self._topics_local else []
        for pub in self.publishers.get(topic, []):
            matched = []
            for sub in subs:
                if sub.type_name != pub.type_name:
                    _log.warning(
                        "topic '%s': publisher type %s and subscription type %s differ; not connected",
                        topic, pub.type_name, sub.type_name,
                    )
                    continue
                if type_key(sub.msg_type) != type_key(pub.msg_type):
                    continue  # two distributions' variants of one type: side by side, as over Zenoh
                if qos_compatible(pub.qos_profile, sub.qos_profile):
                    matched.append(sub)
            pub._local_subs = tuple(matched)

    # -- services ----------------------------------------------------------------------------
    def add_service(self, srv: Service) -> None:
        key = (srv.srv_name, type_key(srv.srv_type))
        with self._lock:
            self.version += 1
            servers = self._service_lists.setdefault(srv.srv_name, [])
            servers.append(srv)
            same = [s for s in servers if (s.srv_name, type_key(s.srv_type)) == key]
            if len(same) > 1:
                _log.warning("service '%s' (%s) has %d servers in this context; calls go to the first",
                             srv.srv_name, srv.type_name, len(same))
            self.services[key] = same[0]

    def remove_service(self, srv: Service) -> None:
        key = (srv.srv_name, type_key(srv.srv_type))
        with self._lock:
            self.version += 1
            servers = self._service_lists.get(srv.srv_name, [])
            if srv in servers:
                servers.remove(srv)
            same = [s for s in servers if (s.srv_name, type_key(s.srv_type)) == key]
            if same:
                self.services[key] = same[0]
            else:
                self.services.pop(key, None)

    def add_client(self, cli: Client) -> None:
        with self._lock:
            self.version += 1
            self.clients.setdefault(cli.srv_name, []).append(cli)

    def remove_client(self, cli: Client) -> None:
        with self._lock:
            self.version += 1
            clients = self.clients.get(cli.srv_name, [])
            if cli in clients:
                clients.remove(cli)

    # -- graph -------------------------------------------------------------------------------
    def count(self, kind: str, name: str) -> int:
        """Entities of ``kind`` called ``name`` in this context (O(1), no graph listing)."""
        table = self._tables.get(kind)
        if table is None:
            return sum(1 for e in self.endpoints() if e.kind == kind and e.name == name)
        with self._lock:
            return len(table.get(name, ()))

    def endpoints(self) -> list[Endpoint]:
        """This context's entities as graph records."""
        out: list[Endpoint] = []
        with self._lock:
            for node in self.nodes:
                out.append(Endpoint(NODE, node.get_name(), node.get_namespace()))
            for kind, table in (
                (PUBLISHER, self.publishers), (SUBSCRIPTION, self.subscriptions),
                (SERVICE, self._service_lists), (CLIENT, self.clients),
            ):
                for name, entities in table.items():
                    for ent in entities:
                        node = ent.node
                        out.append(Endpoint(kind, node.get_name(), node.get_namespace(), name,
                                            ent.type_name, getattr(ent, "qos_profile", None),
                                            gid=getattr(ent, "gid", b"") if kind == PUBLISHER else b""))
        return out
