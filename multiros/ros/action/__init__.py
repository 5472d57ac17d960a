"""ROS 2 actions, shaped like ``rclpy.action``: goals with feedback, a result and cancellation.

::

    from multiros.ros.action import ActionClient, ActionServer, CancelResponse
    from multiros.ros.interfaces import get_action

    SimulateSteps = get_action("simulation_interfaces/action/SimulateSteps")

    def execute(goal_handle):
        for i in range(goal_handle.request.steps):
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                return SimulateSteps.Result()
            goal_handle.publish_feedback(SimulateSteps.Feedback(completed_steps=i + 1))
        goal_handle.succeed()
        return SimulateSteps.Result()

    server = ActionServer(node, SimulateSteps, "simulate", execute,
                          cancel_callback=lambda handle: CancelResponse.ACCEPT)
    client = ActionClient(other_node, SimulateSteps, "/simulate")
    client.wait_for_server(timeout_sec=2.0)
    response = client.send_goal(SimulateSteps.Goal(steps=10), timeout_sec=5.0)  # .status, .result

The wire is rcl_action's (services ``<name>/_action/{send_goal,cancel_goal,get_result}``, topics
``<name>/_action/{feedback,status}``), so rmw_zenoh peers interoperate; see ``server`` and
``client`` for the execution model and the bounds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from multiros.ros.action._common import (
    STATUS_ABORTED,
    STATUS_ACCEPTED,
    STATUS_CANCELED,
    STATUS_CANCELING,
    STATUS_EXECUTING,
    STATUS_SUCCEEDED,
    STATUS_UNKNOWN,
    CancelResponse,
    GoalResponse,
    qos_profile_action_status_default,
)
from multiros.ros.action.client import ActionClient, ClientGoalHandle
from multiros.ros.action.server import ActionServer, ServerGoalHandle

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = [
    "ActionServer", "ActionClient", "ServerGoalHandle", "ClientGoalHandle", "GoalResponse", "CancelResponse",
    "get_action_names_and_types", "qos_profile_action_status_default",
    "STATUS_UNKNOWN", "STATUS_ACCEPTED", "STATUS_EXECUTING", "STATUS_CANCELING", "STATUS_SUCCEEDED",
    "STATUS_CANCELED", "STATUS_ABORTED",
]

_SEND_GOAL_SUFFIX = "/_action/send_goal"


def get_action_names_and_types(node: Node) -> list[tuple[str, list[str]]]:
    """Actions in the graph as ``(name, ["pkg/action/Name"])``, found by their send_goal services."""
    found: dict[str, set[str]] = {}
    for name, types in node.get_service_names_and_types():
        if not name.endswith(_SEND_GOAL_SUFFIX):
            continue
        for type_name in types:
            if type_name.endswith("_SendGoal") and "/action/" in type_name:
                found.setdefault(name[: -len(_SEND_GOAL_SUFFIX)], set()).add(type_name[: -len("_SendGoal")])
    return sorted((name, sorted(types)) for name, types in found.items())
