"""ROS description package ``abb_irb120_description``: the ABB IRB 120 (3 kg, 0.58 m) with primitive geometry.

Files:
    ``urdf/irb120.urdf.xacro``: the robot. Xacro args ``prefix`` (default empty, prepended to every
    link and joint name), ``use_world_frame`` (default true: fixed ``world`` -> ``<prefix>base_link``)
    and ``use_ros2_control`` (default true). It uses only ``$(arg ...)``, so it processes without
    any package lookup.
    ``config/irb120_controllers.yaml``: ros2_control controllers (``arm120_controller`` as in
    FRobs_RL) and per-joint torque-level PID gains.

The ``<ros2_control>`` block names the hardware plugin ``mujoco_ros2_control/MujocoSystem``, gives
initial positions as state-interface ``initial_value`` params, and points at the controllers file
twice, both as ``package://abb_irb120_description/config/irb120_controllers.yaml`` (never ``$(find ...)``, so
the xacro processes without package lookup): a hardware param ``controllers_file`` and a
gz_ros2_control-style ``<gazebo><plugin><parameters>`` element, which multiros' loader reads.

Kinematics, limits and inertials are the ros-industrial irb120_3_58 ones; effort limits (which
ros-industrial leaves at 0) are sized from the model's gravity and inertia loads with the rated
payload (see the xacro header). The link_1 collision cylinder starts just above the base so the
two never touch (MuJoCo does not exclude contacts between world-fused links and their children).
"""

from pathlib import Path

PACKAGE_NAME = "abb_irb120_description"
PACKAGE_DIR = Path(__file__).resolve().parent
URDF_XACRO = PACKAGE_DIR / "urdf" / "irb120.urdf.xacro"
CONTROLLERS_YAML = PACKAGE_DIR / "config" / "irb120_controllers.yaml"

ARM_JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6")
BASE_LINK = "base_link"
EE_LINK = "flange"  # MoveIt's tip in FRobs_RL; tool0 has the same origin, z out of the flange
TOOL_LINK = "tool0"

# Named poses from the MoveIt SRDF, rad.
HOME_POSE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
ARM_UP_POSE = (0.0, 0.0, -1.5727, 0.0, 0.0, 0.0)
