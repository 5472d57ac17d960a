"""The ViperX 300 6DOF's robot layers: its constants on the simulation node (:class:`VX300SRobot`)
and on its real ROS 2 driver (:class:`VX300SRealRobot`), and the four robot envs the task envs
mix a task into.

Simulation: spawned from ``vx300s_description`` (Interbotix' kinematics and limits, primitive
geometry), the arm's group position controller ``arm_position_controller`` and the gripper's
``gripper_position_controller`` (left_finger; right_finger mimics it), the EE frame
``vx300s/ee_gripper_link`` between the finger pads.

Real robot: Interbotix' ROS 2 ros2_control bringup (``interbotix_xsarm_ros_control`` with
``robot_model:=vx300s``): namespace ``/vx300s``, ``/vx300s/joint_states``, the arm's
JointTrajectoryController ``arm_controller`` and the gripper's ``gripper_controller`` (a
JointTrajectoryController on left_finger: the push and pick-and-place twins send it one-point
trajectories). Every name is an option (``namespace=``, ``arm_controller=``, ``gripper_controller=``,
``joint_states_topic=``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence

from rl_environments.arm_ik import VX300STopDownIK
from rl_environments.arm_robot import ArmRobot
from rl_environments.arm_robot_envs import ArmRobotEnv, ArmRobotGoalEnv, ArmRobotRealEnv, ArmRobotRealGoalEnv
from rl_environments.real_arm_robot import RealArmRobot
from rl_environments.robots import vx300s_description as pkg


class VX300SRobot(ArmRobot):
    """The VX300S's constants; see :class:`~rl_environments.arm_robot.ArmRobot`."""

    ROBOT_NAME = pkg.ROBOT_NAME
    DESCRIPTION_PACKAGE = pkg.PACKAGE_NAME
    DESCRIPTION_MODULE = "rl_environments.robots.vx300s_description"
    XACRO_FILE = pkg.URDF_XACRO.name
    XACRO_ARGS = {"robot_name": pkg.ROBOT_NAME}
    CONTROLLERS_FILE = pkg.CONTROLLERS_YAML.name
    ARM_JOINTS = pkg.ARM_JOINTS
    BASE_LINK = f"{pkg.ROBOT_NAME}/{pkg.BASE_LINK}"
    EE_LINK = f"{pkg.ROBOT_NAME}/{pkg.EE_LINK}"
    ARM_CONTROLLER = pkg.ARM_POSITION_CONTROLLER
    CONTROLLERS = pkg.SIM_CONTROLLERS
    GRIPPER_CONTROLLER = pkg.GRIPPER_POSITION_CONTROLLER
    FINGER_JOINTS = pkg.FINGER_JOINTS
    FINGER_MIMIC = -1.0
    SCENE = pkg.SCENE
    # The observation camera's default view (the description's render_camera's): lookat, distance,
    # azimuth, elevation, relative to the base.
    CAMERA_VIEW = ((0.28, 0.05, 0.17), 1.15, 140.0, -25.0)

    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> VX300STopDownIK:
        return VX300STopDownIK(lower, upper)


class VX300SRealRobot(VX300SRobot, RealArmRobot):
    """The VX300S's real-robot constants (see :class:`~rl_environments.real_arm_robot.RealArmRobot`)."""

    REAL_NAMESPACE = pkg.REAL_NAMESPACE
    REAL_ARM_CONTROLLER = pkg.REAL_ARM_CONTROLLER
    REAL_CONTROLLERS = ()
    REAL_GRIPPER_CONTROLLER = pkg.REAL_GRIPPER_CONTROLLER
    REAL_GRIPPER_INTERFACE = "trajectory"
    # The reach config's end-effector box (base frame); the floor 2 cm above the base plate.
    WORKSPACE_MIN = (-0.80, -0.80, 0.0)
    WORKSPACE_MAX = (0.80, 0.80, 0.90)
    FLOOR_Z = 0.02
    MAX_JOINT_DELTA = 0.15


class VX300SRobotEnv(VX300SRobot, ArmRobotEnv):
    """The VX300S robot layer for plain task envs on the simulation node."""


class VX300SRobotGoalEnv(VX300SRobot, ArmRobotGoalEnv):
    """The VX300S robot layer for goal-conditioned task envs on the simulation node."""


class VX300SRobotRealEnv(VX300SRealRobot, ArmRobotRealEnv):
    """The real VX300S robot layer for plain task envs."""


class VX300SRobotRealGoalEnv(VX300SRealRobot, ArmRobotRealGoalEnv):
    """The real VX300S robot layer for goal-conditioned task envs."""
