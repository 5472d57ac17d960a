"""What a run needs from the machine, checked before it starts: memory for the replay buffer, disk
for its checkpoints; and a full disk met during a run, said in one line.

An off-policy algorithm allocates its whole replay buffer when the model is built: ``buffer_size``
transitions, each holding the observation twice (and the next one), the action, reward and flags.
NumPy asks the kernel for it lazily, so a buffer larger than the machine's memory is built without a
word and the run dies of memory hours later, when the buffer fills (a camera keyword added to a
state config turns SB3's default 1e6 transitions into tens of GB); a larger one fails at once with a
NumPy traceback. :func:`check_replay_buffer_memory` computes the size from the spaces first.

Checkpoints keep replay buffers on disk (:mod:`uniros.checkpoints`): :func:`check_disk_for_run`
estimates what the run's retention keeps at most and compares it with the free space of the run's
disk. A write that still fails for lack of space (another program filled the disk) ends the run
with :class:`~uniros.errors.DiskFullError` (:func:`disk_full_error`): every file is written
atomically, so the run stays as it was at its last complete checkpoint, and resumes from there.
"""

from __future__ import annotations

import errno
import inspect
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from uniros.errors import DiskFullError, TrainingConfigError, TrainingError

# Disk a run writes besides checkpoints (monitor CSVs, TensorBoard events, the plot): a margin.
LOG_MARGIN = 32 * 2**20


def _space_bytes(space: Any, *, cast_float64: bool = False) -> int:
    """Bytes one value of ``space`` takes in an SB3 buffer (a Dict space: the sum of its keys)."""
    from gymnasium import spaces

    if isinstance(space, spaces.Dict):
        return sum(_space_bytes(s, cast_float64=cast_float64) for s in space.spaces.values())
    if isinstance(space, spaces.Discrete):
        size = 1
    elif isinstance(space, spaces.MultiDiscrete):
        size = int(np.prod(space.nvec.shape))
    else:
        size = int(np.prod(space.shape)) if space.shape else 1
    dtype = np.dtype(space.dtype if space.dtype is not None else np.float32)
    if cast_float64 and dtype == np.float64:  # SB3 stores float64 actions as float32
        dtype = np.dtype(np.float32)
    return size * dtype.itemsize


def transition_bytes(observation_space: Any, action_space: Any, *, her: bool = False,
                     optimize_memory_usage: bool = False) -> int:
    """Bytes of one transition in SB3's replay buffer: observation and next observation (one with
    ``optimize_memory_usage``), action, reward, done and timeout (and HER's episode bookkeeping)."""
    obs = _space_bytes(observation_space)
    return (obs * (1 if optimize_memory_usage else 2) + _space_bytes(action_space, cast_float64=True)
            + 3 * 4 + (16 if her else 0))


def buffer_size_of(algorithm_cls: type, params: dict[str, Any]) -> int | None:
    """The ``buffer_size`` a model of ``algorithm_cls`` gets from ``params`` (SB3's default when not
    set); ``None`` for an algorithm without a replay buffer."""
    if "buffer_size" in params:
        return int(params["buffer_size"])
    parameter = inspect.signature(algorithm_cls.__init__).parameters.get("buffer_size")
    if parameter is None or not isinstance(parameter.default, int):
        return None
    return int(parameter.default)


def available_memory() -> int | None:
    """Bytes of memory a new allocation can get without swapping: the kernel's ``MemAvailable``,
    lowered to what a cgroup (container) limit leaves; ``None`` where this cannot be read."""
    found: int | None = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        found = None
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
        if limit.isdigit():
            room = max(0, int(limit) - used)
            found = room if found is None else min(found, room)
    except (OSError, ValueError):
        pass
    return found


def _gb(n: float) -> str:
    return f"{n / 1e9:.1f} GB" if n >= 1e8 else f"{n / 1e6:.1f} MB"


def _image_shapes(space: Any) -> list[str]:
    from gymnasium import spaces

    from uniros.image_spaces import is_image

    items = space.spaces.items() if isinstance(space, spaces.Dict) else [("observation", space)]
    return [f"{key} {'x'.join(str(n) for n in s.shape)}" for key, s in items if is_image(s)]


def check_replay_buffer_memory(config: Any, algorithm_cls: type, params: dict[str, Any], observation_space: Any,
                               action_space: Any, *, her: bool = False, available: int | None = None) -> int | None:
    """Refuse a replay buffer larger than the memory available, before it is allocated.

    ``params``: the algorithm's keyword arguments (``buffer_size``, ``optimize_memory_usage``);
    ``available``: bytes (default :func:`available_memory`). Returns the buffer's bytes (``None``:
    no replay buffer).

    Raises:
        TrainingConfigError: one line naming ``buffer_size``, the per-transition size (the image
            keys when there are any), what the buffer needs and what the machine has.
    """
    size = buffer_size_of(algorithm_cls, params)
    if size is None:
        return None
    per = transition_bytes(observation_space, action_space, her=her,
                           optimize_memory_usage=bool(params.get("optimize_memory_usage", False)))
    needed = size * per
    room = available_memory() if available is None else available
    if room is None or needed <= room:
        return needed
    images = _image_shapes(observation_space)
    fits = room // per
    raise TrainingConfigError(
        f"{config.source}: {config.algorithm}_params.buffer_size {size} x {per:,} bytes a transition"
        + (f" (camera images: {', '.join(images)})" if images else "")
        + f" needs a {_gb(needed)} replay buffer, and this machine has {_gb(room)} of memory available: set "
        f"buffer_size below {fits} (the run then forgets its oldest steps)"
        + (", or lower the camera's width and height" if images else ""))


