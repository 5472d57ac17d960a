"""multiros.utils.kinematics: FK known answers, Jacobian vs finite differences, IK round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multiros.utils.kinematics import KinematicChain
from multiros.utils.rotations import matrix_from_quat, quat_from_matrix
from rl_environments.robots import abb_irb120_description as irb120
from rl_environments.robots import rx200_description as rx200


@pytest.fixture(scope="module")
def rx() -> KinematicChain:
    return KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", "rx200/ee_gripper_link")


@pytest.fixture(scope="module")
def abb() -> KinematicChain:
    return KinematicChain.from_urdf(irb120.URDF_XACRO, "base_link", "tool0")


@pytest.fixture(scope="module")
def abb_flange() -> KinematicChain:
    return KinematicChain.from_urdf(irb120.URDF_XACRO, "base_link", "flange")


# ----------------------------------------------------------------------------- construction
def test_chain_properties(rx, abb):
    assert rx.joint_names == rx200.ARM_JOINTS
    assert abb.joint_names == irb120.ARM_JOINTS
    np.testing.assert_allclose(rx.lower, [-math.pi + 1e-5, -1.88496, -1.88496, -1.74533, -math.pi + 1e-5], atol=1e-5)
    np.testing.assert_allclose(abb.upper, [2.87979, 1.91986, 1.22173, 2.79253, 2.094395, 6.98132])
    np.testing.assert_allclose(rx.velocity_limits, [math.pi, 1.0, math.pi, math.pi, math.pi])
    np.testing.assert_allclose(abb.velocity_limits, [4.36332] * 3 + [5.58505] * 2 + [7.33038])


def test_from_urdf_text_and_xacro_args():
    import xacro

    text = xacro.process_file(str(rx200.URDF_XACRO), mappings={"robot_name": "arm"}).toxml()
    chain = KinematicChain.from_urdf(text, "arm/base_link", "arm/ee_gripper_link")
    also = KinematicChain.from_urdf(rx200.URDF_XACRO, "arm/base_link", "arm/ee_gripper_link",
                                    xacro_args={"robot_name": "arm"})
    np.testing.assert_allclose(chain.fk_position(np.zeros(5)), also.fk_position(np.zeros(5)))


def test_world_base_gives_same_answer_when_world_is_identity():
    chain = KinematicChain.from_urdf(irb120.URDF_XACRO, "world", "tool0")
    np.testing.assert_allclose(chain.fk_position(np.zeros(6)), [0.374, 0.0, 0.630], atol=1e-12)


def test_a_tip_offset_is_a_point_fixed_in_the_tip_link(abb_flange):
    """The chain's tip moved by ``tip_offset`` in the tip link's frame: FK, the batched FK and the Jacobian
    all see the point; the offset chain and the link's own differ by the rotated offset only."""
    offset = np.array([0.01, -0.02, 0.15])
    tcp = abb_flange.with_tip_offset(offset)
    also = KinematicChain.from_urdf(irb120.URDF_XACRO, "base_link", "flange", tip_offset=offset)
    qs = np.random.default_rng(3).uniform(abb_flange.lower, abb_flange.upper, size=(20, 6))
    link = abb_flange.fk_matrix(qs)
    expected = link[:, :3, 3] + np.einsum("nij,j->ni", link[:, :3, :3], offset)
    np.testing.assert_allclose(tcp.fk_position(qs), expected, atol=1e-12)
    np.testing.assert_allclose(also.fk_position(qs), expected, atol=1e-12)
    np.testing.assert_allclose(tcp.fk_position(qs[0]), expected[0], atol=1e-12)
    q, eps = qs[0], 1e-7
    numeric = np.stack([(tcp.fk_position(q + eps * np.eye(6)[i]) - tcp.fk_position(q - eps * np.eye(6)[i])) / (2 * eps)
                        for i in range(6)], axis=1)
    np.testing.assert_allclose(tcp.jacobian(q)[:3], numeric, atol=1e-6)
    np.testing.assert_allclose(tcp.with_tip_offset(None).fk_position(qs), link[:, :3, 3], atol=0)
    assert "tip_offset=[0.01, -0.02, 0.15]" in repr(tcp)
    for bad in ([0.0, 0.0], [0.0, math.inf, 0.0]):
        with pytest.raises(ValueError, match="tip_offset must be 3 finite numbers"):
            abb_flange.with_tip_offset(bad)


