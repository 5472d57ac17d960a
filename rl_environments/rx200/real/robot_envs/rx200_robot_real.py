"""Robot env of a real Interbotix ReactorX 200 over its ROS 2 driver (ros2_control).

Defaults follow Interbotix' ROS 2 packages (``interbotix_xsarm_control`` / ``interbotix_xsarm_ros_control``
with ``robot_model:=rx200``): namespace ``/rx200``, ``joint_states`` at ``/rx200/joint_states``, the
arm's JointTrajectoryController ``arm_controller`` over waist, shoulder, elbow, wrist_angle and
wrist_rotate (``gripper_controller`` exists but the reach task does not use it). Every default is
an option: ``namespace=``, ``arm_controller=``, ``joint_states_topic=``, ``command_interface=``, ...
"""

from __future__ import annotations

from rl_environments.arm_robot_envs import ArmRobotRealEnv, ArmRobotRealGoalEnv
from rl_environments.real_arm_robot import RealArmRobot
from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200Robot


class RX200RealRobot(RX200Robot, RealArmRobot):
    """The RX200's real-robot constants (see :class:`~rl_environments.real_arm_robot.RealArmRobot`)."""

    REAL_NAMESPACE = "/rx200"
    REAL_ARM_CONTROLLER = "arm_controller"
    REAL_CONTROLLERS = ()
    # The reach config's end-effector box; the floor 2 cm above the base plate.
    WORKSPACE_MIN = (-0.55, -0.55, 0.0)
    WORKSPACE_MAX = (0.55, 0.55, 0.6)
    FLOOR_Z = 0.02
    MAX_JOINT_DELTA = 0.15


class RX200RobotRealEnv(RX200RealRobot, ArmRobotRealEnv):
    """The real RX200 robot layer for plain task envs; keyword arguments go to
    :class:`~multiros.envs.RealBaseEnv` (robot defaults filled in)."""


class RX200RobotRealGoalEnv(RX200RealRobot, ArmRobotRealGoalEnv):
    """The real RX200 robot layer for goal-conditioned task envs."""
