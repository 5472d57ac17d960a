"""Robot env of the ABB IRB120 (6-DOF) on the MuJoCo simulation node.

FRobs_RL drove this arm through MoveIt plans; here the arm's group position controller takes a
joint target every env step and the ``flange`` pose comes back with the step.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from rl_environments.arm_robot import ArmRobot
from rl_environments.arm_robot_envs import ArmRobotEnv, ArmRobotGoalEnv


class IRB120Robot(ArmRobot):
    """The IRB120's constants; see :class:`~rl_environments.arm_robot.ArmRobot`."""

    ROBOT_NAME = "irb120"
    DESCRIPTION_PACKAGE = "abb_irb120_description"
    DESCRIPTION_MODULE = "rl_environments.robots.abb_irb120_description"
    XACRO_FILE = "irb120.urdf.xacro"
    XACRO_ARGS: ClassVar[Mapping[str, str]] = {}
    CONTROLLERS_FILE = "irb120_controllers.yaml"
    ARM_JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6")
    BASE_LINK = "base_link"
    EE_LINK = "flange"
    ARM_CONTROLLER = "arm_position_controller"
    CONTROLLERS = ("joint_state_broadcaster", "arm_position_controller")


class ABBIRB120RobotEnv(IRB120Robot, ArmRobotEnv):
    """The IRB120 robot layer for plain task envs."""


class ABBIRB120RobotGoalEnv(IRB120Robot, ArmRobotGoalEnv):
    """The IRB120 robot layer for goal-conditioned task envs."""
