"""What ``uniros train --resume`` promises (docs/training.md, "Interrupting and resuming"), each
fault sent on purpose: truncated and garbage checkpoint files, missing replay buffers, a second
``--resume`` of a running run, edits to the run's config, stale temporary files, names that would
leave the run folder, a run that failed or never reached its first checkpoint.

One short HER + SAC run on a tiny goal env (``point_goal_env``) is trained once and copied for each
case; every resume trains it on from 150 to 200 steps.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from uniros.cli import main as cli_main

from .conftest import POINT_GOAL_ENV as ENV
from .conftest import bare_run_folder, resume

# each case trains (2-10 s on a quiet machine); the module ~1 minute
pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("point_goal_env_on_path")]

CONFIG = """algorithm: sac
training_steps: 150
eval_freq: 50
eval_episodes: 3
save_freq: 25
keep_checkpoints: 0
keep_replay_buffers: 0
normalize: true
use_HER: true
video: false
progress_bar: false
sac_params: {learning_starts: 20, batch_size: 16, buffer_size: 5000}
"""


@pytest.fixture(scope="module")
def base_run(tmp_path_factory, point_goal_env_on_path) -> Path:
    """A finished 150-step run with a complete checkpoint every 25 steps (all kept)."""
    folder = tmp_path_factory.mktemp("base")
    (folder / "cfg.yaml").write_text(CONFIG)
    assert cli_main(["train", ENV, "--config", str(folder / "cfg.yaml"), "--output", str(folder / "runs"),
                     "--name", "base", "--eval-episodes", "0"]) == 0
    return folder / "runs" / "base"


@pytest.fixture
def run(base_run, tmp_path) -> Path:
    copy = tmp_path / "runs" / "r"
    shutil.copytree(base_run, copy)
    (copy / ".lock").unlink(missing_ok=True)
    return copy


def _resume(run: Path, capsys, *extra: str) -> tuple[int, str]:
    return resume(run, capsys, "--steps", "200", *extra)


def _meta(run: Path) -> dict:
    return json.loads((run / "run.json").read_text())


def _eval_steps(run: Path) -> list[int]:
    return [int(float(line.split(",")[0])) for line in (run / "evaluations.csv").read_text().splitlines()[1:]]


def _ckpt(run: Path, steps: int, kind: str = "") -> Path:
    return run / "checkpoints" / (f"model_{kind}_{steps}_steps.pkl" if kind else f"model_{steps}_steps.zip")


def test_the_base_run_keeps_every_checkpoint_complete(base_run):
    names = sorted(p.name for p in (base_run / "checkpoints").iterdir())
    for steps in range(25, 151, 25):
        assert {f"model_{steps}_steps.zip", f"model_replay_buffer_{steps}_steps.pkl",
                f"model_vecnormalize_{steps}_steps.pkl"} <= set(names)
    assert _meta(base_run)["status"] == "finished"


def test_a_resume_names_its_checkpoint_and_keeps_the_evaluations_format(run, capsys):
    """The checkpoint used is printed, and evaluations.csv keeps one number format (steps as
    integers, not 150.0 once a resume rewrote the file)."""
    before = (run / "evaluations.csv").read_text().splitlines()
    (run / "checkpoints" / "model_150_steps.zip").write_bytes(b"not a zip")  # the resume rewrites the file
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "resuming from checkpoint model_125_steps.zip (125 steps, with its replay buffer and " \
           "normalisation statistics)" in text
    after = (run / "evaluations.csv").read_text().splitlines()
    assert after[0] == before[0] and after[1:3] == before[1:3]  # the rows before 125 steps, byte for byte
    for line in after[1:]:
        steps, _, _, episodes, *_ = line.split(",")
        assert steps.isdigit() and episodes.isdigit(), line


@pytest.mark.parametrize("cut", ["start", "middle", "end"])
def test_a_truncated_newest_model_falls_back_to_the_previous_checkpoint(run, capsys, cut):
    path = _ckpt(run, 150)
    data = path.read_bytes()
    path.write_bytes(data[: {"start": 10, "middle": len(data) // 2, "end": len(data) - 20}[cut]])
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "skipped checkpoint at 150 steps: model_150_steps.zip: unreadable" in text
    assert "Traceback" not in text
    meta = _meta(run)
    assert meta["resumed_from"] == "model_125_steps.zip" and not meta["resumed_without_buffer"]
    assert meta["status"] == "finished" and meta["steps"] == 200
    assert (run / "checkpoints" / "unusable" / "model_150_steps.zip").is_file()  # set aside, not retried
    assert _eval_steps(run) == [50, 100, 150, 200]  # the evaluation at 150 was redone from 125


def test_garbage_statistics_fall_back_and_say_why(run, capsys):
    _ckpt(run, 150, "vecnormalize").write_bytes(b"\x80\x04garbage")
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "model_vecnormalize_150_steps.pkl: unreadable" in text
    assert _meta(run)["resumed_from"] == "model_125_steps.zip"


def test_statistics_of_another_kind_are_refused(run, capsys):
    with open(_ckpt(run, 150, "vecnormalize"), "wb") as f:
        import pickle

        pickle.dump({"not": "statistics"}, f)
    code, text = _resume(run, capsys)
    assert code == 0 and "holds a dict, not VecNormalize statistics" in text
    assert _meta(run)["resumed_from"] == "model_125_steps.zip"


def test_a_missing_replay_buffer_takes_the_previous_complete_checkpoint(run, capsys):
    _ckpt(run, 150, "replay_buffer").unlink()
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "model_replay_buffer_150_steps.pkl: missing" in text
    assert _meta(run)["resumed_from"] == "model_125_steps.zip"


def test_no_replay_buffer_anywhere_resumes_the_newest_model_and_refills(run, capsys):
    """The newest model loads but no buffer does: HER with an empty buffer used to crash at the first
    update; the buffer now fills for learning_starts steps first."""
    for path in (run / "checkpoints").glob("model_replay_buffer_*.pkl"):
        path.write_bytes(path.read_bytes()[:100])
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "resuming from model_150_steps.zip without a replay buffer" in text
    meta = _meta(run)
    assert meta["resumed_from"] == "model_150_steps.zip" and meta["resumed_without_buffer"]
    assert meta["status"] == "finished" and meta["steps"] == 200


def test_all_models_truncated_starts_the_run_again_and_keeps_what_the_earlier_attempt_wrote(run, capsys):
    """No checkpoint loads: the run starts from step 0, and its intact best model, evaluations, logs
    and the unusable checkpoints are moved aside (earlier/1, checkpoints/unusable), never deleted."""
    for path in (run / "checkpoints").glob("model_*_steps.zip"):
        path.write_bytes(path.read_bytes()[:-30])
    (run / "checkpoints" / "unusable").mkdir()
    (run / "checkpoints" / "unusable" / "model_5_steps.zip").write_bytes(b"set aside by an earlier resume")
    best, evaluations = (run / "best_model.zip").read_bytes(), (run / "evaluations.csv").read_text()
    monitor = (run / "monitor" / "train.monitor.csv").read_text()
    (run / "arm").mkdir()  # the user's, kept in the run's folder: a restart moves only what a run writes
    (run / "arm" / "myarm.yaml").write_text("format: 1\n")
    (run / "notes.txt").write_text("mine")
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert (run / "arm" / "myarm.yaml").read_text() == "format: 1\n" and (run / "notes.txt").read_text() == "mine"
    assert not (run / "earlier" / "1" / "arm").exists() and not (run / "earlier" / "1" / "notes.txt").exists()
    assert "no usable checkpoint" in text and "starting the run again from step 0" in text
    assert f"kept in {run / 'earlier' / '1'}" in text
    meta = _meta(run)
    assert meta["status"] == "finished" and meta["steps"] == 200 and meta["resumed_from"] is None
    assert _eval_steps(run) == [50, 100, 150, 200]
    earlier = run / "earlier" / "1"
    assert (earlier / "best_model.zip").read_bytes() == best
    assert (earlier / "evaluations.csv").read_text() == evaluations
    assert (earlier / "monitor" / "train.monitor.csv").read_text() == monitor
    assert (earlier / "final_model.zip").is_file() and (earlier / "checkpoints" / "latest.json").is_file()
    unusable = sorted(p.name for p in (run / "checkpoints" / "unusable").iterdir())
    assert unusable[0] == "model_100_steps.zip" and "model_5_steps.zip" in unusable
    assert len([n for n in unusable if n.endswith("_steps.zip")]) == 7  # the six truncated ones and the older one
    assert (run / "checkpoints" / "unusable" / "model_5_steps.zip").read_bytes() == b"set aside by an earlier resume"


def test_stale_temporaries_of_killed_writes_are_removed(run, capsys):
    stale = [run / "checkpoints" / ".tmp99999_model_350_steps.zip", run / ".tmp99999_run.json",
             run / "monitor" / ".tmp1_train.monitor.csv"]
    for path in stale:
        path.write_bytes(b"half a file")
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert not [p for p in stale if p.exists()]


def test_a_second_resume_of_a_running_run_is_refused(run, capsys, point_goal_env_on_path):
    """Two processes: the first resumes (and holds the run's lock while it trains); the second is
    refused before it writes anything, and the first's monitor file stays in order."""
    (run / "config.yaml").write_text((run / "config.yaml").read_text())
    monitor = run / "monitor" / "train.monitor.csv"
    earlier = len(monitor.read_text().splitlines()[2:])  # the rows of the run before this resume
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(point_goal_env_on_path), os.environ.get("PYTHONPATH", "")])}
    first = subprocess.Popen([sys.executable, "-c", "import sys; from uniros.cli import main; sys.exit(main())",
                              "train", "--resume", str(run), "--steps", "400", "--eval-episodes", "0"],
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        while _meta(run).get("status") != "running" and first.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert first.poll() is None, first.communicate()[0]
        before = sorted(p.name for p in run.rglob("*") if p.is_file())
        code, text = _resume(run, capsys)
        assert code == 2 and "is in use by another uniros process" in text and "Traceback" not in text
        assert str(first.pid) in text
        assert first.wait(timeout=300) == 0
    finally:
        if first.poll() is None:
            first.kill()
            first.wait(timeout=10)
    assert before  # the refused resume wrote nothing while the first ran (it never got the lock)
    assert _meta(run)["steps"] == 400
    rows = [line for line in monitor.read_text().splitlines()[2:]]
    times = [float(line.split(",")[2]) for line in rows]
    # One writer at a time: the run before and the one resume each appended their rows in time order
    # (the resume's clock starts again at 0); two writers would interleave theirs.
    assert earlier > 0 and len(times) > earlier
    assert times[:earlier] == sorted(times[:earlier]) and times[earlier:] == sorted(times[earlier:])


@pytest.mark.parametrize(("edit", "named"), [
    (lambda c: c.update(algorithm="td3", td3_params=c.pop("sac_params")), "algorithm"),
    (lambda c: c["env_kwargs"].update(extra=1), "env_kwargs"),
    (lambda c: c.update(use_custom_policy=True, policy_params={"net_arch": [8, 8]}), "policy_params"),
    (lambda c: c.update(normalize=False), "normalize"),
    (lambda c: c["sac_params"].update(buffer_size=100), "sac_params.buffer_size"),
    (lambda c: c.update(use_HER=False), "use_HER"),
])
def test_config_edits_a_resumed_run_cannot_honour_are_refused(run, capsys, edit, named):
    data = yaml.safe_load((run / "config.yaml").read_text())["model_params"]
    edit(data)
    (run / "config.yaml").write_text(yaml.safe_dump({"model_params": data}))
    before = (run / "run.json").read_text()
    code, text = _resume(run, capsys)
    assert code == 2, text
    assert f"{named} was" in text and "cannot take this edit" in text and "Traceback" not in text
    assert (run / "run.json").read_text() == before  # refused: nothing written


def test_pinning_the_workers_or_not_is_an_edit_a_resumed_run_takes(run, capsys):
    """``pin_workers`` changes where the workers run, not the model, env or buffer: a resume takes the
    edited file, and ``--no-pin-workers`` for one session."""
    data = yaml.safe_load((run / "config.yaml").read_text())
    data["model_params"]["pin_workers"] = True
    (run / "config.yaml").write_text(yaml.safe_dump(data))
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "cannot take this edit" not in text
    assert yaml.safe_load((run / "config.yaml").read_text())["model_params"]["pin_workers"] is True
    code, text = resume(run, capsys, "--steps", "300", "--no-pin-workers")
    assert code == 0, text  # a flag holds for that session (as --device does); config.yaml keeps the file's
    assert yaml.safe_load((run / "config.yaml").read_text())["model_params"]["pin_workers"] is True


def test_a_mistyped_hyperparameter_is_a_config_error(run, capsys):
    data = yaml.safe_load((run / "config.yaml").read_text())
    data["model_params"]["sac_params"]["learning_rate"] = "fast"
    (run / "config.yaml").write_text(yaml.safe_dump(data))
    code, text = _resume(run, capsys)
    assert code == 2 and "sac_params.learning_rate must be a number, got 'fast'" in text


def test_hyperparameters_a_loaded_model_takes_are_applied(run, capsys):
    data = yaml.safe_load((run / "config.yaml").read_text())
    data["model_params"]["sac_params"].update(learning_rate=0.0123, batch_size=8)
    data["model_params"]["eval_freq"] = 25
    (run / "config.yaml").write_text(yaml.safe_dump(data))
    code, text = _resume(run, capsys)
    assert code == 0, text
    assert "applied to the resumed model" in text and "'learning_rate': 0.0123" in text
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(run / "final_model.zip", load_data=True, device="cpu")
    assert data["learning_rate"] == 0.0123 and data["batch_size"] == 8
    assert _eval_steps(run) == [50, 100, 150, 175, 200]  # eval_freq 25 from 150 on


@pytest.mark.parametrize("prefix", ["../../../x", "/tmp/abs", "a/b", ".hidden", "p" * 65])
def test_a_save_prefix_outside_the_run_folder_is_refused(tmp_path, capsys, prefix):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG + f"save_prefix: {json.dumps(prefix)}\n")
    assert cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs")]) == 2
    assert "save_prefix" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists() and not Path("/tmp/abs_50_steps.zip").exists()


