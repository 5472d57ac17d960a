"""``uniros arm add``: an arm file inferred from a description laid out as a sourced ament workspace
gives it (``share/<pkg>``, xacro with ``$(find)`` and arguments, found through ``AMENT_PREFIX_PATH``).

The descriptions under ``arm_add_data/install/share`` are written for these tests from published
kinematics with primitive geometry (no vendor files): a 7-joint arm with a parallel gripper (Franka
Emika Panda's DH parameters and limits; ``hand:=false`` leaves the gripper out), a 4-joint arm with
a parallel gripper (ROBOTIS OpenManipulator-X's) and a 6-joint arm with a linkage gripper laid out as
UFACTORY's xarm_description lays out the xArm6 and its gripper (what vendors' packages do that a
hand-made file would not: see its xacro). The written file loads, registers its 6 + 6 IDs,
every simulated ID passes gymnasium's checker, the scripted reach reaches, and every bad input is a
one-line error that leaves nothing behind.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from gymnasium.envs.registration import registry
from gymnasium.utils.env_checker import check_env

import uniros
from rl_environments import ARM_TASKS
from rl_environments.arm_file import ArmFileError, load_arm_file
from rl_environments.arm_registry import unregister_arm
from rl_environments.manipulation_scripted import ScriptedReach, run_episode, scripted_policy
from uniros.cli import main as cli

DATA = Path(__file__).parent / "arm_add_data" / "install"
PANDA = "package://uniros_test_panda_description/urdf/panda.urdf.xacro"
OMX = "package://uniros_test_omx_description/urdf/omx.urdf.xacro"
LINKAGE = "package://uniros_test_linkage_description/urdf/linkage_arm.urdf.xacro"
TWOFINGER = "package://uniros_test_twofinger_description/urdf/twofinger_arm.urdf.xacro"
TASKS = ARM_TASKS  # every task of the task table: a gripper arm has them all


@pytest.fixture
def workspace(monkeypatch, tmp_path):
    """The test descriptions' install prefix on AMENT_PREFIX_PATH; arms registered here are removed."""
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(DATA))
    monkeypatch.setenv("UNIROS_ARMS", "")
    names: list[str] = []
    yield names
    for name in names:
        unregister_arm(name)


def _add(capsys, names: list[str], uri: str, name: str, out: Path, *extra: str) -> tuple[Path, list[str]]:
    names.append(name)
    code = cli(["arm", "add", uri, "--name", name, "--output", str(out), *extra])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    ids = [line.strip() for line in printed.out.splitlines() if line.startswith("  ")]
    return out / f"{name}.yaml", ids


