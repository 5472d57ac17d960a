"""``ActionClient`` and ``ClientGoalHandle``, shaped like ``rclpy.action.client``.

Futures complete on their own (no spinning needed, as for service clients). Feedback callbacks
run on a thread of the client's, one at a time in the order the feedback arrived, without the node
lock; a goal's result completes after the feedback that arrived before it has been delivered, so a
feedback callback must not wait for a result of the same client (it would wait for itself until the
wait's timeout). Status is applied in the thread that delivers it.

A result request waits on the server until the goal ends. Over the wire each request is bounded
by the context's ``default_timeout_sec`` and asked again while the server is there, so a goal may
run longer than that; the caller bounds its own wait (``get_result(timeout_sec=...)`` or
``Future.wait``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from multiros.ros.action._common import (
    CANCEL_GOAL,
    FEEDBACK,
    GET_RESULT,
    SEND_GOAL,
    STATUS,
    STATUS_UNKNOWN,
    TERMINAL_STATES,
    action_types,
    new_uuid,
    qos_profile_action_feedback_default,
    qos_profile_action_status_default,
    uuid_bytes,
)
from multiros.ros.exceptions import ServiceCallError, ServiceTimeoutError
from multiros.ros.qos import QoSProfile, qos_profile_services_default
from multiros.ros.task import Future

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["ActionClient", "ClientGoalHandle"]

_log = logging.getLogger(__name__)
#: Feedback messages that may wait for their callbacks; a newer one drops the oldest.
MAX_QUEUED_FEEDBACK = 1000


class _FeedbackDelivery:
    """Feedback in arrival order, handed to the goals' callbacks by one thread of the client's.

    The transport's receive thread only queues a message (``put``), so it is queued before the
    transport reads what followed it on the same link, the server's answer to a result request
    among them. A goal's result is queued too, behind its feedback: a short goal's
    result could otherwise complete, and its feedback callback be forgotten, before the feedback
    published ahead of it had been delivered (seen under load over Zenoh: all of it lost).
    """

    def __init__(self, name: str) -> None:
        self._name = name
        self._items: deque[tuple[bool, Callable[[], None]]] = deque()  # (feedback, deliver)
        self._feedback_queued = 0
        self.dropped = 0  # feedback messages dropped because MAX_QUEUED_FEEDBACK were waiting
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        self._closed = False

    def put(self, deliver: Callable[[], None], *, feedback: bool = False) -> None:
        """Queue ``deliver`` behind everything queued before it (any thread; never blocks long).
        Once closed, run it at once: feedback then finds no callback, and a result still completes.
        At most :data:`MAX_QUEUED_FEEDBACK` feedback messages wait: a newer one drops the oldest (a flood
        of them, forged or not, must not hold a goal's result back); results are never dropped."""
        with self._cond:
            closed = self._closed
            if not closed:
                if feedback:
                    if self._feedback_queued >= MAX_QUEUED_FEEDBACK:
                        self._drop_oldest_feedback()
                    self._feedback_queued += 1
                self._items.append((feedback, deliver))
                if self._thread is None:
                    self._thread = threading.Thread(target=self._run, name=f"feedback {self._name}", daemon=True)
                    self._thread.start()
                self._cond.notify()
        if closed:
            deliver()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._items and not self._closed:
                    self._cond.wait()
                if not self._items:
                    return  # closed, and everything queued before closing was delivered
                feedback, deliver = self._items.popleft()
                self._feedback_queued -= feedback
            try:
                deliver()
            except Exception:  # noqa: BLE001 - the thread must outlive a failing callback
                _log.exception("a feedback callback of action '%s' raised", self._name)

    def _drop_oldest_feedback(self) -> None:
        for i, (feedback, _) in enumerate(self._items):
            if feedback:
                del self._items[i]
                self._feedback_queued -= 1
                if self.dropped == 0:
                    _log.warning("action '%s': more than %d feedback messages waiting; dropping the oldest",
                                 self._name, MAX_QUEUED_FEEDBACK)
                self.dropped += 1
                return

    def close(self) -> None:
        """Deliver what is queued, then stop the thread (waits for it unless called on it)."""
        with self._cond:
            self._closed = True
            self._cond.notify()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5.0)


