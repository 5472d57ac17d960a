"""A training run's directory: its layout, its lock, and its record (``run.json``).

Layout (``uniros train``; never overwritten, one directory per run)::

    runs/<name>/
      config.yaml                 the resolved training config
      run.json                    env ID, env kwargs, algorithm, status, steps done, the config it started with
      monitor/                    train.monitor.csv, eval.monitor.csv (SB3 Monitor)
      tensorboard/                TensorBoard events and progress.csv (SB3 logger)
      checkpoints/                <prefix>_<N>_steps.zip, <prefix>_replay_buffer_<N>_steps.pkl,
                                  <prefix>_vecnormalize_<N>_steps.pkl, latest.json (:mod:`uniros.checkpoints`)
      evaluations.csv             steps, train seconds, success rate, mean return, per evaluation
      best_model.zip              the model with the best evaluation (+ .vecnormalize.pkl)
      final_model.zip             the model at the end (+ .vecnormalize.pkl)
      learning_curve.png          success rate and return against env steps
      best_model.mp4              the best model, a few evaluation episodes at real-time speed (final_model.mp4
                                  when no evaluation picked a best model)
      checkpoints/unusable/       checkpoints a resume found unusable (:mod:`uniros.resume`)
      earlier/<n>/                what an attempt wrote before a resume restarted the run from step 0

One process at a time writes a run: :meth:`RunDir.lock` takes an exclusive ``flock`` on
``<run>/.lock`` (released by the kernel when the process ends, however it ends), and a second
``uniros train --resume`` of the same run is refused. Names stay inside the output folder: a run
name is one plain path component.

A run writes, moves and deletes files in its own folder only. A run folder comes from anywhere (a
colleague's copy, an archive), so a symbolic link in it could point those writes elsewhere: the
lock file is opened without following links (a ``.lock`` link to someone's file would get a PID
written into it), and a run holding any symbolic link (a ``checkpoints/`` linked to another run's,
whose files retention would delete) is refused before anything is written
(:func:`symbolic_links`). When a resumed run has no checkpoint to continue from, what its earlier
attempt wrote is moved to ``earlier/<n>/``, never deleted (:meth:`RunDir.set_aside_for_restart`).
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import stat
import time
from pathlib import Path
from typing import Any

from uniros.checkpoints import (
    Checkpoint,
    atomic_write,
    list_checkpoints,
    load_replay_buffer,
    normalizer_path,
    remove_stale_temporaries,
    save_checkpoint,
    save_model_with_stats,
    save_replay_buffer,
    write_json,
)
from uniros.errors import RunDirError

MAX_NAME_LENGTH = 128
_PLAIN_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")
# What a run directory holds before its run.json is written: a start killed then left only these.
_SKELETON = {"monitor", "checkpoints", "tensorboard", "config.yaml", ".lock"}
# Where a restarted run keeps what its earlier attempts wrote (earlier/1, earlier/2, ...).
EARLIER = "earlier"


def check_run_name(name: str) -> str:
    """``name`` if it is one plain directory name (no ``/``, ``..``, absolute path or overlong name).

    Raises:
        RunDirError: the message says what a name may hold.
    """
    if not _PLAIN_NAME.match(name) or len(name) > MAX_NAME_LENGTH:
        raise RunDirError(f"--name {name[:60] + ('...' if len(name) > 60 else '')!r} must be one plain directory "
                          f"name of at most {MAX_NAME_LENGTH} letters, digits, '.', '_', '+' or '-', not starting "
                          "with '.' (the run directory goes inside --output)")
    return name


def _sanitized(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]", "-", text).lstrip(".-") or "run"


# -- the run directory ---------------------------------------------------------------------------
class RunDir:
    """Paths of one run (see the module docstring for the layout)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self._lock_fd: int | None = None
        self.created_here = False  # made by this process (RunDir.create): discard() may remove it

    @classmethod
    def create(cls, parent: str | Path, name: str | None, env_id: str, algorithm: str) -> RunDir:
        """A new run directory ``parent/name`` (default: ``<env id>_<algo>_<timestamp>``), locked by
        this process; never reuses a run's directory.

        A directory a killed start left behind (no ``run.json``, nothing but the empty layout) is
        taken over.

        Raises:
            RunDirError: a bad name, the name is taken (the message says how to continue that run),
                or another process is creating it.
        """
        parent = Path(parent)
        if name is None:
            stamp = time.strftime("%Y%m%d-%H%M%S")
            base = _sanitized(f"{env_id.rpartition(':')[2]}_{algorithm}_{stamp}")[:MAX_NAME_LENGTH - 8]
            name, n = base, 1
            while (parent / name).exists() and not _abandoned_start(parent / name):
                n += 1
                name = f"{base}_{n}"
        check_run_name(name)
        root = parent / name
        if root.is_symlink():
            raise RunDirError(f"{str(root)!r} is a symbolic link (to {os.readlink(root)}): a new run gets a folder "
                              "of its own; pick another --name")
        if root.exists() and not _abandoned_start(root):
            raise RunDirError(_taken_message(root))
        root.mkdir(parents=True, exist_ok=True)
        run = cls(root)
        run.lock()
        run.created_here = True
        if run.meta.exists():  # another process finished creating it between our check and the lock
            run.release()
            raise RunDirError(_taken_message(root))
        for sub in ("monitor", "checkpoints", "tensorboard"):
            (root / sub).mkdir(exist_ok=True)
        remove_stale_temporaries(root)
        return run

    @classmethod
    def open(cls, root: str | Path) -> RunDir:
        """An existing run directory (for ``--resume`` and ``uniros eval``)."""
        run = cls(Path(root))
        if not run.root.is_dir():
            raise RunDirError(f"run directory {str(run.root)!r} not found")
        if not run.config.is_file() or not run.meta.is_file():
            hint = (" (a start that was killed before it wrote run.json: start it again with "
                    f"uniros train ID --name {run.root.name} --output {run.root.parent})") if _abandoned_start(
                run.root) else "; pass the directory `uniros train` printed"
            raise RunDirError(f"{str(run.root)!r} is not a uniros run directory (no config.yaml and run.json){hint}")
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

    # -- one writer at a time --
    def lock(self) -> None:
        """Take the run's lock for this process (kept until :meth:`release` or the process ends).

        Raises:
            RunDirError: another process holds it, its ``.lock`` is a link or not a plain file, or
                the run holds a symbolic link (:func:`symbolic_links`).
        """
        if self._lock_fd is not None:
            return
        try:
            import fcntl
        except ImportError:  # no flock (Windows): one writer is the user's to ensure
            return
        fd = _open_lock_file(self.root / ".lock")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(fd, 64).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise RunDirError(f"run {str(self.root)!r} is in use by another uniros process (pid {holder}): wait "
                              "for it to end, or stop it; two processes writing one run would mix its files") from None
        links = symbolic_links(self.root)
        if links:
            os.close(fd)
            shown = ", ".join(f"{p.relative_to(self.root)} -> {os.readlink(p)}" for p in links[:3])
            more = ", ..." if len(links) > 3 else ""
            raise RunDirError(f"run {str(self.root)!r} holds symbolic links ({shown}{more}): a run writes, moves and "
                              "deletes files in its own folder only, and through a link it "
                              "would change files elsewhere; replace each link by a copy of what it points to, or "
                              "remove it")
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._lock_fd = fd

    def release(self) -> None:
        """Release the lock (the next writer may take it)."""
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # closing the descriptor drops the flock
            self._lock_fd = None

    @property
    def locked(self) -> bool:
        """Whether this object holds the run's lock."""
        return self._lock_fd is not None

    def discard(self) -> None:
        """Remove a run directory this process created (a run refused before it learnt anything)."""
        if not self.created_here:
            return
        self.release()
        shutil.rmtree(self.root, ignore_errors=True)

    def set_aside_for_restart(self) -> Path | None:
        """Move what an earlier attempt wrote (checkpoints, logs, evaluations, models) to
        ``earlier/<n>/``, keeping ``config.yaml``, ``run.json`` and ``checkpoints/unusable/`` in
        place: the run starts again from step 0 under its name, and nothing is deleted.

        Returns:
            the folder it went to, or ``None`` when the attempt wrote nothing.
        """
        assert self.locked, "set_aside_for_restart needs the run's lock"
        moves = [p for p in sorted(self.root.iterdir()) if _written_by_a_run(p.name) and _holds_something(p)]
        if self.checkpoints.is_dir():
            moves += [p for p in sorted(self.checkpoints.iterdir()) if p.name != "unusable" and _holds_something(p)]
        target = None
        if moves:
            earlier = self.root / EARLIER
            earlier.mkdir(exist_ok=True)
            n = 1 + max((int(p.name) for p in earlier.iterdir() if p.name.isdigit()), default=0)
            target = earlier / str(n)
            for path in moves:
                dest = target / path.relative_to(self.root)
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.rename(path, dest)  # a rename within the run: a link would move as a link
        for sub in ("monitor", "checkpoints", "tensorboard"):
            (self.root / sub).mkdir(exist_ok=True)
        return target


