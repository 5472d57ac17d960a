"""ROS description package ``ur5e_description``: the Universal Robots UR5e with a 2F-85-like gripper.

Sources: the UR5e's nominal DH parameters and Universal Robots' ``ur_description``
(``UniversalRobots/Universal_Robots_ROS2_Description``): the link frames of ``urdf/ur_macro.xacro``
built from the UR5e's default kinematics, ``config/ur5e/joint_limits.yaml`` (position, velocity and
effort limits) and ``config/ur5e/physical_parameters.yaml`` (masses, centres of mass, inertia
tensors). Forward kinematics equals the DH chain's (tests check it; at all zeros tool0 is at
(0.8172, 0.2329, 0.0628) in base_link, UR's (-817.2, -232.9, 62.8) mm in its Base frame). The
gripper is ours: a parallel two-finger gripper with the Robotiq 2F-85's stroke (85 mm) and pad
width (22 mm); see the xacro header. No vendor meshes: primitive shapes.

Files:
    ``urdf/ur5e.urdf.xacro``: the robot. Xacro args ``prefix`` (default empty, ur_description's
    ``tf_prefix``), ``use_world_frame``, ``use_gripper``, ``use_ros2_control`` (default true).
    ``config/ur5e_controllers.yaml``: ros2_control controllers and the joint servo gains.
    ``mjcf/table.xml``, ``mjcf/cube.xml``: the push / pick-and-place scene sized for this arm (:data:`SCENE`).
"""

import math
from pathlib import Path

PACKAGE_NAME = "ur5e_description"
PACKAGE_DIR = Path(__file__).resolve().parent
URDF_XACRO = PACKAGE_DIR / "urdf" / "ur5e.urdf.xacro"
CONTROLLERS_YAML = PACKAGE_DIR / "config" / "ur5e_controllers.yaml"
TABLE_MJCF = PACKAGE_DIR / "mjcf" / "table.xml"
OBJECT_MJCF = PACKAGE_DIR / "mjcf" / "cube.xml"

ROBOT_NAME = "ur5e"  # entity name and namespace; link names carry no prefix (xacro arg prefix="")
ARM_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")
GRIPPER_JOINT = "left_finger_joint"  # half the opening, m; right_finger_joint mimics it (x -1)
FINGER_JOINTS = ("left_finger_joint", "right_finger_joint")
BASE_LINK = "base_link"
FLANGE_LINK = "tool0"  # ur_description's tool frame: z out of the flange
EE_LINK = "grasp_link"  # between the pads, 0.128 m beyond tool0, same axes
EE_APPROACH_AXIS = "z"

# Named arm poses in ARM_JOINTS order, rad. ZERO: the DH zero (stretched along +x). UPRIGHT:
# ur_description's initial_positions. HOME: the tool straight down over the table (the start pose
# of the push / pick-and-place scene and the ros2_control initial values).
ZERO_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
UPRIGHT_POSE = (0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0, 0.0)
HOME_POSE = (0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0)
# left_finger_joint (half the opening, m).
GRIPPER_CLOSED, GRIPPER_OPEN = 0.0, 0.0425
GRIPPER_HOME = GRIPPER_OPEN
JOINT_LIMITS_SOURCE = "Universal Robots ur_description config/ur5e/joint_limits.yaml"
JOINT_LOWER = (-2 * math.pi, -2 * math.pi, -math.pi, -2 * math.pi, -2 * math.pi, -2 * math.pi)
JOINT_UPPER = (2 * math.pi, 2 * math.pi, math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi)
REACH = 0.85  # m, UR's specified reach
DH = {"d1": 0.1625, "a2": -0.425, "a3": -0.3922, "d4": 0.1333, "d5": 0.0997, "d6": 0.0996}

# -- ros2_control controllers (config/ur5e_controllers.yaml)
ARM_POSITION_CONTROLLER = "forward_position_controller"
GRIPPER_POSITION_CONTROLLER = "gripper_position_controller"
ARM_TRAJECTORY_CONTROLLER = "scaled_joint_trajectory_controller"
SIM_CONTROLLERS = ("joint_state_broadcaster", ARM_POSITION_CONTROLLER, GRIPPER_POSITION_CONTROLLER)

# -- the real robot's driver (Universal Robots' ur_robot_driver, default namespace "/", its
# controllers from ur_robot_driver/config/ur_controllers.yaml). The gripper: assumed a Robotiq 2F-85
# driven by PickNik's ros2_robotiq_gripper (a GripperActionController on
# robotiq_85_left_knuckle_joint, 0 = open .. 0.8 rad = closed); a twin maps the finger opening to
# that range. Every name is a default a real twin may override.
REAL_NAMESPACE = ""
REAL_ARM_CONTROLLER = "scaled_joint_trajectory_controller"
REAL_ARM_ACTION = "/scaled_joint_trajectory_controller/follow_joint_trajectory"
REAL_ARM_TOPIC = "/scaled_joint_trajectory_controller/joint_trajectory"
REAL_POSITION_CONTROLLER = "forward_position_controller"
REAL_JOINT_STATES = "/joint_states"
REAL_GRIPPER_CONTROLLER = "robotiq_gripper_controller"
REAL_GRIPPER_ACTION = "/robotiq_gripper_controller/gripper_cmd"
REAL_GRIPPER_JOINT = "robotiq_85_left_knuckle_joint"
REAL_GRIPPER_CLOSED, REAL_GRIPPER_OPEN = 0.8, 0.0  # rad of REAL_GRIPPER_JOINT

# -- push / pick-and-place scene (positions relative to the robot base; the robot stands on the
# table, its base at robot_height in the world). mjcf/table.xml and mjcf/cube.xml match these.
SCENE = {
    "robot_height": 0.40,
    "table_center": (0.30, 0.0, -0.2005),
    "table_half_extents": (0.55, 0.65, 0.1995),
    "table_top": -0.001,
    "object_half_size": 0.025,  # a 5 cm cube of 140 g (the fingers open to 85 mm)
    "object_mass": 0.14,
    "init_ee_position": (0.45, 0.0, 0.20),
    "object_xy_min": (0.35, -0.25),
    "object_xy_max": (0.62, 0.25),
    "goal_xy_min": (0.35, -0.25),
    "goal_xy_max": (0.62, 0.25),
    "target_height_max": 0.25,
    "position_ee_min": (0.20, -0.50, 0.025),
    "position_ee_max": (0.75, 0.50, 0.50),
    "max_object_distance": 0.80,
}