def _error(capsys, *argv: str) -> str:
    assert cli(["arm", "add", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    return err


ARMS = {  # name: (URI, arguments, joints, EE link, approach axis)
    "ArmAddPanda": (PANDA, ("--xacro-arg", "hand=true"), 7, "panda_hand_tcp", "z"),
    "ArmAddOmx": (OMX, (), 4, "end_effector_link", "x"),
    "ArmAddLinkage": (LINKAGE, (), 6, "link_tcp", "z"),
    "ArmAddTwoFinger": (TWOFINGER, (), 6, "link6", "z"),
}
CLOSES_UP = {"ArmAddLinkage"}  # its gripper closes towards the drive's upper limit


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """Both test arms added once (``uniros arm add``) for the tests that only read or use them."""
    out = tmp_path_factory.mktemp("arms")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("AMENT_PREFIX_PATH", str(DATA))
        mp.setenv("UNIROS_ARMS", "")
        result = {}
        for name, (uri, extra, *_) in ARMS.items():
            import io
            from contextlib import redirect_stdout

            buf = io.StringIO()
            with redirect_stdout(buf):
                assert cli(["arm", "add", uri, "--name", name, "--output", str(out), *extra]) == 0
            ids = [line.strip() for line in buf.getvalue().splitlines() if line.startswith("  ")]
            result[name] = (out / f"{name}.yaml", ids)
        yield result
        for name in ARMS:
            unregister_arm(name)


@pytest.mark.parametrize("name", list(ARMS))
def test_arm_add_writes_a_file_that_loads_and_registers_its_ids(written, name):
    path, ids = written[name]
    _, _, joints, ee, approach = ARMS[name]
    assert ids == [f"{name}{t}Sim-v0" for t in TASKS] + [f"{name}{t}Real-v0" for t in TASKS]
    spec = load_arm_file(path)
    assert len(spec.joints) == joints and spec.ee_link == ee and spec.approach_axis == approach
    assert spec.gripper is not None
    assert (spec.gripper.closed > spec.gripper.open) == (name in CLOSES_UP)
    assert Path(spec.controllers_file) == path.parent / name / "controllers.yaml"
    assert spec.scene_files == {} and "scene" not in yaml.safe_load(path.read_text()), \
        "the table and the cube are made from manipulation's sizes: one place"
    assert sorted(p.name for p in (path.parent / name).iterdir()) == ["controllers.yaml"]
    text = path.read_text()
    assert "# inferred: the serial chain" in text and "guessed" in text
    controllers = yaml.safe_load((path.parent / name / "controllers.yaml").read_text())
    gains = controllers["arm_position_controller"]["ros__parameters"]["gains"]
    assert list(gains) == list(spec.joints) and all(g["p"] > 0 and g["d"] > 0 for g in gains.values())
    error = float(text_after((path.parent / name / "controllers.yaml").read_text(), "largest tracking error"))
    assert error < 0.02, "the settle check holds both poses"
    from rl_environments.arm_registry import arm_value

    arm, at = arm_value(name), np.zeros(3)
    cube = arm.scene_entity("object", "cube", at, movable=True)
    half = spec.scene["object_half_size"]
    assert f'size="{half:g} {half:g} {half:g}"' in cube.mjcf and cube.uri == ""
    hx, hy, hz = spec.scene["table_half_extents"]
    assert f'size="{hx:g} {hy:g} {hz:g}"' in arm.scene_entity("table", "table", at, movable=False).mjcf


def text_after(text: str, marker: str) -> str:
    return text.split(marker, 1)[1].split()[0]


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ARMS))
def test_every_sim_id_of_the_written_arm_passes_check_env(written, name):
    for env_id in written[name][1][:6]:
        env = uniros.make(env_id)
        try:
            obs, _ = env.reset(seed=0)
            assert env.observation_space.contains(obs)
            check_env(env.unwrapped, skip_render_check=True)
        finally:
            env.close()


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ARMS))
def test_scripted_reach_succeeds_on_the_written_arm(written, name):
    """The servos hold the start pose and the scripted reach meets every goal of fixed seeds."""
    env = uniros.make(f"{name}ReacherGoalSim-v0", ee_action_type=True)
    try:
        env.reset(seed=0)
        np.testing.assert_allclose(env.unwrapped.arm_positions(), env.unwrapped.task.init_joint_pos, atol=0.03)
        policy = scripted_policy(env)
        assert isinstance(policy, ScriptedReach)
        results = [run_episode(env, policy, seed=s) for s in range(10)]
        assert all(r["is_success"] for r in results), results
    finally:
        env.close()


# The 4-joint arm and the 7-joint arm's stand-in push and pick their cubes (the Panda's pick-and-place: 0.97
# over 30 seeds, its EE moving 3.9 cm a step, so the carry starts slowly: see scripted_policy).
@pytest.mark.slow
@pytest.mark.parametrize(("name", "task"), [("ArmAddOmx", "PushGoal"), ("ArmAddOmx", "PnPGoal"),
                                            ("ArmAddPanda", "PushGoal"), ("ArmAddPanda", "PnPGoal"),
                                            ("ArmAddLinkage", "PushGoal"), ("ArmAddLinkage", "PnPGoal"),
                                            ("ArmAddTwoFinger", "PushGoal"), ("ArmAddTwoFinger", "PnPGoal")])
def test_scripted_push_and_pick_and_place_succeed_on_the_written_arm(written, name, task):
    """The written scene (table, cube, goal boxes) fits the arm: the scripted policy, which reads only
    the observation, moves the cube to the goal on at least 9 of 10 fixed seeds (30 seeds: all)."""
    env = uniros.make(f"{name}{task}Sim-v0", ee_action_type=True)
    try:
        policy = scripted_policy(env)
        results = [run_episode(env, policy, seed=s) for s in range(10)]
        assert sum(r["is_success"] for r in results) >= 9, results
    finally:
        env.close()


