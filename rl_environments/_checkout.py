"""Running from a source checkout: map ``config/`` to ``rl_environments.config`` as an install does.

The installed distribution maps the top-level ``config/`` directory into the package
(``[tool.setuptools.package-dir]``). When the repository root is on ``sys.path`` (scripts and
notebooks run from the checkout) the checkout's ``rl_environments`` shadows the installed one and
has no ``config`` subpackage; this registers the checkout's ``config/`` under that name.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path


def map_checkout_package(name: str, directory: Path) -> None:
    """Make ``name`` (e.g. ``rl_environments.config``) import from ``directory`` when it is not a
    subdirectory of its parent package already (only in a checkout; an install has it in place)."""
    parent_name, _, child = name.rpartition(".")
    parent = sys.modules[parent_name]
    if name in sys.modules or any((Path(p) / child).is_dir() for p in parent.__path__):
        return
    init = directory / "__init__.py"
    if not init.is_file():
        return
    spec = importlib.util.spec_from_file_location(name, init, submodule_search_locations=[str(directory)])
    if spec is None or spec.loader is None:
        return
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    setattr(parent, child, module)
