"""The Niryo Ned2's robot layers: its constants on the simulation node (:class:`NED2Robot`)
and on its real ROS 2 driver (:class:`NED2RealRobot`), and the four robot envs the task envs
mix a task into.

Simulation: spawned from ``ned2_description`` (the frames of Niryo's ROS 2 driver's description, the
limits of Niryo's ``ned_ros``, the jaws of Niryo's Gripper 1, primitive geometry), the arm's group
position controller ``arm_position_controller``, the gripper's ``gripper_position_controller``
(joint_base_to_mors_1; joint_base_to_mors_2 mimics it, its axis reversed), the EE frame
``grasp_link`` between the jaw pads.

Real robot: Niryo's ROS 2 driver (``niryo_ned_ros2_driver``), which bridges the robot's ROS 1
interfaces under their own names in the namespace it is given (none by default): ``/joint_states``
and the arm's ``niryo_robot_follow_joint_trajectory_controller``, commanded through its
``follow_joint_trajectory`` action (the bridge offers the action; the ROS 1 ``command`` topic is not
the ROS 2 ``joint_trajectory`` one), with no ros2_control controller manager to ask (the twins do
not check controllers). The gripper is Niryo's tool commander
(``/niryo_robot_tools_commander/action_server``, ``niryo_ned_ros2_interfaces/action/Tool``), whose
interface definitions uniros does not ship: the push and pick-and-place twins need
``gripper_interface=`` (``"trajectory"``, ``"forward"`` or ``"gripper_action"`` with
``gripper_controller=``, e.g. a small bridge of yours) or ``gripper_interface="none"`` (the gripper
driven by your own node). Every name is an option (``namespace=``, ``arm_controller=``,
``joint_states_topic=``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence

from rl_environments.arm_ik import NED2TopDownIK
from rl_environments.arm_robot import ArmRobot
from rl_environments.arm_robot_envs import ArmRobotEnv, ArmRobotGoalEnv, ArmRobotRealEnv, ArmRobotRealGoalEnv
from rl_environments.real_arm_robot import RealArmRobot
from rl_environments.robots import ned2_description as pkg


class NED2Robot(ArmRobot):
    """The NED2's constants; see :class:`~rl_environments.arm_robot.ArmRobot`."""

    ROBOT_NAME = pkg.ROBOT_NAME
    DESCRIPTION_PACKAGE = pkg.PACKAGE_NAME
    DESCRIPTION_MODULE = "rl_environments.robots.ned2_description"
    XACRO_FILE = pkg.URDF_XACRO.name
    CONTROLLERS_FILE = pkg.CONTROLLERS_YAML.name
    ARM_JOINTS = pkg.ARM_JOINTS
    BASE_LINK = pkg.BASE_LINK
    EE_LINK = pkg.EE_LINK
    ARM_CONTROLLER = pkg.ARM_POSITION_CONTROLLER
    CONTROLLERS = pkg.SIM_CONTROLLERS
    GRIPPER_CONTROLLER = pkg.GRIPPER_POSITION_CONTROLLER
    FINGER_JOINTS = pkg.FINGER_JOINTS
    FINGER_MIMIC = 1.0
    SCENE = pkg.SCENE
    # The observation camera's default view (the description's render_camera's): lookat, distance,
    # azimuth, elevation, relative to the base.
    CAMERA_VIEW = ((0.2, 0.03, 0.16), 0.95, 140.0, -25.0)

    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> NED2TopDownIK:
        return NED2TopDownIK(lower, upper)


class NED2RealRobot(NED2Robot, RealArmRobot):
    """The NED2's real-robot constants (see :class:`~rl_environments.real_arm_robot.RealArmRobot`)."""

    REAL_NAMESPACE = pkg.REAL_NAMESPACE
    REAL_ARM_CONTROLLER = pkg.REAL_ARM_CONTROLLER
    REAL_CONTROLLERS = ()
    REAL_GRIPPER_CONTROLLER = ""
    REAL_GRIPPER_INTERFACE = "niryo_tool"
    REAL_COMMAND_INTERFACE = "action"  # the driver bridges the follow_joint_trajectory action
    REAL_CHECK_CONTROLLERS = False  # no ros2_control controller manager behind Niryo's bridge
    # The reach config's end-effector box (base frame); the floor 2 cm above the base plate.
    WORKSPACE_MIN = (-0.50, -0.50, 0.0)
    WORKSPACE_MAX = (0.50, 0.50, 0.70)
    FLOOR_Z = 0.02
    MAX_JOINT_DELTA = 0.15


class NED2RobotEnv(NED2Robot, ArmRobotEnv):
    """The NED2 robot layer for plain task envs on the simulation node."""


class NED2RobotGoalEnv(NED2Robot, ArmRobotGoalEnv):
    """The NED2 robot layer for goal-conditioned task envs on the simulation node."""


class NED2RobotRealEnv(NED2RealRobot, ArmRobotRealEnv):
    """The real NED2 robot layer for plain task envs."""


class NED2RobotRealGoalEnv(NED2RealRobot, ArmRobotRealGoalEnv):
    """The real NED2 robot layer for goal-conditioned task envs."""