def test_unknown_link_and_no_chain_errors():
    with pytest.raises(ValueError, match="tip_link 'rx200/nope' is not a link"):
        KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", "rx200/nope")
    with pytest.raises(ValueError, match="no kinematic chain"):
        KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/ee_gripper_link", "rx200/base_link")
    with pytest.raises(ValueError, match="no kinematic chain"):
        KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/left_finger_link", "rx200/right_finger_link")
    with pytest.raises(FileNotFoundError, match="not found"):
        KinematicChain.from_urdf("/nonexistent/robot.urdf", "a", "b")
    with pytest.raises(ValueError, match="not valid XML"):
        KinematicChain.from_urdf("<robot", "a", "b")


def test_chain_with_prismatic_and_continuous_joints():
    finger = KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", "rx200/left_finger_link")
    assert finger.joint_names == (*rx200.ARM_JOINTS, "left_finger")
    np.testing.assert_allclose(finger.fk_position([0, 0, 0, 0, 0, 0.03]), [0.381, 0.03, 0.30457], atol=1e-12)
    prop = KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", "rx200/gripper_prop_link")
    assert np.isinf(prop.lower[-1]) and np.isinf(prop.upper[-1])
    q = prop.sample_configurations(np.random.default_rng(0), 50)
    assert np.all(np.abs(q[:, -1]) <= math.pi)


def test_wrong_q_shape(rx):
    with pytest.raises(ValueError, match=r"expected \(\.\.\., 5\)"):
        rx.fk(np.zeros(6))


# ----------------------------------------------------------------------------- FK known answers
def test_rx200_home(rx):
    pos, quat = rx.fk(np.zeros(5))
    np.testing.assert_allclose(pos, [0.408575, 0.0, 0.30457], atol=1e-12)
    np.testing.assert_allclose(quat, [1, 0, 0, 0], atol=1e-12)


def test_rx200_joint_frames_at_home():
    expected = {
        "shoulder_link": (0, 0, 0.06566), "upper_arm_link": (0, 0, 0.10457),
        "forearm_link": (0.05, 0, 0.30457), "wrist_link": (0.25, 0, 0.30457),
        "gripper_link": (0.315, 0, 0.30457), "ee_arm_link": (0.358, 0, 0.30457),
        "fingers_link": (0.381, 0, 0.30457),
    }
    for link, xyz in expected.items():
        chain = KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", f"rx200/{link}")
        np.testing.assert_allclose(chain.fk_position(np.zeros(chain.n_joints)), xyz, atol=1e-12, err_msg=link)


def test_rx200_sleep_pose(rx):
    # The reference gives "about (0.123, 0, 0.074)" for the rx200.yaml Sleep pose: within 1 mm.
    np.testing.assert_allclose(rx.fk_position(rx200.SLEEP_POSE), [0.123, 0.0, 0.074], atol=1e-3)
    # The SRDF variant (shoulder -1.85) is ~7 mm higher: the reference's figure is the rx200.yaml pose.
    srdf = rx.fk_position([0, -1.85, 1.55, 0.8, 0])
    assert 0.005 < srdf[2] - 0.074 < 0.01


def test_rx200_upright_pose(rx):
    # elbow -pi/2: the forearm points straight up from the elbow at (0.05, 0, 0.30457).
    np.testing.assert_allclose(rx.fk_position(rx200.UPRIGHT_POSE), [0.05, 0, 0.30457 + 0.358575], atol=1e-4)


