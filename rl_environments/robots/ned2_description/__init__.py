"""ROS description package ``ned2_description``: the Niryo Ned2 with its standard gripper, primitive geometry.

Sources: the link frames, masses and inertials of the Ned2 description in Niryo's ROS 2 driver
(``NiryoRobotics/ned-ros2-driver``, ``niryo_ned_description/urdf/ned2/niryo_ned2.urdf.xacro``, the
frames a real twin's TF carries), joint limits from Niryo's ``ned_ros``
(``niryo_robot_description/urdf/ned2/niryo_ned2_param.urdf.xacro``), the gripper's jaws from Niryo's
``niryo_gripper1.urdf.xacro`` and the driver's gripper mount. The home pose is pyniryo's
``move_to_home_pose``. No vendor meshes: primitive shapes (the jaw pad geometry is our assumption,
see the xacro header).

Files:
    ``urdf/ned2.urdf.xacro``: the robot. Xacro args ``prefix`` (default empty), ``use_world_frame``,
    ``use_gripper``, ``use_ros2_control`` (default true).
    ``config/ned2_controllers.yaml``: ros2_control controllers and the joint servo gains.
    ``mjcf/table.xml``, ``mjcf/cube.xml``: the push / pick-and-place scene sized for this arm (:data:`SCENE`).
"""

import math
from pathlib import Path

PACKAGE_NAME = "ned2_description"
PACKAGE_DIR = Path(__file__).resolve().parent
URDF_XACRO = PACKAGE_DIR / "urdf" / "ned2.urdf.xacro"
CONTROLLERS_YAML = PACKAGE_DIR / "config" / "ned2_controllers.yaml"
TABLE_MJCF = PACKAGE_DIR / "mjcf" / "table.xml"
OBJECT_MJCF = PACKAGE_DIR / "mjcf" / "cube.xml"

ROBOT_NAME = "ned2"  # entity name and namespace; link names carry no prefix (xacro arg prefix="")
ARM_JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6")
GRIPPER_JOINT = "joint_base_to_mors_1"  # m; joint_base_to_mors_2 mimics it (its axis is reversed)
FINGER_JOINTS = ("joint_base_to_mors_1", "joint_base_to_mors_2")
BASE_LINK = "base_link"
TOOL_LINK = "tool_link"  # Niryo's tool frame: x along the tool
EE_LINK = "grasp_link"  # between the jaw pads, same axes as tool_link
EE_APPROACH_AXIS = "x"

# Named arm poses in ARM_JOINTS order, rad. HOME: pyniryo's move_to_home_pose (the forearm resting
# over the shoulder). ZERO: all zeros (arm up, forearm and tool forward).
HOME_POSE = (0.0, 0.3, -1.3, 0.0, 0.0, 0.0)
ZERO_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
# joint_base_to_mors_1 (m): -0.01 closed (pads 0.7 mm apart) .. 0.01 open (40.7 mm).
GRIPPER_CLOSED, GRIPPER_OPEN = -0.01, 0.01
GRIPPER_HOME = GRIPPER_OPEN
JOINT_LIMITS_SOURCE = "Niryo ned_ros niryo_robot_description/urdf/ned2/niryo_ned2_param.urdf.xacro"
JOINT_LOWER = tuple(math.radians(v) for v in (-169.03, -119.75, -76.78, -119.75, -110.01, -144.96))
JOINT_UPPER = tuple(math.radians(v) for v in (169.03, 34.96, 89.96, 119.75, 60.17, 144.96))
REACH = 0.44  # m, Niryo's specified reach

# -- ros2_control controllers (config/ned2_controllers.yaml)
ARM_POSITION_CONTROLLER = "arm_position_controller"
GRIPPER_POSITION_CONTROLLER = "gripper_position_controller"
ARM_TRAJECTORY_CONTROLLER = "niryo_robot_follow_joint_trajectory_controller"
SIM_CONTROLLERS = ("joint_state_broadcaster", ARM_POSITION_CONTROLLER, GRIPPER_POSITION_CONTROLLER)

# -- the real robot's driver: Niryo's ROS 2 driver (niryo_ned_ros2_driver) bridges the robot's ROS 1
# interfaces under their own names, in the namespace given to the driver (none by default). The arm
# takes trajectories; the gripper is a tool commander action (niryo_ned_ros2_interfaces/action/Tool,
# open/close commands, not positions). Assumed: one robot, driver namespace "". Every name is a
# default a real twin may override.
REAL_NAMESPACE = ""
REAL_ARM_CONTROLLER = "niryo_robot_follow_joint_trajectory_controller"
REAL_ARM_ACTION = "/niryo_robot_follow_joint_trajectory_controller/follow_joint_trajectory"
REAL_ARM_TOPIC = "/niryo_robot_follow_joint_trajectory_controller/command"
REAL_JOINT_STATES = "/joint_states"
REAL_TOOL_ACTION = "/niryo_robot_tools_commander/action_server"
REAL_ROBOT_STATE = "/niryo_robot/robot_state"  # the TCP pose Niryo's stack computes

# -- push / pick-and-place scene (positions relative to the robot base; the robot stands on the
# table, its base at robot_height in the world). mjcf/table.xml and mjcf/cube.xml match these.
SCENE = {
    "robot_height": 0.30,
    "table_center": (0.15, 0.0, -0.1505),
    "table_half_extents": (0.35, 0.40, 0.1495),
    "table_top": -0.001,
    "object_half_size": 0.0125,  # a 2.5 cm cube of 17 g (the jaws open to 40.7 mm)
    "object_mass": 0.017,
    "init_ee_position": (0.22, 0.0, 0.12),
    "object_xy_min": (0.17, -0.12),
    "object_xy_max": (0.29, 0.12),
    "goal_xy_min": (0.17, -0.12),
    "goal_xy_max": (0.29, 0.12),
    "target_height_max": 0.12,
    "position_ee_min": (0.10, -0.30, 0.012),
    "position_ee_max": (0.38, 0.30, 0.30),
    "max_object_distance": 0.40,
}
