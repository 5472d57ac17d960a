"""What a crafted run folder or a small machine can no longer do (issue 38, items 6 and 8): a run
writes, moves and deletes files in its own folder only (a ``.lock``, ``checkpoints/``,
``unusable/`` or any file that is a link is refused before anything is written: 0 files touched
outside the run), a replay buffer larger than the memory available and checkpoints larger than the
free disk are refused before the run starts, and a full disk is one line.

No case trains: each is refused before the first step (a few seconds for those that build a model).
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
from collections import namedtuple
from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces

from uniros.cli import main as cli_main
from uniros.errors import DiskFullError, RunDirError, TrainingConfigError, TrainingError

from .conftest import POINT_GOAL_ENV as ENV
from .conftest import bare_run_folder, resume

pytestmark = pytest.mark.usefixtures("point_goal_env_on_path")

CONFIG = """algorithm: sac
training_steps: 150
eval_freq: 50
eval_episodes: 3
save_freq: 25
normalize: true
use_HER: true
video: false
progress_bar: false
sac_params: {learning_starts: 20, batch_size: 16}
"""


def _crafted_run(tmp_path: Path) -> Path:
    """A run folder as `uniros train` leaves it before its first checkpoint (enough for --resume to open)."""
    root = bare_run_folder(tmp_path / "runs", "r")
    (root / "config.yaml").write_text(CONFIG)
    (root / "run.json").write_text(json.dumps({"env_id": ENV, "algorithm": "sac", "status": "interrupted"}))
    return root


def _snapshot(folder: Path, outside_of: Path) -> dict[str, str]:
    """Every file under ``folder`` but not under ``outside_of``: its SHA-256."""
    found = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not path.is_symlink() and outside_of not in path.parents:
            found[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return found


# -- item 6: links ----------------------------------------------------------------------------------
def test_a_lock_link_never_gets_the_pid(tmp_path, capsys):
    root = _crafted_run(tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (root / ".lock").symlink_to(victim)
    code, text = resume(root, capsys)
    assert code == 2 and ".lock is a symbolic link" in text and "Traceback" not in text, text
    assert victim.read_text() == "precious"


def test_a_dangling_lock_link_creates_nothing(tmp_path, capsys):
    root = _crafted_run(tmp_path)
    target = tmp_path / "elsewhere" / "made.txt"
    target.parent.mkdir()
    (root / ".lock").symlink_to(target)
    code, text = resume(root, capsys)
    assert code == 2 and ".lock is a symbolic link" in text, text
    assert not target.exists()


def test_a_lock_hard_link_is_refused(tmp_path, capsys):
    root = _crafted_run(tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    os.link(victim, root / ".lock")
    code, text = resume(root, capsys)
    assert code == 2 and "2 hard links" in text, text
    assert victim.read_text() == "precious"


def test_a_symlinked_checkpoints_folder_is_refused_and_the_other_run_keeps_its_files(tmp_path, capsys):
    """The probe: retention deleted 10 of another run's files through a linked checkpoints/."""
    root = _crafted_run(tmp_path)
    other = tmp_path / "other_run" / "checkpoints"
    other.mkdir(parents=True)
    for steps in range(1, 11):
        (other / f"model_{steps * 25}_steps.zip").write_bytes(os.urandom(64))
    (root / "checkpoints").rmdir()
    (root / "checkpoints").symlink_to(other, target_is_directory=True)
    before = _snapshot(tmp_path, root)
    code, text = resume(root, capsys)
    assert code == 2 and "holds symbolic links (checkpoints -> " in text and "Traceback" not in text, text
    assert _snapshot(tmp_path, root) == before  # 0 files touched outside the run folder
    assert len(list(other.iterdir())) == 10


@pytest.mark.parametrize("link", ["checkpoints/unusable", "monitor/train.monitor.csv", "evaluations.csv",
                                  "tensorboard", "best_model.zip"])
def test_any_link_in_a_run_is_refused_before_anything_is_written(tmp_path, capsys, link):
    root = _crafted_run(tmp_path)
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "file").write_text("someone's")
    path = root / link
    if path.is_dir():
        path.rmdir()
    path.symlink_to(outside if "." not in path.name else outside / "file")
    before, meta = _snapshot(tmp_path, root), (root / "run.json").read_text()
    code, text = resume(root, capsys)
    assert code == 2 and f"holds symbolic links ({link} -> {path.readlink()}" in text, text
    assert _snapshot(tmp_path, root) == before and (root / "run.json").read_text() == meta
    assert [p.name for p in outside.iterdir()] == ["file"]


