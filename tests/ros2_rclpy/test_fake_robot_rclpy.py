"""``uniros-fake-robot --transport rclpy`` answers a plain rclpy client (tests/ros2_rclpy/plain_ros.py): its
joint_states, controller manager and FollowJointTrajectory action, over Fast DDS from another process."""

from __future__ import annotations

import importlib.util

import pytest

_NEEDED = ("rclpy", "control_msgs", "controller_manager_msgs")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy and the interface packages .ci/rclpy builds (run by .ci/rclpy)", allow_module_level=True)

from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from controller_manager_msgs.srv import ListControllers  # noqa: E402
from plain_ros import PlainPeer, wait_until  # noqa: E402
from rclpy_harness import uniros_script  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectoryPoint  # noqa: E402

pytestmark = pytest.mark.slow
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]


def test_fake_robot_on_rclpy_answers_a_plain_rclpy_client(program) -> None:
    robot = program([uniros_script("uniros-fake-robot"), "--robot", "rx200", "--transport", "rclpy"], "fake-robot")
    with PlainPeer("plain_operator") as peer:
        robot.wait_ready("ready", timeout=60)
        states, _ = peer.collect(JointState, "/rx200/joint_states")
        wait_until(lambda: states, 20, "/rx200/joint_states from the fake robot")
        assert set(ARM) <= set(states[-1].name)
        listed = {c.name: c.state for c in peer.call(
            ListControllers, "/rx200/controller_manager/list_controllers", ListControllers.Request()).controller}
        assert listed.get("arm_controller") == "active", listed
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = ARM
        goal.trajectory.points = [JointTrajectoryPoint(positions=[0.2, 0.1, 0.0, 0.0, 0.0],
                                                       time_from_start=Duration(sec=1))]
        handle, feedback, result = peer.send_goal(
            FollowJointTrajectory, "/rx200/arm_controller/follow_joint_trajectory", goal)
        assert handle.accepted
        assert result is not None and result.status == 4, result  # SUCCEEDED
        assert feedback
        wait_until(lambda: abs(dict(zip(states[-1].name, states[-1].position))["waist"] - 0.2) < 0.05, 10,
                   "the waist at the goal in joint_states")