def test_irb120_home(abb, abb_flange):
    pos, quat = abb.fk(np.zeros(6))
    np.testing.assert_allclose(pos, [0.374, 0.0, 0.630], atol=1e-12)
    # tool0 is the flange pitched by +pi/2: its z axis points along base x.
    np.testing.assert_allclose(matrix_from_quat(quat)[:, 2], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(abb_flange.fk(np.zeros(6))[1], [1, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(abb_flange.fk_position(np.zeros(6)), [0.374, 0.0, 0.630], atol=1e-12)


def test_irb120_joint_frames_at_home():
    expected = {"link_2": (0, 0, 0.29), "link_3": (0, 0, 0.56), "link_4": (0, 0, 0.63), "link_5": (0.302, 0, 0.63)}
    for link, xyz in expected.items():
        chain = KinematicChain.from_urdf(irb120.URDF_XACRO, "base_link", link)
        np.testing.assert_allclose(chain.fk_position(np.zeros(chain.n_joints)), xyz, atol=1e-12)


def test_irb120_arm_up(abb_flange):
    # "about (-0.071, 0, 0.934)": within 1 mm.
    np.testing.assert_allclose(abb_flange.fk_position(irb120.ARM_UP_POSE), [-0.071, 0.0, 0.934], atol=1e-3)


def test_batched_fk_matches_single(abb):
    q = abb.sample_configurations(np.random.default_rng(3), 64)
    pos, quat = abb.fk(q)
    assert pos.shape == (64, 3) and quat.shape == (64, 4)
    for i in range(0, 64, 7):
        p1, q1 = abb.fk(q[i])
        np.testing.assert_allclose(pos[i], p1, atol=1e-12)
        np.testing.assert_allclose(quat[i], q1, atol=1e-12)
    assert abb.fk_matrix(q.reshape(8, 8, 6)).shape == (8, 8, 4, 4)


def test_quaternion_roundtrip():
    rng = np.random.default_rng(0)
    quats = rng.normal(size=(200, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    quats *= np.sign(quats[:, :1])
    np.testing.assert_allclose(quat_from_matrix(matrix_from_quat(quats)), quats, atol=1e-9)
    with pytest.raises(ValueError, match="zero norm"):
        matrix_from_quat([0, 0, 0, 0])


def test_quaternion_of_half_turns():
    # w = 0: the signs of x, y, z must still agree with each other (a half turn about (0.05, -1, 0)
    # once came back as one about (0.05, 1, 0)).
    rng = np.random.default_rng(1)
    axes = rng.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    mats = 2.0 * axes[:, :, None] * axes[:, None, :] - np.eye(3)
    np.testing.assert_allclose(matrix_from_quat(quat_from_matrix(mats)), mats, atol=1e-9)
    np.testing.assert_allclose(matrix_from_quat(quat_from_matrix(mats[3])), mats[3], atol=1e-9)


# ----------------------------------------------------------------------------- Jacobian
@pytest.mark.parametrize("robot", ["rx", "abb"])
def test_jacobian_matches_finite_differences(robot, request):
    chain: KinematicChain = request.getfixturevalue(robot)
    rng = np.random.default_rng(1)
    eps = 1e-6
    for q in chain.sample_configurations(rng, 10):
        jac = chain.jacobian(q)
        tf = chain.fk_matrix(q)
        for i in range(chain.n_joints):
            dq = np.zeros(chain.n_joints)
            dq[i] = eps
            tf_p, tf_m = chain.fk_matrix(q + dq), chain.fk_matrix(q - dq)
            np.testing.assert_allclose(jac[:3, i], (tf_p[:3, 3] - tf_m[:3, 3]) / (2 * eps), atol=1e-6)
            # Angular velocity: vee(dR/dq R^T).
            w = ((tf_p[:3, :3] - tf_m[:3, :3]) / (2 * eps)) @ tf[:3, :3].T
            np.testing.assert_allclose(jac[3:, i], [w[2, 1], w[0, 2], w[1, 0]], atol=1e-6)


def test_prismatic_jacobian_column():
    finger = KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", "rx200/left_finger_link")
    q = np.array([0.3, 0.2, -0.4, 0.5, 0.7, 0.02])
    jac = finger.jacobian(q)
    eps = 1e-6
    dq = np.zeros(6)
    dq[5] = eps
    np.testing.assert_allclose(jac[:3, 5], (finger.fk_position(q + dq) - finger.fk_position(q - dq)) / (2 * eps),
                               atol=1e-8)
    np.testing.assert_allclose(jac[3:, 5], 0.0)


# ----------------------------------------------------------------------------- IK
@pytest.mark.parametrize("robot", ["rx", "abb"])
def test_ik_position_round_trip(robot, request):
    chain: KinematicChain = request.getfixturevalue(robot)
    rng = np.random.default_rng(42)
    qs, targets = chain.sample_reachable(rng, 100, return_q=True)
    converged = 0
    for target in targets:
        q, ok, err = chain.ik(target)
        assert np.all(q >= chain.lower - 1e-12) and np.all(q <= chain.upper + 1e-12)
        if ok:
            converged += 1
            assert err < 1e-4
            assert np.linalg.norm(chain.fk_position(q) - target) < 1e-3
    assert converged >= 95


def test_ik_pose_round_trip_irb120(abb):
    rng = np.random.default_rng(7)
    qs = abb.sample_configurations(rng, 40)
    converged = 0
    for q_true in qs:
        pos, quat = abb.fk(q_true)
        q, ok, _ = abb.ik(pos, quat)
        if ok:
            converged += 1
            p2, quat2 = abb.fk(q)
            assert np.linalg.norm(p2 - pos) < 1e-3
            assert abs(abs(np.dot(quat2, quat)) - 1.0) < 1e-5
    assert converged >= 36


def test_ik_unreachable_reports_not_converged(rx, abb):
    q, ok, err = rx.ik([1.0, 0.0, 0.3])  # 1 m away, reach is ~0.57 m
    assert not ok and err > 0.3
    assert np.all(q >= rx.lower) and np.all(q <= rx.upper)
    q, ok, err = abb.ik([0.0, 0.0, 2.0])
    assert not ok and err > 1.0


def test_ik_respects_limits_when_target_needs_them(rx):
    # Behind and below the base: unreachable within the limits; the answer must stay inside them.
    q, _, _ = rx.ik([-0.3, 0.0, -0.2], restarts=2)
    assert np.all(q >= rx.lower) and np.all(q <= rx.upper)
    q_free, _, _ = rx.ik([-0.3, 0.0, -0.2], joint_limits=False, restarts=0)
    assert q_free.shape == (5,)


def test_ik_from_q0_and_is_repeatable(abb):
    target = abb.fk_position([0.3, 0.4, -0.2, 0.1, 0.5, 0.0])
    a = abb.ik(target, q0=np.zeros(6))
    b = abb.ik(target, q0=np.zeros(6))
    assert a.converged
    np.testing.assert_array_equal(a.q, b.q)
    with pytest.raises(ValueError, match="target_pos"):
        abb.ik([0.1, 0.2])


def test_sample_reachable_uses_the_given_generator(rx):
    a = rx.sample_reachable(np.random.default_rng(5), 10)
    b = rx.sample_reachable(np.random.default_rng(5), 10)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (10, 3)
    assert np.all(np.linalg.norm(a - [0, 0, 0.10457], axis=1) <= 0.2062 + 0.2 + 0.158575 + 1e-9)


@pytest.mark.parametrize("tip", ["rx200/ee_gripper_link", "rx200/left_finger_link"])  # the finger: a prismatic joint
def test_batched_fk_position_matches_the_transforms(tip):
    chain = KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", tip)
    q = chain.sample_configurations(np.random.default_rng(4), 96)
    expected = chain.fk_matrix(q)[:, :3, 3]
    np.testing.assert_allclose(chain.fk_position(q), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(chain.fk_position(q.reshape(8, 12, -1)), expected.reshape(8, 12, 3), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(chain.fk_position(q[5]), chain.fk_matrix(q[5])[:3, 3])
    assert chain.fk_position(q[:0]).shape == (0, 3)