def test_checkpoints_and_set_aside_refuse_a_folder_linked_after_the_check(tmp_path):
    """The folder check when the run locks is not the only guard: a checkpoints/ or unusable/ linked
    while a run trains is refused where checkpoints are saved (and pruned) or set aside."""
    from types import SimpleNamespace

    from uniros.checkpoints import CheckedCheckpoint, Checkpoint
    from uniros.resume import _set_aside
    from uniros.train_config import parse_training_config
    from uniros.trainer import Paths, Session

    other = tmp_path / "other"
    other.mkdir()
    for steps in (25, 50, 75, 100):
        (other / f"model_{steps}_steps.zip").write_bytes(b"another run's")
    linked = tmp_path / "run" / "checkpoints"
    linked.parent.mkdir()
    linked.symlink_to(other, target_is_directory=True)
    config = parse_training_config({"training_steps": 200, "keep_checkpoints": 1}, "c.yaml")
    session = Session(config, None, paths=Paths(checkpoints=linked, meta=tmp_path / "run" / "run.json"))
    session.model = SimpleNamespace(num_timesteps=125)
    with pytest.raises(RunDirError, match="checkpoints is a symbolic link"):
        session.checkpoint()
    assert len(list(other.iterdir())) == 4

    own = tmp_path / "run2" / "checkpoints"
    own.mkdir(parents=True)
    (own / "model_25_steps.zip").write_bytes(b"truncated")
    (own / "unusable").symlink_to(other, target_is_directory=True)
    bad = CheckedCheckpoint(Checkpoint(25, own / "model_25_steps.zip", None, None), problems=["unreadable"])
    with pytest.raises(RunDirError, match="unusable is a symbolic link"):
        _set_aside(bad)
    assert (own / "model_25_steps.zip").is_file() and len(list(other.iterdir())) == 4


def test_a_new_run_never_writes_into_a_linked_run_name(tmp_path, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "x").symlink_to(elsewhere, target_is_directory=True)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    code = cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs"), "--name", "x"])
    assert code == 2 and "is a symbolic link" in capsys.readouterr().err
    assert not list(elsewhere.iterdir())


def test_an_atomic_write_replaces_a_planted_temporary_link(tmp_path):
    from uniros.checkpoints import atomic_write

    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    target = tmp_path / "run" / "run.json"
    target.parent.mkdir()
    (target.parent / f".tmp{os.getpid()}_run.json").symlink_to(victim)
    atomic_write(target, lambda tmp: tmp.write_text("{}"))
    assert target.read_text() == "{}" and not target.is_symlink() and victim.read_text() == "precious"
    assert [p.name for p in target.parent.iterdir()] == ["run.json"]


# -- item 8: memory ---------------------------------------------------------------------------------
def _camera_space(height: int, width: int) -> spaces.Dict:
    vector = spaces.Box(-1.0, 1.0, (3,), np.float32)
    return spaces.Dict({"observation": spaces.Box(-10.0, 10.0, (9,), np.float32), "achieved_goal": vector,
                        "desired_goal": vector, "rgb": spaces.Box(0, 255, (height, width, 3), np.uint8)})


def test_a_camera_replay_buffer_larger_than_memory_is_refused_in_one_line():
    from stable_baselines3 import SAC

    from uniros.resources import check_replay_buffer_memory, transition_bytes
    from uniros.train_config import parse_training_config

    config = parse_training_config({"training_steps": 20_000, "use_HER": True}, "reach.yaml")
    action = spaces.Box(-1.0, 1.0, (4,), np.float32)
    for height, width in ((120, 160), (1080, 1920)):
        space = _camera_space(height, width)
        per = transition_bytes(space, action, her=True)
        assert per == 2 * (height * width * 3 + 15 * 4) + 4 * 4 + 12 + 16
        with pytest.raises(TrainingConfigError) as caught:
            check_replay_buffer_memory(config, SAC, {}, space, action, her=True, available=23 * 10**9)
        text = str(caught.value)
        assert "\n" not in text and text.startswith("reach.yaml: sac_params.buffer_size 1000000 x ")
        assert f"rgb {height}x{width}x3" in text and "23.0 GB of memory available" in text
        assert f"set buffer_size below {23 * 10**9 // per}" in text
    # the state config's buffer fits: 1e6 x 164 bytes
    state = spaces.Dict({k: s for k, s in _camera_space(1, 1).spaces.items() if k != "rgb"})
    assert check_replay_buffer_memory(config, SAC, {}, state, action, her=True, available=23 * 10**9) == 10**6 * (
        2 * 15 * 4 + 16 + 12 + 16)
    assert check_replay_buffer_memory(config, SAC, {"buffer_size": 5000}, _camera_space(120, 160), action,
                                      her=True, available=23 * 10**9) is not None


