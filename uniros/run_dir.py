"""A training run's directory, and checkpoints that survive interruption.

Layout (``uniros train``; never overwritten, one directory per run)::

    runs/<name>/
      config.yaml                 the resolved training config
      run.json                    env ID, env kwargs, algorithm, status, steps done
      monitor/                    train.monitor.csv, eval.monitor.csv (SB3 Monitor)
      tensorboard/                TensorBoard events and progress.csv (SB3 logger)
      checkpoints/                <prefix>_<N>_steps.zip, <prefix>_replay_buffer_<N>_steps.pkl,
                                  <prefix>_vecnormalize_<N>_steps.pkl, latest.json
      evaluations.csv             steps, train seconds, success rate, mean return, per evaluation
      best_model.zip              the model with the best evaluation (+ .vecnormalize.pkl)
      final_model.zip             the model at the end (+ .vecnormalize.pkl)
      learning_curve.png          success rate and return against env steps
      best_model.mp4              the best model, a few evaluation episodes

Every file is written to a temporary name and renamed into place, and ``latest.json`` names a
checkpoint only once all its files are complete: a process killed at any point leaves the previous
checkpoint usable.
"""

from __future__ import annotations

import json
import os
import pickle
import re
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uniros.train_config import TrainingError


class RunDirError(TrainingError, ValueError):
    """A run directory is missing, incomplete, or would be overwritten."""


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` then rename ``tmp`` to ``path`` (a reader never sees a half-written file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".tmp{os.getpid()}_{path.name}")  # same suffix: writers that go by it still work
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as JSON, atomically."""
    atomic_write(path, lambda tmp: tmp.write_text(json.dumps(data, indent=2) + "\n"))


def _save_model_zip(model: Any, path: Path) -> None:
    atomic_write(path, lambda tmp: model.save(str(tmp)))  # the temporary name ends in .zip: SB3 keeps it


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


def load_replay_buffer(model: Any, path: Path) -> None:
    """Load a replay buffer saved by :func:`save_replay_buffer` (or SB3) into ``model`` for a run
    that goes on with a fresh episode.

    A resumed or reloaded run resets its env, so the episode that was running when the buffer was
    saved never continues: SB3's HER buffer rightly truncates it, and the advice its warning gives
    (keep the trajectory when in the same episode) does not apply. That warning alone is silenced.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="The last trajectory in the replay buffer will be truncated")
        model.load_replay_buffer(str(path), truncate_last_traj=True)


# -- checkpoints ---------------------------------------------------------------------------------
@dataclass
class Checkpoint:
    """One complete checkpoint."""

    steps: int
    model: Path
    replay_buffer: Path | None
    vecnormalize: Path | None


def save_checkpoint(
    model: Any, normalizer: Any, folder: Path, prefix: str, *, replay_buffer: bool = True
) -> Checkpoint:
    """Save model, replay buffer and normalisation statistics, then point ``latest.json`` at them.

    File names follow SB3's ``CheckpointCallback``.
    """
    steps = int(model.num_timesteps)
    ckpt = Checkpoint(steps, folder / f"{prefix}_{steps}_steps.zip", None, None)
    _save_model_zip(model, ckpt.model)
    if replay_buffer and getattr(model, "replay_buffer", None) is not None:
        ckpt.replay_buffer = folder / f"{prefix}_replay_buffer_{steps}_steps.pkl"
        save_replay_buffer(model, ckpt.replay_buffer)
    if normalizer is not None:
        ckpt.vecnormalize = folder / f"{prefix}_vecnormalize_{steps}_steps.pkl"
        atomic_write(ckpt.vecnormalize, lambda tmp: normalizer.save(str(tmp)))
    write_json(folder / "latest.json", {
        "steps": steps,
        "model": ckpt.model.name,
        "replay_buffer": ckpt.replay_buffer.name if ckpt.replay_buffer else None,
        "vecnormalize": ckpt.vecnormalize.name if ckpt.vecnormalize else None,
        "time": time.strftime("%Y-%m-%d %H:%M:%S"),
    })
    return ckpt


def list_checkpoints(folder: Path, prefix: str | None = None) -> list[Checkpoint]:
    """Checkpoints in ``folder``, newest first (files as SB3's ``CheckpointCallback`` names them)."""
    found = []
    pattern = re.compile(r"^(?P<prefix>.+)_(?P<steps>\d+)_steps\.zip$")
    for path in folder.glob("*_steps.zip") if folder.is_dir() else ():
        match = pattern.match(path.name)
        if not match or (prefix is not None and match["prefix"] != prefix):
            continue
        p, steps = match["prefix"], int(match["steps"])
        buffer = folder / f"{p}_replay_buffer_{steps}_steps.pkl"
        norm = folder / f"{p}_vecnormalize_{steps}_steps.pkl"
        found.append(Checkpoint(steps, path, buffer if buffer.is_file() else None, norm if norm.is_file() else None))
    return sorted(found, key=lambda c: c.steps, reverse=True)


# -- the run directory ---------------------------------------------------------------------------
class RunDir:
    """Paths of one run (see the module docstring for the layout)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    @classmethod
    def create(cls, parent: str | Path, name: str | None, env_id: str, algorithm: str) -> RunDir:
        """A new run directory ``parent/name`` (default: ``<env id>_<algo>_<timestamp>``); never reuses one."""
        parent = Path(parent)
        if name is None:
            stamp = time.strftime("%Y%m%d-%H%M%S")
            base = f"{env_id.rpartition(':')[2]}_{algorithm}_{stamp}"
            name, n = base, 1
            while (parent / name).exists():
                n += 1
                name = f"{base}_{n}"
        elif "/" in name or name in ("", ".", ".."):
            raise RunDirError(f"--name {name!r} must be a plain directory name")
        root = parent / name
        if root.exists():
            raise RunDirError(
                f"run directory {str(root)!r} exists: pick another --name, or continue it with --resume {root}"
            )
        root.mkdir(parents=True)
        for sub in ("monitor", "checkpoints", "tensorboard"):
            (root / sub).mkdir()
        return cls(root)

    @classmethod
    def open(cls, root: str | Path) -> RunDir:
        """An existing run directory (for ``--resume`` and ``uniros eval``)."""
        run = cls(Path(root))
        if not run.root.is_dir():
            raise RunDirError(f"run directory {str(run.root)!r} not found")
        if not run.config.is_file() or not run.meta.is_file():
            raise RunDirError(
                f"{str(run.root)!r} is not a uniros run directory (no config.yaml and run.json); "
                "pass the directory `uniros train` printed"
            )
        return run

    config = property(lambda self: self.root / "config.yaml")
    meta = property(lambda self: self.root / "run.json")
    monitor = property(lambda self: self.root / "monitor")
    tensorboard = property(lambda self: self.root / "tensorboard")
    checkpoints = property(lambda self: self.root / "checkpoints")
    evaluations = property(lambda self: self.root / "evaluations.csv")
    best_model = property(lambda self: self.root / "best_model.zip")
    final_model = property(lambda self: self.root / "final_model.zip")
    curve = property(lambda self: self.root / "learning_curve.png")
    video = property(lambda self: self.root / "best_model.mp4")

    def read_meta(self) -> dict[str, Any]:
        """``run.json``."""
        try:
            return json.loads(self.meta.read_text())
        except (OSError, ValueError) as exc:
            raise RunDirError(f"{self.meta}: unreadable ({exc})") from exc

    def update_meta(self, **values: Any) -> None:
        """Merge ``values`` into ``run.json``."""
        data = self.read_meta() if self.meta.is_file() else {}
        data.update(values)
        write_json(self.meta, data)


def normalizer_path(model_path: Path) -> Path:
    """Where uniros keeps a model's ``VecNormalize`` statistics: ``<model>.vecnormalize.pkl``."""
    return model_path.with_name(model_path.name[: -len(".zip")] + ".vecnormalize.pkl") if model_path.name.endswith(
        ".zip") else model_path.with_name(model_path.name + ".vecnormalize.pkl")


def save_model_with_stats(model: Any, normalizer: Any, path: Path) -> None:
    """Save a model and, when observations are normalised, its statistics next to it."""
    _save_model_zip(model, path)
    if normalizer is not None:
        atomic_write(normalizer_path(path), lambda tmp: normalizer.save(str(tmp)))
