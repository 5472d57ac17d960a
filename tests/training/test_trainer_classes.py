"""The sb3_ros_support / FRobs_RL trainer classes, and a clean first contact (checkout imports, quiet
import, pickling, `uniros sim --help`)."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

import uniros
from uniros.sb3 import SAC_GOAL, TD3
from uniros.train_config import TrainingConfigError

ROOT = Path(__file__).resolve().parents[2]


def test_td3_as_the_seed_docs_use_it_then_continue_with_load_model(tmp_path):
    cfg = tmp_path / "config"
    cfg.mkdir()
    (cfg / "td3_aux.yaml").write_text(
        "model_params:\n  training_steps: 120\n  save_freq: 50\n  save_prefix: td3_model\n"
        "  trained_model_name: trained_model\n  save_replay_buffer: True\n  log_folder: TD3_New\n"
        "  use_action_noise: True\n  action_noise: {mean: 0.0, sigma: 0.01}\n"
        "  td3_params: {learning_starts: 50, batch_size: 16, buffer_size: 2000, train_freq: {freq: 20, unit: step}}\n"
    )
    env = uniros.make("RX200ReacherSim-v0")
    model = TD3(env, tmp_path / "models", tmp_path / "logs", abs_config_path=str(cfg / "td3_aux.yaml"), verbose=0)
    model.train()
    model.save_model()  # the name is taken by train()'s save: a date suffix
    model.close_env()
    saved = sorted(p.name for p in (tmp_path / "models").iterdir())
    assert "trained_model.zip" in saved and "trained_model_replay_buffer.pkl" in saved
    assert "td3_model_100_steps.zip" in saved and "td3_model_replay_buffer_100_steps.pkl" in saved
    assert any(n.startswith("trained_model_") and n.endswith(".zip") and n != "trained_model.zip" for n in saved)
    assert list((tmp_path / "logs" / "TD3_New").glob("events.out.tfevents.*"))
    # load_model + model_name continue the saved model, its replay buffer and its step count.
    text = (cfg / "td3_aux.yaml").read_text().replace("log_folder: TD3_New", "log_folder: TD3_New\n  load_model: True"
                                                      "\n  model_name: trained_model")
    (cfg / "td3_aux.yaml").write_text(text)
    env = uniros.make("RX200ReacherSim-v0")
    again = TD3(env, tmp_path / "models", tmp_path / "logs", abs_config_path=str(cfg / "td3_aux.yaml"), verbose=0)
    assert again.model.num_timesteps == 120 and again.model.replay_buffer.size() > 0
    assert again.log_dir.name == "TD3_New_2"  # logs are never overwritten
    again.train()
    assert again.model.num_timesteps == 240
    action, _ = again.predict(env.observation_space.sample(), deterministic=True)
    assert env.action_space.contains(action)
    again.close_env()
    loaded = TD3.load_trained(tmp_path / "models" / "trained_model")
    assert loaded.num_timesteps == 120


@pytest.mark.slow
def test_goal_class_default_config_and_wrong_algorithm(tmp_path):
    env = uniros.make("RX200ReacherGoalSim-v0")
    try:
        model = SAC_GOAL(env, tmp_path / "m", tmp_path / "l", verbose=0)  # sb3_ros_support's sac_goal.yaml
        assert type(model.model.replay_buffer).__name__ == "HerReplayBuffer"
        assert model.config.use_sde and model.config.training_steps == 5000
        td3_cfg = tmp_path / "td3.yaml"
        td3_cfg.write_text("training_steps: 10\ntd3_params: {policy_delay: 2}\n")
        with pytest.raises(TrainingConfigError, match="TD3 config .* given to SAC"):
            SAC_GOAL(env, tmp_path / "m", tmp_path / "l", abs_config_path=str(td3_cfg))
    finally:
        env.close()


def _run(code: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.multiprocess
def test_first_contact_from_the_checkout_root_is_clean():
    code = ("import uniros, rl_environments.config, uniros.templates\n"
            f"assert rl_environments.config.__file__.startswith({str(ROOT)!r}), rl_environments.config.__file__\n"
            "env = uniros.make('RX200ReacherGoalSim-v0'); env.reset(seed=0); env.close()\n"
            "h = uniros.make('RX200ReacherGoalSim-v0', render_mode='human'); h.reset()\n"
            "try:\n    h.render()\nexcept Exception as exc:\n    print('ERR', exc)\nh.close()\n")
    done = _run(code, ROOT)
    assert done.returncode == 0, done.stderr
    assert "AdroitHand" not in done.stderr and "AdroitHand" not in done.stdout
    err = done.stdout.split("ERR", 1)[1]
    assert "needs a display" in err and "gui" not in err


def test_envs_pickle_and_deepcopy():
    import copy

    import numpy as np

    env = uniros.make("RX200ReacherGoalSim-v0", seed=3)
    clones = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    try:
        obs, _ = env.reset(seed=1)
        for clone in clones:
            again, _ = clone.reset(seed=1)
            assert all(np.allclose(obs[k], again[k]) for k in obs)
            assert clone.unwrapped.task.host is clone.unwrapped  # the copy's task is the copy's own
            clone.step(clone.action_space.sample())
            task = clone.unwrapped.task
            task.goal = clone.unwrapped.ee_position()  # at the goal: the step says so, in a fresh info
            *_, terminated, _, info = clone.step(np.zeros(clone.action_space.shape, np.float32))
            assert terminated and info["is_success"] is True
    finally:
        for e in [env, *clones]:
            e.close()


def test_uniros_sim_help_is_uniros_sims(capsys):
    from uniros.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["sim", "--help"])
    assert exc.value.code == 0
    assert "--robot" in capsys.readouterr().out


def test_an_unknown_config_file_pkg_names_where_packages_are_found() -> None:
    from uniros.sb3.core import resolve_config_path

    with pytest.raises(TrainingConfigError, match=r"config_file_pkg: package 'no_such_cfg_pkg' not found.*"
                                                  r"AMENT_PREFIX_PATH.*ROS_PACKAGE_PATH.*abs_config_path"):
        resolve_config_path("td3", False, "no_such_cfg_pkg", "td3.yaml", None)
