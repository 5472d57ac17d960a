"""Exceptions raised by the simulation world, descriptions and controllers.

The node maps each class to a ``simulation_interfaces/Result`` code, so keep the hierarchy flat
and the messages self-explanatory (what is wrong, and what to do).
"""

from __future__ import annotations

__all__ = [
    "SimError",
    "DescriptionError",
    "PackageNotFoundError",
    "EntityError",
    "CommandError",
    "ControllerError",
    "UnstableSimulationError",
    "StepInterruptedError",
    "RenderError",
]


class SimError(Exception):
    """Base class of every error raised by ``multiros.sim``."""


class DescriptionError(SimError):
    """A URDF, xacro or MJCF description (or one of its meshes) cannot be loaded.

    Attributes:
        source: the file (or ``"<string>"``) that failed.
        missing_assets: True when the failure is a missing mesh or package (MISSING_ASSETS).
    """

    def __init__(self, message: str, *, source: str = "<string>", missing_assets: bool = False) -> None:
        super().__init__(message)
        self.source = source
        self.missing_assets = missing_assets


class PackageNotFoundError(DescriptionError, LookupError):
    """A ROS package named by ``package://`` or ``$(find ...)`` is not in the package index."""

    def __init__(self, message: str, *, package: str) -> None:
        super().__init__(message, source=f"package://{package}", missing_assets=True)
        self.package = package


class EntityError(SimError, KeyError):
    """An entity, joint, frame or name is unknown, or a name is already taken."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the plain message
        return str(self.args[0]) if self.args else ""


class CommandError(SimError, ValueError):
    """A command is malformed (wrong length, NaN or infinite values, unknown joint) and was not applied."""


class ControllerError(SimError):
    """A controller operation (load, configure, activate, switch, unload) is not possible."""


class UnstableSimulationError(SimError):
    """Physics diverged (MuJoCo BADQACC/BADQPOS/BADQVEL warning or NaN state).

    The entities named in ``entities`` diverged: each was restored to its last good state at rest,
    or, when it diverged again from its own spawn state, removed from the world (those are also in
    ``removed``). The others completed the call untouched.
    """

    def __init__(self, message: str, *, entities: tuple[str, ...], removed: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.entities = entities
        self.removed = removed


class SpawnRefusedError(SimError):
    """A spawned entity may not share the world: it diverges, overlaps another entity, or would
    fall onto a lighter one. The world is as before the spawn.

    Attributes:
        reason: ``"unstable"``, ``"overlap"`` or ``"landing"``.
    """

    def __init__(self, message: str, *, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


class StepInterruptedError(SimError):
    """A long step call stopped early because the simulation node is shutting down.

    Attributes:
        steps_done: physics steps completed before the stop (they stay done).
    """

    def __init__(self, message: str, *, steps_done: int) -> None:
        super().__init__(message)
        self.steps_done = steps_done


class RenderError(SimError):
    """Offscreen rendering or the viewer is not available (no GL backend, no display)."""
