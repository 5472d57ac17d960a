"""ROS description package ``vx300s_description``: the Interbotix ViperX 300 6DOF with primitive geometry.

Sources: kinematics, joint limits, efforts, velocities, masses and inertials are Interbotix'
(``interbotix_xsarm_descriptions/urdf/vx300s.urdf.xacro`` of ``Interbotix/interbotix_ros_manipulators``,
ROS 2 branches); forward kinematics agrees with Interbotix' product-of-exponentials description
(``interbotix_xs_modules`` ``mr_descriptions.vx300s``: home ``M`` at (0.536494, 0, 0.42705));
the Sleep pose and the driver's controller names are from Interbotix' control packages (see below).
The vendor meshes are not shipped: the shapes are primitives (see the xacro header for the gripper
pads, whose inner-face position is our assumption).

Files:
    ``urdf/vx300s.urdf.xacro``: the robot. Xacro args ``robot_name`` (default ``vx300s``, the prefix of
    every link name: ``vx300s/base_link``), ``use_world_frame``, ``use_gripper`` and
    ``use_ros2_control`` (default true), as the RX200's. Only ``$(arg ...)`` and a relative include.
    ``config/vx300s_controllers.yaml``: ros2_control controllers and the joint servo gains.
    ``mjcf/table.xml``, ``mjcf/cube.xml``: the push / pick-and-place scene sized for this arm (:data:`SCENE`).
"""

import math
from pathlib import Path

PACKAGE_NAME = "vx300s_description"
PACKAGE_DIR = Path(__file__).resolve().parent
URDF_XACRO = PACKAGE_DIR / "urdf" / "vx300s.urdf.xacro"
CONTROLLERS_YAML = PACKAGE_DIR / "config" / "vx300s_controllers.yaml"
TABLE_MJCF = PACKAGE_DIR / "mjcf" / "table.xml"
OBJECT_MJCF = PACKAGE_DIR / "mjcf" / "cube.xml"

ROBOT_NAME = "vx300s"  # the xacro's default robot_name: entity name, namespace and link prefix
ARM_JOINTS = ("waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate")
GRIPPER_JOINT = "left_finger"  # the commanded finger; right_finger mimics it (x -1)
FINGER_JOINTS = ("left_finger", "right_finger")
BASE_LINK = "base_link"  # prefix with "<robot_name>/"
EE_LINK = "ee_gripper_link"  # prefix with "<robot_name>/": between the finger pads, x along the gripper
EE_APPROACH_AXIS = "x"  # the EE frame's axis that points out of the gripper

# Named arm poses in ARM_JOINTS order, rad. Sleep: Interbotix' sleep_positions for the vx300s.
HOME_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
SLEEP_POSE = (0.0, -1.85, 1.55, 0.0, 0.8, 0.0)
UPRIGHT_POSE = (0.0, 0.0, -1.5708, 0.0, 0.0, 0.0)
# left_finger positions (m): the URDF limits; the pads touch at ~0.0195 (below CLOSED).
GRIPPER_CLOSED, GRIPPER_HOME, GRIPPER_OPEN = 0.021, 0.039, 0.057
# Joint limits: the URDF's (Interbotix'); rad, in ARM_JOINTS order.
JOINT_LIMITS_SOURCE = "Interbotix interbotix_xsarm_descriptions vx300s.urdf.xacro"
_PI = math.pi - 1e-5  # Interbotix' pi_offset
JOINT_LOWER = (-_PI, math.radians(-106), math.radians(-101), -_PI, math.radians(-107), -_PI)
JOINT_UPPER = (_PI, math.radians(72), math.radians(92), _PI, math.radians(128), _PI)
REACH = 0.75  # m, Trossen's specified reach (stretched, 0.78 m from the shoulder axis to ee_gripper_link)

# -- ros2_control controllers (config/vx300s_controllers.yaml)
ARM_POSITION_CONTROLLER = "arm_position_controller"
GRIPPER_POSITION_CONTROLLER = "gripper_position_controller"
ARM_TRAJECTORY_CONTROLLER = "arm_controller"
SIM_CONTROLLERS = ("joint_state_broadcaster", ARM_POSITION_CONTROLLER, GRIPPER_POSITION_CONTROLLER)

# -- the real robot's driver (Interbotix' ROS 2 ros_control bringup, interbotix_xsarm_ros_control:
# controllers arm_controller and gripper_controller, both JointTrajectoryControllers, in the robot's
# namespace /vx300s). Assumed: that bringup (not the xs_sdk's own JointGroupCommand topics) runs the
# arm; every name is a default a real twin may override.
REAL_NAMESPACE = "/vx300s"
REAL_ARM_CONTROLLER = "arm_controller"
REAL_GRIPPER_CONTROLLER = "gripper_controller"
REAL_ARM_ACTION = "/vx300s/arm_controller/follow_joint_trajectory"
REAL_GRIPPER_ACTION = "/vx300s/gripper_controller/follow_joint_trajectory"
REAL_JOINT_STATES = "/vx300s/joint_states"

# -- push / pick-and-place scene (positions relative to the robot base; the robot stands on the
# table, its base at robot_height in the world). mjcf/table.xml and mjcf/cube.xml match these.
SCENE = {
    "robot_height": 0.40,  # world z of the base: 1 mm above the table top
    "table_center": (0.25, 0.0, -0.2005),  # table centre relative to the base
    "table_half_extents": (0.45, 0.55, 0.1995),  # table.xml's box half sizes
    "table_top": -0.001,
    "object_half_size": 0.02,  # cube.xml: a 4 cm cube of 70 g (the pads open to 75 mm)
    "object_mass": 0.07,
    "init_ee_position": (0.30, 0.0, 0.16),
    "object_xy_min": (0.24, -0.18),
    "object_xy_max": (0.46, 0.18),
    "goal_xy_min": (0.24, -0.18),
    "goal_xy_max": (0.46, 0.18),
    "target_height_max": 0.2,
    "position_ee_min": (0.10, -0.40, 0.02),
    "position_ee_max": (0.60, 0.40, 0.40),
    "max_object_distance": 0.65,
}