def test_a_linkage_gripper_is_written_as_its_package_describes_it(written):
    """UFACTORY-style: one driven knuckle and five mimics, closing towards its upper limit, the drive left
    out of ros2_control, a follower that stops before the drive does, effort="-1", the fingers below the
    base at zero joints. The second finger is the follower on the other side, the range the one every
    follower can take, and each of these is said in the file."""
    path, _ = written["ArmAddLinkage"]
    spec = load_arm_file(path)
    assert spec.gripper.joints == ("drive_joint", "right_outer_knuckle_joint")
    assert (spec.gripper.closed, spec.gripper.open) == (0.7, 0.0)
    assert spec.scene["gripper_min"] == 0.7 and spec.scene["gripper_max"] == 0.0
    text = path.read_text()
    assert "# The description: joint 'joint1' limit effort -1 <= 0 is read as unknown (no limit)." in text
    assert "narrowed to [0, 0.7]" in text and "not in the description's <ros2_control> tag" in text
    assert "4 more joint(s) follow it (a linkage)" in text
    assert spec.scene["object_half_size"] >= 0.015, "a cube for the 8 cm stroke, not for the knuckles' gap"
    # the driver's names from the package's own controllers file, namespace included
    real = spec.real
    assert (real.namespace, real.arm_controller, real.joint_states_topic) == (
        "/linkage", "linkage_traj_controller", "/linkage/joint_states")
    assert (real.gripper_controller, real.gripper_interface) == ("linkage_gripper_controller", "gripper_action")
    assert "inferred: the JointTrajectoryController of the arm's joints in the package's linkage_controllers.yaml" \
        in text


def test_two_independent_fingers_and_no_tool_frame_are_written_as_the_package_describes_them(written):
    """Piper-style: two prismatic finger joints with no <mimic>, both in ros2_control, no link between the
    pads. Both are the gripper (the second at -1 x the first, driven in simulation by one controller over
    both), the end effector is the last link moved to the fingertips' midpoint by arm.tcp_offset, and the
    driver's gripper controller over both joints comes from the package's controllers file."""
    path, _ = written["ArmAddTwoFinger"]
    spec = load_arm_file(path)
    assert spec.gripper.joints == ("joint7", "joint8") and spec.gripper.independent
    assert (spec.gripper.mimic, spec.gripper.closed, spec.gripper.open) == (-1.0, 0.0, 0.038)
    assert spec.tcp_offset == pytest.approx((0.0, 0.0, 0.09), abs=1e-3), "5 cm body + 5 cm pads - 1 cm"
    text = path.read_text()
    assert "driven independently (no <mimic> ties them)" in text
    assert "which arm.tcp_offset makes the end effector" in text
    controllers = yaml.safe_load((path.parent / "ArmAddTwoFinger" / "controllers.yaml").read_text())
    assert controllers["gripper_position_controller"]["ros__parameters"]["joints"] == ["joint7", "joint8"]
    assert (spec.real.arm_controller, spec.real.gripper_controller, spec.real.gripper_interface) == (
        "twofinger_arm_controller", "twofinger_gripper_controller", "trajectory")
    # in simulation the end effector is the link's frame moved by the offset: the chain's tip
    from rl_environments.arm_registry import chain_of

    env = uniros.make("ArmAddTwoFingerPushGoalSim-v0")
    try:
        env.reset(seed=0)
        u = env.unwrapped
        np.testing.assert_allclose(u.ee_position(), chain_of(spec).fk_position(u.arm_positions())
                                   + u.connection.base_position, atol=1e-6)
        env.step(np.array([0.0, 0.0, 0.0, 1.0], np.float32))  # open: one command drives both fingers
        for _ in range(10):
            env.step(np.array([0.0, 0.0, 0.0, 1.0], np.float32))
        names = list(u.connection.states.names)
        q = u.connection.states.position[0]
        assert q[names.index("joint7")] == pytest.approx(0.038, abs=2e-3)
        assert q[names.index("joint8")] == pytest.approx(-0.038, abs=2e-3)
    finally:
        env.close()


