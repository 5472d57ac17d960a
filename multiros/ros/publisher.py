"""``Publisher``: created by ``Node.create_publisher``."""

from __future__ import annotations

import os
from collections import deque
from typing import TYPE_CHECKING, Any

from multiros.ros.graph import SUBSCRIPTION, type_name_of
from multiros.ros.qos import DurabilityPolicy, QoSProfile

if TYPE_CHECKING:
    from multiros.ros.node import Node
    from multiros.ros.subscription import Subscription

__all__ = ["Publisher"]


class Publisher:
    """Publishes messages on one topic.

    In-process subscribers get the published object itself (no serialization, no copy), so do
    not mutate a message after publishing it. Users should not construct this class; call
    ``Node.create_publisher``.
    """

    def __init__(self, node: Node, msg_type: type, topic_name: str, qos_profile: QoSProfile) -> None:
        self.node = node
        self.msg_type = msg_type
        self.type_name = type_name_of(msg_type)
        self.topic_name = topic_name
        self.qos_profile = qos_profile
        self._local_subs: tuple[Subscription, ...] = ()
        self._tl_cache: deque[Any] | None = (
            deque(maxlen=qos_profile.queue_size)
            if qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL else None
        )
        self._wire: Any = None  # transport handle with .publish(msg) and .close()
        self._local_gid = os.urandom(16)
        self._destroyed = False
        self._listened_at: int | None = -1  # graph version of the cached has_subscribers answer
        self._listened = False

    @property
    def topic(self) -> str:
        return self.topic_name

    @property
    def gid(self) -> bytes:
        """This publisher's identity, as its messages carry it to a subscription that asks
        (``with_source``) and as the graph lists it (:attr:`Endpoint.gid`): its rmw_zenoh GID over
        Zenoh, a random one of this process otherwise."""
        return getattr(self._wire, "gid", None) or self._local_gid

    def publish(self, msg: Any) -> None:
        """Publish ``msg`` (an instance of the publisher's message type).

        Raises:
            TypeError: ``msg`` is not an instance of the message type.
            RuntimeError: the publisher was destroyed.
        """
        if not isinstance(msg, self.msg_type):
            raise TypeError(
                f"publisher on '{self.topic_name}' expects {self.type_name}, got {type(msg).__name__}"
            )
        if self._destroyed:
            raise RuntimeError(f"publisher on '{self.topic_name}' was destroyed")
        subs = self._local_subs
        if subs:
            gid = self.gid
            for sub in subs:
                sub._enqueue(msg, gid)
        if self._tl_cache is not None:
            self._tl_cache.append(msg)
        wire = self._wire
        if wire is not None:
            wire.publish(msg)

    def has_subscribers(self) -> bool:
        """Whether any subscription listens on this topic: ``get_subscription_count() > 0``, asked
        again only when the graph changed (a lazy publisher's check on every step)."""
        version = self.node.context.transport.graph_version()
        if version is None or version != self._listened_at:
            self._listened = self.get_subscription_count() > 0  # counted after reading the version
            self._listened_at = version
        return self._listened

    def get_subscription_count(self) -> int:
        """Subscriptions on this topic in the graph (this process and, with Zenoh, the wire)."""
        # topic_name is already resolved; skip re-resolving it (this runs on every lazy publish check).
        return self.node.context.transport.count(SUBSCRIPTION, self.topic_name)

    def destroy(self) -> None:
        """Same as ``Node.destroy_publisher(self)``."""
        self.node.destroy_publisher(self)