#: What a run writes at its top level besides config.yaml and run.json (the layout above); anything else in
#: the folder (notes, an arm file kept beside the run) is the user's, and a restart leaves it where it is.
_RUN_FOLDERS = ("monitor", "tensorboard")
_RUN_FILES = re.compile(r"^(evaluations\.csv|learning_curve\.png|(best|final)_model\.mp4|(best|final)_model\.zip|"
                        r"(best|final)_model\.vecnormalize\.pkl|(best|final)_model\.env\.json|(best|final)_model\.onnx)$")


def _written_by_a_run(name: str) -> bool:
    return name in _RUN_FOLDERS or bool(_RUN_FILES.match(name))


def _holds_something(path: Path) -> bool:
    """A file, or a folder with a file somewhere in it (empty layout folders are not worth keeping)."""
    if path.is_symlink() or not path.is_dir():
        return True
    return any(p.is_file() or p.is_symlink() for p in path.rglob("*"))


def symbolic_links(root: Path) -> list[Path]:
    """Every symbolic link inside ``root`` (folders and files, not followed), sorted."""
    found = []
    for folder, dirs, files in os.walk(root, followlinks=False):
        found += [Path(folder) / name for name in (*dirs, *files) if os.path.islink(os.path.join(folder, name))]
    return sorted(found)


