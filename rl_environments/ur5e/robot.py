"""The Universal Robots UR5e's robot layers: its constants on the simulation node (:class:`UR5eRobot`)
and on its real ROS 2 driver (:class:`UR5eRealRobot`), and the four robot envs the task envs
mix a task into.

Simulation: spawned from ``ur5e_description`` (the UR5e's DH kinematics and ur_description's limits
and physical parameters, a 2F-85-like parallel gripper of ours, primitive geometry), the arm's
group position controller ``forward_position_controller``, the gripper's
``gripper_position_controller`` (left_finger_joint, half the opening; right_finger_joint mimics
it), the EE frame ``grasp_link`` between the pads, 0.128 m beyond ``tool0``.

Real robot: Universal Robots' ``ur_robot_driver`` (namespace ``/``, ``/joint_states``), the arm's
``scaled_joint_trajectory_controller``; the gripper a Robotiq 2F-85 on PickNik's
``ros2_robotiq_gripper`` (``robotiq_gripper_controller``, a GripperActionController:
``control_msgs/action/GripperCommand`` on ``/robotiq_gripper_controller/gripper_cmd``, its knuckle
joint 0 rad open .. 0.8 rad closed; the twins map the finger opening onto it). Every name is an
option (``namespace=``, ``arm_controller=``, ``gripper_controller=``, ``joint_states_topic=``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence

from rl_environments.arm_ik import UR5eTopDownIK
from rl_environments.arm_robot import ArmRobot
from rl_environments.arm_robot_envs import ArmRobotEnv, ArmRobotGoalEnv, ArmRobotRealEnv, ArmRobotRealGoalEnv
from rl_environments.real_arm_robot import RealArmRobot
from rl_environments.robots import ur5e_description as pkg


class UR5eRobot(ArmRobot):
    """The UR5e's constants; see :class:`~rl_environments.arm_robot.ArmRobot`."""

    ROBOT_NAME = pkg.ROBOT_NAME
    DESCRIPTION_PACKAGE = pkg.PACKAGE_NAME
    DESCRIPTION_MODULE = "rl_environments.robots.ur5e_description"
    XACRO_FILE = pkg.URDF_XACRO.name
    CONTROLLERS_FILE = pkg.CONTROLLERS_YAML.name
    ARM_JOINTS = pkg.ARM_JOINTS
    BASE_LINK = pkg.BASE_LINK
    EE_LINK = pkg.EE_LINK
    ARM_CONTROLLER = pkg.ARM_POSITION_CONTROLLER
    CONTROLLERS = pkg.SIM_CONTROLLERS
    GRIPPER_CONTROLLER = pkg.GRIPPER_POSITION_CONTROLLER
    FINGER_JOINTS = pkg.FINGER_JOINTS
    FINGER_MIMIC = -1.0
    SCENE = pkg.SCENE
    # The observation camera's default view (the description's render_camera's): lookat, distance,
    # azimuth, elevation, relative to the base.
    CAMERA_VIEW = ((0.42, 0.08, 0.25), 1.9, 140.0, -25.0)

    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> UR5eTopDownIK:
        return UR5eTopDownIK(lower, upper)


class UR5eRealRobot(UR5eRobot, RealArmRobot):
    """The UR5e's real-robot constants (see :class:`~rl_environments.real_arm_robot.RealArmRobot`)."""

    REAL_NAMESPACE = pkg.REAL_NAMESPACE
    REAL_ARM_CONTROLLER = pkg.REAL_ARM_CONTROLLER
    REAL_CONTROLLERS = ()
    REAL_GRIPPER_CONTROLLER = pkg.REAL_GRIPPER_CONTROLLER
    REAL_GRIPPER_INTERFACE = "gripper_action"
    # The Robotiq 2F-85's knuckle joint: 0 rad open .. 0.8 rad closed; the finger opening maps onto it.
    REAL_GRIPPER_RANGE = (pkg.REAL_GRIPPER_OPEN, pkg.REAL_GRIPPER_CLOSED)
    # The reach config's end-effector box (base frame); the floor 2 cm above the base plate.
    WORKSPACE_MIN = (-0.95, -0.95, 0.0)
    WORKSPACE_MAX = (0.95, 0.95, 1.10)
    FLOOR_Z = 0.02
    MAX_JOINT_DELTA = 0.15


class UR5eRobotEnv(UR5eRobot, ArmRobotEnv):
    """The UR5e robot layer for plain task envs on the simulation node."""


class UR5eRobotGoalEnv(UR5eRobot, ArmRobotGoalEnv):
    """The UR5e robot layer for goal-conditioned task envs on the simulation node."""


class UR5eRobotRealEnv(UR5eRealRobot, ArmRobotRealEnv):
    """The real UR5e robot layer for plain task envs."""


class UR5eRobotRealGoalEnv(UR5eRealRobot, ArmRobotRealGoalEnv):
    """The real UR5e robot layer for goal-conditioned task envs."""
