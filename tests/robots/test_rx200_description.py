"""The rx200_description package: xacro processing, reference numbers, controllers YAML."""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
import yourdfpy
from _urdf_tables import RX200_INERTIALS, RX200_JOINTS, floats, joints, links, total_mass, visual_bounds
from xacro_text import process

from rl_environments.robots import rx200_description as pkg

ARM = list(pkg.ARM_JOINTS)


def test_package_files_exist():
    assert (pkg.PACKAGE_DIR / "package.xml").is_file()
    assert ET.parse(pkg.PACKAGE_DIR / "package.xml").getroot().findtext("name") == pkg.PACKAGE_NAME
    assert pkg.URDF_XACRO.is_file() and pkg.CONTROLLERS_YAML.is_file()


def test_default_args_load_in_yourdfpy(rx200_urdf):
    robot = yourdfpy.URDF.load(io.StringIO(rx200_urdf), build_scene_graph=True, load_meshes=False)
    assert robot.base_link == "world"
    assert set(RX200_JOINTS) <= set(robot.joint_map)
    assert "rx200/ee_gripper_link" in robot.link_map
    assert "<mesh" not in rx200_urdf  # primitives only


@pytest.mark.parametrize("name", sorted(RX200_JOINTS))
def test_joint_matches_reference(rx200_urdf, name):
    jtype, parent, child, xyz, axis, lower, upper, effort, velocity = RX200_JOINTS[name]
    joint = joints(rx200_urdf)[name]
    assert joint.get("type") == jtype
    assert joint.find("parent").get("link") == f"rx200/{parent}"
    assert joint.find("child").get("link") == f"rx200/{child}"
    origin = joint.find("origin")
    np.testing.assert_allclose(floats(origin.get("xyz")), xyz, atol=1e-9)
    np.testing.assert_allclose(floats(origin.get("rpy")), 0.0, atol=1e-12)
    if jtype == "fixed":
        return
    np.testing.assert_allclose(floats(joint.find("axis").get("xyz")), axis)
    limit = joint.find("limit")
    assert float(limit.get("effort")) == effort
    assert float(limit.get("velocity")) == pytest.approx(velocity)
    if lower is not None:
        assert float(limit.get("lower")) == pytest.approx(lower, abs=1e-5)
        assert float(limit.get("upper")) == pytest.approx(upper, abs=1e-5)
    dynamics = joint.find("dynamics")
    assert float(dynamics.get("damping")) == 0.1 and float(dynamics.get("friction")) == 0.1


def test_right_finger_mimics_left(rx200_urdf):
    mimic = joints(rx200_urdf)["right_finger"].find("mimic")
    assert mimic.get("joint") == "left_finger" and float(mimic.get("multiplier")) == -1.0


@pytest.mark.parametrize("link", sorted(RX200_INERTIALS))
def test_inertial_matches_reference_with_rpy(rx200_urdf, link):
    mass, com, rpy, (ixx, iyy, izz, ixy, ixz, iyz) = RX200_INERTIALS[link]
    inertial = links(rx200_urdf)[f"rx200/{link}"].find("inertial")
    assert float(inertial.find("mass").get("value")) == mass
    np.testing.assert_allclose(floats(inertial.find("origin").get("xyz")), com)
    np.testing.assert_allclose(floats(inertial.find("origin").get("rpy")), rpy, atol=1e-12)
    got = {k: float(v) for k, v in inertial.find("inertia").attrib.items()}
    assert got == pytest.approx(dict(ixx=ixx, iyy=iyy, izz=izz, ixy=ixy, ixz=ixz, iyz=iyz))


def test_dummy_links_have_small_inertia(rx200_urdf):
    for link in ("ee_arm_link", "fingers_link", "ee_gripper_link"):
        inertial = links(rx200_urdf)[f"rx200/{link}"].find("inertial")
        assert float(inertial.find("mass").get("value")) == 0.001
        assert all(float(v) <= 1e-6 for v in inertial.find("inertia").attrib.values())


def test_total_mass(rx200_urdf):
    assert total_mass(rx200_urdf) == pytest.approx(1.81, rel=0.02)


def test_every_link_has_geometry_close_to_the_mesh_envelope(rx200_urdf):
    # Visual envelope of each link vs the mesh bounding boxes (x, y, z ranges), within ~1 cm.
    boxes = {
        "base_link": ((-0.172, 0.0765), (-0.0765, 0.0765), (0, 0.065)),
        "shoulder_link": ((-0.0635, 0.0635), (-0.0635, 0.0635), (-0.003, 0.0495)),
        "upper_arm_link": ((-0.0144, 0.0612), (-0.0234, 0.0211), (-0.0144, 0.218)),
        "forearm_link": ((-0.0037, 0.2112), (-0.023, 0.023), (-0.0185, 0.0185)),
        "wrist_link": ((-0.0034, 0.065), (-0.022, 0.022), (-0.020, 0.0353)),
        "gripper_link": ((0, 0.043), (-0.020, 0.020), (-0.020, 0.0353)),
        "gripper_bar_link": ((0, 0.028), (-0.0517, 0.0517), (-0.014, 0.0353)),
        "left_finger_link": ((-0.0121, 0.0432), (-0.011, 0.005), (-0.0145, 0.0145)),
        "right_finger_link": ((-0.0121, 0.0432), (-0.005, 0.011), (-0.0145, 0.0145)),
    }
    robot = yourdfpy.URDF.load(io.StringIO(rx200_urdf), build_scene_graph=False, load_meshes=False)
    for link, expected in boxes.items():
        lo, hi = visual_bounds(robot.link_map[f"rx200/{link}"])
        for axis in range(3):
            assert abs(lo[axis] - expected[axis][0]) <= 0.011, (link, axis, lo, expected)
            assert abs(hi[axis] - expected[axis][1]) <= 0.011, (link, axis, hi, expected)