class ClientGoalHandle:
    """A goal sent by an ``ActionClient``. Created by the client; never construct it."""

    def __init__(self, client: ActionClient, goal_id: Any, response: Any) -> None:
        self._client = client
        self._goal_id = goal_id
        self._accepted = bool(response.accepted)
        self._stamp = response.stamp
        self._status = STATUS_UNKNOWN
        self._result_future: Future | None = None

    @property
    def goal_id(self) -> Any:
        """The goal id (``unique_identifier_msgs/msg/UUID``)."""
        return self._goal_id

    @property
    def stamp(self) -> Any:
        """When the server accepted (or rejected) the goal."""
        return self._stamp

    @property
    def accepted(self) -> bool:
        return self._accepted

    @property
    def status(self) -> int:
        """The last ``action_msgs/msg/GoalStatus`` value seen (status topic or result)."""
        return self._status

    def get_result_async(self) -> Future:
        """A future of the ``GetResult`` response (``.status`` and ``.result``).

        Raises:
            RuntimeError: the goal was rejected.
        """
        if not self._accepted:
            raise RuntimeError("the goal was rejected: it has no result")
        if self._result_future is None:
            self._result_future = self._client._get_result_async(self)
        return self._result_future

    def get_result(self, timeout_sec: float | None = None) -> Any:
        """Wait for the result; ``None`` waits the context's ``default_timeout_sec``.

        Raises:
            ServiceTimeoutError: no result within ``timeout_sec`` (the goal keeps running).
            ServiceCallError: the server failed or went away.
        """
        return self._client._wait(self.get_result_async(), timeout_sec, GET_RESULT)

    def cancel_goal_async(self) -> Future:
        """Ask the server to cancel this goal; a future of the ``CancelGoal`` response."""
        return self._client._cancel_goal_async(self)

    def cancel_goal(self, timeout_sec: float | None = None) -> Any:
        """``cancel_goal_async`` and wait for the response."""
        return self._client._wait(self.cancel_goal_async(), timeout_sec, CANCEL_GOAL)

    def __repr__(self) -> str:
        state = "accepted" if self._accepted else "rejected"
        return f"ClientGoalHandle({uuid_bytes(self._goal_id).hex()}, {state}, status={self._status})"


