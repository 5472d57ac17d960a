"""rl-zoo3, a real client: train (a few hundred steps) and enjoy on a uniros ID with the shipped
hyperparameters, then `uniros eval` on rl-zoo3's run layout (its vecnormalize.pkl)."""

from __future__ import annotations

import os
import subprocess
import sys
from importlib import resources

import pytest

pytest.importorskip("rl_zoo3")


@pytest.mark.slow
@pytest.mark.multiprocess
def test_rl_zoo3_train_enjoy_and_uniros_eval(tmp_path, capsys):
    conf = str(resources.files("rl_environments.config").joinpath("training", "rl_zoo3", "sac.yml"))
    env = {**os.environ, "MUJOCO_GL": "egl"}
    common = ["--algo", "sac", "--env", "RX200ReacherGoalSim-v0", "--gym-packages", "uniros", "-f", "logs",
              "--env-kwargs", "ee_action_type:True"]
    train = [sys.executable, "-m", "rl_zoo3.train", *common, "-conf", conf, "-n", "300", "--eval-freq", "150",
             "--eval-episodes", "2", "--seed", "0", "--hyperparams", "learning_starts:100",
             "--num-threads", "1"]
    done = subprocess.run(train, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    run = tmp_path / "logs" / "sac" / "RX200ReacherGoalSim-v0_1"
    assert (run / "RX200ReacherGoalSim-v0.zip").is_file()
    assert (run / "RX200ReacherGoalSim-v0" / "vecnormalize.pkl").is_file()
    enjoy = [sys.executable, "-m", "rl_zoo3.enjoy", *common, "--exp-id", "1", "-n", "110", "--no-render"]
    done = subprocess.run(enjoy, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Mean episode length" in done.stdout
    from uniros.cli import main

    assert main(["eval", "RX200ReacherGoalSim-v0", str(run / "RX200ReacherGoalSim-v0.zip"), "--episodes", "1"]) == 0
    assert "normalised with the saved statistics" in capsys.readouterr().out
