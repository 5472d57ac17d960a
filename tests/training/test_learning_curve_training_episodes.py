"""The learning curve's grey line: the training episodes of the run's Monitor CSV.

The trainer's Monitor files must carry SB3's header lines (a new run) and keep appending on resume;
the plot must read SB3's ``True``/``False`` success flags and show a trailing mean, not a
zero-padded centred one.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from uniros.reports import plot_learning_curve
from uniros.train_config import TrainingConfig
from uniros.trainer import Paths, Session


class _Episodic(gym.Env):
    """Episodes of 5 steps; every other one succeeds."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self) -> None:
        self.t = self.episode = 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t, self.episode = 0, self.episode + 1
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.t += 1
        done = self.t == 5
        return np.zeros(1, np.float32), -1.0, done, False, {"is_success": done and self.episode % 2 == 0}


def _run_episodes(monitored, n: int) -> None:
    """``n`` episodes of each env of the monitored ``VecEnv`` (it resets ended envs itself)."""
    monitored.reset()
    for _ in range(n * 5):
        monitored.step(np.zeros((monitored.num_envs, 1), np.float32))


@pytest.mark.parametrize("vector", [False, True], ids=["one env (Monitor)", "VecEnv (VecMonitor)"])
def test_monitor_csv_has_header_and_appends_on_resume(tmp_path, vector):
    from stable_baselines3.common.vec_env import DummyVecEnv

    def env():
        return DummyVecEnv([_Episodic, _Episodic]) if vector else _Episodic()

    session = Session(config=TrainingConfig(training_steps=10), env=env(), paths=Paths(monitor=tmp_path))
    monitored = session._monitored(env(), "train")
    _run_episodes(monitored, 3)
    monitored.close()
    again = session._monitored(env(), "train")  # a resumed run
    _run_episodes(again, 2)
    again.close()
    lines = (tmp_path / "train.monitor.csv").read_text().splitlines()
    assert lines[0].startswith("#{") and lines[1] == "r,l,t,is_success"
    envs = 2 if vector else 1
    assert len(lines) == 2 + 5 * envs and sum(line.startswith("#") for line in lines) == 1
    assert [line.split(",")[-1] for line in lines[2:]] == ["False"] * envs + ["True"] * envs + ["False"] * envs + \
        ["False"] * envs + ["True"] * envs  # each run's episodes 1, 2, 3: success on even ones


def test_plot_shows_training_episodes_as_a_trailing_mean(tmp_path):
    csv = tmp_path / "train.monitor.csv"
    rows = [f"-5.0,5,{i}.0,{'True' if i % 2 else 'False'}" for i in range(40)]
    csv.write_text('#{"t_start": 0.0, "env_id": null}\nr,l,t,is_success\n' + "\n".join(rows) + "\n")
    evaluations = [{"steps": 100.0, "success_rate": 0.5, "mean_return": -5.0}]
    fig = plot_learning_curve(evaluations, tmp_path / "curve.png", monitor_csv=csv)
    grey = [line for ax in fig.axes for line in ax.get_lines() if line.get_label().startswith("training episodes")]
    assert len(grey) == 2  # success and return
    success = grey[0]
    assert list(success.get_xdata()) == [5.0 * k for k in range(20, 41)]  # from the 20th episode on
    assert np.allclose(success.get_ydata(), 0.5)  # no zero padding at either end
