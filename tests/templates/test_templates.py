"""``uniros new`` / ``create_from_templates``: generated packages, blanks, and (once the simulation
stack runs) the filled-in RX200 versions under gymnasium's and SB3's ``check_env``."""

from __future__ import annotations

import ast
import importlib
import re
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from uniros.templates_cli import TemplateTargetExistsError, create_from_templates, snake_case, template_dir

TEMPLATES = ["MyRobotEnv", "MyRobotGoalEnv", "MyTaskEnv", "MyTaskGoalEnv", "CustomRobotEnv", "CustomTaskEnv"]


def fill_blanks(path: Path, blanks: dict[str, str]) -> None:
    """Replace each ``# BLANK(name)`` ... ``# END BLANK`` block with ``blanks[name]`` (indented alike)."""
    text = path.read_text()
    for name, code in blanks.items():
        pattern = re.compile(rf"^([ \t]*)# BLANK\({name}\).*?^[ \t]*# END BLANK[^\n]*\n", re.S | re.M)
        match = pattern.search(text)
        assert match, f"{path.name} has no BLANK({name})"
        indent = match.group(1)
        body = textwrap.indent(textwrap.dedent(code).strip() + "\n", indent)
        text = text[: match.start()] + body + text[match.end():]
    path.write_text(text)


def import_package(directory: Path, package: str):
    sys.path.insert(0, str(directory))
    try:
        for mod in [m for m in sys.modules if m == package or m.startswith(package + ".")]:
            del sys.modules[mod]
        return importlib.import_module(package)
    finally:
        sys.path.remove(str(directory))


# -- the templates themselves ------------------------------------------------------------------------
@pytest.mark.parametrize("name", TEMPLATES)
def test_template_parses_and_blanks_are_balanced(name):
    text = (template_dir() / f"{name}.py").read_text()
    ast.parse(text)
    opened = re.findall(r"^[ \t]*# BLANK\((\w+)\)", text, re.M)
    assert opened, f"{name} marks no blanks"
    assert len(opened) == len(set(opened))
    assert len(re.findall(r"^[ \t]*# END BLANK", text, re.M)) == len(opened)


