"""Checkpoints that survive interruption, stay bounded on disk, and are checked before use.

A checkpoint is SB3's ``CheckpointCallback`` set of files: ``<prefix>_<N>_steps.zip`` (the
model), ``<prefix>_replay_buffer_<N>_steps.pkl`` and ``<prefix>_vecnormalize_<N>_steps.pkl``.
Every file is written to a temporary name and renamed into place, and ``latest.json`` names a
checkpoint only once all its files are complete: a process killed at any point leaves the previous
checkpoint usable.

Retention: SB3 keeps every checkpoint, each with its own replay buffer, so a long run's folder
grows with the square of its length (a buffer holds every step so far). Here only the newest
``keep_checkpoints`` checkpoints are kept, and only the newest ``keep_replay_buffers`` of them keep
their replay buffer (:func:`prune_checkpoints`).

:func:`check_checkpoint` reads every file of a checkpoint (the model's parameters, the statistics,
the replay buffer) before a run resumes from it, so a truncated or foreign file is reported and an
older checkpoint used instead of a traceback halfway through building.
"""

from __future__ import annotations

import json
import os
import pickle
import re
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

TMP_PREFIX = ".tmp"


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` then rename ``tmp`` to ``path`` (a reader never sees a half-written file).

    The temporary file is created afresh (``O_EXCL``, not through a link left under its name), and
    the rename replaces ``path`` itself, never a file a link at ``path`` points to. A failed write
    (a full disk) leaves ``path`` as it was and no temporary file.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{TMP_PREFIX}{os.getpid()}_{path.name}")  # same suffix: writers that go by it still work
    try:
        if os.path.lexists(tmp):
            tmp.unlink()
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644))
        write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.lexists(tmp):
            tmp.unlink()


def own_folder(folder: Path) -> Path:
    """``folder``, if it is a folder of its own and not a symbolic link to another's (a run folder's
    ``checkpoints/`` and ``unusable/``; the trainer classes save where their user says).

    Raises:
        RunDirError: a link (files saved, pruned or moved there would be another folder's).
    """
    if folder.is_symlink():
        from uniros.errors import RunDirError

        raise RunDirError(f"{folder} is a symbolic link (to {os.readlink(folder)}): a run saves, prunes and moves "
                          "files in its own folders only; replace the link by a folder")
    return folder


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as JSON, atomically."""
    atomic_write(path, lambda tmp: tmp.write_text(json.dumps(data, indent=2) + "\n"))


def _save_model_zip(model: Any, path: Path) -> None:
    atomic_write(path, lambda tmp: model.save(str(tmp)))  # the temporary name ends in .zip: SB3 keeps it


def normalizer_path(model_path: Path) -> Path:
    """Where uniros keeps a model's ``VecNormalize`` statistics: ``<model>.vecnormalize.pkl``."""
    return model_path.with_name(model_path.name[: -len(".zip")] + ".vecnormalize.pkl") if model_path.name.endswith(
        ".zip") else model_path.with_name(model_path.name + ".vecnormalize.pkl")


def save_model_with_stats(model: Any, normalizer: Any, path: Path) -> None:
    """Save a model and, when observations are normalised, its statistics next to it."""
    _save_model_zip(model, path)
    if normalizer is not None:
        atomic_write(normalizer_path(path), lambda tmp: normalizer.save(str(tmp)))


# -- replay buffers: only the filled part is written -------------------------------------------
def _restore_buffer(cls: type, state: dict[str, Any], size: int) -> Any:
    """Unpickle a compact replay buffer back into a full-size one (SB3's ``load_replay_buffer`` works)."""

    def pad(value: Any) -> Any:
        if isinstance(value, np.ndarray) and value.ndim and value.shape[0] < size:
            full = np.zeros((size, *value.shape[1:]), dtype=value.dtype)
            full[: value.shape[0]] = value
            return full
        if isinstance(value, dict):
            return {k: pad(v) for k, v in value.items()}
        return value

    buffer = cls.__new__(cls)
    restored = {k: pad(v) if k in state.get("_uniros_sliced", ()) else v for k, v in state.items()}
    restored.pop("_uniros_sliced", None)
    if getattr(type(buffer), "__setstate__", None) is not None:
        buffer.__setstate__(restored)
    else:
        buffer.__dict__.update(restored)
    return buffer


class _CompactBuffer:
    """Pickles a replay buffer without its unused capacity (a 1e6-step buffer is hundreds of MB)."""

    def __init__(self, buffer: Any) -> None:
        self.buffer = buffer

    def __reduce__(self) -> tuple[Any, ...]:
        buffer = self.buffer
        size = int(buffer.buffer_size)
        upper = size if buffer.full else int(buffer.pos)
        getstate = getattr(buffer, "__getstate__", None)
        state = dict(getstate() if getstate is not None else buffer.__dict__)
        if state is buffer.__dict__:
            state = dict(state)
        sliced = []
        for key, value in list(state.items()):
            if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == size:
                state[key] = value[:upper]
                sliced.append(key)
            elif isinstance(value, dict) and value and all(
                isinstance(v, np.ndarray) and v.ndim and v.shape[0] == size for v in value.values()
            ):
                state[key] = {k: v[:upper] for k, v in value.items()}
                sliced.append(key)
        state["_uniros_sliced"] = tuple(sliced)
        return (_restore_buffer, (type(buffer), state, size))


def save_replay_buffer(model: Any, path: Path) -> None:
    """Save ``model``'s replay buffer compactly; ``model.load_replay_buffer(path)`` reads it back."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            pickle.dump(_CompactBuffer(model.replay_buffer), f, protocol=pickle.HIGHEST_PROTOCOL)

    atomic_write(path, write)


def read_replay_buffer(path: Path) -> Any:
    """Unpickle a replay buffer file (SB3's or :func:`save_replay_buffer`'s).

    Raises:
        ValueError: the file is not a whole pickled SB3 replay buffer (the message says why).
    """
    from stable_baselines3.common.buffers import ReplayBuffer

    try:
        with open(path, "rb") as f:
            buffer = pickle.load(f)  # noqa: S301 - SB3's format; see docs/training.md on others' run folders
    except Exception as exc:  # truncated, garbage, or a class that no longer exists
        raise ValueError(f"unreadable ({type(exc).__name__}: {exc})") from None
    if not isinstance(buffer, ReplayBuffer):
        raise ValueError(f"holds a {type(buffer).__name__}, not an SB3 replay buffer")
    return buffer


def put_replay_buffer(model: Any, buffer: Any) -> None:
    """Make ``buffer`` (from :func:`read_replay_buffer`) ``model``'s replay buffer, as SB3's
    ``load_replay_buffer(truncate_last_traj=True)`` does.

    A resumed run resets its env, so the episode that was running when the buffer was saved never
    continues: SB3's HER buffer rightly truncates it, and the advice its warning gives (keep the
    trajectory when in the same episode) does not apply. That warning alone is silenced.
    """
    from stable_baselines3 import HerReplayBuffer

    model.replay_buffer = buffer
    if not hasattr(buffer, "handle_timeout_termination"):  # SB3 < 2.1 buffers, as SB3 does
        buffer.handle_timeout_termination = False
        buffer.timeouts = np.zeros_like(buffer.dones)
    if isinstance(buffer, HerReplayBuffer):
        buffer.set_env(model.get_env())
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="The last trajectory in the replay buffer will be truncated")
            buffer.truncate_last_trajectory()
    buffer.device = model.device


def load_replay_buffer(model: Any, path: Path) -> None:
    """Load a replay buffer saved by :func:`save_replay_buffer` (or SB3) into ``model`` for a run
    that goes on with a fresh episode (see :func:`put_replay_buffer`)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="The last trajectory in the replay buffer will be truncated")
        model.load_replay_buffer(str(path), truncate_last_traj=True)


# -- checkpoints ---------------------------------------------------------------------------------
@dataclass
class Checkpoint:
    """One checkpoint's files (``None``: not there)."""

    steps: int
    model: Path
    replay_buffer: Path | None
    vecnormalize: Path | None


def _files(folder: Path, prefix: str, steps: int) -> tuple[Path, Path, Path]:
    return (folder / f"{prefix}_{steps}_steps.zip", folder / f"{prefix}_replay_buffer_{steps}_steps.pkl",
            folder / f"{prefix}_vecnormalize_{steps}_steps.pkl")


def save_checkpoint(
    model: Any, normalizer: Any, folder: Path, prefix: str, *, replay_buffer: bool = True,
    keep_checkpoints: int = 0, keep_replay_buffers: int = 0,
) -> Checkpoint:
    """Save model, replay buffer and normalisation statistics, point ``latest.json`` at them, then
    drop what the retention keeps no more (:func:`prune_checkpoints`).

    File names follow SB3's ``CheckpointCallback``.
    """
    steps = int(model.num_timesteps)
    model_file, buffer_file, stats_file = _files(folder, prefix, steps)
    ckpt = Checkpoint(steps, model_file, None, None)
    _save_model_zip(model, ckpt.model)
    if replay_buffer and getattr(model, "replay_buffer", None) is not None:
        ckpt.replay_buffer = buffer_file
        save_replay_buffer(model, ckpt.replay_buffer)
    elif buffer_file.exists():
        buffer_file.unlink()  # an older run's file under this name is not this checkpoint's
    if normalizer is not None:
        ckpt.vecnormalize = stats_file
        atomic_write(ckpt.vecnormalize, lambda tmp: normalizer.save(str(tmp)))
    write_json(folder / "latest.json", {
        "steps": steps,
        "model": ckpt.model.name,
        "replay_buffer": ckpt.replay_buffer.name if ckpt.replay_buffer else None,
        "vecnormalize": ckpt.vecnormalize.name if ckpt.vecnormalize else None,
        "time": time.strftime("%Y-%m-%d %H:%M:%S"),
    })
    prune_checkpoints(folder, prefix, keep_checkpoints, keep_replay_buffers)
    return ckpt


def list_checkpoints(folder: Path, prefix: str | None = None) -> list[Checkpoint]:
    """Checkpoints in ``folder``, newest first (files as SB3's ``CheckpointCallback`` names them)."""
    found = []
    pattern = re.compile(r"^(?P<prefix>.+)_(?P<steps>\d+)_steps\.zip$")
    for path in folder.glob("*_steps.zip") if folder.is_dir() else ():
        match = pattern.match(path.name)
        if not match or (prefix is not None and match["prefix"] != prefix) or path.name.startswith(TMP_PREFIX):
            continue
        _, buffer, norm = _files(folder, match["prefix"], int(match["steps"]))
        found.append(Checkpoint(int(match["steps"]), path, buffer if buffer.is_file() else None,
                                norm if norm.is_file() else None))
    return sorted(found, key=lambda c: c.steps, reverse=True)


def latest_checkpoint(folder: Path, prefix: str | None = None) -> list[Checkpoint]:
    """Checkpoints, the one ``latest.json`` names first, then the others newest first."""
    found = list_checkpoints(folder, prefix)
    latest = folder / "latest.json"
    if latest.is_file():
        try:
            named = json.loads(latest.read_text())["model"]
            found.sort(key=lambda c: c.model.name != named)
        except (ValueError, KeyError, TypeError):
            pass  # unreadable: newest first is the order to try
    return found


def prune_checkpoints(folder: Path, prefix: str, keep_checkpoints: int, keep_replay_buffers: int) -> list[Path]:
    """Delete checkpoints beyond the newest ``keep_checkpoints`` and replay buffers beyond the newest
    ``keep_replay_buffers`` (0: keep all); returns the deleted files.

    The checkpoint ``latest.json`` names is never deleted.
    """
    found = latest_checkpoint(folder, prefix)
    deleted: list[Path] = []
    for i, ckpt in enumerate(found):
        doomed: list[Path | None] = []
        if keep_checkpoints and i >= keep_checkpoints:
            doomed = [ckpt.model, ckpt.replay_buffer, ckpt.vecnormalize]
        elif keep_replay_buffers and i >= keep_replay_buffers:
            doomed = [ckpt.replay_buffer]
        for path in doomed:
            if path is not None and path.exists():
                path.unlink()
                deleted.append(path)
    return deleted


def remove_stale_temporaries(folder: Path) -> list[Path]:
    """Delete the temporary files of writes that were killed (``.tmp<pid>_*``) in ``folder`` and
    its subfolders. Call it only while holding the folder's run lock (no live writer then)."""
    removed = []
    for path in folder.rglob(f"{TMP_PREFIX}*"):
        if path.is_file():
            path.unlink()
            removed.append(path)
    return removed


# -- checking a checkpoint before resuming from it -----------------------------------------------
@dataclass
class CheckedCheckpoint:
    """A checkpoint whose files were read: what is usable, and why the rest is not.

    Attributes:
        problems: ``file name: what is wrong`` per unusable or missing file.
        buffer: the replay buffer, read (``None``: none needed, or unusable: see ``problems``).
        buffer_missing: a replay buffer was needed and is missing or unusable.
    """

    checkpoint: Checkpoint
    problems: list[str] = field(default_factory=list)
    buffer: Any = None
    buffer_missing: bool = False

    @property
    def complete(self) -> bool:
        """Every file the run needs loads."""
        return not self.problems

    @property
    def model_usable(self) -> bool:
        """The model and its statistics load (the replay buffer may not)."""
        return self.complete or (self.buffer_missing and len(self.problems) == 1)


def _check_model(path: Path, spaces: tuple[Any, Any], algorithm: str) -> str | None:
    from stable_baselines3.common.save_util import load_from_zip_file

    from uniros.algorithms import algorithm_of_saved

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data, params, _ = load_from_zip_file(str(path), load_data=True, device="cpu")
    except Exception as exc:  # a truncated or foreign zip fails in zipfile, pickle or torch
        return f"unreadable ({type(exc).__name__}: {exc})"
    if not data or not params:
        return "unreadable (no model data or parameters in it: truncated, or not an SB3 model)"
    saved_algo = algorithm_of_saved(str(getattr(data.get("policy_class"), "__module__", "")), data)
    if saved_algo is not None and saved_algo != algorithm:
        return f"a {saved_algo.upper()} model, but the run's config says algorithm: {algorithm}"
    for name, current in zip(("observation_space", "action_space"), spaces):
        saved = data.get(name)
        if saved is not None and saved != current:
            return (f"trained with {name} {saved}, but the env gives {current} (were the run's env_id or "
                    "env_kwargs edited? put them back)")
    return None


def _check_stats(path: Path, observation_space: Any) -> str | None:
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as f:
            stats = pickle.load(f)  # noqa: S301 - SB3's format; see docs/training.md on others' run folders
    except Exception as exc:
        return f"unreadable ({type(exc).__name__}: {exc})"
    if not isinstance(stats, VecNormalize):
        return f"holds a {type(stats).__name__}, not VecNormalize statistics"
    if getattr(stats, "observation_space", None) is not None and stats.observation_space != observation_space:
        return f"statistics of another observation space ({stats.observation_space})"
    return None


def check_checkpoint(ckpt: Checkpoint, *, observation_space: Any, action_space: Any, algorithm: str,
                     needs_buffer: bool, needs_stats: bool, n_envs: int = 1) -> CheckedCheckpoint:
    """Read every file of ``ckpt`` the run needs and say what is wrong with each.

    ``needs_buffer``: an off-policy algorithm resumes with its replay buffer; ``needs_stats``:
    observations are normalised. The replay buffer, when it loads, is kept in the result (it is
    the largest file: read once). ``observation_space`` is the env's: a model and its statistics
    hold camera images channel-first (SB3 transposes them), and are compared with it so.
    """
    from uniros.image_spaces import channel_first_space

    observation_space = channel_first_space(observation_space)
    checked = CheckedCheckpoint(ckpt)
    problem = _check_model(ckpt.model, (observation_space, action_space), algorithm)
    if problem:
        checked.problems.append(f"{ckpt.model.name}: {problem}")
    if needs_stats:
        stats = _files(ckpt.model.parent, ckpt.model.name[: -len(f"_{ckpt.steps}_steps.zip")], ckpt.steps)[2]
        problem = "missing" if ckpt.vecnormalize is None else _check_stats(ckpt.vecnormalize, observation_space)
        if problem:
            checked.problems.append(f"{stats.name}: {problem}")
    if needs_buffer and not problem_in(checked, ckpt.model.name):
        prefix = ckpt.model.name[: -len(f"_{ckpt.steps}_steps.zip")]
        name = _files(ckpt.model.parent, prefix, ckpt.steps)[1].name
        if ckpt.replay_buffer is None:
            checked.problems.append(f"{name}: missing")
            checked.buffer_missing = True
        else:
            try:
                buffer = read_replay_buffer(ckpt.replay_buffer)
                problem = _n_envs_problem(buffer, n_envs)
                if problem:
                    raise ValueError(problem)
                checked.buffer = buffer
            except ValueError as exc:
                checked.problems.append(f"{name}: {exc}")
                checked.buffer_missing = True
    return checked


def _n_envs_problem(buffer: Any, n_envs: int) -> str | None:
    held = int(getattr(buffer, "n_envs", n_envs))
    return f"holds {held} envs' transitions, the run trains {n_envs} envs" if held != n_envs else None


def newest_replay_buffer(folder: Path) -> Path:
    """The replay buffer of the newest checkpoint in ``folder`` that kept one.

    Raises:
        ValueError: no checkpoint there kept its replay buffer.
    """
    for ckpt in list_checkpoints(folder):
        if ckpt.replay_buffer is not None:
            return ckpt.replay_buffer
    raise ValueError(f"no checkpoint in {folder} kept its replay buffer")


def replay_buffer_problem(buffer: Any, model: Any) -> str | None:
    """Why ``buffer`` cannot be ``model``'s replay buffer (``None``: it can): another number of envs,
    other spaces, or HER's buffer for a model without HER (or the reverse)."""
    from stable_baselines3 import HerReplayBuffer

    mine = model.replay_buffer
    problem = _n_envs_problem(buffer, int(model.n_envs))
    if problem:
        return problem
    if isinstance(buffer, HerReplayBuffer) != isinstance(mine, HerReplayBuffer):
        return f"a {type(buffer).__name__}, the run's config makes a {type(mine).__name__} (use_HER)"
    for name in ("observation_space", "action_space"):
        if getattr(buffer, name, None) != getattr(mine, name, None):
            return f"{name} {getattr(buffer, name, None)}, the env gives {getattr(mine, name, None)}"
    return None


def problem_in(checked: CheckedCheckpoint, name: str) -> bool:
    """Whether one of ``checked``'s problems is about the file ``name``."""
    return any(p.startswith(f"{name}:") for p in checked.problems)


__all__ = [
    "CheckedCheckpoint",
    "Checkpoint",
    "atomic_write",
    "check_checkpoint",
    "latest_checkpoint",
    "list_checkpoints",
    "load_replay_buffer",
    "newest_replay_buffer",
    "normalizer_path",
    "own_folder",
    "prune_checkpoints",
    "put_replay_buffer",
    "read_replay_buffer",
    "remove_stale_temporaries",
    "replay_buffer_problem",
    "save_checkpoint",
    "save_model_with_stats",
    "save_replay_buffer",
    "write_json",
]
