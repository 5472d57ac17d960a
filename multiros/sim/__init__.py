"""The MuJoCo simulation side of uniros: world, descriptions, controllers, rendering.

Importing this package picks MuJoCo's headless EGL backend (``MUJOCO_GL=egl``) when the user has
not chosen one and no display exists; MuJoCo reads the variable when it is first imported, so
this must happen before ``import mujoco``.
"""

import os as _os
import sys as _sys


def _default_gl_backend() -> None:
    if _os.environ.get("MUJOCO_GL") or not _sys.platform.startswith("linux"):
        return
    if _os.environ.get("DISPLAY") or _os.environ.get("WAYLAND_DISPLAY"):
        return
    if "mujoco" not in _sys.modules:
        _os.environ["MUJOCO_GL"] = "egl"


_default_gl_backend()

from multiros.sim.errors import (  # noqa: E402
    CommandError,
    ControllerError,
    DescriptionError,
    EntityError,
    PackageNotFoundError,
    RenderError,
    SimError,
    UnstableSimulationError,
)
from multiros.sim.packages import PackageIndex, default_index  # noqa: E402

__all__ = [
    "CommandError",
    "ControllerError",
    "DescriptionError",
    "EntityError",
    "PackageNotFoundError",
    "RenderError",
    "SimError",
    "UnstableSimulationError",
    "PackageIndex",
    "default_index",
    "World",
    "WorldOptions",
    "EntityCategory",
    "ResetScope",
    "RealTimeRunner",
]


def __getattr__(name: str):
    # World and friends import mujoco: load them on first use so that the GL choice above, and
    # light imports such as multiros.sim.errors, stay cheap.
    if name in ("World", "WorldOptions", "EntityCategory", "ResetScope", "RealTimeRunner"):
        from multiros.sim import world

        return getattr(world, name)
    raise AttributeError(f"module 'multiros.sim' has no attribute {name!r}")
