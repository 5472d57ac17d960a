"""The MuJoCo simulation side of uniros: world, descriptions, controllers, rendering.

Importing ``multiros`` (which any import of this package does first) picks MuJoCo's headless EGL
backend when the user has not chosen one and no display exists.
"""

from multiros.sim.errors import (
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
