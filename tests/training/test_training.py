"""Training support: YAML parsing and errors, the CLI, and a short HER run that shows learning."""

from __future__ import annotations

import copy
import os

import numpy as np
import pytest

import rl_environments
import uniros
from uniros.cli import main as cli_main
from uniros.training import (
    TrainingConfigError,
    default_config_for,
    evaluate,
    load_training_config,
    parse_training_config,
    train,
)


@pytest.mark.parametrize("env_id", rl_environments.ENV_IDS)
def test_every_simulated_id_ships_a_config_that_parses(env_id):
    config = default_config_for(env_id)
    assert config.algorithm == "sac" and config.training_steps >= 10_000
    assert config.use_her == (env_id in rl_environments.GOAL_ENV_IDS)
    # One update per env step at any n_envs (docs/training.md, "Several envs at once").
    assert config.algo_params["gradient_steps"] == -1 and config.algo_params["train_freq"] == (1, "step")
    assert (config.demonstrations > 0) == (env_id in rl_environments.MANIPULATION_ENV_IDS)
    assert config.eval_freq > 0 and config.save_freq > 0 and config.keep_replay_buffers == 1


def test_rl_zoo3_hyperparameters_cover_every_simulated_id():
    from importlib import resources

    import yaml

    folder = resources.files("rl_environments.config").joinpath("training", "rl_zoo3")
    for algo in ("sac", "tqc"):
        data = yaml.safe_load(folder.joinpath(f"{algo}.yml").read_text())
        assert set(data) == set(rl_environments.ENV_IDS), algo
        for env_id, params in data.items():
            dict_obs = env_id in rl_environments.GOAL_ENV_IDS or env_id in rl_environments.CAMERA_ENV_IDS
            assert params["policy"] == ("MultiInputPolicy" if dict_obs else "MlpPolicy"), env_id
            assert ("replay_buffer_class" in params) == (env_id in rl_environments.GOAL_ENV_IDS)


def test_frobs_style_yaml_parses(tmp_path):
    path = tmp_path / "td3.yaml"
    path.write_text(
        "model_params:\n"
        "  algorithm: td3\n  training_steps: 100000\n  save_freq: 5000\n"
        "  use_custom_policy: False\n  use_action_noise: True\n  action_noise: {mean: 0.0, sigma: 0.01}\n"
        "  td3_params:\n    learning_rate: 0.001\n    batch_size: 100\n    policy_delay: 2\n"
        "    train_freq:\n      freq: 20\n      unit: step\n"
    )
    config = load_training_config(path)
    assert config.algorithm == "td3" and config.training_steps == 100000
    assert config.action_noise == {"mean": 0.0, "sigma": 0.01}
    assert config.algo_params["train_freq"] == (20, "step")


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"algorithm": "sac"}, "missing key 'training_steps'"),
        ({"algorithm": "rainbow", "training_steps": 10}, "algorithm 'rainbow'"),
        ({"algorithm": "ppo", "training_steps": 10, "use_HER": True}, "off-policy"),
        ({"algorithm": "sac", "training_steps": "ten"}, "'training_steps' must be int"),
        ({"algorithm": "sac", "training_steps": 10, "sac_params": [1]}, "'sac_params' must be dict"),
        ({"algorithm": "sac", "training_steps": 10, "use_custom_policy": True}, "missing key 'policy_params'"),
        ({"training_steps": 10, "policy_params": {"net_arch": [8]}}, "policy_params is given without use_custom"),
        ({"training_steps": 10, "eval_frq": 5}, "unknown key 'eval_frq'; did you mean 'eval_freq'"),
        ({"training_steps": 10, "sac_params": {"learnig_rate": 1}}, "did you mean 'learning_rate'"),
        ({"training_steps": 10, "her_params": {"n_sampled_goals": 4}}, "did you mean 'n_sampled_goal'"),
        ({"model_params": {"training_steps": 10}, "extra": 1}, "unknown key 'extra'"),
        ({"algorithm": "sac", "training_steps": 10, "td3_params": {}}, "has td3_params but the algorithm is 'sac'"),
        ({"algorithm": "td3", "training_steps": 10, "use_sde": True}, "use_sde works with"),
        ({"training_steps": 10, "n_envs": 0}, "n_envs must be at least 1, got 0"),
        ({"training_steps": 10, "n_envs": -2}, "n_envs must be at least 1"),
        ({"training_steps": 10, "n_envs": "four"}, "'n_envs' must be int"),
        ({"training_steps": 10, "n_envs": True}, "'n_envs' must be int"),
        ({"training_steps": 10, "n_envs": 2.5}, "'n_envs' must be int"),
        ({"training_steps": 10, "pin_workers": "yes"}, "'pin_workers' must be bool"),
        ({"training_steps": 10, "pin_workers": None}, "pin_workers must be true or false, got None"),
        ({"training_steps": 10, "env_kwargs": {"pin_workers": True}}, "pin_workers is a key of the run, not of each"),
        ({"training_steps": 10, "n_envs": None}, "n_envs must be at least 1, got None"),
        ({"training_steps": None}, "training_steps must be at least 1, got None"),
        ({"training_steps": 10, "eval_freq": None}, "eval_freq must be 0 .off. or positive, got None"),
    ],
)
def test_bad_training_yaml_names_the_key(data, match):
    with pytest.raises(TrainingConfigError, match=match):
        parse_training_config(data, "cfg.yaml")


