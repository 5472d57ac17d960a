"""Robot env of a real ABB IRB 120 over ros2_control.

Defaults follow the ros2_control set-up of ABB's ROS 2 driver (``abb_ros2``, ``abb_bringup``): no
namespace (``/joint_states``, ``/controller_manager``) and a JointTrajectoryController named
``joint_trajectory_controller`` over ``joint_1`` .. ``joint_6``. Every default is an option
(``namespace=``, ``arm_controller=``, ...); against uniros' simulation node use
``namespace="/irb120", arm_controller="arm120_controller"``.
"""

from __future__ import annotations

from rl_environments.abb_irb120.sim.robot_envs.irb120_robot_sim import IRB120Robot
from rl_environments.abb_irb120.sim.task_envs.reacher.config import EE_HIGH, EE_LOW
from rl_environments.arm_robot_envs import ArmRobotRealEnv, ArmRobotRealGoalEnv
from rl_environments.real_arm_robot import RealArmRobot


class IRB120RealRobot(IRB120Robot, RealArmRobot):
    """The IRB120's real-robot constants (see :class:`~rl_environments.real_arm_robot.RealArmRobot`)."""

    REAL_NAMESPACE = "/"
    REAL_ARM_CONTROLLER = "joint_trajectory_controller"
    REAL_CONTROLLERS = ()
    WORKSPACE_MIN = EE_LOW
    WORKSPACE_MAX = EE_HIGH
    FLOOR_Z = 0.02
    MAX_JOINT_DELTA = 0.15


class ABBIRB120RobotRealEnv(IRB120RealRobot, ArmRobotRealEnv):
    """The real IRB120 robot layer for plain task envs."""


class ABBIRB120RobotRealGoalEnv(IRB120RealRobot, ArmRobotRealGoalEnv):
    """The real IRB120 robot layer for goal-conditioned task envs."""