@pytest.mark.parametrize("name", ["../escape", "/tmp/abs", "a/b", "..", "n" * 300])
def test_a_run_name_outside_the_output_folder_is_refused(tmp_path, capsys, name):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    assert cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs"), "--name", name]) == 2
    err = capsys.readouterr().err
    assert "must be one plain directory name" in err and "Traceback" not in err and len(err) < 400
    assert not (tmp_path / "runs").exists() and not (tmp_path / "escape").exists()


def test_a_full_disk_is_one_line_and_the_run_resumes(run, capsys, monkeypatch):
    """ENOSPC while the second checkpoint's replay buffer is written (half of it on disk): one line,
    exit code 2, run.json says failed, latest.json still names the last complete checkpoint, no
    temporary file is left, and the run resumes from that checkpoint."""
    import errno

    from uniros import checkpoints

    real_save, calls = checkpoints.save_replay_buffer, []

    def save_replay_buffer(model, path):
        calls.append(path)
        if len(calls) < 2:
            return real_save(model, path)

        def write(tmp):
            with open(tmp, "wb") as f:
                f.write(b"half a replay buffer")
                raise OSError(errno.ENOSPC, "No space left on device")

        checkpoints.atomic_write(path, write)

    monkeypatch.setattr(checkpoints, "save_replay_buffer", save_replay_buffer)
    code, text = _resume(run, capsys, "--steps", "250")
    assert code == 2, text
    errors = [line for line in text.splitlines() if line.startswith("uniros train: error:")]
    assert len(errors) == 1 and "disk full" in errors[0] and "No space left on device" in errors[0]
    assert "last complete checkpoint (175 steps)" in errors[0] and f"uniros train --resume {run}" in errors[0]
    assert "Traceback" not in text
    meta = _meta(run)
    assert meta["status"] == "failed" and "No space left on device" in meta["error"]
    assert json.loads((run / "checkpoints" / "latest.json").read_text())["steps"] == 175
    assert not [p for p in run.rglob(".tmp*")]
    monkeypatch.setattr(checkpoints, "save_replay_buffer", real_save)
    code, text = _resume(run, capsys, "--steps", "250")
    assert code == 0, text
    assert _meta(run)["resumed_from"] == "model_175_steps.zip" and _meta(run)["status"] == "finished"


