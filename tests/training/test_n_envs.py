"""`n_envs`: `uniros train` on a batched vector env (N robots in one simulation node), its schedule in
env steps, HER's learning_starts, the monitor file across a resume, and what is refused."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import yaml

import uniros
from uniros.cli import main as cli_main
from uniros.run_envs import check_n_envs, fit_learning_starts, make_train_env
from uniros.train_config import TrainingConfig, TrainingConfigError, parse_training_config
from uniros.training import start_run

TINY = (
    "algorithm: sac\ntraining_steps: 800\neval_freq: 200\neval_episodes: 2\nsave_freq: 100\nnormalize: true\n"
    "use_HER: true\nkeep_checkpoints: 0\nsac_params: {learning_starts: 100, batch_size: 32, buffer_size: 50000}\n"
    "env_kwargs: {ee_action_type: true, max_episode_steps: 50}\n"
)


def _monitor_rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    lines = path.read_text().splitlines()
    comments = [line for line in lines if line.startswith("#")]
    rows = list(csv.DictReader(line for line in lines if not line.startswith("#")))
    return comments, rows


def test_n_envs_round_trips_through_the_resolved_config():
    config = parse_training_config({"training_steps": 10, "n_envs": 6}, "cfg.yaml")
    assert config.n_envs == 6
    assert parse_training_config(config.to_dict(), "again.yaml").n_envs == 6
    assert parse_training_config({"training_steps": 10}, "cfg.yaml").n_envs == 1


@pytest.mark.multiprocess
def test_pin_workers_reaches_the_vector_env_from_the_yaml_and_the_command_line(tmp_path):
    """``pin_workers`` (YAML key, ``--pin-workers``): the train env's workers pinned, the resolved config
    keeps it, off by default; with one env nothing to pin."""
    import os

    config = parse_training_config({"training_steps": 10, "n_envs": 2, "pin_workers": True}, "cfg.yaml")
    assert config.pin_workers and parse_training_config(config.to_dict(), "again.yaml").pin_workers
    assert not parse_training_config({"training_steps": 10}, "cfg.yaml").pin_workers
    cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if len(cores) >= 2:
        venv = make_train_env("RX200ReacherGoalSim-v0", config)
        try:
            assert venv.venv.worker_cores == [cores[1]]
            assert os.sched_getaffinity(venv.venv.pids[0]) == {cores[1]}
        finally:
            venv.close()
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(TINY.replace("training_steps: 800", "training_steps: 20").replace("eval_freq: 200", "eval_freq: 0"))
    assert cli_main(["train", "RX200ReacherGoalSim-v0", "--config", str(cfg), "--n-envs", "2", "--pin-workers",
                     "--eval-episodes", "0", "--no-video", "--no-progress", "--output", str(tmp_path / "runs"),
                     "--name", "pinned"]) == 0
    assert yaml.safe_load((tmp_path / "runs" / "pinned" / "config.yaml").read_text())["model_params"]["pin_workers"]


def test_learning_starts_waits_for_an_ended_episode_of_n_envs():
    her = parse_training_config({"training_steps": 10, "use_HER": True, "n_envs": 8,
                                 "sac_params": {"learning_starts": 500}}, "cfg.yaml")
    changed = fit_learning_starts("RX200ReacherGoalSim-v0", her)  # registered with 100-step episodes
    assert her.algo_params["learning_starts"] == 800
    assert changed is not None and "500 -> 800" in changed
    assert fit_learning_starts("RX200ReacherGoalSim-v0", her) is None  # already enough: untouched

    short = parse_training_config({"training_steps": 10, "use_HER": True, "n_envs": 4,
                                   "env_kwargs": {"max_episode_steps": 30}}, "cfg.yaml")
    fit_learning_starts("RX200ReacherGoalSim-v0", short)
    assert short.algo_params["learning_starts"] == 120  # SB3's default 100 < 4 x 30

    for untouched in (TrainingConfig(use_her=True, n_envs=1, algo_params={"learning_starts": 10}),
                      TrainingConfig(use_her=False, n_envs=8, algo_params={"learning_starts": 10})):
        assert fit_learning_starts("RX200ReacherGoalSim-v0", untouched) is None
        assert untouched.algo_params == {"learning_starts": 10}


def test_what_cannot_be_batched_is_refused_before_anything_is_built(capsys, tmp_path):
    with pytest.raises(TrainingConfigError, match="cfg.yaml: n_envs: 2 trains 2 envs .* drives a real robot"):
        make_train_env("RX200ReacherGoalReal-v0", TrainingConfig(n_envs=2, source="cfg.yaml"))
    with pytest.raises(TrainingConfigError, match="--n-envs 3 trains 3 envs of Pendulum-v1 .* not a uniros simulated"):
        check_n_envs("Pendulum-v1", TrainingConfig(n_envs=3), "--n-envs 3")
    episodic = parse_training_config({"training_steps": 10, "n_envs": 2, "sac_params": {
        "train_freq": {"freq": 1, "unit": "episode"}}}, "ep.yaml")
    with pytest.raises(TrainingConfigError, match="ep.yaml: n_envs: 2: train_freq counts episodes"):
        check_n_envs("RX200ReacherGoalSim-v0", episodic)
    check_n_envs("Pendulum-v1", TrainingConfig(n_envs=1))  # one env: anything goes
    # The batched vector env itself refuses another library's env before it starts a node.
    import uniros

    with pytest.raises(TypeError, match="needs uniros envs on the simulation node; Pendulum-v1 is PendulumEnv"):
        uniros.make_vec("Pendulum-v1", 2, vectorization_mode="batched")
    # From the command line: refused before a run directory is written.
    cfg = tmp_path / "real.yaml"
    cfg.write_text("training_steps: 10\n")
    assert cli_main(["train", "RX200ReacherGoalReal-v0", "--config", str(cfg), "--n-envs", "2",
                     "--output", str(tmp_path / "runs")]) == 2
    assert "--n-envs 2 trains 2 envs of RX200ReacherGoalReal-v0" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_start_run_writes_what_the_run_trains_with(tmp_path):
    config = parse_training_config({"training_steps": 10, "use_HER": True, "n_envs": 4,
                                    "sac_params": {"learning_starts": 100}}, "cfg.yaml")
    run = start_run("RX200ReacherGoalSim-v0", config, output=tmp_path, name="r")
    saved = yaml.safe_load(run.config.read_text())["model_params"]
    assert saved["n_envs"] == 4 and saved["sac_params"]["learning_starts"] == 400
    with pytest.raises(TrainingConfigError, match="drives a real robot"):
        start_run("RX200ReacherGoalReal-v0", TrainingConfig(n_envs=2), output=tmp_path, name="r2")
    assert not (tmp_path / "r2").exists()


@pytest.mark.slow
def test_train_resume_on_a_batched_vector_env(tmp_path, capsys):
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(TINY)
    run = tmp_path / "runs" / "r4"
    args = ["train", "RX200ReacherGoalSim-v0", "--config", str(cfg), "--n-envs", "4", "--output",
            str(tmp_path / "runs"), "--name", "r4", "--eval-episodes", "2", "--no-video", "--no-progress"]
    assert cli_main(args) == 0
    out = capsys.readouterr()
    assert "x 4 envs" in out.out
    assert "note: learning_starts 100 -> 200" in out.err  # 4 envs x 50-step episodes
    assert "note: gradient_steps 1 with 4 envs makes 1 update(s) per 4 env steps" in out.err

    saved = yaml.safe_load((run / "config.yaml").read_text())["model_params"]
    assert saved["n_envs"] == 4 and saved["sac_params"]["learning_starts"] == 200
    meta = json.loads((run / "run.json").read_text())
    assert meta["status"] == "finished" and meta["steps"] == 800

    from uniros.reports import read_evaluations

    rows = read_evaluations(run / "evaluations.csv")
    # eval_freq and save_freq are env steps: 4 envs evaluate every 50 vector steps.
    assert [r["steps"] for r in rows] == [200, 400, 600, 800]
    # Every column is filled: the spread of the evaluation's returns and its episodes' mean length too.
    assert all(r["std_return"] >= 0 and 1 <= r["mean_length"] <= 50 for r in rows)
    # An evaluation's own time is not training time: the row at the last step is not past the total.
    assert rows[-1]["train_seconds"] <= meta["train_seconds"]
    latest = json.loads((run / "checkpoints" / "latest.json").read_text())
    assert latest["steps"] == 800
    # save_freq counts env steps too: a checkpoint every 25 vector steps of 4 envs.
    saved_steps = sorted(int(p.name.split("_")[1]) for p in (run / "checkpoints").glob("model_*_steps.zip"))
    assert saved_steps == list(range(100, 801, 100))

    comments, episodes = _monitor_rows(run / "monitor" / "train.monitor.csv")
    assert len(comments) == 1 and len(episodes) >= 800 // 50  # 200 steps of each env, episodes of <= 50
    assert {row["is_success"] for row in episodes} <= {"True", "False"}
    assert all(1 <= int(row["l"]) <= 50 for row in episodes)

    # A resumed run keeps its n_envs (its replay buffer holds 4 envs' transitions) ...
    assert cli_main(["train", "--resume", str(run), "--n-envs", "2"]) == 2
    assert "a resumed run keeps it" in capsys.readouterr().err
    # ... and carries on, appending to the monitor file.
    assert cli_main(["train", "--resume", str(run), "--steps", "1200", "--eval-episodes", "0", "--no-video",
                     "--no-progress"]) == 0
    assert json.loads((run / "run.json").read_text())["steps"] == 1200
    assert [r["steps"] for r in read_evaluations(run / "evaluations.csv")] == [200, 400, 600, 800, 1000, 1200]
    comments_after, episodes_after = _monitor_rows(run / "monitor" / "train.monitor.csv")
    assert len(comments_after) == 1 and episodes_after[:len(episodes)] == episodes
    assert len(episodes_after) > len(episodes)


@pytest.mark.slow
def test_gradient_steps_minus_one_keeps_one_update_per_env_step(tmp_path):
    """The shipped configs' gradient_steps: -1 (SB3: as many gradient steps as env steps collected)
    makes as many updates per env step with 4 envs as with one; a positive value gets a note."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    from uniros.trainer import Session
    from uniros.training import note_updates_per_env_step

    updates = {}
    for n in (1, 4):
        config = parse_training_config({"training_steps": 200, "n_envs": n, "eval_freq": 0, "save_freq": 0,
                                        "progress_bar": False, "sac_params": {
                                            "learning_starts": 40, "batch_size": 8, "gradient_steps": -1},
                                        "use_custom_policy": True, "policy_params": {"net_arch": [8]}}, "cfg.yaml")
        assert note_updates_per_env_step(config) is None
        env = gym.make("Pendulum-v1") if n == 1 else DummyVecEnv([lambda: gym.make("Pendulum-v1")] * n)
        session = Session(config, env, success_info=False)
        try:
            session.build()
            session.learn()
            updates[n] = session.model._n_updates
        finally:
            session.close()
    assert updates[1] == 200 - 40 and abs(updates[4] - updates[1]) <= 4
    positive = parse_training_config({"training_steps": 10, "n_envs": 8, "sac_params": {"gradient_steps": 2}})
    assert "2 update(s) per 8 env steps (0.25 per env step" in note_updates_per_env_step(positive)


