"""What action servers and clients share: goal states, QoS, entity names, UUIDs and stamps.

An action ``/name`` is, on the wire (rcl_action, rmw_zenoh), three services and two topics:
``/name/_action/send_goal`` (``pkg/action/X_SendGoal``), ``/name/_action/cancel_goal``
(``action_msgs/srv/CancelGoal``), ``/name/_action/get_result`` (``pkg/action/X_GetResult``),
``/name/_action/feedback`` (``pkg/action/X_FeedbackMessage``) and ``/name/_action/status``
(``action_msgs/msg/GoalStatusArray``, transient local).
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from multiros.ros.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

__all__ = [
    "GoalResponse",
    "CancelResponse",
    "GoalEvent",
    "STATUS_UNKNOWN",
    "STATUS_ACCEPTED",
    "STATUS_EXECUTING",
    "STATUS_CANCELING",
    "STATUS_SUCCEEDED",
    "STATUS_CANCELED",
    "STATUS_ABORTED",
    "ACTIVE_STATES",
    "TERMINAL_STATES",
    "STATUS_NAMES",
    "qos_profile_action_status_default",
    "qos_profile_action_feedback_default",
    "ActionTypes",
    "action_types",
    "SEND_GOAL",
    "CANCEL_GOAL",
    "GET_RESULT",
    "FEEDBACK",
    "STATUS",
    "ZERO_UUID",
    "uuid_bytes",
    "new_uuid",
    "stamp_ns",
]

# action_msgs/msg/GoalStatus values.
STATUS_UNKNOWN = 0
STATUS_ACCEPTED = 1
STATUS_EXECUTING = 2
STATUS_CANCELING = 3
STATUS_SUCCEEDED = 4
STATUS_CANCELED = 5
STATUS_ABORTED = 6
ACTIVE_STATES = frozenset({STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING})
TERMINAL_STATES = frozenset({STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED})
STATUS_NAMES = {
    STATUS_UNKNOWN: "UNKNOWN", STATUS_ACCEPTED: "ACCEPTED", STATUS_EXECUTING: "EXECUTING",
    STATUS_CANCELING: "CANCELING", STATUS_SUCCEEDED: "SUCCEEDED", STATUS_CANCELED: "CANCELED",
    STATUS_ABORTED: "ABORTED",
}

SEND_GOAL = "/_action/send_goal"
CANCEL_GOAL = "/_action/cancel_goal"
GET_RESULT = "/_action/get_result"
FEEDBACK = "/_action/feedback"
STATUS = "/_action/status"

ZERO_UUID = bytes(16)

# rcl_action's defaults: status is latched (depth 1, transient local); feedback is a plain topic.
qos_profile_action_status_default = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
qos_profile_action_feedback_default = QoSProfile(depth=10)


class GoalResponse(IntEnum):
    """What a server's ``goal_callback`` returns (rclpy's values)."""

    REJECT = 1
    ACCEPT = 2


class CancelResponse(IntEnum):
    """What a server's ``cancel_callback`` returns (rclpy's values)."""

    REJECT = 1
    ACCEPT = 2


class GoalEvent(IntEnum):
    """Events of rcl_action's goal state machine."""

    EXECUTE = 0
    CANCEL_GOAL = 1
    SUCCEED = 2
    ABORT = 3
    CANCELED = 4


@dataclass(frozen=True)
class ActionTypes:
    """The message and service classes one action uses on the wire."""

    name: str
    goal: type
    result: type
    feedback: type
    send_goal: Any
    get_result: Any
    feedback_message: type
    cancel_goal: Any
    status_array: type
    goal_status: type
    goal_info: type
    uuid: type
    time: type


def action_types(action_type: Any) -> ActionTypes:
    """Collect the classes of ``action_type`` (a class from ``get_action``, or its name).

    Raises:
        TypeError: ``action_type`` is not an action type.
    """
    from multiros.ros.interfaces import get_action, get_message, get_service

    if isinstance(action_type, str):
        action_type = get_action(action_type)
    impl = getattr(action_type, "Impl", None)
    if impl is None or not all(hasattr(action_type, a) for a in ("Goal", "Result", "Feedback", "_type")):
        raise TypeError(
            f"{action_type!r} is not an action type: use get_action('pkg/action/Name') from multiros.ros.interfaces"
        )
    return ActionTypes(
        name=action_type._type,
        goal=action_type.Goal,
        result=action_type.Result,
        feedback=action_type.Feedback,
        send_goal=impl.SendGoalService,
        get_result=impl.GetResultService,
        feedback_message=impl.FeedbackMessage,
        cancel_goal=get_service("action_msgs/srv/CancelGoal"),
        status_array=get_message("action_msgs/msg/GoalStatusArray"),
        goal_status=get_message("action_msgs/msg/GoalStatus"),
        goal_info=get_message("action_msgs/msg/GoalInfo"),
        uuid=get_message("unique_identifier_msgs/msg/UUID"),
        time=get_message("builtin_interfaces/msg/Time"),
    )


def uuid_bytes(goal_id: Any) -> bytes:
    """The 16 bytes of a goal id given as a UUID message, ``uuid.UUID`` or bytes.

    Raises:
        ValueError: not 16 bytes.
    """
    if isinstance(goal_id, uuid.UUID):
        return goal_id.bytes
    raw = getattr(goal_id, "uuid", goal_id)
    if isinstance(raw, (bytes, bytearray, memoryview)):
        raw = bytes(raw)
    else:
        try:
            raw = bytes(bytearray(raw))
        except (TypeError, ValueError):
            raise ValueError(f"goal id {goal_id!r} is not 16 bytes (a UUID)") from None
    if len(raw) != 16:
        raise ValueError(f"goal id has {len(raw)} bytes; a UUID has 16")
    return raw


def new_uuid() -> bytes:
    """A random (version 4) goal id."""
    return uuid.uuid4().bytes


def stamp_ns(stamp: Any) -> int:
    """A ``builtin_interfaces/msg/Time`` in nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
