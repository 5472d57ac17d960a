"""``Subscription``: created by ``Node.create_subscription``; callbacks run in the executor."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from multiros.ros.graph import type_name_of
from multiros.ros.qos import QoSProfile

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["Subscription"]


class Subscription:
    """Receives messages on one topic into a queue of ``qos_profile.depth`` (oldest dropped).

    The callback runs when an executor spinning the node takes the message, under the node's
    callback lock. Users should not construct this class; call ``Node.create_subscription``.

    ``with_source``: the callback is ``callback(msg, source)``, ``source`` the publisher's
    identity (:attr:`Publisher.gid <multiros.ros.publisher.Publisher.gid>`, the GID of an rmw_zenoh
    attachment; ``None`` where the transport gives none: rclpy).
    """

    def __init__(
        self, node: Node, msg_type: type, topic_name: str, callback: Callable[..., None],
        qos_profile: QoSProfile, with_source: bool = False,
    ) -> None:
        self.node = node
        self.msg_type = msg_type
        self.type_name = type_name_of(msg_type)
        self.topic_name = topic_name
        self.with_source = bool(with_source)
        # The queue holds (msg, source) pairs then, and the callback takes them apart.
        self.callback: Callable[[Any], None] = (lambda item: callback(*item)) if with_source else callback
        self.qos_profile = qos_profile
        self._queue: deque[Any] = deque(maxlen=qos_profile.queue_size)
        self._notify = node.context.notify
        self._wire: Any = None
        self._destroyed = False

    @property
    def topic(self) -> str:
        return self.topic_name

    def _enqueue(self, msg: Any, source: bytes | None = None) -> None:
        # Called by publishers in this process and by transport threads.
        if self._destroyed:
            return
        self._queue.append((msg, source) if self.with_source else msg)
        self._notify()

    def _deliver_directly(self, wire_inline: bool = False) -> None:
        """Run the callback in the delivering thread instead of queueing it for an executor.

        Action clients use this so feedback and status need no spinning (as service replies
        need none). The callback runs without the node lock; it must be short and thread-safe.
        ``wire_inline``: over a wire transport, also run it on the transport's receive thread
        (Zenoh: in order with the service requests that arrive after the message on the same
        link) instead of a delivery thread per subscription; it must then never block.
        """
        self._enqueue = self._run_now  # type: ignore[method-assign]  # shadows the queueing method
        if wire_inline and self._wire is not None and hasattr(self._wire, "deliver_inline"):
            self._wire.deliver_inline()
        while True:
            ok, item = self._take()
            if not ok:
                break
            if self.with_source:
                self._run_now(*item)
            else:
                self._run_now(item)

    def _run_now(self, msg: Any, source: bytes | None = None) -> None:
        if self._destroyed:
            return
        try:
            self.callback((msg, source) if self.with_source else msg)
        except Exception:  # noqa: BLE001 - a transport thread must survive a failing callback
            self.node.get_logger().exception("subscription callback on '%s' raised", self.topic_name)

    def _take(self) -> tuple[bool, Any]:
        try:
            return True, self._queue.popleft()
        except IndexError:
            return False, None

    def get_publisher_count(self) -> int:
        """Publishers on this topic in the graph."""
        return self.node.count_publishers(self.topic_name)

    def destroy(self) -> None:
        """Same as ``Node.destroy_subscription(self)``."""
        self.node.destroy_subscription(self)