def test_a_redundant_arms_ik_from_its_seed_resolves_the_redundancy_toward_home(workspace):
    """A 7-joint arm's top-down IK from its seed keeps pulling the null space toward home after the pose is
    met (the arm's usual posture), where a solve from the current pose keeps the redundancy where it is."""
    from multiros.sim.description import xacro_to_urdf
    from multiros.sim.packages import default_index
    from multiros.utils.kinematics import KinematicChain
    from rl_environments.arm_ik import ChainTopDownIK

    index = default_index()
    text = xacro_to_urdf(index.resolve_uri(PANDA), {"hand": "true"}, index=index)
    chain = KinematicChain.from_urdf(text, "panda_link0", "panda_hand_tcp")
    home = np.array([0.0, -0.2, 0.0, -2.4, 0.0, 2.2, 0.8])
    twisted = np.array([1.5481, -1.1101, -1.2867, -2.317, -1.0467, 1.6885, -1.5972])
    target = chain.fk_position(twisted)
    ik = ChainTopDownIK(chain, "z", "y", twisted.tolist(), home=home.tolist())
    kept = ik.solve(target, q0=twisted)  # from the current pose: a step, not a jump
    resolved = ik.solve(target)  # from the seed: toward home
    for q in (kept, resolved):
        np.testing.assert_allclose(chain.fk_position(q), target, atol=1e-3)
    np.testing.assert_allclose(kept, twisted, atol=1e-3)
    assert np.linalg.norm((resolved - home)[:-1]) < 0.5 * np.linalg.norm((twisted - home)[:-1])


