"""ROS description package ``rx200_description``: the Interbotix ReactorX 200 with primitive geometry.

Files:
    ``urdf/rx200.urdf.xacro``: the robot (``urdf/primitives.xacro`` holds its macros). Xacro args
    ``robot_name`` (default ``rx200``, the prefix of every link name: ``rx200/base_link``),
    ``use_world_frame`` (default true: fixed ``world`` -> ``<robot_name>/base_link``),
    ``use_gripper`` (default true: gripper motor and fingers; the ``ee_gripper_link`` frame is
    always there), ``use_ros2_control`` (default true) and ``use_zed2`` (default false: a Zed2-like
    stereo camera in front of the table, publishing on the topics of Stereolabs' ROS 2 wrapper,
    ``/<robot_name>/zed2/zed_node/rgb/image_rect_color``, ``.../depth/depth_registered``, ...;
    see :mod:`multiros.sim.cameras`). It uses only ``$(arg ...)`` and a relative include, so it
    processes without any package lookup.
    ``config/rx200_controllers.yaml``: ros2_control controllers and per-joint PID gains.

The ``<ros2_control>`` block names the hardware plugin ``mujoco_ros2_control/MujocoSystem``, gives
initial positions as state-interface ``initial_value`` params, and points at the controllers file
twice, both as ``package://rx200_description/config/rx200_controllers.yaml`` (never ``$(find ...)``, so
the xacro processes without package lookup): a hardware param ``controllers_file`` and a
gz_ros2_control-style ``<gazebo><plugin><parameters>`` element, which multiros' loader reads.

Kinematics, limits, dynamics and inertials are Interbotix' (joint names unprefixed, damping and
friction 0.1 on moving joints); the 1 g dummy frames get 1e-6 kg m^2 instead of 0.001. Collision
simplifications (visuals keep the full envelope): the shoulder collides with its turntable only and
the upper arm capsule has no sphere at the shoulder end, so the Sleep pose is contact-free; the
gripper horn is visual only; finger collision boxes start where the gripper bar ends.
"""

from pathlib import Path

PACKAGE_NAME = "rx200_description"
PACKAGE_DIR = Path(__file__).resolve().parent
URDF_XACRO = PACKAGE_DIR / "urdf" / "rx200.urdf.xacro"
CONTROLLERS_YAML = PACKAGE_DIR / "config" / "rx200_controllers.yaml"

ARM_JOINTS = ("waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate")
GRIPPER_JOINTS = ("gripper", "left_finger", "right_finger")
BASE_LINK = "base_link"  # prefix with "<robot_name>/"
EE_LINK = "ee_gripper_link"  # prefix with "<robot_name>/"

# Named arm poses (waist, shoulder, elbow, wrist_angle, wrist_rotate), rad.
HOME_POSE = (0.0, 0.0, 0.0, 0.0, 0.0)
SLEEP_POSE = (0.0, -1.80, 1.55, 0.8, 0.0)
UPRIGHT_POSE = (0.0, 0.0, -1.5708, 0.0, 0.0)
# left_finger positions (m); right_finger mirrors them.
GRIPPER_CLOSED, GRIPPER_HOME, GRIPPER_OPEN = 0.015, 0.0195, 0.037

# -- push / pick-and-place scene (positions relative to the robot base; the robot stands on the
# table, its base at robot_height in the world). mjcf/table.xml and mjcf/cube.xml match these.
SCENE = {
    "robot_height": 0.30,  # world z of the base: 1 mm above the table top (table.xml: top at z = 0.299)
    "table_center": (0.175, 0.0, -0.1505),  # table centre relative to the base
    "table_half_extents": (0.375, 0.40, 0.1495),  # table.xml's box half sizes
    "table_top": -0.001,
    "object_half_size": 0.015,  # cube.xml: a 3 cm cube of 30 g
    "object_mass": 0.03,
    "init_ee_position": (0.20, 0.0, 0.10),  # the gripper above the table, pointing down
    "object_xy_min": (0.15, -0.14),
    "object_xy_max": (0.31, 0.14),
    "goal_xy_min": (0.15, -0.14),
    "goal_xy_max": (0.31, 0.14),
    "target_height_max": 0.15,
    "position_ee_min": (0.06, -0.30, 0.018),  # z: the finger tips stay 2 mm above the table
    "position_ee_max": (0.40, 0.30, 0.25),
    "max_object_distance": 0.45,
}