def test_trainer_classes_train_the_env_they_are_given(tmp_path):
    from uniros.sb3 import SAC_GOAL
    from uniros.vec_env import make_batched_vec_env

    cfg = tmp_path / "sac.yaml"
    cfg.write_text("training_steps: 120\nsave_freq: 0\nuse_HER: true\nn_envs: 3\n"
                   "sac_params: {learning_starts: 20, batch_size: 16, buffer_size: 2000}\n")
    env = make_batched_vec_env("RX200ReacherGoalSim-v0", 3, max_episode_steps=20)
    try:
        model = SAC_GOAL(env, tmp_path / "m", tmp_path / "l", abs_config_path=str(cfg), verbose=0)
        assert model.config.n_envs == 3 and model.model.n_envs == 3
        model.train()
        assert model.model.num_timesteps == 120 and model.model.replay_buffer.n_envs == 3
    finally:
        env.close()
    # With HER, learning waits for an ended episode of every env: 3 envs of 20 steps.
    assert model.config.algo_params["learning_starts"] == 60 and model.model.learning_starts == 60
    # The YAML's n_envs and the env given must agree: a trainer class does not build envs itself.
    single = uniros.make("RX200ReacherGoalSim-v0")
    try:
        with pytest.raises(TrainingConfigError, match="n_envs is 3 but the env given steps 1"):
            SAC_GOAL(single, tmp_path / "m", tmp_path / "l", abs_config_path=str(cfg), verbose=0)
    finally:
        single.close()
