"""The vx300s, ur5e and ned2 descriptions in the simulation: they load in the simulation node with
their controllers, hold a stretched pose under gravity (no compensation) with their gains, the
gripper closes on the scene's cube and lifts it, and the scripted push / pick-and-place solve fixed
seeds (the full figures come from benchmarks/bench_arm_grasps.py)."""

from __future__ import annotations

import numpy as np
import pytest

import multiros.sim  # noqa: F401  (headless MuJoCo)
from multiros.sim import launch
from multiros.utils.kinematics import KinematicChain
from rl_environments.arm_validation import ARMS, ArmScene, run_pick_and_place, run_push

ARM_NAMES = sorted(ARMS)


@pytest.fixture(scope="module", params=ARM_NAMES)
def scene(request):
    conn = launch.connect("composed", timestep=0.004)
    try:
        yield ArmScene(request.param, conn)
    finally:
        conn.close()


def test_loads_in_the_simulation_node(scene):
    pkg = scene.pkg
    assert {scene.entity, "table", "object"} <= set(scene.sim.get_entities())
    state = scene.sim.step_robot(scene.entity, steps=0, frames=[scene.ee_frame])
    assert set(pkg.ARM_JOINTS) | set(pkg.FINGER_JOINTS) <= set(state.names)
    controllers = {c.name: c.state for c in scene.sim.list_controllers(f"/{scene.entity}")}
    assert all(controllers.get(c) == "active" for c in pkg.SIM_CONTROLLERS), controllers
    # The node's EE frame is where the description's kinematics puts it.
    q = np.array([state.position[state.names.index(j)] for j in pkg.ARM_JOINTS])
    prefix = scene.spec.link_prefix
    chain = KinematicChain.from_urdf(pkg.URDF_XACRO, prefix + pkg.BASE_LINK, prefix + pkg.EE_LINK)
    np.testing.assert_allclose(state.frame_positions[0], chain.fk_position(q) + scene.base, atol=1e-6)


@pytest.mark.parametrize("arm", ARM_NAMES)
def test_holds_a_stretched_pose_under_gravity(arm, tmp_path):
    from multiros.sim.world import World, WorldOptions

    pkg = ARMS[arm].package
    # The forearm (VX300S) or the whole arm (UR5e, Ned2) straight out.
    stretched = pkg.HOME_POSE if arm == "vx300s" else pkg.ZERO_POSE
    world = World(WorldOptions(timestep=0.004), mesh_cache=tmp_path)
    try:
        world.spawn(arm, pkg.URDF_XACRO, gravity_compensation=False, controllers=list(pkg.SIM_CONTROLLERS),
                    joint_positions=dict(zip(pkg.ARM_JOINTS, stretched)))
        world.set_command(arm, pkg.ARM_POSITION_CONTROLLER, stretched)
        names = list(world.joint_names(arm))
        idx = [names.index(j) for j in pkg.ARM_JOINTS]
        world.step(375)  # 1.5 s
        js = world.joint_state(arm)
        sag = np.abs(js.position[idx] - stretched)
        assert sag.max() < 0.01, f"{arm} sags {dict(zip(pkg.ARM_JOINTS, sag.round(4)))}"
        assert np.abs(js.velocity[idx]).max() < 1e-3, "it has settled"
    finally:
        world.close()


def test_gripper_closes_on_the_cube_and_lifts_it(scene):
    pkg, half = scene.pkg, scene.half
    scene.reset(np.array(scene.scene["init_ee_position"][:2]), 0.0)
    cube = scene.cube.copy()
    yaw = float(np.pi / 2 + np.arctan2(cube[1], cube[0]))  # square to the cube's faces (its yaw is radial)
    for z in (cube[2] + 0.06, cube[2] + scene.spec.grasp_depth):
        for _ in range(40):
            scene.step(np.array([cube[0], cube[1], z]), yaw, pkg.GRIPPER_OPEN)
    for _ in range(15):
        scene.step(scene.ee_target, yaw, pkg.GRIPPER_CLOSED)
    # The fingers stop on the cube: the pads 2 * half apart, less their contact penetration
    # (MuJoCo's soft contacts: ~1 mm a pad for the RX200-like squeeze of the VX300S and Ned2, ~2.5 mm
    # for the UR5e's 25 N).
    opening = {"vx300s": lambda g: 2 * (g - 0.0195), "ur5e": lambda g: 2 * g + 0.001,
               "ned2": lambda g: 0.02068 + 2 * g}[scene.spec.name]
    assert 2 * half - 0.006 < opening(scene.finger) < 2 * half + 0.001
    lifted = scene.ee_target + (0, 0, 0.1)
    for _ in range(30):
        scene.step(lifted, yaw, pkg.GRIPPER_CLOSED)
    # It comes up with the gripper (a held cube creeps down by up to ~1.5 mm/s in soft contacts).
    assert 0.09 < scene.cube[2] - cube[2] < 0.105, "the cube came up with the gripper"

@pytest.mark.slow
@pytest.mark.parametrize("task", ["push", "pnp"])
def test_scripted_tasks_solve_fixed_seeds(scene, task):
    run = run_push if task == "push" else run_pick_and_place
    results = [run(scene, seed) for seed in range(3)]
    assert all(r.success for r in results), [(r.distance, r.events) for r in results]
