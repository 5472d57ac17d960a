"""``uniros-fake-robot --arm FILE --physics TASK``: the physics stand-in of push, pick-and-place and slide.

In process: the world it builds (the Sim twin's scene, the robot under the driver's controllers),
perturbations read back from the MuJoCo model, the gap's offsets, the lab helper that puts the object
back when the arm returns to its start pose, and bad options (one line, exit code 2). Over the wire (a
child process on a private router, stopped by PID): joint_states under the driver's names, the object
on the tracker topic in the base frame, the place_object topic, and the RX200 push Real twin pushing
the object with its scripted policy.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from multiros.hardware.gap import load_gap_profile
from multiros.hardware.physics_hardware import PhysicsHardware
from multiros.hardware.process import FakeRobotProcess
from multiros.ros import Context, Node
from multiros.ros.interfaces import get_message
from rl_environments.arm_file import ArmFile
from rl_environments.arm_registry import registered_arms
from uniros import physics_stand_in as ps
from uniros.fake_robot import arm_robot_spec

from .conftest import TopicRecorder, make_real

_CWD = tempfile.gettempdir()
JointState = get_message("sensor_msgs/msg/JointState")
PoseStamped = get_message("geometry_msgs/msg/PoseStamped")


def _arm(name: str = "RX200") -> ArmFile:
    return registered_arms()[name]


def _hardware(task: str = "push", scales: dict[str, float] | None = None, gap: Any = None,
              arm: ArmFile | None = None) -> tuple[PhysicsHardware, ps.PhysicsScene]:
    arm = arm or _arm()
    scene = ps.physics_scene(arm, task)
    return ps.physics_hardware(arm_robot_spec(arm), arm, scene, scales or {}, gap=gap), scene


def _body_mass(hw: PhysicsHardware, body: str) -> float:
    model = hw.world.model
    return float(model.body_mass[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)])


# ------------------------------------------------------------------------------ in process
def test_the_world_holds_the_sim_twins_scene_and_the_drivers_controllers() -> None:
    arm = _arm()
    hw, scene = _hardware()
    try:
        assert sorted(hw.start_controllers()) == ["arm_controller", "gripper_controller", "joint_state_broadcaster"]
        assert set(hw.world.entity_names()) == {"rx200", "rx200_table", "rx200_object"}
        position, _ = hw.pose(scene.object.name)
        # spawned at the start box's centre, resting on the table (the Sim twin's base at robot_height)
        cfg = arm.manipulation
        assert cfg is not None
        np.testing.assert_allclose(scene.base, (0.0, 0.0, cfg["robot_height"]))
        centre = (np.add(cfg["object_xy_min"], cfg["object_xy_max"]) / 2).tolist()
        np.testing.assert_allclose(position, [*centre, cfg["table_top"] + cfg["object_half_size"] + scene.base[2]],
                                   atol=1e-9)
        names, _, _ = hw.published_state()
        assert len(names) == len(arm_robot_spec(arm).published_joints)
        # the world's clock is the wall clock, and update() steps it up to now
        hw.update()
        assert abs(hw.time - time.time()) < 0.1
        before = hw.steps
        hw.update(now=hw.time + 0.1)
        assert hw.steps - before == pytest.approx(0.1 / hw.world.timestep, abs=1)
        hw.update()  # a clock far ahead is not caught up at once: at most max_lag seconds of physics
    finally:
        hw.close()


def test_perturbations_scale_the_spawned_values_read_back_from_the_model() -> None:
    nominal, _ = _hardware()
    try:
        object_mass = _body_mass(nominal, "rx200_object/object")
        link_mass = _body_mass(nominal, "rx200/rx200/shoulder_link")
    finally:
        nominal.close()
    scales = ps.draw_scales(ps.parse_perturbation(["object_mass=2.5", "link_mass=0.8:0.8"]), np.random.default_rng(0))
    assert scales == {"link_mass": 0.8, "object_mass": 2.5}
    hw, _ = _hardware(scales=scales)
    try:
        assert _body_mass(hw, "rx200_object/object") == pytest.approx(2.5 * object_mass)
        assert _body_mass(hw, "rx200/rx200/shoulder_link") == pytest.approx(0.8 * link_mass)
    finally:
        hw.close()


def test_perturbation_options_profiles_files_and_seeded_draws(tmp_path: Path) -> None:
    assert ps.parse_perturbation([]) == {}
    hard = ps.parse_perturbation(["hard", "object_mass=3"])
    assert hard["object_mass"] == (3.0, 3.0) and hard["table_friction"] == ps.PERTURB_PROFILES["hard"]["table_friction"]
    path = tmp_path / "p.yaml"
    path.write_text("object_friction: [0.5, 0.7]\njoint_damping: 2\n")
    assert ps.parse_perturbation([str(path)]) == {"object_friction": (0.5, 0.7), "joint_damping": (2.0, 2.0)}
    a = ps.draw_scales(hard, np.random.default_rng(3))
    assert a == ps.draw_scales(hard, np.random.default_rng(3)) != ps.draw_scales(hard, np.random.default_rng(4))
    assert all(lo <= a[k] <= hi for k, (lo, hi) in hard.items())
    for bad, match in ((["object_mas=2"], "did you mean 'object_mass'"), (["object_mass=0"], "0.01 <= low"),
                       (["object_mass=2:1"], "low <= high"), (["object_mass=x"], "a scale or a range"),
                       (["nope"], "not KEY=SCALE, a profile"), ([str(tmp_path)], "cannot be read")):
        with pytest.raises(ps.PhysicsOptionError, match=match):
            ps.parse_perturbation(bad)


def test_the_gaps_offsets_are_the_encoders_and_its_timing_the_worlds_command_shaping() -> None:
    gap = load_gap_profile("none", {"offset": "0.02", "latency": "0.05"})
    hw, _ = _hardware(gap=gap)
    try:
        hw.start_controllers()
        hw.update()
        published, _, _ = hw.published_state()
        truth, _, _ = hw.true_state()
        diff = np.subtract(published, truth)[:5]
        assert np.all(np.abs(diff) <= 0.02) and np.any(np.abs(diff) > 1e-4)
        np.testing.assert_allclose(diff, hw.offsets[:5])
        shaping = hw.world._get("rx200").shaping  # the world applies the command rows
        assert shaping is not None and shaping.latency == pytest.approx(0.05)
    finally:
        hw.close()


def _settle_after_a_move(gap: Any) -> np.ndarray:
    """The true arm joints 3 s (world time) after the shoulder and elbow are commanded 0.3 rad up."""
    hw, _ = _hardware(gap=gap)
    try:
        hw.start_controllers()
        home = np.asarray(hw.true_state()[0][:5])
        hw.set_command("rx200", "arm_controller", (home + [0.0, 0.3, 0.3, 0.0, 0.0]).tolist())
        start = hw.time
        for k in range(1, 61):
            hw.update(now=start + 0.05 * k)
        return np.asarray(hw.true_state()[0][:5])
    finally:
        hw.close()


def test_droop_and_backlash_act_through_the_worlds_command_shaping() -> None:
    """The gap's droop (shoulder and elbow) and backlash (every arm joint) as dead bands of the command
    shaping: the drooping joints settle the droop (plus the backlash) short of where the same world
    without them settles."""
    gap = load_gap_profile("none", {"droop": "0.03", "backlash": "0.005"})
    hw, _ = _hardware(gap=gap)
    try:
        shaping = hw.world._get("rx200").shaping
        assert shaping is not None
        np.testing.assert_allclose(shaping.droop[:5], [0.005, 0.035, 0.035, 0.005, 0.005])
    finally:
        hw.close()
    short = _settle_after_a_move(None) - _settle_after_a_move(gap)
    np.testing.assert_allclose(short[1:3], [0.035, 0.035], atol=0.004)
    with pytest.raises(ValueError, match="droop_joints"):
        _hardware(gap=load_gap_profile("none", {"droop": "0.03", "droop_joints": "7"}))


def test_the_helper_puts_the_object_back_once_the_arm_returns_to_its_start_pose() -> None:
    arm = _arm()
    hw, scene = _hardware()
    try:
        hw.start_controllers()
        helper = ps.LabHelper(hw, scene, arm.joints, "random", np.random.default_rng(0))
        hw.place(scene.object.name, (0.5, 0.5, 1.0))  # knocked off the table
        helper.check()  # the arm is at home, far from the start pose: nothing yet
        assert helper.placed == 0
        hw.world.set_joint_positions("rx200", list(arm.joints), scene.start_pose)
        helper.check()  # back at the start pose: the object is put back, in the start box
        assert helper.placed == 1
        position, _ = hw.pose(scene.object.name)
        rel = position - np.asarray(scene.base)
        assert np.all(rel[:2] >= scene.object_xy_min) and np.all(rel[:2] <= scene.object_xy_max)
        assert rel[2] == pytest.approx(scene.rest_z)
        helper.check()  # still there: once per return
        assert helper.placed == 1
        spawn = ps.LabHelper(hw, scene, arm.joints, "spawn")
        assert spawn.next_pose()[0] == pytest.approx(scene.object.position)
        with pytest.raises(ps.PhysicsOptionError, match="--physics-reset 'x'"):
            ps.LabHelper(hw, scene, arm.joints, "x")
    finally:
        hw.close()


def test_slide_and_pick_and_place_scenes() -> None:
    slide = ps.physics_scene(_arm(), "slide")
    assert "puck" in slide.object.description and slide.yaw_range == 0.05
    pnp = ps.physics_scene(_arm("VX300S"), "pnp")
    assert pnp.object.name == "vx300s_object" and len(pnp.start_pose) == len(_arm("VX300S").joints)
    with pytest.raises(ps.PhysicsOptionError, match="has no gripper"):
        ps.physics_scene(_arm("IRB120"), "push")
    with pytest.raises(ps.PhysicsOptionError, match="one of push, pnp, slide"):
        ps.physics_scene(_arm(), "reach")


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uniros.fake_robot", "--router", "none", *args],
                          capture_output=True, text=True, timeout=120, cwd=_CWD)


@pytest.mark.slow
@pytest.mark.parametrize(("args", "match"), [
    (["--physics", "reach"], "--physics 'reach': the task is one of push, pnp, slide"),
    (["--physics", "push", "--physics-perturb", "object_mas=2"], "did you mean 'object_mass'"),
    (["--physics", "push", "--physics-perturb", "object_mass=1000"], "0.01 <= low <= high <= 100"),
    (["--physics", "push", "--physics-reset", "never"], "--physics-reset 'never'"),
    (["--physics", "push", "--tracker-latency", "5"], "--tracker-latency must be within"),
    (["--physics", "push", "--time-constant", "0.2"], "--time-constant: with --physics"),
    (["--physics", "push"], "has no gripper"),
], ids=["task", "key", "scale", "reset", "latency", "time-constant", "no-gripper"])
def test_bad_physics_options_are_one_line_and_exit_code_2(args: list[str], match: str) -> None:
    out = _run("--arm", str(_arm("IRB120" if match == "has no gripper" else "RX200").path), *args)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("uniros-fake-robot: ") and match in lines[0], out.stderr


def test_physics_needs_an_arm_file() -> None:
    out = _run("--robot", "rx200", "--physics", "push")
    assert out.returncode == 2 and "--physics needs --arm" in out.stderr


# ------------------------------------------------------------------------------ over the wire
@pytest.fixture(scope="module")
def stand_in(graph: Context) -> Iterator[FakeRobotProcess]:
    arm = _arm()
    robot = FakeRobotProcess(None, context=graph, module="uniros.fake_robot", namespace=arm.real.namespace,
                             args=["--arm", str(arm.path), "--physics", "push", "--physics-reset", "spawn",
                                   "--tracker-noise", "0.0005", "--tracker-latency", "0.02", "--log-level",
                                   "WARNING"], timeout_sec=90.0, cwd=_CWD)
    try:
        yield robot
    finally:
        robot.stop()


def _latest(recorder: TopicRecorder) -> Any:
    return recorder.messages[-1] if recorder.messages else None


@pytest.mark.multiprocess
@pytest.mark.slow
def test_the_stand_in_serves_the_drivers_joint_states_and_the_object_on_the_tracker_topic(
        graph: Context, stand_in: FakeRobotProcess) -> None:
    arm = _arm()
    joints = TopicRecorder(graph, JointState, f"{stand_in.namespace}/joint_states")
    poses = TopicRecorder(graph, PoseStamped, "/object_pose")
    node = Node(f"placer_{time.monotonic_ns()}", context=graph)
    try:
        assert joints.wait_count(5, 20.0) and poses.wait_count(5, 20.0)
        assert list(_latest(joints).name) == arm_robot_spec(arm).published_joints
        pose = _latest(poses)
        assert pose.header.frame_id == arm.base_link
        scene = ps.physics_scene(arm, "push")
        # base frame: the object's world position less the base's, within the tracker's noise
        expected = np.subtract(scene.object.position, scene.base)
        got = [pose.pose.position.x, pose.pose.position.y, pose.pose.position.z]
        np.testing.assert_allclose(got, expected, atol=0.005)
        # A hand puts the object elsewhere (base frame), through <ns>/physics/place_object.
        pub = node.create_publisher(PoseStamped, f"{stand_in.namespace}/physics/place_object", 10)
        msg = PoseStamped()
        msg.header.frame_id = arm.base_link
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = 0.3, 0.1, float(expected[2])
        msg.pose.orientation.w = 1.0

        def moved() -> bool:
            pub.publish(msg)
            last = _latest(poses)
            return abs(last.pose.position.x - 0.3) < 0.005 and abs(last.pose.position.y - 0.1) < 0.005

        assert graph.wait_for(moved, 20.0)
    finally:
        node.destroy_node()
        joints.close()
        poses.close()


@pytest.mark.multiprocess
@pytest.mark.slow
def test_the_push_twins_scripted_policy_pushes_the_object(graph: Context, stand_in: FakeRobotProcess) -> None:
    env = make_real(graph, "RX200PushGoalReal-v0", startup_timeout=20.0, object_pose_timeout=5.0)
    try:
        task = env.unwrapped.task
        seed = 0
        obs, _ = env.reset(seed=seed)
        while np.linalg.norm(task.object_position() - task.goal) < 0.08:  # a goal the object must move to
            seed += 1
            obs, _ = env.reset(seed=seed)
        start = task.object_position()
        policy = task.scripted_policy()
        policy.reset()
        truncated = False
        while not truncated:
            obs, _, _, truncated, info = env.step(policy(obs))
            assert info.get("truncated_reason") is None
        moved = float(np.linalg.norm(task.object_position() - start))
        assert moved > 0.02, f"the object moved {moved:.4f} m (now {task.object_goal_distance():.3f} m from the goal)"
    finally:
        env.close()
