"""Callback groups, as in rclpy: which callbacks of a node may run at the same time.

By default a node's callbacks never run concurrently: each runs under the node's lock (rclpy's
default ``MutuallyExclusiveCallbackGroup``). A service created with a
:class:`ReentrantCallbackGroup` runs without that lock, so calls that arrive on several transport
threads run side by side: for a node that guards its own state with locks of its own and must
answer a quick request while a slow one is in progress (the simulation node's services). A
:class:`MutuallyExclusiveCallbackGroup` serialises the callbacks of its members only.

Groups apply to services (``Node.create_service(..., callback_group=...)``); subscription and
timer callbacks always run under the node's lock.
"""

from __future__ import annotations

import threading
from typing import Any

__all__ = ["CallbackGroup", "MutuallyExclusiveCallbackGroup", "ReentrantCallbackGroup"]


class CallbackGroup:
    """Base class: :attr:`lock` is held around each member's callback (``None``: no lock)."""

    lock: Any = None


class MutuallyExclusiveCallbackGroup(CallbackGroup):
    """Members' callbacks run one at a time (reentrant: a callback may call another member in-process)."""

    def __init__(self) -> None:
        self.lock = threading.RLock()


class ReentrantCallbackGroup(CallbackGroup):
    """Members' callbacks may run at the same time, in whatever threads deliver them."""

    lock = None
