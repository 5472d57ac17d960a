"""`uniros train` run directories: interrupt (SIGINT, SIGTERM) and resume, the files being real, and
`uniros eval` on them and on bad input."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from uniros.cli import main as cli_main

TINY = (
    "algorithm: sac\ntraining_steps: {steps}\neval_freq: 200\neval_episodes: 2\nsave_freq: 100\nnormalize: true\n"
    "use_HER: true\nvideo_episodes: 1\nsac_params: {{learning_starts: 100, batch_size: 32, buffer_size: 50000}}\n"
    "env_kwargs: {{ee_action_type: true, max_episode_steps: 50}}\n"
)
UNIROS = [sys.executable, "-c", "import sys; from uniros.cli import main; sys.exit(main())"]


def _latest_steps(run: Path) -> int:
    try:
        return json.loads((run / "checkpoints" / "latest.json").read_text())["steps"]
    except (OSError, ValueError, KeyError):
        return 0


def _interrupt_when_checkpointed(args: list[str], run: Path, signum: int, after: int, cwd: Path) -> tuple[int, str]:
    env = {**os.environ, "MUJOCO_GL": "egl"}
    proc = subprocess.Popen(UNIROS + args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while _latest_steps(run) <= after and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, f"finished before the signal: {proc.communicate()}"
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    return proc.returncode, out + err


@pytest.mark.slow
@pytest.mark.multiprocess
def test_interrupt_resume_and_the_run_directory(tmp_path, capsys):
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(TINY.format(steps=900))
    run = tmp_path / "runs" / "r1"
    args = ["train", "RX200ReacherGoalSim-v0", "--config", str(cfg), "--output", str(tmp_path / "runs"),
            "--name", "r1", "--eval-episodes", "2"]
    code, text = _interrupt_when_checkpointed(args, run, signal.SIGINT, 0, tmp_path)
    assert code == 130, text
    assert "interrupted by SIGINT" in text and f"uniros train --resume {run}" in text
    assert "Traceback" not in text
    first = _latest_steps(run)
    assert first >= 100 and json.loads((run / "run.json").read_text())["status"] == "interrupted"

    code, text = _interrupt_when_checkpointed(["train", "--resume", str(run)], run, signal.SIGTERM, first, tmp_path)
    assert code == 143, text
    assert "interrupted by SIGTERM" in text and "Traceback" not in text
    second = _latest_steps(run)
    assert second > first  # the step count carried on

    # A name in use is refused, not overwritten, and the message says how to continue that run.
    assert cli_main(args) == 2
    assert f"holds a run that did not finish (interrupted): continue it from its checkpoint at {second} steps " \
           f"with uniros train --resume {run}" in capsys.readouterr().err

    # A corrupt newest checkpoint: resume falls back to the previous one (which, with the default
    # retention, kept no replay buffer: it refills).
    newest = run / "checkpoints" / f"model_{second}_steps.zip"
    newest.write_bytes(b"not a zip")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cli_main(["train", "--resume", str(run), "--eval-episodes", "3"]) == 0
    # The resumed run starts a fresh episode: SB3's advice to keep the last trajectory does not apply.
    assert not [w for w in caught if "last trajectory in the replay buffer" in str(w.message)]
    out = capsys.readouterr()
    assert f"skipped checkpoint at {second} steps: model_{second}_steps.zip: unreadable" in out.err
    meta = json.loads((run / "run.json").read_text())
    assert meta["status"] == "finished" and meta["steps"] == 900
    # Retention: three model checkpoints, one replay buffer, whatever the run's length.
    ckpts = run / "checkpoints"
    assert len(list(ckpts.glob("model_*_steps.zip"))) == 3 and len(list(ckpts.glob("model_replay_buffer_*"))) == 1
    # The final evaluation and `uniros eval` play the same seeded episodes: the same figures.
    final = re.search(r"final evaluation of best_model.zip over 3 episodes: success rate (\S+ \[\S+, \S+\]).*"
                      r"mean return (\S+),", out.out)
    assert final, out.out

    # The files are real.
    for name in ("config.yaml", "final_model.zip", "final_model.vecnormalize.pkl", "best_model.zip",
                 "best_model.vecnormalize.pkl", "evaluations.csv", "learning_curve.png", "best_model.mp4",
                 "monitor/train.monitor.csv", "monitor/eval.monitor.csv"):
        assert (run / name).is_file(), name
        assert str(run / name) in out.out or name.startswith("monitor") or name.endswith(".pkl") \
            or name == "config.yaml" or name == "best_model.zip", name
    from uniros.reports import plot_learning_curve, read_evaluations

    rows = read_evaluations(run / "evaluations.csv")
    assert [r["steps"] for r in rows] == [200, 400, 600, 800]  # the schedule survived two resumes
    fig = plot_learning_curve(rows, tmp_path / "curve.png")
    eval_line = next(line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == "eval_success")
    assert list(eval_line.get_xdata()) == [200, 400, 600, 800] and eval_line.get_marker() == "o"
    import imageio.v2 as imageio

    png = imageio.imread(run / "learning_curve.png")
    assert png.shape[0] > 100 and png.std() > 10
    reader = imageio.get_reader(str(run / "best_model.mp4"))
    assert reader.get_meta_data()["fps"] == 10  # real time: the reach task steps every 100 ms
    frames = [np.asarray(f, dtype=int) for f in reader]
    assert len(frames) >= 2 + 5  # the reset frame, the steps, the last one held 0.5 s
    assert np.abs(frames[0] - frames[-1]).mean() > 1  # the robot moves
    assert np.abs(frames[-1] - frames[-5]).mean() < 1.0  # the end is held (H.264 changes a few pixels)
    green = [int(((f[..., 1] - np.maximum(f[..., 0], f[..., 2])) > 60).sum()) for f in frames]
    # The goal marker (green) is drawn. How long it stays visible depends on the policy (a good one
    # parks the gripper on it), and the policy on where the signals above interrupted training:
    # tests/training/test_reports.py checks the marker on a fixed trajectory.
    assert max(green) > 20, "the goal marker is not visible"
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    scalars = set()
    for events in (run / "tensorboard").glob("events.out.tfevents.*"):
        acc = EventAccumulator(str(events))
        acc.Reload()
        scalars |= set(acc.Tags()["scalars"])
    assert "eval/success_rate" in scalars
    # uniros eval: a run directory (its best model, its env), a missing file, a model for another env.
    assert cli_main(["eval", str(run), "--episodes", "3"]) == 0
    out = capsys.readouterr().out
    assert "normalised with the saved statistics" in out
    assert f"success rate {final[1]} (95% CI) over 3 episodes" in out and f"mean return {final[2]}," in out
    assert cli_main(["eval", "RX200ReacherGoalSim-v0", str(tmp_path / "nope"), "--algo", "sac"]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and ".zip.zip" not in err and "cannot tell" not in err
    assert cli_main(["eval", "ABBIRB120ReacherGoalEnv-v0", str(run / "final_model.zip"), "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "cannot run on" in err or "does not fit this env" in err or "was trained with" in err
    assert "Traceback" not in err


def test_module_colon_id_env_from_the_cli(tmp_path, capsys, monkeypatch):
    pkg = tmp_path / "my_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "my_module.py").write_text(
        "from gymnasium.envs.registration import register, registry\n"
        "if 'MyUnirosTestEnv-v0' not in registry:\n"
        "    register(id='MyUnirosTestEnv-v0', entry_point="
        "'rl_environments.arm_envs:RX200ReacherGoalEnv', max_episode_steps=20)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    cfg = tmp_path / "c.yaml"
    cfg.write_text("training_steps: 60\neval_freq: 0\nsave_freq: 30\nvideo: false\nuse_HER: true\n"
                   "sac_params: {learning_starts: 40, batch_size: 16, buffer_size: 1000}\n")
    out = tmp_path / "runs"
    assert cli_main(["train", "my_pkg.my_module:MyUnirosTestEnv-v0", "--config", str(cfg), "--output", str(out),
                     "--name", "mine", "--eval-episodes", "1"]) == 0
    assert (out / "mine" / "final_model.zip").is_file()
    assert cli_main(["eval", "my_pkg.my_module:MyUnirosTestEnv-v0", str(out / "mine"), "--episodes", "1"]) == 0
    capsys.readouterr()
    assert cli_main(["train", "no_such_pkg.mod:X-v0", "--output", str(out)]) == 2
    assert "cannot import 'no_such_pkg.mod'" in capsys.readouterr().err


def test_module_colon_id_imports_from_the_working_directory(tmp_path, monkeypatch):
    """The ``uniros`` console script's sys.path has its bin directory, not the working directory: a
    user's package in the directory they run from still imports, and only then is the directory added."""
    from uniros.run_envs import resolve_env_id
    from uniros.train_config import TrainingError

    (tmp_path / "my_cwd_pkg").mkdir()
    (tmp_path / "my_cwd_pkg" / "__init__.py").write_text(
        "from gymnasium.envs.registration import register, registry\n"
        "if 'MyCwdTestEnv-v0' not in registry:\n"
        "    register(id='MyCwdTestEnv-v0', entry_point='gymnasium.envs.classic_control:CartPoleEnv')\n"
    )
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", os.getcwd(), str(tmp_path))])
    monkeypatch.delitem(sys.modules, "my_cwd_pkg", raising=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(TrainingError, match="cannot import 'absent_pkg'"):
        resolve_env_id("absent_pkg:X-v0")
    assert os.getcwd() not in sys.path  # nothing there to import: the path is left alone
    assert resolve_env_id("my_cwd_pkg:MyCwdTestEnv-v0") == "MyCwdTestEnv-v0"
    assert sys.path[0] == os.getcwd()
