"""The abb_irb120_description package: xacro processing, reference numbers, controllers YAML."""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
import yourdfpy
from _urdf_tables import IRB120_FIXED, IRB120_INERTIALS, IRB120_JOINTS, floats, joints, links, total_mass, visual_bounds
from xacro_text import process

from rl_environments.robots import abb_irb120_description as pkg

ARM = list(pkg.ARM_JOINTS)


def test_package_files_exist():
    assert ET.parse(pkg.PACKAGE_DIR / "package.xml").getroot().findtext("name") == pkg.PACKAGE_NAME
    assert pkg.URDF_XACRO.is_file() and pkg.CONTROLLERS_YAML.is_file()


def test_default_args_load_in_yourdfpy(irb120_urdf):
    robot = yourdfpy.URDF.load(io.StringIO(irb120_urdf), build_scene_graph=True, load_meshes=False)
    assert robot.base_link == "world"
    assert set(IRB120_JOINTS) | set(IRB120_FIXED) <= set(robot.joint_map)
    assert {"base", "flange", "tool0"} <= set(robot.link_map)
    assert "<mesh" not in irb120_urdf


@pytest.mark.parametrize("name", sorted(IRB120_JOINTS))
def test_joint_matches_reference(irb120_urdf, name):
    jtype, parent, child, xyz, axis, lower, upper, velocity = IRB120_JOINTS[name]
    joint = joints(irb120_urdf)[name]
    assert joint.get("type") == jtype
    assert (joint.find("parent").get("link"), joint.find("child").get("link")) == (parent, child)
    np.testing.assert_allclose(floats(joint.find("origin").get("xyz")), xyz, atol=1e-12)
    np.testing.assert_allclose(floats(joint.find("origin").get("rpy")), 0.0, atol=1e-12)
    np.testing.assert_allclose(floats(joint.find("axis").get("xyz")), axis)
    limit = joint.find("limit")
    assert (float(limit.get("lower")), float(limit.get("upper"))) == (lower, upper)
    assert float(limit.get("velocity")) == velocity
    # A real, finite effort limit (ros-industrial has 0, FRobs_RL 1000).
    assert 1.0 <= float(limit.get("effort")) <= 200.0


@pytest.mark.parametrize("name", sorted(IRB120_FIXED))
def test_fixed_frames(irb120_urdf, name):
    parent, child, xyz, rpy = IRB120_FIXED[name]
    joint = joints(irb120_urdf)[name]
    assert joint.get("type") == "fixed"
    assert (joint.find("parent").get("link"), joint.find("child").get("link")) == (parent, child)
    np.testing.assert_allclose(floats(joint.find("origin").get("xyz")), xyz, atol=1e-12)
    np.testing.assert_allclose(floats(joint.find("origin").get("rpy")), rpy, atol=1e-12)


def test_effort_limit_of_j2_holds_the_stretched_arm_with_payload(irb120_urdf):
    # q2 = pi/2, q3 = -pi/2: the arm is horizontal and links 3-6 keep the base orientation, so each
    # COM's moment arm about J2 is its x in the base frame. 3 kg payload 0.1 m beyond the flange.
    arms = {"link_2": 0.10124, "link_3": 0.27 + 0.02281, "link_4": 0.27 + 0.2247,
            "link_5": 0.572 - 0.00109, "link_6": 0.644 - 0.00706}
    tau_j2 = 9.81 * (sum(IRB120_INERTIALS[k][0] * r for k, r in arms.items()) + 3.0 * 0.744)
    assert tau_j2 == pytest.approx(44.6, abs=0.2)
    assert float(joints(irb120_urdf)["joint_2"].find("limit").get("effort")) >= 2.5 * tau_j2


@pytest.mark.parametrize("link", sorted(IRB120_INERTIALS))
def test_inertial_matches_reference(irb120_urdf, link):
    mass, com, (ixx, ixy, ixz, iyy, iyz, izz) = IRB120_INERTIALS[link]
    inertial = links(irb120_urdf)[link].find("inertial")
    assert float(inertial.find("mass").get("value")) == mass
    np.testing.assert_allclose(floats(inertial.find("origin").get("xyz")), com)
    np.testing.assert_allclose(floats(inertial.find("origin").get("rpy")), 0.0)
    got = {k: float(v) for k, v in inertial.find("inertia").attrib.items()}
    assert got == pytest.approx(dict(ixx=ixx, ixy=ixy, ixz=ixz, iyy=iyy, iyz=iyz, izz=izz))


