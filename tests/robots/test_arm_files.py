"""Arm files (rl_environments.arm_file, arm_registry): the shipped ones check out against their
descriptions, a copy under another name registers the six tasks and their Real twins, UNIROS_ARMS
reaches another process, training configs derive from the task, and every bad input is one line
naming the file and the key, with nothing registered."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import rl_environments
from rl_environments.arm_file import ARM_FILE_FORMAT, ArmFileError, load_arm_file
from rl_environments.arm_registry import arm_env_ids, chain_of, register_arm, registered_arms, unregister_arm

SHIPPED = Path(rl_environments.__file__).resolve().parent.parent / "config" / "arms"
if not SHIPPED.is_dir():  # an installed package: config is rl_environments.config
    from importlib import resources

    SHIPPED = Path(str(resources.files("rl_environments.config").joinpath("arms")))


@pytest.fixture
def ur5e_data() -> dict:
    return yaml.safe_load((SHIPPED / "ur5e.yaml").read_text())


@pytest.fixture
def write(tmp_path, monkeypatch):
    # register_arm adds its file to UNIROS_ARMS for child processes: put the variable back afterwards
    monkeypatch.setenv("UNIROS_ARMS", os.environ.get("UNIROS_ARMS", ""))
    made: list[str] = []

    def _write(data: dict, name: str = "arm.yaml") -> Path:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        made.append(str(data.get("name")))
        return path

    yield _write
    for name in made:
        if name not in ("VX300S", "UR5e", "NED2", "IRB120"):
            unregister_arm(name)


@pytest.mark.parametrize("name", ["vx300s", "ur5e", "ned2", "irb120"])
def test_shipped_arm_files_match_their_descriptions(name):
    spec = load_arm_file(SHIPPED / f"{name}.yaml")
    chain = chain_of(spec)
    assert chain.joint_names == spec.joints
    assert registered_arms()[spec.name].path == spec.path
    ids = arm_env_ids(spec)
    assert len(ids) == (8 if spec.gripper else 4)  # a gripperless arm (the IRB120): reach and slide
    assert all(i in gym.registry and real in gym.registry for i, (_, _, real) in ids.items())
    # the home pose and the reach's start pose lie within the joint limits
    for pose in (spec.home, spec.reach["init_joint_pos"]):
        assert np.all(chain.lower - 1e-9 <= pose) and np.all(np.asarray(pose) <= chain.upper + 1e-9)


def test_an_arm_file_under_another_name_registers_its_ids(ur5e_data, write):
    ur5e_data["name"], ur5e_data["robot_name"] = "MyUR", "myur"
    ids = register_arm(write(ur5e_data))
    tasks = ("Reacher", "ReacherGoal", "Push", "PushGoal", "PnP", "PnPGoal", "Slide", "SlideGoal")
    assert ids == [f"MyUR{t}Sim-v0" for t in tasks] + [f"MyUR{t}Real-v0" for t in tasks]
    assert "MyURPnPGoalSim-v0" in rl_environments.GOAL_ENV_IDS
    assert rl_environments.SIM_TO_REAL["MyURPushSim-v0"] == "MyURPushReal-v0"
    env = gym.make("MyURReacherGoalSim-v0")
    try:
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        assert env.unwrapped.arm.robot_name == "myur" and env.spec.max_episode_steps == 100
        obs, *_ = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
    finally:
        env.close()
    # the same file again is a no-op re-registration; child processes are told of the file
    assert register_arm(write(ur5e_data)) == ids
    assert str(registered_arms()["MyUR"].path) in os.environ["UNIROS_ARMS"].split(os.pathsep)
    unregister_arm("MyUR")
    assert "MyURReacherGoalSim-v0" not in gym.registry and str(ur5e_data) not in os.environ["UNIROS_ARMS"]
    assert not [p for p in os.environ["UNIROS_ARMS"].split(os.pathsep) if p.endswith("arm.yaml")]


def test_a_gripperless_arm_gets_the_reach_only(ur5e_data, write):
    ur5e_data["name"] = "ArmNoGrip"
    ur5e_data["gripper"] = None
    del ur5e_data["manipulation"], ur5e_data["scene"]
    ids = register_arm(write(ur5e_data))
    assert ids == ["ArmNoGripReacherSim-v0", "ArmNoGripReacherGoalSim-v0", "ArmNoGripSlideSim-v0",
                   "ArmNoGripSlideGoalSim-v0", "ArmNoGripReacherReal-v0", "ArmNoGripReacherGoalReal-v0",
                   "ArmNoGripSlideReal-v0", "ArmNoGripSlideGoalReal-v0"]  # no push or pick-and-place


def test_uniros_arms_registers_in_another_process(ur5e_data, tmp_path):
    ur5e_data["name"] = "EnvArm"
    path = tmp_path / "envarm.yaml"
    path.write_text(yaml.safe_dump(ur5e_data))
    code = "import rl_environments, gymnasium as gym; print('EnvArmPnPSim-v0' in gym.registry)"
    env = {**os.environ, "UNIROS_ARMS": os.pathsep.join([str(path), ""])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"
    # A broken entry beside a good one: one line on stderr, the good file's IDs registered all the same,
    # and uniros.make of an ID it would have given says why it is not there.
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: 1\nname: X\n")
    code += ("; import uniros; from uniros.factory import UnknownEnvError\ntry:\n    uniros.make('XReacherSim-v0')\n"
             "except UnknownEnvError as e:\n    print(e)")
    both = os.pathsep.join([str(bad), str(path)])
    out = subprocess.run([sys.executable, "-c", code], env={**env, "UNIROS_ARMS": both}, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip() == f"UNIROS_ARMS: {bad}: key 'description' is missing (its IDs are not registered)"
    first, second = out.stdout.splitlines()[:2]
    assert first == "True" and f"Not registered: UNIROS_ARMS: {bad}: key 'description' is missing." in second


def test_an_arm_file_whose_path_holds_the_separator_reaches_child_processes(ur5e_data, write, tmp_path):
    """UNIROS_ARMS is split at ':'; a file in a folder named 'a:b' reaches the processes this one starts
    (vector-env workers, nodes) through UNIROS_ARMS_JSON instead."""
    ur5e_data["name"], ur5e_data["robot_name"] = "ColonArm", "colonarm"
    folder = tmp_path / "runs:2026"
    folder.mkdir()
    path = folder / "colon.yaml"
    path.write_text(yaml.safe_dump(ur5e_data, sort_keys=False))
    register_arm(path)
    try:
        assert str(path) not in os.environ["UNIROS_ARMS"]
        code = "import rl_environments, gymnasium as gym; print('ColonArmPnPSim-v0' in gym.registry)"
        out = subprocess.run([sys.executable, "-c", code], env=dict(os.environ), capture_output=True, text=True,
                             timeout=120)
        assert out.returncode == 0 and out.stdout.strip() == "True", out.stderr
        assert out.stderr == ""
    finally:
        unregister_arm("ColonArm")
    assert str(path) not in os.environ.get("UNIROS_ARMS_JSON", "")


def test_a_description_that_is_not_xml_is_named_not_printed(ur5e_data, write, tmp_path):
    """A description URI pointing at a 140 KB text file: one short line naming the key, not the file's text."""
    (tmp_path / "notxml.urdf").write_text("SECRET " * 20_000)
    ur5e_data["name"], ur5e_data["description"]["uri"], ur5e_data["description"]["xacro_args"] = (
        "NotXml", "notxml.urdf", {})
    with pytest.raises(ArmFileError) as err:
        register_arm(write(ur5e_data, "notxml.yaml"))
    message = str(err.value)
    assert "key 'description.uri'" in message and "is not XML" in message
    assert len(message) < 400 and message.count("SECRET") <= 6