def test_templates_package_imports_no_template():
    import importlib.util

    import gymnasium

    spec = importlib.util.spec_from_file_location("_templates_probe", template_dir() / "__init__.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert "MyTaskEnv-v0" not in gymnasium.registry
    assert "uniros new" in module.__doc__


def test_snake_case():
    assert snake_case("MyArm") == "my_arm"
    assert snake_case("RX200") == "rx200"
    assert snake_case("Ur5e") == "ur5e"


# -- create_from_templates -------------------------------------------------------------------------------
@pytest.mark.parametrize(("goal", "style", "robot_cls", "task_cls"), [
    (False, "multiros", "MyArmRobotEnv", "MyArmTaskEnv"),
    (True, "multiros", "MyArmRobotGoalEnv", "MyArmTaskGoalEnv"),
    (False, "frobs", "MyArmRobotEnv", "MyArmTaskEnv"),
])
def test_creates_named_package_that_registers_its_id(tmp_path, goal, style, robot_cls, task_cls):
    import gymnasium

    created = create_from_templates("MyArm", tmp_path, goal=goal, style=style)
    root = tmp_path / "my_arm"
    assert created == [root / "__init__.py", root / "my_arm_robot_env.py", root / "my_arm_task_env.py"]
    robot_text, task_text = created[1].read_text(), created[2].read_text()
    assert f"class {robot_cls}(" in robot_text
    assert f"class {task_cls}({robot_cls})" in task_text
    assert "from .my_arm_robot_env import" in task_text
    for leftover in ("MyRobot", "MyTask", "CustomRobot", "CustomTask", '"my_robot"'):
        assert leftover not in robot_text + task_text
    pkg = import_package(tmp_path, "my_arm")
    env_id = pkg.ENV_ID
    assert env_id == f"{task_cls}-v0"
    spec = gymnasium.spec(pkg.ENV_ID)
    assert spec.entry_point == f"my_arm.my_arm_task_env:{task_cls}"
    del gymnasium.registry[pkg.ENV_ID]


def test_unfilled_robot_blank_fails_clearly_before_starting_anything(tmp_path):
    create_from_templates("Blank", tmp_path)
    pkg = import_package(tmp_path, "blank")
    with pytest.raises(NotImplementedError, match="fill in the BLANK\\(robot\\) block"):
        pkg.BlankTaskEnv()
    import gymnasium

    del gymnasium.registry[pkg.ENV_ID]


def test_refuses_to_overwrite_and_writes_nothing(tmp_path):
    root = tmp_path / "my_arm"
    root.mkdir()
    (root / "my_arm_task_env.py").write_text("# mine\n")
    with pytest.raises(TemplateTargetExistsError, match="refusing to overwrite.*my_arm_task_env.py"):
        create_from_templates("MyArm", tmp_path)
    assert sorted(p.name for p in root.iterdir()) == ["my_arm_task_env.py"]
    assert (root / "my_arm_task_env.py").read_text() == "# mine\n"
    with pytest.raises(FileExistsError):  # also a FileExistsError (and a ValueError for the CLI)
        create_from_templates("MyArm", tmp_path)


@pytest.mark.parametrize("bad", ["myArm", "My-Arm", "My Arm", "", "1Arm"])
def test_bad_names_refused(tmp_path, bad):
    with pytest.raises(ValueError, match="CamelCase"):
        create_from_templates(bad, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_frobs_goal_and_unknown_style_refused(tmp_path):
    with pytest.raises(ValueError, match="no goal-conditioned"):
        create_from_templates("MyArm", tmp_path, goal=True, style="frobs")
    with pytest.raises(ValueError, match="template style 'gazebo'"):
        create_from_templates("MyArm", tmp_path, style="gazebo")


def test_cli_new(tmp_path, capsys):
    from uniros.cli import main

    assert main(["new", "CliArm", "--directory", str(tmp_path), "--goal"]) == 0
    assert "cli_arm_task_env.py" in capsys.readouterr().out
    assert main(["new", "CliArm", "--directory", str(tmp_path), "--goal"]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err


# -- filled-in RX200 versions, run on the simulation node ------------------------------------------------
ARM = '["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]'
MULTIROS_ROBOT = {"robot": f"""
    robot_model_xml = "package://rx200_description/urdf/rx200.urdf.xacro"
    urdf_xacro_args = {{"robot_name": "my_arm"}}
    controllers_list = ["joint_state_broadcaster", "arm_position_controller"]
    self.arm_joints = {ARM}
    self.arm_controller = "arm_position_controller"
    self.ee_frame = "my_arm/ee_gripper_link"
    self.home_position = [0.0, -0.3, 0.3, 0.0, 0.0]
"""}
GOAL_BOX = """
    self.goal_low, self.goal_high = np.array([0.15, -0.2, 0.1]), np.array([0.35, 0.2, 0.35])
    self.goal = (self.goal_low + self.goal_high) / 2
    self.tolerance = 0.02
"""
MULTIROS_TASK = {
    "spaces": textwrap.dedent("""
        n = len(self.arm_joints)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        high = np.concatenate([np.full(n, np.pi), np.ones(6)]).astype(np.float32)
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
    """) + textwrap.dedent(GOAL_BOX),
    "init_pose": "self.goal = self.np_random.uniform(self.goal_low, self.goal_high)",
    "set_action": "self.set_joint_targets(np.clip(self.get_joint_positions() + 0.05 * action, -1.5, 1.5))",
    "get_obs": "return np.concatenate([self.get_joint_positions(), self.get_ee_position(), self.goal])"
               ".astype(np.float32)",
    "get_reward": """
        distance = float(np.linalg.norm(self.get_ee_position() - self.goal))
        self.info["is_success"] = distance < self.tolerance
        return -distance
    """,
    "check_if_done": 'return bool(self.info.get("is_success", False))',
}
MULTIROS_GOAL_TASK = {
    "spaces": textwrap.dedent("""
        n = len(self.arm_joints)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        goal = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(-np.pi, np.pi, shape=(n,), dtype=np.float32),
            "achieved_goal": goal, "desired_goal": goal})
    """) + textwrap.dedent(GOAL_BOX),
    "init_pose": "self.goal = self.np_random.uniform(self.goal_low, self.goal_high)",
    "set_action": "self.set_joint_targets(np.clip(self.get_joint_positions() + 0.05 * action, -1.5, 1.5))",
    "get_obs": """
        return {"observation": self.get_joint_positions().astype(np.float32),
                "achieved_goal": self.get_ee_position().astype(np.float32),
                "desired_goal": self.goal.astype(np.float32)}
    """,
}
FROBS_ROBOT = {"robot": f"""
    pkg_name = "rx200_description"
    urdf_file = "rx200.urdf.xacro"
    urdf_xacro_args = ["robot_name:=my_arm"]
    controller_list = ["joint_state_broadcaster", "arm_position_controller"]
    self.joint_names_arm = {ARM}
    self.arm_controller = "arm_position_controller"
    self.ee_frame = "my_arm/ee_gripper_link"
"""}
FROBS_TASK = {
    "spaces": textwrap.dedent("""
        self.action_space = spaces.Box(-1.0, 1.0, shape=(5,), dtype=np.float32)
        high = np.concatenate([np.full(5, np.pi), np.ones(6)]).astype(np.float32)
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
    """) + textwrap.dedent(GOAL_BOX),
    "init_params": """
        self.move_to_initial_pose(self.joint_names_arm, [0.0, -0.3, 0.3, 0.0, 0.0])
        self.goal = self.np_random.uniform(self.goal_low, self.goal_high)
    """,
    "send_action": "self.set_joint_targets(np.clip(self.get_joint_angles() + 0.05 * action, -1.5, 1.5))",
    "get_observation": "return np.concatenate([self.get_joint_angles(), self.get_ee_pos(), self.goal])"
                       ".astype(np.float32)",
    "get_reward": "return -float(np.linalg.norm(self.get_ee_pos() - self.goal))",
    "check_if_done": """
        done = bool(np.linalg.norm(self.get_ee_pos() - self.goal) < self.tolerance)
        if done:
            self.info["is_success"] = 1.0
        return done
    """,
}
CASES = {
    "multiros": (False, "multiros", MULTIROS_ROBOT, MULTIROS_TASK),
    "multiros_goal": (True, "multiros", MULTIROS_ROBOT, MULTIROS_GOAL_TASK),
    "frobs": (False, "frobs", FROBS_ROBOT, FROBS_TASK),
}


def make_filled(tmp_path: Path, case: str, name: str = "MyArm"):
    goal, style, robot_blanks, task_blanks = CASES[case]
    _, robot_file, task_file = create_from_templates(name, tmp_path, goal=goal, style=style)
    fill_blanks(robot_file, robot_blanks)
    fill_blanks(task_file, task_blanks)
    pkg = import_package(tmp_path, snake_case(name))
    return pkg, getattr(pkg, [n for n in pkg.__all__ if n != "ENV_ID"][0])


def test_filled_templates_still_parse(tmp_path):
    for i, case in enumerate(CASES):
        pkg, cls = make_filled(tmp_path / str(i), case)
        assert cls.__name__.startswith("MyArm")
        import gymnasium

        del gymnasium.registry[pkg.ENV_ID]


def _stack_ready() -> bool:
    """The filled templates need a composed node that spawns the RX200 with its arm controller."""
    try:
        from multiros.sim.launch import connect, robot_resource

        conn = connect("composed")
        try:
            uri, text = robot_resource(robot_model_xml="package://rx200_description/urdf/rx200.urdf.xacro",
                                       xacro_args={"robot_name": "probe"},
                                       controllers_list=["joint_state_broadcaster", "arm_position_controller"])
            conn.client.spawn_entity("probe", uri=uri, resource_string=text, namespace="/probe", timeout_sec=60)
        finally:
            conn.close()
    except Exception:
        return False
    return True


needs_stack = pytest.mark.skipif(not _stack_ready(), reason="simulation stack cannot spawn the RX200 yet")


@needs_stack
@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_filled_template_passes_check_env_composed(tmp_path, case):
    import gymnasium
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    pkg, cls = make_filled(tmp_path, case)
    env = cls()
    try:
        check_env(env, skip_render_check=True)
        sb3_check_env(env, warn=True)
        obs, info = env.reset(seed=3)
        for _ in range(10):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs)
            assert "is_success" in info
            assert np.isfinite(reward)
    finally:
        env.close()
        del gymnasium.registry[pkg.ENV_ID]


@needs_stack
@pytest.mark.slow
def test_filled_goal_template_is_deterministic_and_vectorised(tmp_path):
    import gymnasium

    pkg, cls = make_filled(tmp_path, "multiros_goal")
    env = cls()
    try:
        runs = []
        for _ in range(2):
            obs, _ = env.reset(seed=11)
            trace = [obs["desired_goal"]]
            rng = np.random.default_rng(0)
            for _ in range(5):
                obs, *_ = env.step(rng.uniform(-1, 1, 5).astype(np.float32))
                trace.append(obs["achieved_goal"])
            runs.append(np.array(trace))
        np.testing.assert_array_equal(runs[0], runs[1])
        ag = np.random.default_rng(1).uniform(-0.3, 0.3, (64, 3))
        dg = np.random.default_rng(2).uniform(-0.3, 0.3, (64, 3))
        batch = env.compute_reward(ag, dg, [{}] * 64)
        single = np.array([env.compute_reward(a, d, {}) for a, d in zip(ag, dg)])
        np.testing.assert_allclose(batch, single)
    finally:
        env.close()
        del gymnasium.registry[pkg.ENV_ID]


@needs_stack
@pytest.mark.slow
@pytest.mark.multiprocess
def test_filled_template_passes_check_env_cross_process(tmp_path):
    import gymnasium
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    pkg, cls = make_filled(tmp_path, "multiros_goal")
    env = cls(sim_mode="process", timeout_sec=60.0)
    try:
        assert env.sim_connection.pid is not None
        check_env(env, skip_render_check=True)
        sb3_check_env(env, warn=True)
    finally:
        env.close()
        del gymnasium.registry[pkg.ENV_ID]


@needs_stack
@pytest.mark.slow
def test_wrapped_filled_template_frobs_training_stack(tmp_path):
    """FRobs_RL's example stack: NormalizeAction -> NormalizeObserv -> TimeLimit(max_steps)."""
    import gymnasium

    from multiros.wrappers import NormalizeActionWrapper, NormalizeObservWrapper, TimeLimitWrapper

    pkg, cls = make_filled(tmp_path, "frobs")
    env = TimeLimitWrapper(NormalizeObservWrapper(NormalizeActionWrapper(cls())), max_steps=5)
    try:
        env.reset(seed=0)
        for _ in range(5):
            *_, terminated, truncated, info = env.step(env.action_space.sample())
            if terminated:
                break
        assert truncated or terminated
        assert "is_success" in info
    finally:
        env.close()
        del gymnasium.registry[pkg.ENV_ID]


@needs_stack
@pytest.mark.slow
def test_her_learns_through_goal_normalising_wrapper(tmp_path):
    """SB3 HER relabels through the wrapper's compute_reward (env_method), goals normalised."""
    import gymnasium
    from stable_baselines3 import SAC, HerReplayBuffer

    from multiros.wrappers import NormalizeObservWrapper, TimeLimitWrapper

    pkg, cls = make_filled(tmp_path, "multiros_goal")
    env = TimeLimitWrapper(NormalizeObservWrapper(cls(), normalize_goal_spaces=True), max_steps=10)
    try:
        model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer, learning_starts=40,
                    batch_size=32, buffer_size=1000, seed=0, policy_kwargs={"net_arch": [16]})
        model.learn(total_timesteps=60)
        obs, _ = env.reset(seed=0)
        action, _ = model.predict(obs, deterministic=True)
        assert env.action_space.contains(action)
    finally:
        env.close()
        del gymnasium.registry[pkg.ENV_ID]


@needs_stack
@pytest.mark.slow
@pytest.mark.parametrize("case", ["multiros_goal", "frobs"])
def test_filled_template_steps_in_a_batched_vector_env(tmp_path, case):
    """A user's env written with MultiROS (or FRobs_RL) hooks steps in ``make_vec``'s batched vector
    env through its own hooks, env by env, one request per node: the same numbers as separate envs."""
    import gymnasium
    from gymnasium.vector import SyncVectorEnv

    import uniros

    pkg, _ = make_filled(tmp_path, case)
    n = 2
    batched = uniros.make_vec(pkg.ENV_ID, n, vectorization_mode="batched", max_episode_steps=6)
    separate = SyncVectorEnv([lambda: gymnasium.make(pkg.ENV_ID, max_episode_steps=6) for _ in range(n)])
    try:
        assert batched.batch.task is None  # no batch-first task: each env's hooks
        obs_b, _ = batched.reset(seed=5)
        obs_s, _ = separate.reset(seed=5)
        rng = np.random.default_rng(1)
        for _ in range(14):  # crosses two autoresets
            for a, b in ((obs_b, obs_s),):
                if isinstance(a, dict):
                    for key in a:
                        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
                else:
                    np.testing.assert_array_equal(a, b)
            actions = rng.uniform(-1, 1, (n, *batched.single_action_space.shape)).astype(np.float32)
            obs_b, rew_b, term_b, trunc_b, _ = batched.step(actions)
            obs_s, rew_s, term_s, trunc_s, _ = separate.step(actions)
            np.testing.assert_array_equal(rew_b, rew_s)
            np.testing.assert_array_equal(term_b | trunc_b, term_s | trunc_s)
    finally:
        batched.close()
        separate.close()
        del gymnasium.registry[pkg.ENV_ID]


def _green_pixels(image: np.ndarray) -> int:
    image = np.asarray(image, dtype=int)
    return int(((image[..., 1] - np.maximum(image[..., 0], image[..., 2])) > 60).sum())


@needs_stack
@pytest.mark.parametrize("case", ["multiros", "multiros_goal", "frobs"])
def test_filled_templates_draw_the_goal_marker(tmp_path, case):
    """The task templates draw their goal (``show_goal`` of the robot templates) once the goal blank
    is filled: rendered images show the green sphere where the goal is."""
    import gymnasium

    pkg, cls = make_filled(tmp_path, case)
    env = cls(render_mode="rgb_array")
    try:
        env.reset(seed=0)
        assert env.unwrapped._goal_marker is not None
        shown = _green_pixels(env.render())
        env.unwrapped.show_goal([5.0, 5.0, -5.0])  # out of the camera's view: the green goes with it
        assert shown > 20 and _green_pixels(env.render()) == 0
    finally:
        env.close()
        del gymnasium.registry[pkg.ENV_ID]


@needs_stack
def test_a_shipped_rx200_config_on_a_template_env_is_a_short_error(tmp_path, capsys):
    """The shipped RX200 config sets ee_action_type, which a template env does not take: one line,
    exit code 2, no run directory."""
    import gymnasium

    from uniros.cli import main

    pkg, _ = make_filled(tmp_path, "multiros_goal")
    from importlib import resources

    shipped = resources.files("rl_environments.config").joinpath("training", "tasks", "ReacherGoal.yaml")
    try:
        code = main(["train", pkg.ENV_ID, "--config", str(shipped), "--output", str(tmp_path / "runs")])
        err = capsys.readouterr().err
        assert code == 2 and f"{pkg.ENV_ID} does not take the env kwarg 'ee_action_type'" in err
        assert "Traceback" not in err and len(err.strip().splitlines()) <= 2
        assert not (tmp_path / "runs").exists() or not list((tmp_path / "runs").iterdir())
    finally:
        del gymnasium.registry[pkg.ENV_ID]
