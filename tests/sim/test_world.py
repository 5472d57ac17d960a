"""World: one test per method (spawn, delete, states, joints, frames, step, reset, physics, stability)."""

from __future__ import annotations

import importlib.util
import threading
from pathlib import Path

import numpy as np
import pytest

from multiros.sim.errors import DescriptionError, EntityError, UnstableSimulationError
from multiros.sim.world import EntityCategory, RealTimeRunner, ResetScope

ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
BALL = "package://test_arm_description/urdf/ball.xml"
PENDULUM = "package://test_arm_description/urdf/pendulum.xml"


def test_spawn_two_robots_in_namespaces(make_world):
    world = make_world()
    a = world.spawn("left", ARM_XACRO, pose=([0, -0.5, 0], [1, 0, 0, 0]), namespace="/ns_a",
                    joint_positions={"joint2": 0.0})
    b = world.spawn("right", ARM_XACRO, pose=([0, 0.5, 0], [1, 0, 0, 0]), xacro_args={"link_length": "0.3"})
    assert (a.namespace, b.namespace) == ("/ns_a", "/right")
    assert a.category == EntityCategory.ROBOT and a.fixed_base
    assert world.entity_names() == ("left", "right")
    assert "ee_link" in a.frames and a.joint_names == ("joint1", "joint2", "joint3")
    np.testing.assert_allclose(world.frame_pose("ee_link", "left")[0], [0, -0.5, 0.5], atol=1e-9)
    # joint2 starts at the ros2_control initial_value unless given; link_length makes the right arm longer
    assert world.joint_state("left").position[1] == 0.0
    assert world.joint_state("right").position[1] == pytest.approx(0.3)
    assert world.frame_pose("link3", "right")[0][2] != world.frame_pose("link3", "left")[0][2]


