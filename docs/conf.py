"""Sphinx configuration of the uniros documentation (Markdown pages through myst-parser).

Build: ``.venv/bin/sphinx-build -W --keep-going -b html docs build/docs`` (what ``.ci/run`` does).
The pages of the registered env IDs (``env_ids/``) are written at build time by ``_ext/env_pages.py``
from gymnasium's registry and the env classes, so they cannot drift from the code.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
os.environ.setdefault("MUJOCO_GL", "egl")  # the env pages build envs; no display needed

project = "uniros"
author = "the uniros authors"
copyright = "the uniros authors, Apache-2.0"  # noqa: A001  (Sphinx's name)

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "env_pages",
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "scripts", "env_ids/_*.md"]

# MyST: anchors for headings so that links such as ros.md#actions resolve; ::: fences for directives.
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

# autodoc + napoleon (the code's docstrings are Google style).
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"show-inheritance": True}
# Overrides without a docstring of their own (step, reset, ...) would show gymnasium's, which is not
# written for this renderer; the page of the base class has the contract.
autodoc_inherit_docstrings = False
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # "Attributes:" as fields: a NamedTuple's fields are not described twice

html_theme = "furo"
html_title = "uniros"
pygments_style = "sphinx"