def test_total_mass(irb120_urdf):
    assert total_mass(irb120_urdf) == pytest.approx(18.15, rel=0.01)


def test_geometry_close_to_the_mesh_envelope(irb120_urdf):
    boxes = {
        "base_link": ((-0.211, 0.090), (-0.090, 0.090), (0, 0.166)),
        "link_1": ((-0.1075, 0.1075), (-0.1085, 0.1085), (0.155, 0.353)),
        "link_2": ((-0.072, 0.072), (-0.110, 0.109), (-0.072, 0.318)),
        "link_3": ((-0.089, 0.155), (-0.056, 0.060), (-0.049, 0.140)),
        "link_4": ((0.149, 0.342), (-0.064, 0.064), (-0.046, 0.060)),
        "link_5": ((-0.066, 0.066), (-0.035, 0.035), (-0.041, 0.041)),
        "link_6": ((-0.013, 0), (-0.020, 0.020), (-0.020, 0.020)),
    }
    robot = yourdfpy.URDF.load(io.StringIO(irb120_urdf), build_scene_graph=False, load_meshes=False)
    for link, expected in boxes.items():
        lo, hi = visual_bounds(robot.link_map[link])
        for axis in range(3):
            assert abs(lo[axis] - expected[axis][0]) <= 0.012, (link, axis, lo, expected)
            assert abs(hi[axis] - expected[axis][1]) <= 0.012, (link, axis, hi, expected)


def test_prefix_and_world_frame_args():
    urdf = process(pkg.URDF_XACRO, prefix="left_", use_world_frame="false")
    names = set(links(urdf))
    assert "world" not in names
    assert {"left_base_link", "left_link_6", "left_flange", "left_tool0"} <= names
    assert {f"left_{j}" for j in ARM} <= set(joints(urdf))
    assert ET.fromstring(urdf).find("ros2_control").get("name") == "left_irb120_system"


def test_ros2_control_block(irb120_urdf):
    block = ET.fromstring(irb120_urdf).find("ros2_control")
    assert block.get("type") == "system"
    assert block.find("hardware/plugin").text == "mujoco_ros2_control/MujocoSystem"
    assert [j.get("name") for j in block.findall("joint")] == ARM
    for joint in block.findall("joint"):
        assert [c.get("name") for c in joint.findall("command_interface")] == ["position", "velocity", "effort"]
        assert [s.get("name") for s in joint.findall("state_interface")] == ["position", "velocity", "effort"]


def test_controllers_yaml():
    cfg = yaml.safe_load(pkg.CONTROLLERS_YAML.read_text())
    cm = cfg["controller_manager"]["ros__parameters"]
    assert cm["joint_state_broadcaster"]["type"] == "joint_state_broadcaster/JointStateBroadcaster"
    assert cm["arm120_controller"]["type"] == "joint_trajectory_controller/JointTrajectoryController"
    assert cm["arm_position_controller"]["type"] == "position_controllers/JointGroupPositionController"
    traj = cfg["arm120_controller"]["ros__parameters"]
    assert traj["joints"] == ARM and traj["command_interfaces"] == ["position"]
    assert traj["constraints"]["goal_time"] == 0.6
    for ctrl in ("arm120_controller", "arm_position_controller"):
        gains = cfg[ctrl]["ros__parameters"]["gains"]
        assert list(gains) == ARM
        assert all(gains[j]["p"] > 0 and gains[j]["d"] > 0 for j in ARM)


def test_named_poses_within_limits(irb120_urdf):
    table = joints(irb120_urdf)
    for pose in (pkg.HOME_POSE, pkg.ARM_UP_POSE):
        for name, value in zip(ARM, pose):
            limit = table[name].find("limit")
            assert float(limit.get("lower")) <= value <= float(limit.get("upper"))
    assert math.isclose(pkg.ARM_UP_POSE[2], -1.5727)
