"""The vx300s, ur5e and ned2 description packages against their vendors' numbers: joint tables and
limits, forward kinematics at named poses (Interbotix' product of exponentials, UR's DH chain,
Niryo's joint frames), masses, controllers YAML and driver names, the scene files; and the top-down
IK of rl_environments.arm_ik."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from importlib.metadata import entry_points

import mujoco
import numpy as np
import pytest
import yaml
from _urdf_tables import floats, joints, total_mass
from xacro_text import process

from multiros.utils.kinematics import KinematicChain
from rl_environments.arm_registry import arm_of, top_down_ik_of
from rl_environments.robots import ned2_description as ned2
from rl_environments.robots import ur5e_description as ur5e
from rl_environments.robots import vx300s_description as vx300s

PACKAGES = {"vx300s": vx300s, "ur5e": ur5e, "ned2": ned2}
PI = math.pi
rad = math.radians


@pytest.fixture(scope="module", params=sorted(PACKAGES))
def arm(request):
    pkg = PACKAGES[request.param]
    return request.param, pkg, process(pkg.URDF_XACRO)


def _link(pkg, name: str) -> str:
    return f"{pkg.ROBOT_NAME}/{name}" if pkg is vx300s else name


def _chain(pkg, tip: str) -> KinematicChain:
    return KinematicChain.from_urdf(pkg.URDF_XACRO, _link(pkg, pkg.BASE_LINK), _link(pkg, tip))


# ------------------------------------------------------------------ vendor tables (read from the sources)
# Interbotix vx300s.urdf.xacro: joint -> (xyz, axis, lower, upper, effort, velocity).
VX300S_JOINTS = {
    "waist": ((0, 0, 0.079), (0, 0, 1), -PI + 1e-5, PI - 1e-5, 10, PI),
    "shoulder": ((0, 0, 0.04805), (0, 1, 0), rad(-106), rad(72), 20, PI),
    "elbow": ((0.05955, 0, 0.3), (0, 1, 0), rad(-101), rad(92), 15, PI),
    "forearm_roll": ((0.2, 0, 0), (1, 0, 0), -PI + 1e-5, PI - 1e-5, 2, PI),
    "wrist_angle": ((0.1, 0, 0), (0, 1, 0), rad(-107), rad(128), 5, PI),
    "wrist_rotate": ((0.069744, 0, 0), (1, 0, 0), -PI + 1e-5, PI - 1e-5, 1, PI),
    "left_finger": ((0, 0, 0), (0, 1, 0), 0.021, 0.057, 5, 1),
    "right_finger": ((0, 0, 0), (0, 1, 0), -0.057, -0.021, 5, 1),
}
VX300S_FIXED = {"ee_arm": 0.042825, "ee_bar": 0.025875, "ee_gripper": 0.0385}
# Interbotix mr_descriptions.vx300s (space-frame screw axes and home pose of ee_gripper_link).
VX300S_SLIST = np.array([[0, 0, 1, 0, 0, 0], [0, 1, 0, -0.12705, 0, 0], [0, 1, 0, -0.42705, 0, 0.05955],
                         [1, 0, 0, 0, 0.42705, 0], [0, 1, 0, -0.42705, 0, 0.35955],
                         [1, 0, 0, 0, 0.42705, 0]], dtype=float).T
VX300S_M = np.array([[1, 0, 0, 0.536494], [0, 1, 0, 0], [0, 0, 1, 0.42705], [0, 0, 0, 1]], dtype=float)

# ur_description config/ur5e/joint_limits.yaml: (lower, upper, effort), all at 180 deg/s.
UR5E_LIMITS = {"shoulder_pan_joint": (-2 * PI, 2 * PI, 150), "shoulder_lift_joint": (-2 * PI, 2 * PI, 150),
               "elbow_joint": (-PI, PI, 150), "wrist_1_joint": (-2 * PI, 2 * PI, 28),
               "wrist_2_joint": (-2 * PI, 2 * PI, 28), "wrist_3_joint": (-2 * PI, 2 * PI, 28)}
UR5E_MASSES = {"shoulder_link": 3.761, "upper_arm_link": 8.058, "forearm_link": 2.846, "wrist_1_link": 1.37,
               "wrist_2_link": 1.3, "wrist_3_link": 0.365}

# Niryo: joint frames of ned-ros2-driver's niryo_ned2.urdf.xacro (xyz, rpy), limits of ned_ros'
# niryo_ned2_param.urdf.xacro (deg), effort and velocity of the URDF.
NED2_JOINTS = {
    "joint_1": ((0, 0, 0.1013), (0, 0, 0), -169.03, 169.03, 10.0, 10.0),
    "joint_2": ((0, 0, 0.065), (PI / 2, 0, 0), -119.75, 34.96, 10.0, 8.0),
    "joint_3": ((0.012, 0.221, 0), (0, 0, PI / 2), -76.78, 89.96, 7.0, 8.0),
    "joint_4": ((0.0325, -0.065, 0), (PI / 2, 0, 0), -119.75, 119.75, 7.0, 2.0),
    "joint_5": ((0, 0, 0.17), (-PI / 2, 0, 0), -110.01, 60.17, 6.0, 2.0),
    "joint_6": ((0.00925, -0.0197, 0), (PI / 2, 0, 0), -144.96, 144.96, 5.0, 2.0),
}
NED2_TOOL = ((0, 0, 0.0215), (PI, -PI / 2, 0))
NED2_MASSES = {"shoulder_link": 0.35056, "arm_link": 1.0838, "elbow_link": 0.22126, "forearm_link": 0.35686,
               "wrist_link": 0.22126, "hand_link": 0.0070027}


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], [-sp, cp * sr, cp * cr]])


def _tf(xyz, rpy=(0, 0, 0), rot=None) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = _rpy(*rpy) if rot is None else rot
    t[:3, 3] = xyz
    return t


def _rz(q: float) -> np.ndarray:
    return _tf((0, 0, 0), (0, 0, q))


def _expm_screw(s: np.ndarray, q: float) -> np.ndarray:
    """exp([S] q) of a unit revolute screw axis S = (w, v)."""
    w, v = s[:3], s[3:]
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    rot = np.eye(3) + np.sin(q) * k + (1 - np.cos(q)) * k @ k
    p = (np.eye(3) * q + (1 - np.cos(q)) * k + (q - np.sin(q)) * k @ k) @ v
    return _tf(p, rot=rot)


def vx300s_poe(q) -> np.ndarray:
    t = np.eye(4)
    for i in range(6):
        t = t @ _expm_screw(VX300S_SLIST[:, i], q[i])
    return t @ VX300S_M


def ur5e_dh(q) -> np.ndarray:
    """UR's DH chain in ROS' base_link (UR's Base turned by pi about z), ending at tool0."""
    d = [ur5e.DH["d1"], 0, 0, ur5e.DH["d4"], ur5e.DH["d5"], ur5e.DH["d6"]]
    a = [0, ur5e.DH["a2"], ur5e.DH["a3"], 0, 0, 0]
    alpha = [PI / 2, 0, 0, PI / 2, -PI / 2, 0]
    t = _rz(PI)
    for i in range(6):
        ct, st, ca, sa = np.cos(q[i]), np.sin(q[i]), np.cos(alpha[i]), np.sin(alpha[i])
        t = t @ np.array([[ct, -st * ca, st * sa, a[i] * ct], [st, ct * ca, -ct * sa, a[i] * st],
                          [0, sa, ca, d[i]], [0, 0, 0, 1]])
    return t


def ned2_vendor_fk(q) -> np.ndarray:
    t = np.eye(4)
    for (xyz, rpy, *_), qi in zip(NED2_JOINTS.values(), q):
        t = t @ _tf(xyz, rpy) @ _rz(qi)
    return t @ _tf(*NED2_TOOL)


# ------------------------------------------------------------------ package files
def test_packages_are_registered_and_complete(arm):
    name, pkg, _ = arm
    assert ET.parse(pkg.PACKAGE_DIR / "package.xml").getroot().findtext("name") == pkg.PACKAGE_NAME
    for path in (pkg.URDF_XACRO, pkg.CONTROLLERS_YAML, pkg.TABLE_MJCF, pkg.OBJECT_MJCF):
        assert path.is_file(), path
    registered = {ep.name: ep.value for ep in entry_points(group="uniros.description_packages")}
    assert registered[pkg.PACKAGE_NAME] == f"rl_environments.robots.{pkg.PACKAGE_NAME}"


def test_primitives_only_and_args(arm):
    name, pkg, urdf = arm
    assert "<mesh" not in urdf
    prefix_arg = {"robot_name": "arm2"} if pkg is vx300s else {"prefix": "arm2_"}
    other = process(pkg.URDF_XACRO, use_world_frame="false", use_gripper="false", use_ros2_control="false",
                    **prefix_arg)
    root = ET.fromstring(other)
    names = {e.get("name") for e in root.findall("link")}
    assert "world" not in names and root.find("ros2_control") is None
    assert not any(j.get("name") == pkg.GRIPPER_JOINT or j.get("name", "").endswith(pkg.GRIPPER_JOINT)
                   for j in root.findall("joint"))
    ee = f"arm2/{pkg.EE_LINK}" if pkg is vx300s else f"arm2_{pkg.EE_LINK}"
    assert ee in names, "the EE frame stays without the gripper"


# ------------------------------------------------------------------ joint tables and limits
def test_vx300s_joints_match_interbotix():
    table = joints(process(vx300s.URDF_XACRO))
    for name, (xyz, axis, lower, upper, effort, velocity) in VX300S_JOINTS.items():
        joint = table[name]
        np.testing.assert_allclose(floats(joint.find("origin").get("xyz")), xyz, atol=1e-12)
        np.testing.assert_allclose(floats(joint.find("axis").get("xyz")), axis)
        limit = joint.find("limit")
        assert float(limit.get("lower")) == pytest.approx(lower, abs=1e-9), name
        assert float(limit.get("upper")) == pytest.approx(upper, abs=1e-9), name
        assert float(limit.get("effort")) == effort and float(limit.get("velocity")) == pytest.approx(velocity)
    for name, x in VX300S_FIXED.items():
        np.testing.assert_allclose(floats(table[name].find("origin").get("xyz")), (x, 0, 0))
    assert table["right_finger"].find("mimic").get("joint") == "left_finger"


def test_ur5e_limits_match_ur_description():
    table = joints(process(ur5e.URDF_XACRO))
    for name, (lower, upper, effort) in UR5E_LIMITS.items():
        limit = table[name].find("limit")
        assert float(limit.get("lower")) == pytest.approx(lower) and float(limit.get("upper")) == pytest.approx(upper)
        assert float(limit.get("effort")) == effort and float(limit.get("velocity")) == pytest.approx(PI)


def test_ned2_joints_match_niryo():
    table = joints(process(ned2.URDF_XACRO))
    for name, (xyz, rpy, lower, upper, effort, velocity) in NED2_JOINTS.items():
        joint = table[name]
        np.testing.assert_allclose(floats(joint.find("origin").get("xyz")), xyz, atol=1e-12)
        np.testing.assert_allclose(floats(joint.find("origin").get("rpy")), rpy, atol=1e-12)
        limit = joint.find("limit")
        assert float(limit.get("lower")) == pytest.approx(rad(lower)) and float(limit.get("upper")) == pytest.approx(
            rad(upper))
        assert float(limit.get("effort")) == effort and float(limit.get("velocity")) == velocity
    for jaw in ned2.FINGER_JOINTS:
        limit = table[jaw].find("limit")
        assert (float(limit.get("lower")), float(limit.get("upper")), float(limit.get("effort"))) == (-0.01, 0.01, 1.0)


def test_limit_constants_are_the_urdf_limits(arm):
    name, pkg, urdf = arm
    chain = _chain(pkg, pkg.EE_LINK)
    assert chain.joint_names == tuple(pkg.ARM_JOINTS)
    np.testing.assert_allclose(chain.lower, pkg.JOINT_LOWER, atol=1e-9)
    np.testing.assert_allclose(chain.upper, pkg.JOINT_UPPER, atol=1e-9)
    finger = joints(urdf)[pkg.GRIPPER_JOINT].find("limit")
    assert {float(finger.get("lower")), float(finger.get("upper"))} == {pkg.GRIPPER_CLOSED, pkg.GRIPPER_OPEN}
    for pose_name in ("HOME_POSE", "SLEEP_POSE", "UPRIGHT_POSE", "ZERO_POSE"):
        pose = getattr(pkg, pose_name, None)
        if pose is not None:
            assert np.all(chain.lower <= pose) and np.all(pose <= chain.upper), pose_name


def test_masses(arm):
    name, pkg, urdf = arm
    links = {e.get("name"): e for e in ET.fromstring(urdf).findall("link")}
    vendor = {"ur5e": UR5E_MASSES, "ned2": NED2_MASSES, "vx300s": {}}[name]
    for link, mass in vendor.items():
        assert float(links[link].find("inertial/mass").get("value")) == mass
    expected = {"vx300s": 3.75, "ur5e": 22.6, "ned2": 3.05}[name]  # vendor arm + our gripper parts
    assert total_mass(urdf) == pytest.approx(expected, rel=0.03)


# ------------------------------------------------------------------ forward kinematics
def _random_q(pkg, n: int = 8) -> np.ndarray:
    rng = np.random.default_rng(1)
    low, high = np.maximum(pkg.JOINT_LOWER, -PI), np.minimum(pkg.JOINT_UPPER, PI)
    return rng.uniform(low, high, size=(n, len(pkg.ARM_JOINTS)))


def test_vx300s_fk_matches_interbotix_product_of_exponentials():
    chain = _chain(vx300s, vx300s.EE_LINK)
    poses = [vx300s.HOME_POSE, vx300s.SLEEP_POSE, vx300s.UPRIGHT_POSE, *_random_q(vx300s)]
    for q in poses:
        np.testing.assert_allclose(chain.fk_matrix(np.asarray(q)), vx300s_poe(q), atol=1e-9)
    np.testing.assert_allclose(chain.fk_matrix(np.zeros(6))[:3, 3], (0.536494, 0, 0.42705), atol=1e-9)


def test_ur5e_fk_matches_the_dh_chain():
    chain = _chain(ur5e, ur5e.FLANGE_LINK)
    for q in [ur5e.ZERO_POSE, ur5e.UPRIGHT_POSE, ur5e.HOME_POSE, *_random_q(ur5e)]:
        np.testing.assert_allclose(chain.fk_matrix(np.asarray(q)), ur5e_dh(q), atol=1e-9)
    # UR's zero pose: TCP (no tool) at (-817.2, -232.9, 62.8) mm in UR's Base = base_link turned by pi.
    np.testing.assert_allclose(chain.fk_matrix(np.zeros(6))[:3, 3], (0.8172, 0.2329, 0.0628), atol=1e-9)
    # HOME points the tool straight down.
    np.testing.assert_allclose(chain.fk_matrix(np.asarray(ur5e.HOME_POSE))[:3, 2], (0, 0, -1), atol=1e-6)


def test_ned2_fk_matches_niryos_frames():
    chain = _chain(ned2, ned2.TOOL_LINK)
    for q in [ned2.HOME_POSE, ned2.ZERO_POSE, *_random_q(ned2)]:
        np.testing.assert_allclose(chain.fk_matrix(np.asarray(q)), ned2_vendor_fk(q), atol=1e-9)
    # All zeros: arm up, forearm forward, tool_link x (the tool axis) forward.
    zero = chain.fk_matrix(np.zeros(6))
    np.testing.assert_allclose(zero[:3, 3], (0.012 + 0.065 + 0.17 + 0.0197 + 0.0215, 0, 0.1013 + 0.065 + 0.221
                                             + 0.0325 + 0.00925), atol=1e-9)
    np.testing.assert_allclose(zero[:3, 0], (1, 0, 0), atol=1e-9)


# ------------------------------------------------------------------ controllers and driver names
def test_controllers_yaml(arm):
    name, pkg, _ = arm
    cfg = yaml.safe_load(pkg.CONTROLLERS_YAML.read_text())
    types = cfg["controller_manager"]["ros__parameters"]
    arm_joints = list(pkg.ARM_JOINTS)
    assert types[pkg.ARM_TRAJECTORY_CONTROLLER]["type"] == "joint_trajectory_controller/JointTrajectoryController"
    for controller in (pkg.ARM_POSITION_CONTROLLER, pkg.GRIPPER_POSITION_CONTROLLER):
        assert types[controller]["type"] == "position_controllers/JointGroupPositionController"
    assert cfg[pkg.ARM_TRAJECTORY_CONTROLLER]["ros__parameters"]["joints"] == arm_joints
    assert cfg[pkg.ARM_POSITION_CONTROLLER]["ros__parameters"]["joints"] == arm_joints
    assert cfg[pkg.GRIPPER_POSITION_CONTROLLER]["ros__parameters"]["joints"] == [pkg.GRIPPER_JOINT]
    assert cfg["joint_state_broadcaster"]["ros__parameters"]["joints"] == [*arm_joints, pkg.GRIPPER_JOINT]
    for controller in (pkg.ARM_TRAJECTORY_CONTROLLER, pkg.ARM_POSITION_CONTROLLER):
        gains = cfg[controller]["ros__parameters"]["gains"]
        assert list(gains) == arm_joints and all(g["p"] > 0 and g["d"] > 0 for g in gains.values())
    assert set(pkg.SIM_CONTROLLERS) <= set(types)
    # The real drivers' names (what a real twin connects to by default).
    controller = {"vx300s": "arm_controller", "ur5e": "scaled_joint_trajectory_controller",
                  "ned2": "niryo_robot_follow_joint_trajectory_controller"}[name]
    namespace = "/vx300s" if name == "vx300s" else ""
    assert controller == pkg.REAL_ARM_CONTROLLER
    assert f"{namespace}/{controller}/follow_joint_trajectory" == pkg.REAL_ARM_ACTION
    assert pkg.ARM_TRAJECTORY_CONTROLLER == pkg.REAL_ARM_CONTROLLER


def test_scene_matches_the_mjcf_files(arm):
    name, pkg, _ = arm
    scene = pkg.SCENE
    table = mujoco.MjModel.from_xml_path(str(pkg.TABLE_MJCF))
    np.testing.assert_allclose(table.geom_size[0], scene["table_half_extents"])
    top = scene["robot_height"] + scene["table_center"][2] + scene["table_half_extents"][2]
    assert top == pytest.approx(scene["robot_height"] + scene["table_top"])
    cube = mujoco.MjModel.from_xml_path(str(pkg.OBJECT_MJCF))
    np.testing.assert_allclose(cube.geom_size[0], [scene["object_half_size"]] * 3)
    assert cube.body_mass[1] == pytest.approx(scene["object_mass"])
    # The cube fits the open gripper with room for IK and pose errors, and the closed one grips it.
    opening = {"vx300s": lambda g: 2 * (g - 0.0195), "ur5e": lambda g: 2 * g + 0.001,
               "ned2": lambda g: 0.02068 + 2 * g}[name]
    assert opening(pkg.GRIPPER_OPEN) > 2 * scene["object_half_size"] + 0.015
    assert opening(pkg.GRIPPER_CLOSED) < 2 * scene["object_half_size"] - 0.01


# ------------------------------------------------------------------ top-down IK
ARM_NAMES = {"vx300s": "VX300S", "ur5e": "UR5e", "ned2": "NED2"}


def top_down_ik(name):
    return top_down_ik_of(arm_of(ARM_NAMES.get(name, name)))


@pytest.mark.parametrize("name", sorted(PACKAGES))
def test_top_down_ik_reaches_the_scene(name):
    pkg = PACKAGES[name]
    ik = top_down_ik(name)  # from the shipped arm file
    chain = _chain(pkg, pkg.EE_LINK)
    approach = {"x": 0, "z": 2}[pkg.EE_APPROACH_AXIS]
    closing = {"vx300s": 1, "ur5e": 0, "ned2": 1}[name]
    s = pkg.SCENE
    rng = np.random.default_rng(0)
    q = None
    for _ in range(25):
        target = (*rng.uniform(s["object_xy_min"], s["object_xy_max"]),
                  rng.uniform(s["object_half_size"], s["object_half_size"] + s["target_height_max"]))
        yaw = rng.uniform(-PI, PI)
        q = ik.solve(target, yaw, q0=q)
        assert np.all(ik.lower <= q) and np.all(q <= ik.upper)
        tf = chain.fk_matrix(q)
        np.testing.assert_allclose(tf[:3, 3], target, atol=2e-4)
        assert tf[2, approach] < -0.9999, "the gripper points straight down"
        assert abs(math.sin(math.atan2(tf[1, closing], tf[0, closing]) - yaw)) < 1e-3, "fingers close along yaw"
    # Default yaw: across the radial direction, as the RX200's IK.
    tf = chain.fk_matrix(ik.solve((s["object_xy_max"][0], 0.1, 0.05)))
    radial = np.array([s["object_xy_max"][0], 0.1]) / np.hypot(s["object_xy_max"][0], 0.1)
    assert abs(tf[:2, closing] @ radial) < 1e-3


@pytest.mark.parametrize("name", sorted(PACKAGES))
def test_top_down_ik_out_of_reach_is_clipped_not_raised(name):
    ik = top_down_ik(name)
    q = ik.solve((5.0, 0.0, 0.1))
    assert np.all(np.isfinite(q)) and np.all(ik.lower <= q) and np.all(q <= ik.upper)
    with pytest.raises(ValueError, match="no arm 'rx201' is registered"):
        top_down_ik("rx201")