def test_a_hostile_arm_file_is_one_quick_line(tmp_path):
    """A 2 KB "billion laughs" (anchors whose aliases refer to each other), deep nesting and a huge file:
    refused in one line before anything expands them, in UNIROS_ARMS too."""
    import time

    laughs = tmp_path / "laughs.yaml"
    lol = ",".join(['"lol"'] * 9)
    laughs.write_text(f"format: 1\nname: Laughs\na: &a [{lol}]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{','.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8)))
    deep = tmp_path / "deep.yaml"
    deep.write_text("format: 1\nname: Deep\narm: " + "[" * 200 + "]" * 200 + "\n")
    for path, message in ((laughs, "expands to more than 50,000 values"), (deep, "nested deeper than 64 levels")):
        start = time.monotonic()
        with pytest.raises(ArmFileError, match=message) as err:
            load_arm_file(path)
        assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)
        assert time.monotonic() - start < 5.0
    code = "import uniros, rl_environments; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "UNIROS_ARMS": str(laughs)},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
    assert "expands to more than 50,000 values" in out.stderr and out.stderr.count("\n") == 1


def test_a_broken_uniros_arms_entry_is_one_line_in_every_command(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: 1\nname: X\n")
    env = {**os.environ, "UNIROS_ARMS": str(bad)}
    line = f"UNIROS_ARMS: {bad}: key 'description' is missing (its IDs are not registered)"
    for argv in (["-m", "uniros.cli", "list"], ["-m", "uniros.fake_robot", "--help"]):
        out = subprocess.run([sys.executable, *argv], env=env, capture_output=True, text=True, timeout=120)
        assert out.returncode == 0 and out.stderr.strip() == line, (argv, out.stderr)


def test_training_configs_derive_from_the_task_with_the_arm_files_overrides(ur5e_data, write):
    from uniros.train_config import default_config_for

    ur5e_data["name"] = "TrainArm"
    ur5e_data["training"] = {"ReacherGoal": {"training_steps": 4321, "sac_params": {"batch_size": 64}}}
    register_arm(write(ur5e_data))
    cfg = default_config_for("TrainArmReacherGoalSim-v0")
    assert cfg.training_steps == 4321
    assert cfg.algo_params["batch_size"] == 64 and cfg.algo_params["gamma"] == 0.95
    assert "training.ReacherGoal" in cfg.source
    assert default_config_for("UR5eReacherGoalSim-v0").training_steps == 10000


def _mutate(data: dict, path: str, value) -> dict:
    *parents, last = path.split(".")
    node = data
    for key in parents:
        node = node.setdefault(key, {})
    if value is KeyError:
        del node[last]
    else:
        node[last] = value
    return data


BAD = [
    ("arm.ee_lnk", "grasp_link", "'arm.ee_lnk' is not a key of arm; did you mean 'ee_link'?"),
    ("format", ARM_FILE_FORMAT + 1, "newer than this uniros reads (1): upgrade uniros"),
    ("arm.base_link", KeyError, "key 'arm.base_link' is missing"),
    ("arm.home", [0.0, 1.0], "key 'arm.home' must be a list of 6 finite numbers"),
    ("arm.joints", ["a", "b", "c"], "the tasks serve serial arms of 4 to 7 joints"),
    ("arm.approach_axis", "w", "must be one of x, y, z"),
    ("gripper.joints", ["left_finger_joint", "elbow_joint"], "names arm joints ['elbow_joint']"),
    ("reach.reach_tolerence", 0.02, "did you mean 'reach_tolerance'?"),
    ("reach.delta_coeff", "big", "key 'delta_coeff' must be a finite number"),
    ("real.gripper_interface", "magic", "real.gripper_interface' must be one of"),
    ("training.Reach", {}, "did you mean 'Reacher'?"),
    ("arm.tcp_offset", [0.0, 0.0], "key 'arm.tcp_offset' must be a list of 3 finite numbers"),
    ("arm.tcp_offset", [0.0, 0.0, 120.0], "more than 0.5 m from arm.ee_link along an axis; it is in metres"),
    ("arm.tcp_offset", [0.0, float("nan"), 0.0], "must be a list of 3 finite numbers"),
    ("gripper.independent", "yes", "key 'gripper.independent' must be true or false"),
    ("reach.delta_coeff", float("inf"), "key 'delta_coeff' must be a finite number, got inf"),
    ("reach.min_joint_pos", [0.0, 0.0, 0.0, float("nan"), 0.0, 0.0], "must be a list of 6 finite numbers"),
    ("reach.reach_tolerance", -0.02, "key 'reach_tolerance' must be above zero"),
    ("reach.position_goal_min", [2.0, 0.0, 0.0], "'position_goal_min' is above 'position_goal_max' at index 0"),
    ("manipulation.object_xy_min", [9.0, 0.0], "'object_xy_min' is above 'object_xy_max' at index 0"),
    ("real.max_joint_delta", 1.0e9, "must be in (0, 1]"),
    ("real.workspace_min", [5.0, -1.0, 0.0], "real.workspace_min' is above real.workspace_max at index 0"),
    ("arm.home", [0.5] * 40_000, "key 'arm.home' must be a list of 6 finite numbers, got [0.5, 0.5"),
    ("real.reset_tolerance", 0.0, "real.reset_tolerance' is 0 rad: it must be in (0, 0.5]"),
    ("real.reset_settle_tolerance", -0.1, "must be in [0, 0.5]"),
    ("dynamics.latency", 30.0, "key 'dynamics.latency' is 30 s, outside [0, 2]"),
    ("dynamics.gain", [1.0, 1.0], "key 'dynamics.gain' must be a list of 6 finite numbers"),
    ("dynamics.offset", 3.0, "key 'dynamics.offset' has 3, outside [-0.2, 0.2]"),
    ("dynamics.lag", 0.1, "key 'dynamics.lag' is not a key of dynamics"),
]


@pytest.mark.parametrize(("key", "value", "message"), BAD, ids=[b[0] for b in BAD])
def test_bad_keys_are_one_line_errors_and_register_nothing(ur5e_data, write, key, value, message):
    ur5e_data["name"] = "BadArm"
    path = write(_mutate(ur5e_data, key, value))
    before = set(gym.registry)
    with pytest.raises(ArmFileError) as err:
        register_arm(path)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)
    assert len(str(err.value)) <= 1000, "an excerpt of the value, not all of it"
    assert set(gym.registry) == before and "BadArm" not in registered_arms()