def test_spawn_rejects_bad_names_and_poses(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    with pytest.raises(EntityError, match="already exists"):
        world.spawn("arm", ARM_XACRO)
    with pytest.raises(EntityError, match="invalid"):
        world.spawn("9 bad", ARM_XACRO)
    with pytest.raises(ValueError, match="zero"):
        world.spawn("b", BALL, pose=([0, 0, 1], [0, 0, 0, 0]))
    with pytest.raises(ValueError, match="finite"):
        world.spawn("b", BALL, pose=([0, np.nan, 1], [1, 0, 0, 0]))
    with pytest.raises(ValueError, match="outside"):
        world.spawn("b", ARM_XACRO, joint_positions={"joint2": 3.0})
    with pytest.raises(DescriptionError):
        world.spawn("b", "<robot name='x'><link name='a'>")
    assert world.entity_names() == ("arm",)
    world.step(5)  # the world still works after the refusals


def test_delete_keeps_other_state(make_world):
    world = make_world()
    world.spawn("keep", ARM_XACRO)
    world.spawn("gone", ARM_XACRO, pose=([1, 0, 0], [1, 0, 0, 0]))
    world.set_command("keep", "arm_controller", [0.4, -0.3, 0.2])
    world.step(40)  # mid-motion: non-zero velocities
    before = world.joint_state("keep")
    q, v, t = before.position.copy(), before.velocity.copy(), world.time
    assert np.any(np.abs(v) > 1e-3)
    world.delete("gone")
    after = world.joint_state("keep")
    np.testing.assert_array_equal(after.position, q)
    np.testing.assert_array_equal(after.velocity, v)
    assert world.time == t and not world.has_entity("gone")
    with pytest.raises(EntityError):
        world.delete("gone")
    world.step(200)
    np.testing.assert_allclose(world.joint_state("keep").position, [0.4, -0.3, 0.2], atol=5e-3)


def test_spawn_delete_cycles_rebuild_the_spec_and_keep_the_others_bit_for_bit(make_world, monkeypatch):
    """Every 10 deletions the world builds its spec afresh (MuJoCo's spec keeps memory for what was deleted):
    the entities that stay move on exactly as in a world that keeps its spec."""
    import multiros.sim.world as world_module

    rebuilds = []
    original = world_module.World._rebuild_spec

    def counted(self) -> None:
        rebuilds.append(1)
        original(self)

    monkeypatch.setattr(world_module.World, "_rebuild_spec", counted)

    def run(rebuild_every: int) -> tuple:
        monkeypatch.setattr(world_module, "_REBUILD_EVERY", rebuild_every)
        world = make_world()
        world.spawn("keep", ARM_XACRO)
        world.spawn("box", "<mujoco><worldbody><body name='b'><freejoint/><geom type='box' size='0.05 0.05 0.05' "
                           "mass='0.2'/></body></worldbody></mujoco>", pose=([0.6, 0.3, 0.5], [1, 0, 0, 0]))
        world.set_command("keep", "arm_controller", [0.4, -0.3, 0.2])
        for k in range(23):
            world.spawn("visitor", ARM_XACRO, pose=([1.5, 0, 0], [1, 0, 0, 0]))
            world.step(7)
            world.delete("visitor")
            world.step(3 + k % 4)
        world.set_command("keep", "arm_controller", [-0.2, 0.3, 0.1])
        world.step(30)
        arm, box = world.joint_state("keep"), world.get_entity_state("box")
        return arm.position.copy(), arm.velocity.copy(), box.position.copy(), box.linear_velocity.copy(), world.time

    rebuilt = run(10)
    assert len(rebuilds) == 2  # 23 deletions
    kept = run(10**9)
    assert len(rebuilds) == 2
    for a, b in zip(rebuilt, kept):
        np.testing.assert_array_equal(a, b)


def _wide_urdf(joints: int) -> str:
    """benchmarks/bench_entity_delete.py's robot: ``joints`` actuated revolute joints in chains of 50."""
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_entity_delete.py"
    spec = importlib.util.spec_from_file_location("bench_entity_delete", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.wide_urdf(joints)


def test_deleting_a_large_entity_removes_all_of_it_and_nothing_else(make_world, tmp_path):
    """The body goes first and takes its joints' actuators with it (one by one, ~1,000 actuators held the
    node's lock 20-36 s; benchmarks/bench_entity_delete.py): nothing of it is left, the other robot
    keeps its actuators and state, and the world still steps."""
    world = make_world()
    world.spawn("keep", ARM_XACRO)
    kept = [world.model.actuator(i).name for i in range(world.model.nu)]
    path = tmp_path / "wide.urdf"
    path.write_text(_wide_urdf(300))
    world.spawn("wide", str(path), pose=([2, 0, 0], [1, 0, 0, 0]))
    assert world.model.nu == len(kept) + 300
    q = world.joint_state("keep").position.copy()
    world.delete("wide")
    names = [world.model.actuator(i).name for i in range(world.model.nu)]
    bodies = [world.model.body(i).name for i in range(world.model.nbody)]
    assert names == kept and not [b for b in bodies if b.startswith("wide")]
    np.testing.assert_array_equal(world.joint_state("keep").position, q)
    world.step(5)


def test_spawn_keeps_other_state(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    world.set_command("arm", "", [0.4, -0.3, 0.2])
    world.step(30)
    q = world.joint_state("arm").position.copy()
    world.spawn("ball", BALL, pose=([0.5, 0, 0.5], [1, 0, 0, 0]))
    np.testing.assert_array_equal(world.joint_state("arm").position, q)


def test_entity_state_floating_object(make_world):
    world = make_world()
    info = world.spawn("ball", BALL, pose=([0.2, 0.1, 0.5], [1, 0, 0, 0]))
    assert info.category == EntityCategory.DYNAMIC_OBJECT and not info.fixed_base
    world.set_entity_state("ball", position=[1, 2, 3], orientation=[0, 0, 0, 2],
                           linear_velocity=[0.1, 0, 0], angular_velocity=[0, 0, 1.5])
    s = world.get_entity_state("ball")
    np.testing.assert_allclose(s.position, [1, 2, 3])
    np.testing.assert_allclose(s.orientation, [0, 0, 0, 1])  # normalised
    np.testing.assert_allclose(s.linear_velocity, [0.1, 0, 0])
    np.testing.assert_allclose(s.angular_velocity, [0, 0, 1.5], atol=1e-12)
    world.step(50)
    assert world.get_entity_state("ball").position[2] < 3  # gravity acts
    with pytest.raises(ValueError, match="zero"):
        world.set_entity_state("ball", orientation=[0, 0, 0, 0])
    with pytest.raises(EntityError):
        world.get_entity_state("nobody")


def test_entity_state_fixed_base_moves_base(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO, joint_positions={"joint2": 0.0})
    world.set_entity_state("arm", position=[1, 0, 0.2], orientation=[0.7071068, 0, 0, 0.7071068])
    s = world.get_entity_state("arm")
    np.testing.assert_allclose(s.position, [1, 0, 0.2], atol=1e-9)
    np.testing.assert_allclose(world.frame_pose("ee_link", "arm")[0], [1, 0, 0.7], atol=1e-6)
    with pytest.raises(ValueError, match="fixed base"):
        world.set_entity_state("arm", linear_velocity=[1, 0, 0])
    world.reset(ResetScope.STATE)
    np.testing.assert_allclose(world.get_entity_state("arm").position, [0, 0, 0], atol=1e-12)


def test_static_object(make_world):
    world = make_world()
    info = world.spawn("post", BALL, category=EntityCategory.STATIC_OBJECT, pose=([0, 0, 0.3], [1, 0, 0, 0]))
    assert info.fixed_base
    world.step(100)
    np.testing.assert_allclose(world.get_entity_state("post").position, [0, 0, 0.3])


def test_bounds(make_world):
    world = make_world()
    world.spawn("ball", BALL, pose=([0.2, 0.1, 0.5], [1, 0, 0, 0]))
    lo, hi = world.bounds("ball")
    np.testing.assert_allclose(lo, [0.17, 0.07, 0.47], atol=1e-9)
    np.testing.assert_allclose(hi, [0.23, 0.13, 0.53], atol=1e-9)


def test_joint_state_and_names(arm_world):
    js = arm_world.joint_state("arm")
    assert js.names == arm_world.joint_names("arm") == ("joint1", "joint2", "joint3")
    assert js.position.shape == js.velocity.shape == js.effort.shape == (3,)


def test_set_joint_positions(arm_world):
    arm_world.set_joint_positions("arm", ["joint3", "joint1"], [0.5, -1.0])
    np.testing.assert_allclose(arm_world.joint_state("arm").position, [-1.0, 0.3, 0.5])
    arm_world.step(100)  # hold=True: the controllers keep the teleported pose
    np.testing.assert_allclose(arm_world.joint_state("arm").position, [-1.0, 0.3, 0.5], atol=2e-3)
    with pytest.raises(ValueError, match="outside"):
        arm_world.set_joint_positions("arm", ["joint2"], [2.5])
    with pytest.raises(ValueError, match="finite"):
        arm_world.set_joint_positions("arm", ["joint2"], [np.nan])
    with pytest.raises(EntityError, match="no joint"):
        arm_world.set_joint_positions("arm", ["elbow"], [0.0])
    with pytest.raises(ValueError, match="lengths"):
        arm_world.set_joint_positions("arm", ["joint1", "joint2"], [0.0])


def test_frame_set_survives_recompile(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO, joint_positions={"joint2": 0.0})
    fs = world.frame_set(["ee_link", "world", "link2"], "arm")
    poses = fs.poses()
    assert poses.shape == (3, 7)
    np.testing.assert_allclose(poses[0, :3], [0, 0, 0.5], atol=1e-9)
    np.testing.assert_allclose(poses[1], [0, 0, 0, 1, 0, 0, 0], atol=1e-12)
    world.spawn("other", ARM_XACRO, pose=([1, 0, 0], [1, 0, 0, 0]), joint_positions={"joint2": 0.0})
    np.testing.assert_allclose(fs.positions()[0], [0, 0, 0.5], atol=1e-9)
    with pytest.raises(EntityError, match="known frames"):
        world.frame_set(["nope"], "arm")
    full = world.frame_set(["other/ee_link"])
    np.testing.assert_allclose(full.positions()[0], [1, 0, 0.5], atol=1e-9)
    world.delete("arm")
    with pytest.raises(EntityError, match="deleted"):
        fs.poses()


def test_frames_agree_with_the_joint_state_after_a_step(make_world):
    """mj_step computes positions before integrating: without a kinematics pass after the step call
    the frames would show the arm one physics step behind its joint state."""
    import mujoco

    world = make_world()
    world.spawn("arm", ARM_XACRO)
    fs = world.frame_set(["ee_link", "link2"], "arm")
    world.set_command("arm", "arm_controller", [0.9, -0.6, 0.8])
    trajectory = []
    for _ in range(5):
        world.step(7)
        lagging = world.data.xpos[world.model.body("arm/ee_link").id].copy()  # before any frame read
        poses = fs.poses().copy()
        check = mujoco.MjData(world.model)
        check.qpos[:] = world.data.qpos
        check.mocap_pos[:], check.mocap_quat[:] = world.data.mocap_pos, world.data.mocap_quat
        mujoco.mj_kinematics(world.model, check)
        np.testing.assert_allclose(poses[0, :3], check.xpos[world.model.body("arm/ee_link").id], atol=1e-12)
        np.testing.assert_allclose(poses[1, 3:], check.xquat[world.model.body("arm/link2").id], atol=1e-12)
        trajectory.append((lagging, poses[0, :3].copy()))
    assert max(np.linalg.norm(lag - now) for lag, now in trajectory) > 1e-5  # the arm moved within one step


def test_frame_set_pose_arrays_are_fresh_copies_of_poses(make_world):
    """pose_arrays (links only, in order: gathered from MuJoCo; otherwise split from poses) equals
    poses, after a step too, and returns new arrays each call."""
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    world.spawn("pend", PENDULUM, pose=([1, 0, 1], [1, 0, 0, 0]))
    sets = [world.frame_set(["ee_link", "link2"], "arm"), world.frame_set(["link2", "ee_link"], "arm"),
            world.frame_set(["tip", "bob"], "pend"), world.frame_set(["arm/ee_link", "pend/tip"])]
    world.set_command("arm", "arm_controller", [0.9, -0.6, 0.8])
    for _ in range(3):
        world.step(5)
        for fs in sets:
            positions, orientations = fs.pose_arrays()
            rows = fs.poses()
            np.testing.assert_array_equal(positions, rows[:, :3])
            np.testing.assert_array_equal(orientations, rows[:, 3:])
            again = fs.pose_arrays()
            assert not np.shares_memory(positions, again[0]) and not np.shares_memory(positions, rows)
    assert sets[0]._bodies_in_order and not sets[2]._bodies_in_order  # both paths ran


def test_joint_state_arrays_are_fresh_copies_of_joint_state(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    world.set_command("arm", "arm_controller", [0.9, -0.6, 0.8])
    world.step(20)
    arrays = world.joint_state_arrays("arm")
    js = world.joint_state("arm")
    for a, b in zip(arrays, (js.position, js.velocity, js.effort)):
        np.testing.assert_array_equal(a, b)
        assert not np.shares_memory(a, b)
    assert np.any(arrays[2] != 0)


def test_mjcf_site_frame(make_world):
    world = make_world()
    world.spawn("pend", PENDULUM, pose=([0, 0, 1], [1, 0, 0, 0]))
    np.testing.assert_allclose(world.frame_pose("tip", "pend")[0], [0, 0, 0.7], atol=1e-9)


def _rollout(world, n=300):
    world.set_command("arm", "arm_controller", [0.7, -0.4, 0.9])
    world.step(n // 2)
    world.set_command("arm", "arm_controller", [-0.2, 0.5, -0.3])
    world.step(n // 2)
    js = world.joint_state("arm")
    return js.position.copy(), js.velocity.copy(), world.time


def test_step_is_deterministic(make_world):
    def fresh():
        w = make_world()
        w.spawn("arm", ARM_XACRO, initial=True)
        w.spawn("ball", BALL, pose=([0.15, 0, 0.9], [1, 0, 0, 0]), initial=True)
        return w

    a, b = _rollout(fresh()), _rollout(fresh())
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes() and a[2] == b[2]
    w = fresh()
    first = _rollout(w)
    w.reset()
    again = _rollout(w)
    assert first[0].tobytes() == again[0].tobytes() and first[1].tobytes() == again[1].tobytes()


def test_a_step_call_replays_from_its_start_state(arm_world):
    """``step_start_state`` is where the last step call began, commands written: ``mj_step`` from it
    repeats that call's physics bit for bit (what benchmarks time as the physics limit)."""
    import mujoco

    arm_world.step(20)
    arm_world.set_command("arm", "arm_controller", [0.7, -0.4, 0.9])
    arm_world.step(25)
    start = arm_world.step_start_state()
    kind = mujoco.mjtState.mjSTATE_INTEGRATION
    after = np.empty(mujoco.mj_stateSize(arm_world.model, kind))
    mujoco.mj_getState(arm_world.model, arm_world.data, after, kind)
    data = mujoco.MjData(arm_world.model)
    mujoco.mj_setState(arm_world.model, data, start, kind)
    assert np.array_equal(data.ctrl, arm_world.data.ctrl)  # the call's commands, not the ones before
    mujoco.mj_step(arm_world.model, data, 25)
    replayed = np.empty_like(after)
    mujoco.mj_getState(arm_world.model, data, replayed, kind)
    assert replayed.tobytes() == after.tobytes()
    start[:] = 0.0  # a copy: the world's own snapshot is untouched
    assert arm_world.step_start_state().any()


def test_time_and_step(arm_world):
    arm_world.step(0)
    assert arm_world.time == 0.0
    arm_world.step(10)
    assert arm_world.time == pytest.approx(10 * 0.002)
    with pytest.raises(ValueError):
        arm_world.step(-1)


def test_reset_scopes(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO, initial=True)
    world.spawn("ball", BALL, pose=([0.5, 0, 0.5], [1, 0, 0, 0]))
    world.set_command("arm", "", [0.5, 0.5, 0.5])
    world.step(100)
    t = world.time
    world.reset(ResetScope.TIME)
    assert world.time == 0.0 and world.joint_state("arm").position[0] > 0.3
    world.step(10)
    world.reset(ResetScope.STATE)
    assert world.time == pytest.approx(10 * 0.002)
    np.testing.assert_allclose(world.joint_state("arm").position, [0, 0.3, 0])
    np.testing.assert_allclose(world.get_entity_state("ball").position, [0.5, 0, 0.5])
    world.step(100)  # controllers hold the reset pose
    np.testing.assert_allclose(world.joint_state("arm").position, [0, 0.3, 0], atol=2e-3)
    world.reset(ResetScope.SPAWNED)
    assert world.entity_names() == ("arm",) and world.time > 0
    world.spawn("ball", BALL, pose=([0.5, 0, 0.5], [1, 0, 0, 0]))
    world.step(20)
    world.reset(ResetScope.DEFAULT)
    assert world.entity_names() == ("arm",) and world.time == 0.0 and t > 0


def test_physics_properties(arm_world):
    arm_world.timestep = 0.001
    assert arm_world.timestep == 0.001
    arm_world.step(10)
    assert arm_world.time == pytest.approx(0.01)
    arm_world.gravity = (0, 0, -1.62)
    np.testing.assert_allclose(arm_world.gravity, [0, 0, -1.62])
    arm_world.spawn("ball", BALL)  # survives a recompile
    assert arm_world.timestep == 0.001 and arm_world.gravity[2] == pytest.approx(-1.62)
    with pytest.raises(ValueError):
        arm_world.timestep = 0.0
    with pytest.raises(ValueError):
        arm_world.gravity = (0, np.inf, 0)


def test_unstable_entity_is_contained(make_world):
    def fresh():
        w = make_world()
        w.spawn("arm", ARM_XACRO)
        w.spawn("pend", PENDULUM, pose=([1, 0, 1], [1, 0, 0, 0]), joint_positions={"swing": 0.8})
        w.set_command("arm", "", [0.3, 0.2, 0.1])
        w.step(50)
        return w

    world, reference = fresh(), fresh()
    arm = world._entities["arm"]  # white-box: poison the arm's velocity
    arm_q = world.joint_state("arm").position.copy()
    world.data.qvel[arm.jnt_dadr[1]] = 1e30
    with pytest.raises(UnstableSimulationError) as info:
        world.step(10)
    reference.step(10)
    assert info.value.entities == ("arm",)
    assert np.all(np.isfinite(world.data.qpos)) and np.all(np.isfinite(world.data.qvel))
    np.testing.assert_allclose(world.joint_state("arm").position, arm_q, atol=1e-4)  # restored, at rest
    np.testing.assert_allclose(world.joint_state("arm").velocity, 0.0, atol=1e-6)
    # the pendulum stepped on exactly as in an undisturbed world
    np.testing.assert_allclose(world.joint_state("pend").position, reference.joint_state("pend").position,
                               rtol=1e-12, atol=1e-12)
    assert world.time == reference.time
    world.step(100)  # and the world keeps running
    assert np.all(np.isfinite(world.joint_state("arm").position))


STIFF_HINGE = ('<mujoco><worldbody><body name="b"><joint name="hinge" type="hinge" axis="0 1 0" stiffness="1000" '
               'springref="0.5"/><geom type="capsule" size="0.01 0.05" mass="0.001"/></body></worldbody></mujoco>')


def test_an_entity_that_diverges_from_its_spawn_state_is_removed_alone(make_world):
    """It used to be restored call after call, and to reset the whole world (time and all) when
    restoring did not help: every other robot's steps failed."""
    def fresh():
        w = make_world()
        w.spawn("arm", ARM_XACRO)
        w.set_command("arm", "", [0.3, 0.2, 0.1])
        w.step(20)
        return w

    world, reference = fresh(), fresh()
    world.spawn("hostile", STIFF_HINGE, pose=([2, 0, 0.5], [1, 0, 0, 0]))  # no admission checks here
    with pytest.raises(UnstableSimulationError) as info:
        world.step(30)
    reference.step(30)
    assert info.value.entities == ("hostile",) and info.value.removed == ("hostile",)
    assert "removed from the world" in str(info.value)
    assert world.entity_names() == ("arm",) and world.time == reference.time
    np.testing.assert_allclose(world.joint_state("arm").position, reference.joint_state("arm").position,
                               rtol=0, atol=1e-9)
    with pytest.raises(EntityError, match="hostile.*removed from the world"):
        world.joint_state("hostile")
    world.step(100)  # no error any more
    world.spawn("hostile", ARM_XACRO, pose=([1, 0, 0], [1, 0, 0, 0]))  # the name is free again
    assert world.removal_reason("hostile") is None


def test_admission_refuses_what_would_harm_the_others(make_world):
    from multiros.sim.errors import SpawnRefusedError
    from multiros.sim.limits import DescriptionLimits

    world = make_world()
    world.spawn("arm", ARM_XACRO)
    box = ('<mujoco><worldbody><body name="box"><freejoint/><geom type="box" size="0.05 0.05 0.05" '
           'mass="{m}"/></body></worldbody></mujoco>')
    cases = [("stiff", STIFF_HINGE, [2, 0, 0.5], "unstable"), ("through", box.format(m=1), [0.03, 0, 0.25], "overlap"),
             ("above", box.format(m=1e4), [0.05, 0, 1.0], "landing")]
    for name, text, position, reason in cases:
        world.spawn(name, text, pose=(position, [1, 0, 0, 0]))
        with pytest.raises(SpawnRefusedError) as info:
            world.admit(name)
        assert info.value.reason == reason and f"'{name}'" in str(info.value)
        world.delete(name)
    off = DescriptionLimits(trial_steps=0, max_penetration=float("inf"), max_load_ratio=float("inf"))
    for name, text, position, _ in cases:  # each check can be turned off
        world.spawn(name, text, pose=(position, [1, 0, 0, 0]))
        world.admit(name, off)
        world.delete(name)


def test_realtime_runner_paces_and_stops(arm_world):
    chunks = []
    done = threading.Event()

    def on_chunk(world):
        chunks.append(world.time)
        if len(chunks) >= 5:
            done.set()

    runner = RealTimeRunner(arm_world, real_time_factor=0.0, chunk_steps=5, on_chunk=on_chunk)
    runner.start()
    try:
        assert done.wait(5.0)
    finally:
        runner.stop()
    assert not runner.running and chunks == sorted(chunks) and arm_world.time >= 5 * 5 * 0.002
    runner.real_time_factor = 1.0
    done.clear()
    chunks.clear()
    runner.start()
    try:
        assert done.wait(5.0)
        with runner.lock:  # the node's access pattern: hold the lock, the runner waits
            t = arm_world.time
            assert arm_world.time == t
    finally:
        runner.stop()
    assert runner.error is None
