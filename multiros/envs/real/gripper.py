"""A real gripper, commanded the way its ROS 2 driver takes commands: a task's finger target (the
simulated finger joint's position, metres) mapped onto the driver's range and sent as

* ``"trajectory"``: a one-point ``JointTrajectory`` on ``<controller>/joint_trajectory`` (a
  JointTrajectoryController on the gripper joint: Interbotix' ``gripper_controller``);
* ``"forward"``: ``std_msgs/Float64MultiArray`` on ``<controller>/commands`` (a forward or group
  position controller);
* ``"gripper_action"``: a ``control_msgs/action/GripperCommand`` goal on ``<controller>/gripper_cmd``
  (a GripperActionController: PickNik's ``ros2_robotiq_gripper``), sent only when the target moves
  (more than 1 % of the range) and never waited for, so the control loop keeps its rate;
* ``"none"``: nothing (another process of yours drives the gripper).

Every command is finite and clipped into the driver's range; nothing is sent once the env has
stopped after a fault.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["GRIPPER_INTERFACES", "RealGripper"]

GRIPPER_INTERFACES = ("trajectory", "forward", "gripper_action", "none")


class RealGripper:
    """One env's gripper (see the module docstring).

    Args:
        connection: the robot's connection (its node, robot link and control loop).
        interface: one of :data:`GRIPPER_INTERFACES`.
        controller: the driver's gripper controller (relative to the robot's namespace).
        joint: the gripper joint a trajectory commands.
        env_range: the task's finger positions ``(closed, open)``.
        real_range: the driver's values at ``(closed, open)`` (default: ``env_range``).
        max_effort: a GripperCommand goal's effort limit (N; 0: the driver's default).
        followers: ``(joint, multiplier)`` of joints a trajectory or forward command also drives, each at
            its multiplier times ``joint``'s value (two independently driven fingers, commanded together).
    """

    def __init__(self, connection: Any, interface: str, controller: str, joint: str, env_range: Sequence[float],
                 real_range: Sequence[float] | None = None, max_effort: float = 0.0,
                 followers: Sequence[tuple[str, float]] = ()) -> None:
        if interface not in GRIPPER_INTERFACES:
            raise ValueError(f"gripper_interface {interface!r} is not one of {list(GRIPPER_INTERFACES)}")
        if interface != "none" and not controller:
            raise ValueError(f"gripper_interface={interface!r} needs gripper_controller= (the driver's gripper "
                             "controller)")
        lo, hi = (float(v) for v in env_range)
        rlo, rhi = (float(v) for v in (real_range if real_range is not None else env_range))
        if not all(map(math.isfinite, (lo, hi, rlo, rhi))) or hi == lo:
            raise ValueError(f"gripper ranges must be finite and not empty: env {env_range}, driver {real_range}")
        self.connection, self.interface, self.controller, self.joint = connection, interface, controller, joint
        self.env_range, self.real_range = (lo, hi), (rlo, rhi)
        self.max_effort = float(max_effort)
        self.followers = tuple((str(name), float(m)) for name, m in followers)
        if not all(math.isfinite(m) for _, m in self.followers):
            raise ValueError(f"gripper follower multipliers must be finite, got {list(followers)}")
        if self.followers and interface == "gripper_action":
            raise ValueError("a GripperCommand action takes one position: gripper followers need the "
                             "'trajectory' or 'forward' interface")
        self.last: float | None = None
        self._client: Any = None
        if interface == "gripper_action":
            from multiros.ros.action import ActionClient
            from multiros.ros.interfaces import get_action

            self._goal_type = get_action("control_msgs/action/GripperCommand")
            self._client = ActionClient(connection.node, self._goal_type,
                                        connection.link.resolve(f"{controller}/gripper_cmd"))

    def to_driver(self, finger: float) -> float:
        """The driver's value for the task's finger position (linear, clipped into the driver's range)."""
        lo, hi = self.env_range
        rlo, rhi = self.real_range
        value = rlo + (float(finger) - lo) / (hi - lo) * (rhi - rlo)
        return float(np.clip(value, min(rlo, rhi), max(rlo, rhi)))

    def command(self, finger: float) -> None:
        """Send the finger target ``finger`` (task units) to the driver."""
        if not math.isfinite(float(finger)):
            raise ValueError(f"gripper target {finger!r} is not finite; nothing was sent")
        self.connection.ensure_commandable()
        value = self.to_driver(finger)
        if self.interface == "none":
            return
        values = np.array([value, *(m * value for _, m in self.followers)])
        if self.interface == "trajectory":
            self.connection.link.publish_trajectory(self.controller, [self.joint, *(n for n, _ in self.followers)],
                                                    values, self.connection.loop.cycle)
        elif self.interface == "forward":
            self.connection.link.publish_forward(self.controller, values)
        else:
            span = abs(self.real_range[1] - self.real_range[0])
            if self.last is not None and abs(value - self.last) <= 0.01 * span:
                return
            goal = self._goal_type.Goal()
            goal.command.position = value
            goal.command.max_effort = self.max_effort
            self._client.send_goal_async(goal)
        self.last = value

    def wait_ready(self, timeout: float) -> bool:
        """Whether the driver's gripper interface is there (an action server, or a subscriber)."""
        if self.interface == "none":
            return True
        if self.interface == "gripper_action":
            return bool(self._client.wait_for_server(timeout_sec=timeout))
        return bool(self.connection.link.wait_for_subscriber(self.controller, self.interface, timeout))

    def close(self) -> None:
        if self._client is not None:
            try:
                self._client.destroy()
            except Exception:  # noqa: BLE001 - closing goes on
                pass