def test_arm_add_prints_the_scripted_check_and_arm_check_repeats_it(written, workspace, capsys):
    path, _ = written["ArmAddOmx"]
    assert cli(["arm", "check", str(path), "--seeds", "2"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in out[:3]] == [f"ArmAddOmx{t}Sim-v0" for t in ("ReacherGoal", "PushGoal",
                                                                                        "PnPGoal")]
    assert all("scripted success 1.00 (2 of 2 seeds)" in line for line in out[:3]), out
    assert out[3].startswith("ArmAddOmx: passed")
    assert "ArmAddOmxReacherSim-v0" in registry, "the check leaves the arm registered as it was"


def test_a_drafted_file_the_scripted_policies_fail_on_is_not_written(workspace, capsys, tmp_path, monkeypatch):
    """The check is what decides: with a bar no task can meet, arm add refuses in one line and writes
    nothing, and arm check of a written file exits 1 naming what failed."""
    import rl_environments.arm_check as arm_check

    out = tmp_path / "arms"
    monkeypatch.setattr(arm_check, "PASS_RATE", 1.01)
    workspace.append("Unchecked")
    err = _error(capsys, OMX, "--name", "Unchecked", "--output", str(out))
    assert "the scripted check failed: UncheckedReacherGoalSim-v0: scripted success 1.00" in err
    assert "--no-check" in err
    assert not out.exists() or not any(out.iterdir())
    assert "UncheckedReacherSim-v0" not in registry
    path, ids = _add(capsys, workspace, OMX, "Unchecked", out, "--no-check")
    assert ids[0] == "UncheckedReacherSim-v0"
    assert cli(["arm", "check", str(path), "--seeds", "1"]) == 1
    assert "FAILED" in capsys.readouterr().out


def test_an_arm_without_a_gripper_is_reach_only_and_says_so(workspace, capsys, tmp_path):
    path, ids = _add(capsys, workspace, PANDA, "ArmAddPandaBare", tmp_path, "--xacro-arg", "hand=false")
    reach_and_slide = ("Reacher", "ReacherGoal", "Slide", "SlideGoal")  # no push or pick-and-place
    assert ids == [f"ArmAddPandaBare{t}{side}-v0" for side in ("Sim", "Real") for t in reach_and_slide]
    text = path.read_text()
    assert "gripper: null  # no actuated joint after the arm: reach only" in text
    spec = load_arm_file(path)
    assert spec.gripper is None and spec.ee_link == "panda_link8" and not spec.scene_files
    assert not (tmp_path / "ArmAddPandaBare" / "table.xml").exists()


def test_ros2_control_plugin_names_the_real_drivers_controllers(workspace, capsys, tmp_path):
    """A xacro argument (a prefix) reaches the names; the Dynamixel plugin gives ROBOTIS' controller names."""
    path, _ = _add(capsys, workspace, OMX, "ArmAddOmxReal", tmp_path, "--xacro-arg", "prefix=omx_")
    spec = load_arm_file(path)
    assert spec.joints == ("omx_joint1", "omx_joint2", "omx_joint3", "omx_joint4")
    assert spec.real.arm_controller == "arm_controller" and spec.real.gripper_interface == "gripper_action"
    assert "dynamixel_hardware" in path.read_text()

def test_without_a_known_plugin_the_real_names_are_conventional_and_marked_guessed(written):
    panda = written["ArmAddPanda"][0]
    assert load_arm_file(panda).real.arm_controller == "joint_trajectory_controller"
    assert "guessed: ROS 2 control's conventional names" in panda.read_text()


def _write_package(root: Path, name: str, urdf: str) -> str:
    share = root / "share" / name
    (share / "urdf").mkdir(parents=True)
    (share / "package.xml").write_text(f"<package format='3'><name>{name}</name></package>")
    (share / "urdf" / "robot.urdf").write_text(urdf)
    return f"package://{name}/urdf/robot.urdf"


def _chain_urdf(types: list[str], extra: str = "") -> str:
    links = "".join(f"<link name='l{i}'><inertial><mass value='0.5'/><inertia ixx='0.01' iyy='0.01' izz='0.01' "
                    f"ixy='0' ixz='0' iyz='0'/></inertial></link>" for i in range(len(types) + 1))
    joints = "".join(f"<joint name='j{i}' type='{t}'><parent link='l{i}'/><child link='l{i + 1}'/>"
                     f"<origin xyz='0 0 0.1'/><axis xyz='0 {1 if i % 2 else 0} {0 if i % 2 else 1}'/>"
                     f"<limit lower='-1' upper='1' effort='10' velocity='1'/></joint>" for i, t in enumerate(types))
    return f"<robot name='r'>{links}{joints}{extra}</robot>"


@pytest.mark.parametrize(("urdf", "match"), [
    ("<robot name='r'><link name='a'>", "malformed URDF XML"),
    (_chain_urdf(["revolute"] * 3), "no serial chain of 4 to 7 revolute joints"),
    (_chain_urdf(["prismatic"] * 5), "are all prismatic"),
    (_chain_urdf(["revolute"] * 8), "has 8 revolute joints"),
    (_chain_urdf(["revolute"] * 5).replace("</robot>", "<link name='m'><visual><geometry><mesh filename="
                                           "'package://arm_add_bad/meshes/nope.stl'/></geometry></visual></link>"
                                           "<joint name='f' type='fixed'><parent link='l5'/><child link='m'/>"
                                           "</joint></robot>"), "mesh 'package://arm_add_bad/meshes/nope.stl'"),
    (_chain_urdf(["prismatic"] + ["revolute"] * 6), "the arm's base 'l1' hangs from moving joint(s) ['j0'] (a torso"),
])
def test_bad_descriptions_are_one_line_errors_and_write_nothing(workspace, capsys, tmp_path, monkeypatch, urdf,
                                                                 match):
    prefix = tmp_path / "ws"
    uri = _write_package(prefix, "arm_add_bad", urdf)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    out = tmp_path / "out"
    err = _error(capsys, uri, "--name", "ArmAddBad", "--output", str(out))
    assert match in err and uri in err and "fix:" in err
    assert not out.exists() or not any(out.iterdir())


REACH_ONLY = {  # a gripper arm add cannot make grasp: (description, xacro arguments, the line it prints)
    # a vendor's hand whose fingers carry visuals only (franka_ros2's Panda at 0.1.13): nothing can touch the cube
    "ArmAddBareFingers": (PANDA, ("hand=true", "finger_collision=false"),
                          "the fingers of ['panda_finger_joint1', 'panda_finger_joint2'] have no <collision> geometry, "
                          "so the simulation cannot grasp with them: reach only; add collision geometry to the finger "
                          "links"),
    # open fingers leaving less than the smallest cube needs (jaws colliding as their convex hulls, a short stroke)
    "ArmAddNarrow": (TWOFINGER, ("finger_stroke=0.005",),
                     "the open fingers' collision geometry leaves 1.2 cm between them (MuJoCo collides a mesh as its "
                     "convex hull), too little for the smallest cube (1.6 cm): reach only; fix: give the finger links "
                     "primitive <collision> pads on their inner faces"),
}


@pytest.mark.parametrize("name", list(REACH_ONLY))
def test_a_gripper_that_cannot_grasp_is_reach_only_in_one_line(workspace, capsys, tmp_path, name):
    """The file is written for reach, no push or pick-and-place ID exists, and arm add says why on a line
    of its own, with the fix."""
    uri, args, why = REACH_ONLY[name]
    workspace.append(name)
    code = cli(["arm", "add", uri, *(part for arg in args for part in ("--xacro-arg", arg)), "--name", name,
                "--output", str(tmp_path)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert [x for x in printed.out.splitlines() if x.startswith("reach only:")] == [f"reach only: {why}"]
    assert f"{name}PushSim-v0" not in printed.out and f"{name}ReacherSim-v0" in printed.out


def test_missing_package_file_and_xacro_argument_are_one_line_errors(workspace, capsys, tmp_path):
    out = tmp_path / "out"
    err = _error(capsys, "package://no_such_description/urdf/r.urdf", "--name", "ArmAddX", "--output", str(out))
    assert "package 'no_such_description' not found" in err and "AMENT_PREFIX_PATH" in err
    assert "ROS_PACKAGE_PATH" in err and "extra_paths=" in err and "index's extra paths" not in err
    err = _error(capsys, str(tmp_path / "nope.urdf"), "--name", "ArmAddX", "--output", str(out))
    assert "not found" in err
    err = _error(capsys, PANDA, "--name", "ArmAddX", "--output", str(out))  # `hand` has no default
    assert "hand" in err and "--xacro-arg" in err
    err = _error(capsys, OMX, "--name", "ArmAddX", "--xacro-arg", "prefix", "--output", str(out))
    assert "NAME=VALUE" in err
    assert not out.exists() or not any(out.iterdir())


def test_an_existing_file_is_kept_unless_forced_and_names_in_use_are_refused(written, workspace, capsys, tmp_path):
    path = written["ArmAddOmx"][0]
    before = path.read_text()
    err = _error(capsys, OMX, "--name", "ArmAddOmx", "--output", str(path.parent))
    assert str(path) in err and "--force" in err and path.read_text() == before
    other = tmp_path / "other"
    err = _error(capsys, OMX, "--name", "ArmAddOmx", "--output", str(other))
    assert "is the name of the registered arm" in err and not other.exists()
    err = _error(capsys, OMX, "--name", "UR5e", "--output", str(other))  # a shipped arm's
    assert "UR5e" in err and not other.exists()
    err = _error(capsys, OMX, "--name", "9lives", "--output", str(other))
    assert "--name" in err and not other.exists()


def test_force_replaces_the_file_and_its_folder_leaving_no_temporary_files(workspace, capsys, tmp_path):
    stale = tmp_path / "ArmAddOmxTwice" / "stale.txt"
    stale.parent.mkdir()
    stale.write_text("from before")
    (tmp_path / "ArmAddOmxTwice.yaml").write_text("old")
    err = _error(capsys, OMX, "--name", "ArmAddOmxTwice", "--output", str(tmp_path))
    assert "--force" in err and (tmp_path / "ArmAddOmxTwice.yaml").read_text() == "old"
    path, ids = _add(capsys, workspace, OMX, "ArmAddOmxTwice", tmp_path, "--force")
    assert len(ids) == 2 * len(ARM_TASKS) and load_arm_file(path).name == "ArmAddOmxTwice" and not stale.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ArmAddOmxTwice", "ArmAddOmxTwice.yaml"]


def test_a_path_uri_is_written_relative_to_the_arm_file(workspace, capsys, tmp_path):
    copy = tmp_path / "desc"
    shutil.copytree(DATA / "share" / "uniros_test_omx_description", copy)
    out = tmp_path / "arms"
    path, ids = _add(capsys, workspace, str(copy / "urdf" / "omx.urdf.xacro"), "ArmAddOmxPath", out)
    assert yaml.safe_load(path.read_text())["description"]["uri"] == "../desc/urdf/omx.urdf.xacro"
    assert len(ids) == 2 * len(ARM_TASKS)


def test_arm_file_error_is_a_value_error():
    assert issubclass(ArmFileError, ValueError)


def test_a_joint_without_an_axis_turns_about_urdfs_default_x_axis():
    """URDF's ``<axis>`` defaults to ``1 0 0``: the description's tree turns a revolute joint without one about x
    and slides a prismatic one along x (it once read the missing axis as NaN)."""
    from rl_environments.arm_description_tree import _tree

    urdf = """<robot name="r"><link name="base"/><link name="a"/><link name="b"/>
      <joint name="turn" type="revolute"><parent link="base"/><child link="a"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/><origin xyz="0 0.1 0"/>
        <limit lower="0" upper="0.05" effort="1" velocity="1"/></joint></robot>"""
    tree = _tree(urdf, "test.urdf")
    angle = 0.5
    turned = tree.transform("a", {"turn": angle})
    c, s = np.cos(angle), np.sin(angle)
    assert np.allclose(turned[:3, :3], [[1, 0, 0], [0, c, -s], [0, s, c]])
    slid = tree.transform("b", {"turn": 0.0, "slide": 0.03})
    assert np.allclose(slid[:3, 3], [0.03, 0.1, 0.0])
