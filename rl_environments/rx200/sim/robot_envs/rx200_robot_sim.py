"""Robot env of the Interbotix ReactorX 200 (5-DOF arm + gripper) on the MuJoCo simulation node.

``RX200RobotEnv`` (plain) and ``RX200RobotGoalEnv`` (goal-conditioned) spawn the RX200 from the
``rx200_description`` package shipped with uniros, activate the arm's group position controller
and the gripper controller, and return the ``rx200/ee_gripper_link`` pose with every step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import ClassVar

from rl_environments.arm_robot import ArmRobot
from rl_environments.arm_robot_envs import ArmRobotEnv, ArmRobotGoalEnv
from rl_environments.manipulation import RX200TopDownIK
from rl_environments.robots import rx200_description


class RX200Robot(ArmRobot):
    """The RX200's constants; see :class:`~rl_environments.arm_robot.ArmRobot`."""

    ROBOT_NAME = "rx200"
    DESCRIPTION_PACKAGE = "rx200_description"
    DESCRIPTION_MODULE = "rl_environments.robots.rx200_description"
    XACRO_FILE = "rx200.urdf.xacro"
    XACRO_ARGS: ClassVar[Mapping[str, str]] = {"robot_name": "rx200"}
    CONTROLLERS_FILE = "rx200_controllers.yaml"
    ARM_JOINTS = ("waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate")
    BASE_LINK = "rx200/base_link"
    EE_LINK = "rx200/ee_gripper_link"
    ARM_CONTROLLER = "arm_position_controller"
    CONTROLLERS = ("joint_state_broadcaster", "arm_position_controller", "gripper_controller")
    GRIPPER_CONTROLLER = "gripper_controller"
    FINGER_JOINTS = ("left_finger", "right_finger")
    SCENE = rx200_description.SCENE
    # The observation camera's default view (the description's render_camera's): lookat, distance,
    # azimuth, elevation, relative to the base.
    CAMERA_VIEW = ((0.164, 0.039, 0.115), 0.734, 140.0, -25.0)
    # With use_zed2: the Zed2's left camera on Stereolabs' zed_wrapper topics.
    CAMERA_TOPICS: ClassVar[Mapping[str, tuple[str, str]]] = {
        "zed2_left": ("zed2/zed_node/rgb/image_rect_color", "zed2/zed_node/depth/depth_registered")}

    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> RX200TopDownIK:
        return RX200TopDownIK(lower, upper)

    def open_fingers_at_reset(self, opening: float) -> None:
        """The commanded finger only (right_finger follows through the description's mimic): the
        RX200's episodes have started so since the push and pick-and-place envs were recorded."""
        self.connection.set_joint_positions(self.FINGER_JOINTS[:1], [opening])


class RX200RobotEnv(RX200Robot, ArmRobotEnv):
    """The RX200 robot layer for plain (non-goal) task envs. Keyword arguments go to
    :class:`~multiros.envs.MujocoBaseEnv` (robot defaults filled in)."""


class RX200RobotGoalEnv(RX200Robot, ArmRobotGoalEnv):
    """The RX200 robot layer for goal-conditioned task envs."""
