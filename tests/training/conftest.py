"""What the training tests that run ``uniros train`` on the tiny goal env (``point_goal_env.py``)
share: its ID, this folder on ``sys.path`` so that the ID's module imports, a run folder laid out by
hand, and ``uniros train --resume`` run in this process.

The folder is a package (``__init__.py``), as tests/real is, so that its modules import these with
``from .conftest import ...``.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from uniros.cli import main as cli_main

#: The folder of ``point_goal_env.py`` (a child process's PYTHONPATH for ``POINT_GOAL_ENV``).
POINT_GOAL_FOLDER = Path(__file__).resolve().parent
#: The tiny goal env's ID: its module is imported from ``POINT_GOAL_FOLDER``.
POINT_GOAL_ENV = "point_goal_env:UnirosTestPointGoal-v0"


@pytest.fixture(scope="module")
def point_goal_env_on_path() -> Iterator[Path]:
    """``POINT_GOAL_FOLDER`` on ``sys.path`` while a module's tests run, taken off after them."""
    folder = str(POINT_GOAL_FOLDER)
    sys.path.insert(0, folder)
    yield POINT_GOAL_FOLDER
    sys.path.remove(folder)


def bare_run_folder(output: Path, name: str) -> Path:
    """``output/name`` with the empty subfolders ``uniros train`` makes first (monitor, checkpoints,
    tensorboard), as a run killed before it wrote anything more leaves it."""
    root = output / name
    for sub in ("monitor", "checkpoints", "tensorboard"):
        (root / sub).mkdir(parents=True)
    return root


def resume(run: Path, capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    """``uniros train --resume run --eval-episodes 0 *args`` in this process: the exit code and what
    it printed (stdout then stderr)."""
    code = cli_main(["train", "--resume", str(run), "--eval-episodes", "0", *args])
    out = capsys.readouterr()
    return code, out.out + out.err
