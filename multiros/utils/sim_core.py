"""Start, stop, pause, reset and step a simulation node, and change its physics.

The verbs of MultiROS' ``gazebo_core``/``gazebo_physics`` and FRobs_RL's ``ros_gazebo`` for the
MuJoCo simulation node, with two differences: every function takes the simulation explicitly (a
:class:`~multiros.sim.client.SimulationClient`, or the :class:`~multiros.sim.launch.SimulationConnection`
that :func:`launch_sim` returns), so two simulations in one process never mix; and failures raise
(:class:`~multiros.sim.client.SimulationNodeError` when the node does not answer in time,
:class:`~multiros.sim.client.SimulationServiceError` when it refuses) instead of returning ``False``.

:mod:`multiros.utils.gazebo_core` holds the same functions under their MultiROS names.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any, Literal

from multiros.sim.client import SimulationClient
from multiros.sim.launch import SimulationConnection, connect

_logger = logging.getLogger(__name__)

Sim = SimulationClient | SimulationConnection
"""What the functions below accept: a client, or the handle :func:`launch_sim` returns."""

# simulation_interfaces/srv/ResetSimulation scope bits.
SCOPE_TIME, SCOPE_STATE = 1, 2


def client_of(sim: Sim) -> SimulationClient:
    """The :class:`SimulationClient` of ``sim`` (a client, or a handle with a ``client``).

    Raises:
        TypeError: ``sim`` is neither.
    """
    if isinstance(sim, SimulationClient):
        return sim
    client = getattr(sim, "client", None)
    if client is None:
        raise TypeError(
            f"expected a SimulationClient or the handle launch_sim() returns, got {type(sim).__name__}; "
            "pass the simulation explicitly (there is no global simulation)"
        )
    return client


# -- start and stop ------------------------------------------------------------------------------
def launch_sim(
    mode: Literal["composed", "process"] = "composed",
    *,
    node_name: str = "mujoco_sim",
    gui: bool = False,
    paused: bool = True,
    real_time_factor: float = 1.0,
    timestep: float | None = None,
    transport: str | None = None,
    timeout_sec: float = 10.0,
) -> SimulationConnection:
    """Start a simulation node and return a handle to it.

    Args:
        mode: ``"composed"`` (in this process, in-process transport: the fast default) or
            ``"process"`` (a child process over Zenoh, stopped by PID on :func:`close_sim`).
        node_name: the node's name.
        gui: open the MuJoCo viewer (needs a display).
        paused: start paused (lockstep stepping) instead of playing in real time.
        real_time_factor: playing speed (1.0 = wall clock, <= 0 = as fast as possible).
        timestep: physics time step in seconds (``None``: the node's default).
        transport: ``"inproc"`` or ``"zenoh"`` (default: inproc when composed, zenoh otherwise).
        timeout_sec: how long to wait for a child process to answer, and the default timeout of
            every later call through the handle's client.

    Returns:
        A :class:`~multiros.sim.launch.SimulationConnection`: ``.client``, ``.node``, ``.pid``, ``.close()``.
        Pass it (or its ``client``) to the other functions; close it with :func:`close_sim`.

    Raises:
        ValueError: an unknown mode or a mode/transport mismatch.
        SimulationNodeError: a child process did not become ready within ``timeout_sec``.
    """
    if mode not in ("composed", "process"):
        raise ValueError(f"launch mode {mode!r} is not 'composed' or 'process' (use connect() for a running node)")
    return connect(mode, node_name=node_name, transport=transport, gui=gui, timeout_sec=timeout_sec,
                   paused=paused, real_time_factor=real_time_factor, timestep=timestep)


def close_sim(handle: SimulationConnection) -> bool:
    """Stop what :func:`launch_sim` started (composed node or child process, by PID). Idempotent.

    Returns:
        ``True`` (MultiROS' ``close_gazebo`` returned a success flag).
    """
    if not isinstance(handle, SimulationConnection):
        raise TypeError(f"close_sim() needs the handle launch_sim() returned, got {type(handle).__name__}")
    handle.close()
    return True


# -- play, pause, reset, step ----------------------------------------------------------------------
def pause_sim(sim: Sim) -> None:
    """Pause physics (already paused is fine)."""
    client_of(sim).pause()


def unpause_sim(sim: Sim) -> None:
    """Let physics run in real time at the node's real-time factor (already playing is fine)."""
    client_of(sim).unpause()


def reset_sim(sim: Sim, reset_type: Literal["world", "simulation"] = "simulation") -> None:
    """Reset the simulation.

    Args:
        reset_type: ``"world"`` resets poses and velocities and keeps simulation time running
            (Gazebo's ``reset_world``); ``"simulation"`` also rewinds time to 0 (``reset_simulation``).
            Spawned entities stay in both cases.

    Raises:
        ValueError: another ``reset_type``.
    """
    if reset_type == "world":
        scope = SCOPE_STATE
    elif reset_type == "simulation":
        scope = SCOPE_STATE | SCOPE_TIME
    else:
        raise ValueError(f"reset_type {reset_type!r} is not 'world' or 'simulation'")
    client_of(sim).reset_simulation(scope)


def step_sim(sim: Sim, steps: int = 1) -> None:
    """Advance a paused simulation by ``steps`` physics steps (one service call, no CLI process).

    Raises:
        ValueError: ``steps`` is not a positive integer.
    """
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    client_of(sim).step_simulation(steps)


# -- physics properties ----------------------------------------------------------------------------
def get_physics_properties(sim: Sim) -> dict[str, Any]:
    """``{"time_step": s, "real_time_factor": f, "gravity": (x, y, z)}``."""
    return client_of(sim).get_physics_properties()


def set_physics_properties(
    sim: Sim,
    *,
    time_step: float | None = None,
    real_time_factor: float | None = None,
    gravity: Sequence[float] | None = None,
) -> None:
    """Change any of the time step, real-time factor and gravity (``None`` keeps a value)."""
    if time_step is not None and not time_step > 0:
        raise ValueError(f"time_step must be > 0 seconds, got {time_step!r}")
    if gravity is not None and len(gravity) != 3:
        raise ValueError(f"gravity must be (x, y, z), got {gravity!r}")
    client_of(sim).set_physics_properties(time_step=time_step, real_time_factor=real_time_factor, gravity=gravity)


def get_time_step(sim: Sim) -> float:
    """The physics time step in seconds."""
    return float(get_physics_properties(sim)["time_step"])


def set_time_step(sim: Sim, time_step: float) -> None:
    """Change the physics time step (the real-time factor is kept, as in FRobs_RL)."""
    set_physics_properties(sim, time_step=time_step)


def get_real_time_factor(sim: Sim) -> float:
    """The real-time factor of playing mode (1.0 = wall clock)."""
    return float(get_physics_properties(sim)["real_time_factor"])


def set_real_time_factor(sim: Sim, real_time_factor: float) -> None:
    """Speed of playing mode: 1.0 = wall clock, 2.0 = twice as fast, <= 0 = as fast as possible.

    Lockstep stepping (the envs' default) is not paced by it at all.
    """
    set_physics_properties(sim, real_time_factor=real_time_factor)


def get_gravity(sim: Sim) -> tuple[float, float, float]:
    """Gravity ``(x, y, z)`` in m/s^2."""
    return tuple(get_physics_properties(sim)["gravity"])  # type: ignore[return-value]


def set_gravity(sim: Sim, gravity: Sequence[float] = (0.0, 0.0, -9.81)) -> None:
    """Set gravity ``(x, y, z)`` in m/s^2."""
    set_physics_properties(sim, gravity=gravity)


__all__ = [
    "Sim", "client_of", "launch_sim", "close_sim", "pause_sim", "unpause_sim", "reset_sim", "step_sim",
    "get_physics_properties", "set_physics_properties", "get_time_step", "set_time_step",
    "get_real_time_factor", "set_real_time_factor", "get_gravity", "set_gravity",
]