def test_a_run_stopped_before_its_first_checkpoint_is_never_a_dead_end(tmp_path, capsys):
    """A run directory without a checkpoint (the process died early): --name says to use --resume,
    and --resume starts it again from step 0 under its name."""
    from uniros.training import parse_training_config, start_run

    config = parse_training_config(yaml.safe_load(CONFIG), "cfg.yaml")
    run = start_run(ENV, config, output=tmp_path / "runs", name="early")
    run.release()  # the process that made it is gone
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    assert cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs"), "--name", "early"]) == 2
    err = capsys.readouterr().err
    assert f"uniros train --resume {run.root}" in err and "again from step 0" in err
    code, text = _resume(run.root, capsys)
    assert code == 0, text
    assert "starting the run again from step 0" in text and _meta(run.root)["steps"] == 200


def test_a_directory_left_by_a_killed_start_is_taken_over(tmp_path):
    from uniros.run_dir import RunDir

    root = bare_run_folder(tmp_path / "runs", "half")
    (root / ".tmp123_config.yaml").write_text("half")
    run = RunDir.create(tmp_path / "runs", "half", ENV, "sac")
    assert run.root == root and run.locked and not (root / ".tmp123_config.yaml").exists()


def test_a_refused_run_writes_nothing(tmp_path, capsys):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG + "env_kwargs: {ee_action_type: true}\n")
    assert cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert "does not take the env kwarg 'ee_action_type'" in err and "Traceback" not in err
    assert not list((tmp_path / "runs").iterdir()) if (tmp_path / "runs").exists() else True


def test_a_resumed_run_reports_when_it_first_reached_the_target(run, capsys):
    """The first evaluation at the target may lie before the resume (here every evaluation reaches
    0.0): a resumed run reports it from evaluations.csv instead of "never reached"."""
    code, text = _resume(run, capsys, "--target", "0.0")
    assert code == 0, text
    assert "first eval success >= 0.0: 50 steps" in text and "never reached" not in text
