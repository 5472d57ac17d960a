"""LeRobot over uniros (run by ``.ci/lerobot`` in ``.venv-lerobot``; docs/lerobot.md).

LeRobot 0.4.4 imports torchvision at the top of its dataset and processor modules, and PyPI's only
torchvision for torch 2.13 is the CUDA build, which cannot be imported next to the CPU torch. The
fixture :func:`lerobot_path` puts the stand-in of ``torchvision_stub/`` first on ``sys.path`` (and on
``PYTHONPATH`` for the ``lerobot-eval`` processes the tests start) when the real one does not import.
The tests that need LeRobot skip where it is not installed (the project venv).
"""

from __future__ import annotations

import importlib
import importlib.metadata
import os
import sys
from pathlib import Path

import pytest

STUB = Path(__file__).resolve().parent / "torchvision_stub"


def _real_torchvision_imports() -> bool:
    try:
        import torchvision  # noqa: F401
    except (ImportError, RuntimeError):
        for name in [n for n in sys.modules if n == "torchvision" or n.startswith("torchvision.")]:
            del sys.modules[name]
        return False
    return True


@pytest.fixture(scope="session")
def lerobot_path() -> str:
    """LeRobot importable (the torchvision stand-in first on the path if needed); returns the
    ``PYTHONPATH`` for LeRobot's own processes."""
    # The distribution, not ``import lerobot``: where LeRobot is not installed, this very folder
    # (tests/lerobot, on sys.path through tests/) imports as a namespace package named "lerobot".
    try:
        importlib.metadata.version("lerobot")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("LeRobot is not installed (.ci/lerobot makes .venv-lerobot)")
    if not _real_torchvision_imports() and str(STUB) not in sys.path:
        sys.path.insert(0, str(STUB))
    importlib.import_module("lerobot.envs")  # where LeRobot is installed, a failure here is the test's
    paths = [p for p in (str(STUB) if str(STUB) in sys.path else "", os.environ.get("PYTHONPATH", "")) if p]
    return os.pathsep.join(paths)