class ActionClient:
    """A client of the action ``action_name``.

    Args:
        node: the node the client belongs to.
        action_type: the action class (``get_action("pkg/action/Name")``).
        action_name: the action's name (relative, absolute or ``~/``).

    Raises:
        TypeError: ``action_type`` is not an action type.
    """

    def __init__(
        self,
        node: Node,
        action_type: Any,
        action_name: str,
        *,
        goal_service_qos_profile: QoSProfile = qos_profile_services_default,
        result_service_qos_profile: QoSProfile = qos_profile_services_default,
        cancel_service_qos_profile: QoSProfile = qos_profile_services_default,
        feedback_sub_qos_profile: QoSProfile = qos_profile_action_feedback_default,
        status_sub_qos_profile: QoSProfile = qos_profile_action_status_default,
        callback_group: Any = None,
    ) -> None:
        self._node = node
        self._context = node.context
        self._types = action_types(action_type)
        self._action_type = action_type
        self._name = node.resolve_service_name(action_name)
        self._lock = threading.Lock()
        self._feedback_callbacks: dict[bytes, Callable[[Any], None]] = {}
        self._handles: dict[bytes, ClientGoalHandle] = {}
        self._last_status: Any = None
        self._destroyed = False
        t = self._types
        self._goal_client = node.create_client(t.send_goal, self._name + SEND_GOAL,
                                               qos_profile=goal_service_qos_profile)
        self._cancel_client = node.create_client(t.cancel_goal, self._name + CANCEL_GOAL,
                                                 qos_profile=cancel_service_qos_profile)
        self._result_client = node.create_client(t.get_result, self._name + GET_RESULT,
                                                 qos_profile=result_service_qos_profile)
        self._feedback = _FeedbackDelivery(self._name)
        self._feedback_sub = node.create_subscription(t.feedback_message, self._name + FEEDBACK,
                                                      self._on_feedback, feedback_sub_qos_profile)
        self._feedback_sub._deliver_directly(wire_inline=True)  # queued in wire order with the replies
        self._status_sub = node.create_subscription(t.status_array, self._name + STATUS,
                                                    self._on_status, status_sub_qos_profile)
        self._status_sub._deliver_directly()
        node.add_waitable(self)

    @property
    def action_name(self) -> str:
        return self._name

    @property
    def action_type(self) -> Any:
        return self._action_type

    # -- readiness ---------------------------------------------------------------------------
    def server_is_ready(self) -> bool:
        """Whether the action's three services are known."""
        return all(c.service_is_ready() for c in (self._goal_client, self._cancel_client, self._result_client))

    def wait_for_server(self, timeout_sec: float | None = None) -> bool:
        """Wait until the server is ready; ``False`` after ``timeout_sec`` (``None``: the
        context's ``default_timeout_sec``)."""
        timeout = self._context.default_timeout_sec if timeout_sec is None else float(timeout_sec)
        return self._context.wait_for(self.server_is_ready, timeout)

    # -- goals -------------------------------------------------------------------------------
    def send_goal_async(
        self, goal: Any, feedback_callback: Callable[[Any], None] | None = None, goal_uuid: Any = None,
        *, timeout_sec: float | None = None,
    ) -> Future:
        """Send ``goal``; a future of the ``ClientGoalHandle`` (check ``.accepted``).

        ``feedback_callback(feedback_message)`` gets this goal's ``X_FeedbackMessage`` messages
        (``.feedback`` holds the action's Feedback). ``timeout_sec`` bounds the wait for the
        server's answer (default: the context's ``default_timeout_sec``); the future then fails.

        Raises:
            TypeError: ``goal`` is not the action's Goal message.
            RuntimeError: the client was destroyed.
        """
        t = self._types
        if not isinstance(goal, t.goal):
            raise TypeError(f"action '{self._name}': send_goal expects {t.goal._type}, got {type(goal).__name__}")
        if self._destroyed:
            raise RuntimeError(f"action client of '{self._name}' was destroyed")
        gid = new_uuid() if goal_uuid is None else uuid_bytes(goal_uuid)
        goal_id = t.uuid(uuid=gid)
        if feedback_callback is not None:
            with self._lock:
                self._feedback_callbacks[gid] = feedback_callback
        outer = Future(self._context.notify)
        sent = self._goal_client.call_async(t.send_goal.Request(goal_id=goal_id, goal=goal), timeout_sec=timeout_sec)

        def on_response(done: Future) -> None:
            exc = done.exception()
            if exc is not None or done.cancelled():
                self._forget(gid)
                outer.set_exception(exc or ServiceCallError(self._name + SEND_GOAL, "request cancelled"))
                return
            handle = ClientGoalHandle(self, goal_id, done.result())
            if handle.accepted:
                with self._lock:
                    self._handles[gid] = handle
                self._apply_status(self._last_status, {gid: handle})  # status may have come first
            else:
                self._forget(gid)
            outer.set_result(handle)

        sent.add_done_callback(on_response)
        return outer

    def send_goal(
        self, goal: Any, feedback_callback: Callable[[Any], None] | None = None, goal_uuid: Any = None,
        timeout_sec: float | None = None,
    ) -> Any:
        """Send ``goal`` and wait for its result; ``None`` if the server rejected it.

        ``timeout_sec`` bounds the whole wait (``None``: the context's ``default_timeout_sec``).

        Raises:
            ServiceTimeoutError: no answer or no result in time (the goal keeps running).
            ServiceCallError: the server failed or went away.
        """
        timeout = self._context.default_timeout_sec if timeout_sec is None else float(timeout_sec)
        deadline = time.monotonic() + timeout
        handle = self._wait(self.send_goal_async(goal, feedback_callback, goal_uuid), timeout, SEND_GOAL)
        if not handle.accepted:
            return None
        return self._wait(handle.get_result_async(), max(0.0, deadline - time.monotonic()), GET_RESULT)

    def _wait(self, future: Future, timeout_sec: float | None, suffix: str) -> Any:
        timeout = self._context.default_timeout_sec if timeout_sec is None else float(timeout_sec)
        if not future.wait(timeout):
            raise ServiceTimeoutError(self._name + suffix, timeout, "no answer from the action server")
        return future.result()

    def _cancel_goal_async(self, handle: ClientGoalHandle) -> Future:
        t = self._types
        info = t.goal_info(goal_id=handle.goal_id)
        return self._cancel_client.call_async(t.cancel_goal.Request(goal_info=info))

    def _get_result_async(self, handle: ClientGoalHandle) -> Future:
        gid = uuid_bytes(handle.goal_id)
        request = self._types.get_result.Request(goal_id=handle.goal_id)
        outer = Future(self._context.notify)
        per_request = self._context.default_timeout_sec

        def attempt() -> None:
            started = time.monotonic()
            pending = self._result_client.call_async(request, timeout_sec=per_request)

            def on_reply(done: Future) -> None:
                exc = done.exception()
                if (isinstance(exc, ServiceTimeoutError) and not outer.done() and not self._destroyed
                        and self._context.ok() and time.monotonic() - started >= 0.9 * per_request
                        and self._result_client.service_is_ready()):
                    attempt()  # the goal is still running: ask again
                    return
                if exc is not None or done.cancelled():
                    outer.set_exception(exc or ServiceCallError(self._name + GET_RESULT, "request cancelled"))
                    return
                response = done.result()

                def complete() -> None:
                    handle._status = int(response.status)
                    self._forget(gid)
                    outer.set_result(response)

                self._feedback.put(complete)  # after the feedback that arrived before the result

            pending.add_done_callback(on_reply)

        attempt()
        return outer

    def _forget(self, gid: bytes) -> None:
        with self._lock:
            self._feedback_callbacks.pop(gid, None)
            self._handles.pop(gid, None)

    # -- topics (run in the delivering thread) ------------------------------------------------
    def _on_feedback(self, msg: Any) -> None:
        gid = bytes(msg.goal_id.uuid)
        if gid not in self._feedback_callbacks:  # no goal of ours waits for it (forged, or a goal that ended)
            return

        def deliver() -> None:
            callback = self._feedback_callbacks.get(gid)
            if callback is not None:
                callback(msg)

        self._feedback.put(deliver, feedback=True)

    def _on_status(self, msg: Any) -> None:
        self._last_status = msg
        self._apply_status(msg, self._handles)

    @staticmethod
    def _apply_status(msg: Any, handles: dict[bytes, ClientGoalHandle]) -> None:
        if msg is None or not handles:
            return
        for status in msg.status_list:
            handle = handles.get(bytes(status.goal_info.goal_id.uuid))
            if handle is not None and handle._status not in TERMINAL_STATES:
                handle._status = int(status.status)

    # -- teardown ----------------------------------------------------------------------------
    def destroy(self) -> None:
        """Destroy the client's services and subscriptions."""
        if self._destroyed:
            return
        self._destroyed = True
        node = self._node
        for cli in (self._goal_client, self._cancel_client, self._result_client):
            node.destroy_client(cli)
        node.destroy_subscription(self._feedback_sub)
        node.destroy_subscription(self._status_sub)
        with self._lock:
            self._feedback_callbacks.clear()
            self._handles.clear()
        self._feedback.close()  # results already queued still complete
        node.remove_waitable(self)

    def __repr__(self) -> str:
        return f"ActionClient({self._name!r}, {self._types.name})"