def test_policy_params_beside_use_custom_policy_false_are_named_unused(caplog):
    """MultiROS/FRobs_RL files keep policy_params with use_custom_policy: false: accepted, with a warning."""
    with caplog.at_level("WARNING", logger="uniros.train_config"):
        config = parse_training_config({"training_steps": 10, "use_custom_policy": False,
                                        "policy_params": {"net_arch": [8]}}, "cfg.yaml")
    assert config.policy_params is None
    assert "policy_params is not used" in caplog.text


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(TrainingConfigError, match="not found"):
        load_training_config(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("model_params: [unclosed")
    with pytest.raises(TrainingConfigError, match="not valid YAML"):
        load_training_config(bad)
    with pytest.raises(TrainingConfigError, match="no shipped training config"):
        default_config_for("CartPole-v1")


def test_frobs_yaml_without_algorithm_key_takes_it_from_the_block():
    config = parse_training_config({"model_params": {"training_steps": 5, "td3_params": {"policy_delay": 2}}})
    assert config.algorithm == "td3"
    with pytest.raises(TrainingConfigError, match="TD3 config .* given to SAC"):
        parse_training_config({"training_steps": 5, "td3_params": {}}, "td3.yaml", algorithm="sac")


def test_cli_list(capsys):
    assert cli_main(["list"]) == 0
    out = capsys.readouterr().out
    assert "RX200ReacherGoalSim-v0" in out and "ABBIRB120ReacherEnv-v0" in out
    assert "RX200ReacherGoalReal-v0" in out and "ABBIRB120ReacherGoalRealEnv-v0" in out


def test_cli_list_and_a_simulated_env_work_with_a_sourced_humble(tmp_path):
    """A sourced Humble (ROS_DISTRO=humble) is no reason to refuse simulated envs, which need no ROS;
    only a transport that reaches Humble peers is refused, when it is opened (tests/interfaces)."""
    import subprocess
    import sys

    env = {**os.environ, "ROS_DISTRO": "humble"}
    out = subprocess.run([sys.executable, "-m", "uniros.cli", "list"], env=env, capture_output=True, text=True,
                         timeout=120, stdin=subprocess.DEVNULL)
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
    assert "RX200ReacherGoalSim-v0" in out.stdout
    probe = ("import uniros; e = uniros.make('RX200ReacherGoalSim-v0'); e.reset(seed=0); "
             "print(e.step(e.action_space.sample())[1]); e.close()")
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=180,
                         stdin=subprocess.DEVNULL)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout.strip().splitlines()[-1]) in (-1.0, 0.0)  # the sparse reward of one step


def _error(capsys, *argv: str) -> str:
    assert cli_main(list(argv)) == 2
    err = capsys.readouterr().err
    error = [line for line in err.strip().splitlines() if not line.startswith("note: ")]
    assert "Traceback" not in err and len(error) <= 2, err
    return err