def test_args_prefix_world_frame_and_gripper():
    urdf = process(pkg.URDF_XACRO, robot_name="arm2", use_world_frame="false", use_gripper="false")
    names = set(links(urdf))
    assert "world" not in names
    assert "arm2/base_link" in names and "arm2/ee_gripper_link" in names
    assert not any(n.startswith("rx200/") for n in names)
    assert "arm2/left_finger_link" not in names and "left_finger" not in joints(urdf)
    assert set(ARM) <= set(joints(urdf))
    root = ET.fromstring(urdf)
    assert root.find("ros2_control").get("name") == "arm2_system"
    no_control = process(pkg.URDF_XACRO, use_ros2_control="false")
    assert ET.fromstring(no_control).find("ros2_control") is None


def test_ros2_control_block(rx200_urdf):
    block = ET.fromstring(rx200_urdf).find("ros2_control")
    assert block.get("type") == "system"
    assert block.find("hardware/plugin").text == "mujoco_ros2_control/MujocoSystem"
    params = {p.get("name"): p.text for p in block.findall("hardware/param")}
    assert params["controllers_file"] == "package://rx200_description/config/rx200_controllers.yaml"
    by_name = {j.get("name"): j for j in block.findall("joint")}
    for name in [*ARM, "left_finger"]:
        assert [c.get("name") for c in by_name[name].findall("command_interface")] == [
            "position", "velocity", "effort"]
        assert [s.get("name") for s in by_name[name].findall("state_interface")] == [
            "position", "velocity", "effort"]
    assert by_name["right_finger"].findall("command_interface") == []


def test_controllers_yaml():
    cfg = yaml.safe_load(pkg.CONTROLLERS_YAML.read_text())
    cm = cfg["controller_manager"]["ros__parameters"]
    assert cm["update_rate"] == 500
    assert cm["joint_state_broadcaster"]["type"] == "joint_state_broadcaster/JointStateBroadcaster"
    assert cm["arm_controller"]["type"] == "joint_trajectory_controller/JointTrajectoryController"
    assert cm["arm_position_controller"]["type"] == "position_controllers/JointGroupPositionController"
    assert cm["gripper_controller"]["type"] == "position_controllers/JointGroupPositionController"
    arm = cfg["arm_controller"]["ros__parameters"]
    assert arm["joints"] == ARM
    assert arm["command_interfaces"] == ["position"]
    assert arm["state_interfaces"] == ["position", "velocity"]
    assert cfg["arm_position_controller"]["ros__parameters"]["joints"] == ARM
    assert cfg["gripper_controller"]["ros__parameters"]["joints"] == ["left_finger"]
    for ctrl in ("arm_controller", "arm_position_controller"):
        gains = cfg[ctrl]["ros__parameters"]["gains"]
        assert list(gains) == ARM
        # p and i are the Interbotix Gazebo effort-controller gains.
        assert [gains[j]["p"] for j in ARM] == [100, 500, 300, 100, 100]
        assert [gains[j]["i"] for j in ARM] == [5, 10, 10, 3, 1]
        assert all(gains[j]["d"] > 0 for j in ARM)


def test_named_poses_are_within_limits(rx200_urdf):
    table = joints(rx200_urdf)
    for pose in (pkg.HOME_POSE, pkg.SLEEP_POSE, pkg.UPRIGHT_POSE):
        for name, value in zip(ARM, pose):
            limit = table[name].find("limit")
            assert float(limit.get("lower")) <= value <= float(limit.get("upper"))
    assert math.isclose(pkg.GRIPPER_HOME, 0.0195)


def test_zed2_option_adds_a_stereo_pair_on_the_zed_wrapper_topics(rx200_urdf):
    def sensors(urdf):
        return {s.get("name"): s for s in ET.fromstring(urdf).iter("sensor")}

    assert set(sensors(rx200_urdf)) == {"render_camera"}, "off by default"
    zed = sensors(process(pkg.URDF_XACRO, use_zed2="true"))
    left, right = zed["zed2_left"], zed["zed2_right"]
    assert left.get("type") == "depth" and right.get("type") == "camera"
    assert left.findtext("plugin/ros/namespace") == "/rx200/zed2/zed_node"
    assert left.findtext("plugin/camera_name") == "rgb" and right.findtext("plugin/camera_name") == "right"
    remaps = [r.text for r in left.findall("plugin/ros/remapping")]
    assert "rgb/image_raw:=rgb/image_rect_color" in remaps and "rgb/depth/image_raw:=depth/depth_registered" in remaps
    # The right camera sits 0.12 m (the Zed2's baseline) to the right of the left one, same orientation.
    pl, pr = floats(left.findtext("pose")), floats(right.findtext("pose"))
    assert np.linalg.norm(pl[:3] - pr[:3]) == pytest.approx(0.12) and np.allclose(pl[3:], pr[3:])
    # 640 x 360 with the Zed2's 70 degree vertical field of view.
    hfov = float(left.findtext("camera/horizontal_fov"))
    assert math.degrees(2 * math.atan(math.tan(hfov / 2) * 360 / 640)) == pytest.approx(70.0, abs=0.1)
