"""``ActionServer`` and ``ServerGoalHandle``, shaped like ``rclpy.action.server``.

Execution model (differs from rclpy on purpose, as services here need no executor):

* ``goal_callback``, ``cancel_callback`` and ``handle_accepted_callback`` run inside the
  send_goal / cancel_goal service callbacks (under the node's callback lock): keep them short.
* ``execute_callback`` runs on a thread of its own per goal (started by
  ``ServerGoalHandle.execute()``), without the node lock, so a long goal never blocks the node's
  services. It must return the ``Result`` after calling ``succeed()``, ``abort()`` or
  ``canceled()`` on the handle (without one of them the goal is aborted, as rclpy does).
* ``get_result`` requests for a running goal are answered when it ends (deferred response).

Bounds: at most ``max_goals`` goals are active at once (more are rejected before
``goal_callback`` runs); finished goals keep their result for ``result_timeout`` seconds and at
most ``max_results`` of them are kept (oldest dropped first); at most
``MAX_RESULT_WAITERS`` get_result requests wait per goal (the oldest is answered with an error
when more arrive). Goal ids that are all zero or already used are rejected; unknown goal ids in
get_result get status UNKNOWN, in cancel_goal ERROR_UNKNOWN_GOAL_ID.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from multiros.ros.action._common import (
    ACTIVE_STATES,
    CANCEL_GOAL,
    FEEDBACK,
    GET_RESULT,
    SEND_GOAL,
    STATUS,
    STATUS_ABORTED,
    STATUS_ACCEPTED,
    STATUS_CANCELED,
    STATUS_CANCELING,
    STATUS_EXECUTING,
    STATUS_NAMES,
    STATUS_SUCCEEDED,
    STATUS_UNKNOWN,
    TERMINAL_STATES,
    ZERO_UUID,
    ActionTypes,
    CancelResponse,
    GoalEvent,
    GoalResponse,
    action_types,
    qos_profile_action_feedback_default,
    qos_profile_action_status_default,
    stamp_ns,
)
from multiros.ros.exceptions import ServiceCallError
from multiros.ros.qos import QoSProfile, qos_profile_services_default
from multiros.ros.task import Future

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["ActionServer", "ServerGoalHandle", "default_goal_callback", "default_cancel_callback",
           "default_handle_accepted_callback", "MAX_RESULT_WAITERS"]

_log = logging.getLogger(__name__)

MAX_RESULT_WAITERS = 64
_JOIN_ON_DESTROY_SEC = 2.0

# rcl_action's goal state machine, plus ABORT from ACCEPTED (a goal never executed when the
# server shuts down or handle_accepted_callback fails).
_TRANSITIONS = {
    (STATUS_ACCEPTED, GoalEvent.EXECUTE): STATUS_EXECUTING,
    (STATUS_ACCEPTED, GoalEvent.CANCEL_GOAL): STATUS_CANCELING,
    (STATUS_ACCEPTED, GoalEvent.ABORT): STATUS_ABORTED,
    (STATUS_EXECUTING, GoalEvent.CANCEL_GOAL): STATUS_CANCELING,
    (STATUS_EXECUTING, GoalEvent.SUCCEED): STATUS_SUCCEEDED,
    (STATUS_EXECUTING, GoalEvent.ABORT): STATUS_ABORTED,
    (STATUS_CANCELING, GoalEvent.SUCCEED): STATUS_SUCCEEDED,
    (STATUS_CANCELING, GoalEvent.ABORT): STATUS_ABORTED,
    (STATUS_CANCELING, GoalEvent.CANCELED): STATUS_CANCELED,
}


def default_goal_callback(goal_request: Any) -> GoalResponse:
    """Accept every goal."""
    return GoalResponse.ACCEPT


def default_cancel_callback(goal_handle: ServerGoalHandle) -> CancelResponse:
    """Reject every cancel request (rclpy's default)."""
    return CancelResponse.REJECT


def default_handle_accepted_callback(goal_handle: ServerGoalHandle) -> None:
    """Execute the goal at once."""
    goal_handle.execute()


class ServerGoalHandle:
    """One goal on the server side. Created by ``ActionServer``; never construct it."""

    def __init__(self, server: ActionServer, goal_id: bytes, request: Any, stamp: Any) -> None:
        self._server = server
        self._id = goal_id
        self._goal_id_msg = server._types.uuid(uuid=goal_id)
        self._request = request
        self._stamp = stamp
        self._status = STATUS_ACCEPTED
        self._thread: threading.Thread | None = None

    @property
    def goal_id(self) -> Any:
        """The goal id (``unique_identifier_msgs/msg/UUID``)."""
        return self._goal_id_msg

    @property
    def request(self) -> Any:
        """The goal message the client sent."""
        return self._request

    @property
    def stamp(self) -> Any:
        """When the goal was accepted (``builtin_interfaces/msg/Time``)."""
        return self._stamp

    @property
    def status(self) -> int:
        """The ``action_msgs/msg/GoalStatus`` value."""
        return self._status

    @property
    def is_active(self) -> bool:
        """Accepted, executing or canceling (not finished)."""
        return self._status in ACTIVE_STATES

    @property
    def is_cancel_requested(self) -> bool:
        """A cancel request was accepted (or the server is being destroyed): stop soon."""
        return self._status == STATUS_CANCELING

    def execute(self, execute_callback: Callable[[ServerGoalHandle], Any] | None = None) -> None:
        """Start executing: ``execute_callback`` (default: the server's) runs on its own thread.

        Raises:
            RuntimeError: the goal is not in the ACCEPTED state, or is executing already.
        """
        self._server._execute(self, execute_callback or self._server._execute_callback)

    def publish_feedback(self, feedback: Any) -> None:
        """Publish ``feedback`` (the action's ``Feedback`` message) for this goal.

        Ignored once the goal has finished. Raises ``TypeError`` for another message type.
        """
        self._server._publish_feedback(self, feedback)

    def succeed(self) -> None:
        """Mark the goal SUCCEEDED (from EXECUTING or CANCELING)."""
        self._server._transition(self, GoalEvent.SUCCEED)

    def abort(self) -> None:
        """Mark the goal ABORTED (from ACCEPTED, EXECUTING or CANCELING)."""
        self._server._transition(self, GoalEvent.ABORT)

    def canceled(self) -> None:
        """Mark the goal CANCELED (only from CANCELING, after a cancel request was accepted)."""
        self._server._transition(self, GoalEvent.CANCELED)

    def destroy(self) -> None:
        """Nothing to release; kept for rclpy compatibility."""

    def __repr__(self) -> str:
        return f"ServerGoalHandle({self._id.hex()}, {STATUS_NAMES.get(self._status, self._status)})"


class _Goal:
    __slots__ = ("handle", "response", "waiters", "finished_at")

    def __init__(self, handle: ServerGoalHandle) -> None:
        self.handle = handle
        self.response: Any = None  # the GetResult response once the goal is finished
        self.waiters: list[Future] = []
        self.finished_at = 0.0


def _same_but_feedback(types: ActionTypes, variant: ActionTypes, action_name: str) -> ActionTypes:
    """``variant``, checked to share ``types``' goal, result and cancel services (so one server serves both)."""
    from multiros.ros.interfaces import type_hash

    if variant.name != types.name or any(
        type_hash(getattr(variant, part)) != type_hash(getattr(types, part)) for part in ("send_goal", "get_result")
    ):
        raise ValueError(f"action server '{action_name}': feedback variant {variant.name} differs from "
                         f"{types.name} in more than its feedback; serve it with an action server of its own")
    return variant


class ActionServer:
    """Serves one action under ``action_name`` for ``node``.

    Args:
        node: the node serving the action.
        action_type: the action class (``get_action("pkg/action/Name")``).
        action_name: the action's name (relative, absolute or ``~/``).
        execute_callback: ``f(goal_handle) -> Result``; runs on a thread of its own per goal.
        goal_callback: ``f(goal) -> GoalResponse`` (default: accept).
        handle_accepted_callback: ``f(goal_handle)`` for accepted goals (default: execute now).
        cancel_callback: ``f(goal_handle) -> CancelResponse`` (default: reject, as rclpy).
        result_timeout: seconds a finished goal's result is kept (rclpy's default, 900).
        max_goals: most goals active at once; more are rejected.
        max_results: most finished goals kept; the oldest are forgotten first.
        feedback_variants: ``(action_type, convert)`` pairs for other definitions of this action
            (another ROS distribution's) that share its goal, result and cancel services but not its
            feedback: each feedback is also published as ``convert(feedback)`` on that variant's
            feedback type, so their clients get feedback too (control_msgs' FollowJointTrajectory
            gained feedback fields after Jazzy).

    Raises:
        TypeError: ``action_type`` is not an action type.
        ValueError: a bound is not positive, or a feedback variant differs in more than its feedback.
    """

    def __init__(
        self,
        node: Node,
        action_type: Any,
        action_name: str,
        execute_callback: Callable[[ServerGoalHandle], Any],
        *,
        goal_callback: Callable[[Any], GoalResponse] = default_goal_callback,
        handle_accepted_callback: Callable[[ServerGoalHandle], None] = default_handle_accepted_callback,
        cancel_callback: Callable[[ServerGoalHandle], CancelResponse] = default_cancel_callback,
        goal_service_qos_profile: QoSProfile = qos_profile_services_default,
        result_service_qos_profile: QoSProfile = qos_profile_services_default,
        cancel_service_qos_profile: QoSProfile = qos_profile_services_default,
        feedback_pub_qos_profile: QoSProfile = qos_profile_action_feedback_default,
        status_pub_qos_profile: QoSProfile = qos_profile_action_status_default,
        result_timeout: float = 900.0,
        max_goals: int = 32,
        max_results: int = 256,
        callback_group: Any = None,
        feedback_variants: Sequence[tuple[Any, Callable[[Any], Any]]] = (),
    ) -> None:
        if result_timeout <= 0 or max_goals < 1 or max_results < 1:
            raise ValueError(
                f"action server '{action_name}': result_timeout ({result_timeout}), max_goals ({max_goals}) "
                f"and max_results ({max_results}) must be positive"
            )
        self._node = node
        self._types = action_types(action_type)
        self._action_type = action_type
        self._name = node.resolve_service_name(action_name)
        self._execute_callback = execute_callback
        self._goal_callback = goal_callback
        self._handle_accepted_callback = handle_accepted_callback
        self._cancel_callback = cancel_callback
        self.result_timeout = float(result_timeout)
        self.max_goals = int(max_goals)
        self.max_results = int(max_results)
        self._lock = threading.RLock()
        self._status_lock = threading.RLock()  # taken before _lock, never while holding it
        self._goals: dict[bytes, _Goal] = {}
        self._finished: OrderedDict[bytes, _Goal] = OrderedDict()
        self._active = 0
        self._destroyed = False
        self._last_warning = 0.0
        t = self._types
        variants = [(_same_but_feedback(t, action_types(v), action_name), c) for v, c in feedback_variants]
        self._status_pub = node.create_publisher(t.status_array, self._name + STATUS, status_pub_qos_profile)
        self._feedback_pub = node.create_publisher(t.feedback_message, self._name + FEEDBACK,
                                                   feedback_pub_qos_profile)
        self._feedback_variants = [
            (node.create_publisher(vt.feedback_message, self._name + FEEDBACK, feedback_pub_qos_profile), vt, convert)
            for vt, convert in variants
        ]
        self._services = [
            node.create_service(t.send_goal, self._name + SEND_GOAL, self._on_send_goal,
                                qos_profile=goal_service_qos_profile),
            node.create_service(t.cancel_goal, self._name + CANCEL_GOAL, self._on_cancel_goal,
                                qos_profile=cancel_service_qos_profile),
            node.create_service(t.get_result, self._name + GET_RESULT, self._on_get_result,
                                qos_profile=result_service_qos_profile),
        ]
        node.add_waitable(self)

    @property
    def action_name(self) -> str:
        """The resolved action name."""
        return self._name

    @property
    def action_type(self) -> Any:
        return self._action_type

    def register_execute_callback(self, execute_callback: Callable[[ServerGoalHandle], Any]) -> None:
        self._execute_callback = execute_callback

    def register_goal_callback(self, goal_callback: Callable[[Any], GoalResponse]) -> None:
        self._goal_callback = goal_callback

    def register_cancel_callback(self, cancel_callback: Callable[[ServerGoalHandle], CancelResponse]) -> None:
        self._cancel_callback = cancel_callback

    def register_handle_accepted_callback(self, callback: Callable[[ServerGoalHandle], None]) -> None:
        self._handle_accepted_callback = callback

    def goal_handles(self) -> list[ServerGoalHandle]:
        """Handles of the goals that are still active."""
        with self._lock:
            return [g.handle for g in self._goals.values() if g.response is None]

    # -- services ----------------------------------------------------------------------------
    def _warn(self, text: str, *args: Any) -> None:
        # Floods of bad requests must not flood the log: one warning per second at most.
        now = time.monotonic()
        if now - self._last_warning >= 1.0:
            self._last_warning = now
            _log.warning("action '%s': " + text, self._name, *args)

    def _on_send_goal(self, request: Any, response: Any) -> Any:
        response.stamp = self._node.get_clock().now().to_msg()
        response.accepted = False
        goal_id = bytes(request.goal_id.uuid)
        if self._destroyed:
            return response
        if goal_id == ZERO_UUID:
            self._warn("rejected a goal with the all-zero goal id (reserved for 'all goals' in cancel)")
            return response
        with self._lock:
            self._sweep()
            if goal_id in self._goals:
                self._warn("rejected a goal whose id %s is already in use", goal_id.hex())
                return response
            if self._active >= self.max_goals:
                self._warn("rejected a goal: %d goals are active (max_goals=%d)", self._active, self.max_goals)
                return response
        try:
            verdict = self._goal_callback(request.goal)
        except Exception:  # noqa: BLE001 - user code must not kill the server
            _log.exception("action '%s': goal_callback raised; goal rejected", self._name)
            return response
        if verdict != GoalResponse.ACCEPT:
            return response
        handle = ServerGoalHandle(self, goal_id, request.goal, response.stamp)
        with self._lock:
            if goal_id in self._goals or self._active >= self.max_goals or self._destroyed:
                return response  # lost a race with another request
            self._goals[goal_id] = _Goal(handle)
            self._active += 1
        response.accepted = True
        self._publish_status()
        try:
            self._handle_accepted_callback(handle)
        except Exception:  # noqa: BLE001
            _log.exception("action '%s': handle_accepted_callback raised; goal %s aborted", self._name, goal_id.hex())
            if handle.is_active:
                handle.abort()
            self._finish(handle, None)
        return response

    def _on_cancel_goal(self, request: Any, response: Any) -> Any:
        t = self._types
        goal_id = bytes(request.goal_info.goal_id.uuid)
        before = stamp_ns(request.goal_info.stamp)
        with self._lock:
            self._sweep()
            if goal_id == ZERO_UUID:
                candidates = [g.handle for g in self._goals.values()
                              if before == 0 or stamp_ns(g.handle.stamp) <= before]
            else:
                target = self._goals.get(goal_id)
                candidates = [] if target is None else [target.handle]
                if before != 0:
                    candidates += [g.handle for g in self._goals.values()
                                   if g.handle._id != goal_id and stamp_ns(g.handle.stamp) <= before]
        if goal_id != ZERO_UUID and not candidates:
            response.return_code = t.cancel_goal.Response.ERROR_UNKNOWN_GOAL_ID
            return response
        canceling = []
        for handle in candidates:
            status = handle.status
            if status == STATUS_CANCELING:
                canceling.append(handle)
            elif status in (STATUS_ACCEPTED, STATUS_EXECUTING):
                try:
                    verdict = self._cancel_callback(handle)
                except Exception:  # noqa: BLE001
                    _log.exception("action '%s': cancel_callback raised; cancel rejected", self._name)
                    continue
                if verdict == CancelResponse.ACCEPT:
                    try:
                        self._transition(handle, GoalEvent.CANCEL_GOAL)
                    except RuntimeError:
                        continue  # finished meanwhile
                    canceling.append(handle)
        response.goals_canceling = [t.goal_info(goal_id=h.goal_id, stamp=h.stamp) for h in canceling]
        if canceling:
            response.return_code = t.cancel_goal.Response.ERROR_NONE
        elif goal_id != ZERO_UUID and all(h.status in TERMINAL_STATES for h in candidates):
            response.return_code = t.cancel_goal.Response.ERROR_GOAL_TERMINATED
        else:
            response.return_code = t.cancel_goal.Response.ERROR_REJECTED
        return response

    def _on_get_result(self, request: Any, response: Any) -> Any:
        goal_id = bytes(request.goal_id.uuid)
        with self._lock:
            self._sweep()
            goal = self._goals.get(goal_id)
            if goal is None:
                response.status = STATUS_UNKNOWN
                return response
            if goal.response is not None:
                return goal.response
            if self._destroyed:
                raise ServiceCallError(self._name + GET_RESULT, "the action server is shutting down")
            dropped = goal.waiters.pop(0) if len(goal.waiters) >= MAX_RESULT_WAITERS else None
            future = Future()
            goal.waiters.append(future)
        if dropped is not None:
            dropped.set_exception(ServiceCallError(
                self._name + GET_RESULT,
                f"more than {MAX_RESULT_WAITERS} get_result requests wait for goal {goal_id.hex()}; "
                "the oldest was dropped: ask again"))
        return future

    # -- goal life cycle ---------------------------------------------------------------------
    def _transition(self, handle: ServerGoalHandle, event: GoalEvent) -> None:
        with self._lock:
            new = _TRANSITIONS.get((handle._status, event))
            if new is None:
                raise RuntimeError(
                    f"action '{self._name}': goal {handle._id.hex()} cannot go from "
                    f"{STATUS_NAMES.get(handle._status)} with event {event.name}"
                )
            handle._status = new
            executing = handle._thread is not None
        self._publish_status()
        if new in TERMINAL_STATES and not executing:
            self._finish(handle, None)

    def _execute(self, handle: ServerGoalHandle, callback: Callable[[ServerGoalHandle], Any]) -> None:
        with self._lock:
            if handle._thread is not None or handle._status != STATUS_ACCEPTED:
                raise RuntimeError(
                    f"action '{self._name}': goal {handle._id.hex()} cannot execute: it is "
                    f"{STATUS_NAMES.get(handle._status)}{' and has run' if handle._thread else ''}"
                )
            thread = threading.Thread(target=self._run, args=(handle, callback), daemon=True,
                                      name=f"action{self._name}:{handle._id.hex()[:8]}")
            handle._thread = thread
        try:
            self._transition(handle, GoalEvent.EXECUTE)
        except RuntimeError:
            pass  # a cancel request came first: the callback runs and sees is_cancel_requested
        thread.start()

    def _run(self, handle: ServerGoalHandle, callback: Callable[[ServerGoalHandle], Any]) -> None:
        result = None
        try:
            result = callback(handle)
        except Exception:  # noqa: BLE001 - the goal aborts, the server lives on
            _log.exception("action '%s': execute_callback raised; goal %s aborted", self._name, handle._id.hex())
        if handle.is_active:
            if result is not None:
                _log.warning("action '%s': goal %s returned without succeed()/abort()/canceled(); aborted",
                             self._name, handle._id.hex())
            with self._lock:
                handle._status = STATUS_ABORTED
            self._publish_status()
        self._finish(handle, result)

    def _finish(self, handle: ServerGoalHandle, result: Any) -> None:
        """Store the result of a goal in a terminal state and answer its get_result waiters."""
        t = self._types
        if result is None:
            result = t.result()
        elif not isinstance(result, t.result):
            _log.warning("action '%s': execute_callback returned %s, not %s; an empty result is sent",
                         self._name, type(result).__name__, t.result._type)
            result = t.result()
        with self._lock:
            goal = self._goals.get(handle._id)
            if goal is None or goal.response is not None:
                return
            goal.response = t.get_result.Response(status=handle._status, result=result)
            goal.finished_at = time.monotonic()
            self._finished[handle._id] = goal
            self._active -= 1
            waiters, goal.waiters = goal.waiters, []
            self._sweep()
        for future in waiters:
            future.set_result(goal.response)
        self._publish_status()

    def _sweep(self) -> None:
        """Forget finished goals past ``result_timeout`` or beyond ``max_results`` (lock held)."""
        deadline = time.monotonic() - self.result_timeout
        while self._finished:
            goal_id, goal = next(iter(self._finished.items()))
            if goal.finished_at > deadline and len(self._finished) <= self.max_results:
                break
            del self._finished[goal_id]
            self._goals.pop(goal_id, None)

    # -- topics ------------------------------------------------------------------------------
    def _publish_status(self) -> None:
        t = self._types
        with self._status_lock:
            if self._destroyed:
                return
            with self._lock:
                status_list = [
                    t.goal_status(goal_info=t.goal_info(goal_id=g.handle.goal_id, stamp=g.handle.stamp),
                                  status=g.handle._status)
                    for g in self._goals.values()
                ]
            try:
                self._status_pub.publish(t.status_array(status_list=status_list))
            except Exception:  # noqa: BLE001 - e.g. the node was destroyed meanwhile
                _log.debug("action '%s': status not published", self._name, exc_info=True)

    def _publish_feedback(self, handle: ServerGoalHandle, feedback: Any) -> None:
        t = self._types
        if not isinstance(feedback, t.feedback):
            raise TypeError(
                f"action '{self._name}': publish_feedback expects {t.feedback._type}, got {type(feedback).__name__}"
            )
        if not handle.is_active or self._destroyed:
            return
        try:
            self._feedback_pub.publish(t.feedback_message(goal_id=handle.goal_id, feedback=feedback))
            for pub, vt, convert in self._feedback_variants:
                pub.publish(vt.feedback_message(goal_id=handle.goal_id, feedback=convert(feedback)))
        except RuntimeError:
            _log.debug("action '%s': feedback not published", self._name, exc_info=True)

    # -- teardown ----------------------------------------------------------------------------
    def destroy(self, timeout_sec: float = _JOIN_ON_DESTROY_SEC) -> None:
        """Stop serving: running goals are canceled (they see ``is_cancel_requested``) and get
        ``timeout_sec`` to end (0: do not wait, e.g. while holding a lock their threads need);
        clients still waiting for a result get an error."""
        if self._destroyed:
            return
        with self._lock:
            goals = list(self._goals.values())
        for goal in goals:
            if goal.handle._thread is not None and goal.handle._status in (STATUS_ACCEPTED, STATUS_EXECUTING):
                try:
                    self._transition(goal.handle, GoalEvent.CANCEL_GOAL)
                except RuntimeError:
                    pass  # it finished meanwhile
        self._destroyed = True
        deadline = time.monotonic() + max(0.0, timeout_sec)
        for goal in goals if timeout_sec > 0 else ():
            thread = goal.handle._thread
            if thread is not None and thread is not threading.current_thread():
                thread.join(max(0.0, deadline - time.monotonic()))
                if thread.is_alive():
                    _log.warning("action '%s': goal %s still executing after the server was destroyed",
                                 self._name, goal.handle._id.hex())
        with self._lock:
            waiters = [f for g in self._goals.values() for f in g.waiters]
            for g in self._goals.values():
                g.waiters = []
        for future in waiters:
            future.set_exception(ServiceCallError(self._name + GET_RESULT, "the action server was destroyed"))
        node = self._node
        for srv in self._services:
            node.destroy_service(srv)
        node.destroy_publisher(self._feedback_pub)
        for pub, _, _ in self._feedback_variants:
            node.destroy_publisher(pub)
        node.destroy_publisher(self._status_pub)
        node.remove_waitable(self)

    def __repr__(self) -> str:
        return f"ActionServer({self._name!r}, {self._types.name})"