def test_common_mistakes_are_one_or_two_lines_with_exit_code_2(capsys, tmp_path):
    out = tmp_path / "runs"
    assert "unknown env 'RX200ReacherGoalSm-v0'; did you mean 'RX200ReacherGoalSim-v0'" in _error(
        capsys, "train", "RX200ReacherGoalSm-v0", "--output", str(out))
    assert "give the model to evaluate: uniros eval RX200ReacherGoalSim-v0 MODEL" in _error(
        capsys, "eval", "RX200ReacherGoalSim-v0")
    assert "unknown env 'NoSuchEnv-v0'" in _error(capsys, "eval", "NoSuchEnv-v0", str(tmp_path))
    assert "no shipped training config for 'CartPole-v1'" in _error(
        capsys, "train", "CartPole-v1", "--output", str(out))
    real = _error(capsys, "train", "RX200ReacherGoalReal-v0", "--output", str(out))
    assert "it drives a real robot. Train its simulated twin (RX200ReacherGoalSim-v0)" in real
    assert "uniros eval RX200ReacherGoalReal-v0 MODEL" in real
    cfg = tmp_path / "bogus.yaml"
    cfg.write_text("training_steps: 100\nvideo: false\nenv_kwargs: {bogus_knob: 1}\n")
    err = _error(capsys, "train", "RX200ReacherGoalSim-v0", "--config", str(cfg), "--output", str(out))
    assert "RX200ReacherGoalSim-v0 does not take the env kwarg 'bogus_knob'" in err
    assert not out.exists() or not list(out.iterdir())  # a refused run writes nothing


def test_a_real_env_without_a_robot_is_a_short_error(capsys, tmp_path):
    cfg = tmp_path / "real.yaml"
    cfg.write_text("training_steps: 100\nvideo: false\nuse_HER: true\nenv_kwargs: {startup_timeout: 1.0}\n")
    out = tmp_path / "runs"
    err = _error(capsys, "train", "RX200ReacherGoalReal-v0", "--config", str(cfg), "--output", str(out))
    assert "RobotConnectionError: no usable joint states from /rx200/joint_states" in err
    assert "uniros-fake-robot" in err
    from multiros.ros.transport.rclpy.loader import rclpy_available

    domain = os.environ["ROS_DOMAIN_ID"]
    if rclpy_available():  # the Real env's default transport: rclpy, on its middleware
        assert f"same ROS_DOMAIN_ID ({domain}) and ROS 2 middleware" in err and "Zenoh" not in err
    else:
        router = os.environ["UNIROS_ZENOH_ROUTER"]
        assert f"same ROS_DOMAIN_ID ({domain}) and Zenoh router {router} (UNIROS_ZENOH_ROUTER)" in err
    assert not out.exists() or not list(out.iterdir())


@pytest.mark.slow
def test_short_her_training_beats_a_random_policy():
    """HER + SAC on RX200ReacherGoalSim-v0 for a few thousand steps: the trained policy succeeds far
    more often than a random one, both evaluated on the same goals. The full-length learning-speed
    figures come from benchmarks/bench_training.py."""
    config = copy.deepcopy(default_config_for("RX200ReacherGoalSim-v0"))
    config.training_steps = 6000
    config.eval_freq = 1000
    config.eval_episodes = 10
    config.stop_at_success = 0.8
    result = train("RX200ReacherGoalSim-v0", config)

    class RandomPolicy:
        def __init__(self, space):
            self.space = space

        def predict(self, obs, deterministic=True):
            return self.space.sample(), None

    env = uniros.make("RX200ReacherGoalSim-v0", **config.env_kwargs)
    try:
        env.action_space.seed(0)
        trained = evaluate(result.model, env, 20, seed=123, normalizer=result.normalizer)["success_rate"]
        random = evaluate(RandomPolicy(env.action_space), env, 20, seed=123)["success_rate"]
    finally:
        env.close()
    assert random <= 0.2
    assert trained >= random + 0.5, f"trained {trained:.2f} vs random {random:.2f} after {result.total_steps} steps"
    assert np.isfinite(result.train_seconds)