@pytest.mark.parametrize("observation", [_camera_space(84, 84), spaces.Box(-1.0, 1.0, (17,), np.float64)])
def test_the_estimate_is_what_sb3_allocates(observation):
    from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer

    from uniros.resources import transition_bytes

    action = spaces.Box(-1.0, 1.0, (4,), np.float64)  # SB3 keeps float64 actions as float32
    cls = DictReplayBuffer if isinstance(observation, spaces.Dict) else ReplayBuffer
    buffer = cls(100, observation, action, device="cpu")
    arrays = [buffer.actions, buffer.rewards, buffer.dones, buffer.timeouts]
    for part in (buffer.observations, buffer.next_observations):
        arrays += list(part.values()) if isinstance(part, dict) else [part]
    assert sum(a.nbytes for a in arrays) == 100 * transition_bytes(observation, action)


def test_a_run_whose_buffer_does_not_fit_leaves_nothing(tmp_path, capsys, monkeypatch):
    from uniros import resources

    monkeypatch.setattr(resources, "available_memory", lambda: 10 * 2**20)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    code = cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs"), "--name", "big"])
    err = capsys.readouterr().err
    assert code == 2 and "sac_params.buffer_size 1000000" in err and "10.5 MB of memory available" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "runs" / "big").exists()


# -- item 8: disk -----------------------------------------------------------------------------------
def test_the_disk_estimate_follows_retention():
    from uniros.resources import LOG_MARGIN, checkpoint_disk_bytes
    from uniros.train_config import parse_training_config

    config = parse_training_config({"training_steps": 1000, "save_freq": 100}, "c.yaml")  # keep 3 and 1
    # 3 checkpoints + best, final and a temporary: 6 models; the newest buffer (1000 transitions) and
    # the next one's temporary file
    assert checkpoint_disk_bytes(config, 100, 1000, 10_000) == 6 * 1000 + 2 * 1000 * 100 + LOG_MARGIN
    config = parse_training_config({"training_steps": 1000, "save_freq": 250, "keep_checkpoints": 0,
                                    "keep_replay_buffers": 0}, "c.yaml")
    buffers = (250 + 500 + 600 + 600) * 100 + 600 * 100  # every buffer, capped at buffer_size 600
    assert checkpoint_disk_bytes(config, 100, 1000, 600) == 7 * 1000 + buffers + LOG_MARGIN
    assert checkpoint_disk_bytes(config, None, 1000, None) == 7 * 1000 + LOG_MARGIN  # on-policy: no buffer


def test_a_run_larger_than_the_free_disk_is_refused_and_leaves_nothing(tmp_path, capsys, monkeypatch):
    import shutil

    from uniros import resources

    real = shutil.disk_usage
    usage = namedtuple("usage", "total used free")

    def disk_usage(path):
        return usage(10**9, 10**9 - 2**20, 2**20) if str(tmp_path) in str(path) else real(path)

    monkeypatch.setattr(resources.shutil, "disk_usage", disk_usage)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    code = cli_main(["train", ENV, "--config", str(cfg), "--output", str(tmp_path / "runs"), "--name", "d"])
    err = capsys.readouterr().err
    assert code == 2 and "of disk" in err and "1.0 MB free" in err and "keep_replay_buffers 1" in err, err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "runs" / "d").exists()


def test_a_full_disk_is_recognised_under_torch_s_runtime_error(tmp_path):
    from uniros.resources import disk_full_error

    try:
        try:
            raise OSError(errno.ENOSPC, "No space left on device", "/runs/r/checkpoints/model_5_steps.zip")
        except OSError:
            raise RuntimeError("[enforce fail at inline_container.cc:672] . unexpected pos 704 vs 598") from None
    except RuntimeError as exc:
        error = disk_full_error(exc, tmp_path, "kept")
    assert isinstance(error, DiskFullError) and isinstance(error, OSError) and isinstance(error, TrainingError)
    assert error.errno == errno.ENOSPC
    assert str(error).startswith("disk full writing /runs/r/checkpoints/model_5_steps.zip: No space left on device")
    assert str(error).endswith("; kept")
    assert disk_full_error(OSError(errno.EACCES, "Permission denied"), tmp_path, "kept") is None
    assert disk_full_error(ValueError("x"), tmp_path, "kept") is None
