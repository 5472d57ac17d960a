"""Both descriptions in MuJoCo: they compile, masses and frames agree with the kinematics utility,
named poses are contact-free, and the controllers YAML's PID gains hold and reach poses stably."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import yaml
from xacro_text import process

from multiros.utils.kinematics import KinematicChain
from rl_environments.robots import abb_irb120_description as irb120
from rl_environments.robots import rx200_description as rx200

ROBOTS = {
    "rx200": (rx200, "rx200/", "arm_controller", "ee_gripper_link",
              {"HOME": rx200.HOME_POSE, "SLEEP": rx200.SLEEP_POSE, "UPRIGHT": rx200.UPRIGHT_POSE}),
    "irb120": (irb120, "", "arm120_controller", "tool0",
               {"HOME": irb120.HOME_POSE, "ARM_UP": irb120.ARM_UP_POSE}),
}


def _model(pkg, dt: float = 0.002) -> mujoco.MjModel:
    # MuJoCo's own URDF importer (it fuses fixed links into their parents, which is fine here).
    model = mujoco.MjModel.from_xml_string(process(pkg.URDF_XACRO))
    model.opt.timestep = dt
    return model


def _set_pose(model, data, pkg, pose) -> np.ndarray:
    qadr = np.array([model.jnt_qposadr[model.joint(n).id] for n in pkg.ARM_JOINTS])
    data.qpos[:] = 0.0
    data.qpos[qadr] = pose
    for name, value in (("left_finger", rx200.GRIPPER_HOME), ("right_finger", -rx200.GRIPPER_HOME)):
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) >= 0:
            data.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_forward(model, data)
    return qadr


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_compiles_with_reference_mass(robot):
    # MuJoCo's importer fuses the fixed base into the world body and drops its mass.
    pkg = ROBOTS[robot][0]
    base_mass = {"rx200": 0.766135, "irb120": 6.215}[robot]
    expected = {"rx200": 1.81, "irb120": 18.15}[robot] - base_mass
    assert _model(pkg).body_mass.sum() == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_body_frames_match_kinematics(robot):
    pkg, prefix, _, _, _ = ROBOTS[robot]
    model = _model(pkg)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    names = [model.body(i).name for i in range(1, model.nbody)]
    base = f"{prefix}base_link"
    chains = {n: KinematicChain.from_urdf(pkg.URDF_XACRO, base, n) for n in names}
    for _ in range(5):
        q = KinematicChain.from_urdf(pkg.URDF_XACRO, base, names[-1]).sample_configurations(rng, 1)[0]
        _set_pose(model, data, pkg, q[: len(pkg.ARM_JOINTS)])
        for name, chain in chains.items():
            arm_q = data.qpos[[model.jnt_qposadr[model.joint(j).id] for j in chain.joint_names]]
            pos, quat = chain.fk(arm_q)
            np.testing.assert_allclose(data.body(name).xpos, pos, atol=1e-9, err_msg=name)
            assert abs(abs(np.dot(data.body(name).xquat, quat)) - 1.0) < 1e-9, name


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_named_poses_are_contact_free(robot):
    pkg, _, _, _, poses = ROBOTS[robot]
    model = _model(pkg)
    data = mujoco.MjData(model)
    for name, pose in poses.items():
        _set_pose(model, data, pkg, pose)
        touching = [(model.body(model.geom_bodyid[c.geom1]).name, model.body(model.geom_bodyid[c.geom2]).name)
                    for c in data.contact[: data.ncon]]
        assert touching == [], f"{robot} {name} pose: contacts {touching}"


def _pid_run(model, pkg, controller: str, start, target, seconds: float) -> np.ndarray:
    """Torque PID from the controllers YAML, clamped to the URDF effort; returns joint errors per step."""
    gains = yaml.safe_load(pkg.CONTROLLERS_YAML.read_text())[controller]["ros__parameters"]["gains"]
    names = list(pkg.ARM_JOINTS)
    kp, kd, ki = (np.array([gains[n][k] for n in names]) for k in ("p", "d", "i"))
    i_max = np.array([gains[n]["i_clamp"] for n in names]) / np.maximum(ki, 1e-12)
    dofs = np.array([model.jnt_dofadr[model.joint(n).id] for n in names])
    effort = np.array([model.jnt_actfrcrange[model.joint(n).id][1] for n in names])
    data = mujoco.MjData(model)
    qadr = _set_pose(model, data, pkg, start)
    integral = np.zeros(len(names))
    errors = []
    for _ in range(int(seconds / model.opt.timestep)):
        err = np.asarray(target) - data.qpos[qadr]
        integral = np.clip(integral + err * model.opt.timestep, -i_max, i_max)
        torque = kp * err + ki * integral - kd * data.qvel[dofs]
        data.qfrc_applied[dofs] = np.clip(torque, -effort, effort)
        mujoco.mj_step(model, data)
        errors.append(err)
    return np.array(errors)


@pytest.mark.parametrize("dt", [0.001, 0.002])
@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_controller_gains_reach_and_hold_poses(robot, dt):
    pkg, _, controller, _, poses = ROBOTS[robot]
    model = _model(pkg, dt)
    if robot == "rx200":
        moves = [(rx200.SLEEP_POSE, rx200.HOME_POSE), (rx200.HOME_POSE, (0.5, 0.3, -0.3, 0.5, 1.0))]
    else:
        moves = [(irb120.HOME_POSE, irb120.ARM_UP_POSE), (irb120.HOME_POSE, (0.5, 0.8, -0.6, 0.4, 0.6, 1.0))]
    for start, target in moves:
        errors = _pid_run(model, pkg, controller, start, target, seconds=1.5)
        tail = errors[-int(0.2 / dt):]
        assert np.all(np.isfinite(errors))
        assert np.abs(tail).max() < 0.02, f"{robot}: {start}->{target} ends {tail[-1]}"
        assert np.ptp(tail, axis=0).max() < 2e-3, f"{robot}: limit cycle {np.ptp(tail, axis=0)}"


# ------------------------------------------------------------------- multiros' own loader, if present
@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_multiros_loader_ee_site_matches_fk(robot):
    description = pytest.importorskip("multiros.sim.description")
    pkg, prefix, _, ee, _ = ROBOTS[robot]
    desc = description.load_description(pkg.URDF_XACRO)
    model = desc.spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    chain = KinematicChain.from_urdf(pkg.URDF_XACRO, f"{prefix}base_link", f"{prefix}{ee}")
    pos, quat = chain.fk(np.zeros(chain.n_joints))
    np.testing.assert_allclose(data.site(f"{prefix}{ee}").xpos, pos, atol=1e-9)
    expected_rot = np.zeros(9)
    mujoco.mju_quat2Mat(expected_rot, quat)
    np.testing.assert_allclose(data.site(f"{prefix}{ee}").xmat, expected_rot, atol=1e-9)
    assert desc.controllers_yaml == pkg.CONTROLLERS_YAML
    assert model.body_mass.sum() == pytest.approx({"rx200": 1.81, "irb120": 18.15}[robot], rel=0.02)