def checkpoint_disk_bytes(config: Any, per_transition: int | None, model_bytes: int, buffer_size: int | None) -> int:
    """The most disk the run's checkpoints, best and final models take at once under its retention
    (``keep_checkpoints``, ``keep_replay_buffers``), plus the temporary file of the next write and a
    margin for logs. ``per_transition``/``buffer_size`` ``None``: no replay buffer."""
    total = int(config.training_steps)
    freq = int(config.save_freq)
    keep = int(config.keep_checkpoints)
    saves = range(freq, total + 1, freq) if freq > 0 else range(0)
    kept = list(saves[-keep:] if keep else saves)
    if not kept or kept[-1] != total:
        kept = [*kept, total][-keep:] if keep else [*kept, total]  # the checkpoint at the end of the run
    models = (len(kept) + 3) * model_bytes  # + best, final, and the temporary file of the next save
    buffers = 0
    if per_transition and buffer_size:
        with_buffer = kept[-int(config.keep_replay_buffers):] if int(config.keep_replay_buffers) else kept
        largest = min(total, buffer_size) * per_transition  # the next buffer's temporary file
        buffers = sum(min(s, buffer_size) * per_transition for s in with_buffer) + largest
    return models + buffers + LOG_MARGIN


def model_bytes(model: Any) -> int:
    """Bytes of a saved model: its parameters, and an optimizer's two moments per parameter."""
    params = sum(p.numel() * p.element_size() for p in model.policy.parameters())
    return 3 * int(params)


def _folder_bytes(folder: Path) -> int:
    total = 0
    for path in folder.glob("*"):
        if path.is_file() and not path.is_symlink():
            total += path.stat().st_size
    return total


def check_disk_for_run(run_root: Path, config: Any, model: Any, *, free: int | None = None) -> int:
    """Refuse a run whose checkpoints would not fit on the run folder's disk.

    What the run's files already take (a resumed run's checkpoints, which retention replaces) counts
    toward the estimate (:func:`checkpoint_disk_bytes`). Returns the bytes still needed.

    Raises:
        TrainingError: one line with what is needed, what is free, and what to change.
    """
    from uniros.algorithms import is_off_policy

    buffer_size = per = None
    if is_off_policy(config.algorithm) and getattr(model, "replay_buffer", None) is not None:
        buffer_size = int(model.buffer_size)
        her = type(model.replay_buffer).__name__ == "HerReplayBuffer"
        per = transition_bytes(model.observation_space, model.action_space, her=her,
                               optimize_memory_usage=bool(getattr(model, "optimize_memory_usage", False)))
    estimate = checkpoint_disk_bytes(config, per, model_bytes(model), buffer_size)
    already = _folder_bytes(run_root / "checkpoints") + _folder_bytes(run_root)
    needed = max(0, estimate - already)
    room = shutil.disk_usage(run_root).free if free is None else free
    if needed > room:
        raise TrainingError(
            f"{run_root}: the run's checkpoints need about {_gb(needed)} more of disk (keep_checkpoints "
            f"{config.keep_checkpoints}, keep_replay_buffers {config.keep_replay_buffers}"
            + (f", replay buffers of up to {min(config.training_steps, buffer_size or 0)} transitions x {per:,} bytes"
               if per else "")
            + f") and its disk has {_gb(room)} free: free space, keep fewer replay buffers or checkpoints, "
            "lower buffer_size, or train into another --output")
    return needed


def disk_full_error(exc: BaseException, where: Path, then: str | Callable[[], str]) -> DiskFullError | None:
    """A :class:`DiskFullError` for ``exc`` when it (or an exception it came from: torch reports a
    failed write as a ``RuntimeError``) is a full disk or quota, else ``None``. The message says
    what failed, what is free on ``where``'s disk, then ``then`` (the state of the run and what to
    do; a callable is called only for a full disk)."""
    seen: set[int] = set()
    cause: BaseException | None = exc
    while cause is not None and id(cause) not in seen:
        seen.add(id(cause))
        if isinstance(cause, OSError) and cause.errno in (errno.ENOSPC, errno.EDQUOT):
            what = f" writing {cause.filename}" if cause.filename else ""
            try:
                free = f" ({_gb(shutil.disk_usage(where).free)} free now)"
            except OSError:
                free = ""
            error = DiskFullError(f"disk full{what}: {os.strerror(cause.errno)}{free}; "
                                  f"{then() if callable(then) else then}")
            error.errno = cause.errno
            return error
        cause = cause.__cause__ or cause.__context__
    return None


def run_state_after_disk_full(run_root: Path, last_checkpoint: int | None) -> str:
    """What a run that met a full disk is left as, and how to continue it."""
    at = (f"as it was at its last complete checkpoint ({last_checkpoint} steps)" if last_checkpoint is not None
          else "without a checkpoint (a resume starts it again from step 0)")
    return f"the run {run_root} is kept {at}: free space, then continue it with uniros train --resume {run_root}"


__all__ = [
    "LOG_MARGIN",
    "available_memory",
    "buffer_size_of",
    "check_disk_for_run",
    "check_replay_buffer_memory",
    "checkpoint_disk_bytes",
    "disk_full_error",
    "model_bytes",
    "run_state_after_disk_full",
    "transition_bytes",
]