@pytest.mark.parametrize(("key", "value", "message"), [
    ("arm.ee_link", "no_such_link", "key 'arm.ee_link'"),
    ("arm.joints", ["shoulder_lift_joint", "shoulder_pan_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                    "wrist_3_joint"], "are not the moving joints"),
    ("description.uri", "package://no_such_description/urdf/x.urdf", "key 'description.uri'"),
    ("gripper.joints", ["no_finger", "right_finger_joint"], "'no_finger' is not a joint of the description"),
    ("gripper.joints", ["right_finger_joint", "left_finger_joint"], "mimics another joint"),
    ("gripper.joints", ["wrist_3_link-ft_frame"], "is a fixed joint, not an actuated one"),
    ("gripper.independent", True, "'right_finger_joint' mimics another joint, so it is not driven"),
])
def test_a_description_that_does_not_hold_the_chain_is_refused(ur5e_data, write, key, value, message):
    ur5e_data["name"] = "BadChain"
    path = write(_mutate(ur5e_data, key, value))
    before = set(gym.registry)
    with pytest.raises(ArmFileError, match=message):
        register_arm(path)
    assert set(gym.registry) == before


def test_an_unparsable_description_and_a_clashing_name(ur5e_data, write, tmp_path):
    (tmp_path / "broken.urdf").write_text("<robot name='x'><link name='a'>")
    ur5e_data["name"] = "Broken"
    ur5e_data["description"]["uri"] = "broken.urdf"
    with pytest.raises(ArmFileError, match="key 'description.uri'"):
        register_arm(write(ur5e_data, "broken.yaml"))
    ur5e_data = yaml.safe_load((SHIPPED / "ur5e.yaml").read_text())  # a second file named like a shipped arm
    with pytest.raises(ArmFileError, match="'UR5e' is already registered by .*ur5e.yaml"):
        register_arm(write(ur5e_data, "ur5e_copy.yaml"))
    (tmp_path / "notyaml.yaml").write_text("format: [1\n")
    with pytest.raises(ArmFileError, match="not valid YAML"):
        load_arm_file(tmp_path / "notyaml.yaml")


def test_a_run_records_its_arm_file_and_eval_or_resume_registers_it_again(ur5e_data, write, tmp_path):
    """A run of an arm file's ID records the file (run.json: arm_file); a process that has not
    registered it (no UNIROS_ARMS) registers it from there; a file gone is one line saying so."""
    import json

    from uniros.run_envs import arm_file_of, check_env_id, register_run_arm
    from uniros.train_config import TrainingConfig
    from uniros.training import TrainingError, open_run, start_run

    assert arm_file_of("UR5eReacherGoalSim-v0") is None and arm_file_of("RX200PushGoalReal-v0") is None
    ur5e_data["name"] = "RunArm"
    path = write(ur5e_data, "runarm.yaml")
    register_arm(path)
    assert arm_file_of("RunArmReacherGoalSim-v0") == str(path) == arm_file_of("RunArmPushReal-v0")
    run = start_run("RunArmReacherGoalSim-v0", TrainingConfig(training_steps=10), output=tmp_path, name="r")
    meta = json.loads(run.meta.read_text())
    assert meta["arm_file"] == str(path)
    run.release()

    unregister_arm("RunArm")
    with pytest.raises(TrainingError, match=r"unknown env 'RunArmReacherGoalSim-v0'.*UNIROS_ARMS=FILE"):
        check_env_id("RunArmReacherGoalSim-v0")
    notes: list[str] = []
    register_run_arm(meta, "run.json", notes.append)
    assert "RunArmReacherGoalSim-v0" in gym.registry and notes == [f"registered the arm file {path} this run "
                                                                   "was trained with (run.json)"]
    unregister_arm("RunArm")
    reopened, env_id, _ = open_run(tmp_path / "r")  # --resume: the same, before the env is made
    reopened.release()
    assert env_id == "RunArmReacherGoalSim-v0" and env_id in gym.registry
    unregister_arm("RunArm")
    from uniros.eval_target import eval_target

    (tmp_path / "r" / "best_model.zip").write_bytes(b"")
    # `uniros eval RUN`: a run folder may come from anyone, and an arm file's xacro may run code: the ID is typed
    with pytest.raises(TrainingError, match=r"comes from the arm file .*runarm.yaml \(its xacro may run code\): "
                                            r"evaluate it by typing the ID yourself, `uniros eval RunArmReacherGoal"):
        eval_target(str(tmp_path / "r"), None, None, notes.append)
    assert "RunArmReacherGoalSim-v0" not in gym.registry
    # `uniros eval ID RUN` and `uniros eval REAL_ID RUN`: typed, the run's arm file registers
    for first in ("RunArmReacherGoalSim-v0", "RunArmReacherGoalReal-v0"):
        target = eval_target(first, str(tmp_path / "r"), None, notes.append)
        assert target[0] == first
        unregister_arm("RunArm")

    # The file renamed its arm: nothing of it stays registered, and the error says so.
    renamed = dict(ur5e_data, name="RunArmRenamed")
    path.write_text(yaml.safe_dump(renamed, sort_keys=False))
    with pytest.raises(TrainingError, match=r"no longer registers RunArmReacherGoalSim-v0 \(it registers "
                                            r"RunArmRenamedReacherSim-v0"):
        register_run_arm(meta, "run.json")
    assert "RunArmRenamedReacherSim-v0" not in gym.registry and "RunArmRenamed" not in registered_arms()

    path.unlink()
    with pytest.raises(TrainingError, match=r"comes from the arm file .*runarm.yaml, which is gone: put it back"):
        register_run_arm(meta, "run.json")
    assert "RunArmReacherGoalSim-v0" not in gym.registry
    # A file gone does not matter to an ID that needs no arm file, and a typo is still "unknown env".
    run_dir = str(tmp_path / "r")
    assert eval_target("RX200ReacherGoalSim-v0", run_dir, None, notes.append)[0] == "RX200ReacherGoalSim-v0"
    with pytest.raises(TrainingError, match="unknown env 'TypoArmReacherGoalSim-v0'"):
        eval_target("TypoArmReacherGoalSim-v0", run_dir, None, notes.append)
    with pytest.raises(TrainingError, match="which is gone"):  # the run's own ID: the file is what is missing
        eval_target(None, run_dir, None, notes.append)


def test_a_world_the_node_refuses_is_one_training_error_naming_the_arm_file(ur5e_data, write):
    """uniros train / eval make their env through run_envs.make_env: a scene the simulation refuses to spawn
    (here a table raised into the robot's base) is one line naming the ID, the node's reason and the arm
    file, not a traceback."""
    from uniros.run_envs import make_env
    from uniros.train_config import TrainingError

    ur5e_data["name"], ur5e_data["robot_name"] = "RaisedTable", "raisedtable"
    ur5e_data["manipulation"]["table_center"] = [0.3, 0.0, 0.05]  # the table's top 25 cm above the base
    path = write(ur5e_data, "raised.yaml")
    register_arm(path)
    with pytest.raises(TrainingError) as err:
        make_env("RaisedTablePushGoalSim-v0")
    message = str(err.value)
    assert message.startswith("RaisedTablePushGoalSim-v0 cannot be made: /mujoco_sim/spawn_entity failed")
    assert f"`uniros arm check {path}`" in message and "\n" not in message
    # the same with n_envs: 2, whose second env is made in a worker process (its traceback stays there)
    from uniros.run_envs import make_train_env
    from uniros.train_config import TrainingConfig

    with pytest.raises(TrainingError) as err:
        make_train_env("RaisedTablePushGoalSim-v0", TrainingConfig(n_envs=2))
    message = str(err.value)
    assert message.startswith("RaisedTablePushGoalSim-v0 cannot be made: ") and "spawn_entity failed" in message
    assert f"`uniros arm check {path}`" in message and "\n" not in message and "Traceback" not in message


def test_a_relative_arm_file_of_a_run_is_found_beside_the_run_not_in_the_working_folder(ur5e_data, tmp_path,
                                                                                         monkeypatch):
    """A run moved with its arm file beside it (run.json: "arm_file": "arm/movedarm.yaml") registers it from the
    run's folder, wherever the command runs."""
    from gymnasium.envs.registration import registry

    from uniros.run_envs import register_run_arm

    ur5e_data["name"], ur5e_data["robot_name"] = "MovedArm", "movedarm"
    run = tmp_path / "runs" / "moved"
    (run / "arm").mkdir(parents=True)
    (run / "arm" / "movedarm.yaml").write_text(yaml.safe_dump(ur5e_data, sort_keys=False))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.setenv("UNIROS_ARMS", os.environ.get("UNIROS_ARMS", ""))
    meta = {"env_id": "MovedArmReacherGoalSim-v0", "arm_file": "arm/movedarm.yaml"}
    try:
        register_run_arm(meta, str(run / "run.json"))
        assert "MovedArmReacherGoalSim-v0" in registry
    finally:
        unregister_arm("MovedArm")


def test_dynamics_and_reset_tolerances_reach_the_arm_and_its_real_twin(ur5e_data, write):
    """``dynamics:`` (as ``uniros sysid`` writes it) is read per joint, a number standing for every joint;
    the reset tolerances of ``real:`` become the Real twin's arguments."""
    from rl_environments.arm import Arm

    ur5e_data["name"] = "DynArm"
    ur5e_data["dynamics"] = {"latency": 0.1, "time_constant": 0.25, "gain": [1.0, 0.98, 0.97, 1.0, 1.0, 1.0],
                             "offset": [0.0, -0.03, 0.03, 0.0, 0.0, 0.0], "fit_residual": 0.002, "source": "a bag"}
    ur5e_data["real"]["reset_settle_tolerance"] = 0.04
    arm_file = load_arm_file(write(ur5e_data))
    dyn = arm_file.dynamics
    assert dyn.latency == 0.1 and dyn.time_constant == (0.25,) * 6 and dyn.gain[2] == 0.97
    assert dyn.offset[1] == -0.03 and dyn.fit_residual == 0.002 and not dyn.nominal
    assert load_arm_file(SHIPPED / "ur5e.yaml").dynamics.nominal
    kwargs, _ = Arm(arm_file).real_kwargs({})
    assert kwargs["reset_settle_tolerance"] == 0.04 and kwargs["reset_tolerance"] == 0.02
    kwargs, _ = Arm(arm_file).real_kwargs({"reset_settle_tolerance": 0.0})
    assert kwargs["reset_settle_tolerance"] == 0.0, "the user's argument wins over the file's"