def _open_lock_file(path: Path) -> int:
    """Open (create) a run's lock file without following a link, and only if it is a plain file of
    its own (not another file's hard link, not a FIFO that would block)."""
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(
        os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP or path.is_symlink():
            raise RunDirError(f"{path} is a symbolic link (to {os.readlink(path)}), not the run's lock file: a run "
                              "writes its PID there; remove the link") from None
        raise RunDirError(f"{path}: cannot open the run's lock file ({exc.strerror})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
        os.close(fd)
        what = "not a plain file" if not stat.S_ISREG(info.st_mode) else f"a file with {info.st_nlink} hard links"
        raise RunDirError(f"{path} is {what}, not the run's lock file: a run writes its PID there; remove it")
    return fd


def _abandoned_start(root: Path) -> bool:
    """``root`` is what a killed ``RunDir.create`` left: no ``run.json``, nothing but the empty layout."""
    if not root.is_dir() or (root / "run.json").exists():
        return False
    for path in root.iterdir():
        if path.name.startswith(".tmp"):
            continue
        if path.name not in _SKELETON or (path.is_dir() and any(path.iterdir())):
            return False
    return True


def _taken_message(root: Path) -> str:
    try:
        meta = json.loads((root / "run.json").read_text())
    except (OSError, ValueError):
        meta = {}
    status = meta.get("status")
    if status == "finished":
        return f"run directory {str(root)!r} holds a finished run: pick another --name"
    if status in ("created", "running", "interrupted", "failed"):
        steps = list_checkpoints(root / "checkpoints")
        where = (f"from its checkpoint at {steps[0].steps} steps" if steps
                 else "again from step 0 (it has no checkpoint)")
        return (f"run directory {str(root)!r} holds a run that did not finish ({status}): continue it {where} with "
                f"uniros train --resume {root}, or pick another --name")
    return f"{str(root)!r} exists and is not a run this version of uniros can continue: pick another --name"


__all__ = [
    "EARLIER",
    "Checkpoint",
    "RunDir",
    "RunDirError",
    "atomic_write",
    "check_run_name",
    "load_replay_buffer",
    "normalizer_path",
    "save_checkpoint",
    "save_model_with_stats",
    "save_replay_buffer",
    "symbolic_links",
    "write_json",
]
