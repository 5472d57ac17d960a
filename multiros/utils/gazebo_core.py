"""MultiROS' ``gazebo_core`` / ``gazebo_physics`` names for :mod:`multiros.utils.sim_core`.

Ported code keeps its calls and adds the simulation as the first argument::

    handle = gazebo_core.launch_gazebo(gui=False, paused=True)   # was: ros_port, gz_port, pid = ...
    gazebo_core.pause_gazebo(handle)                             # was: pause_gazebo()
    gazebo_core.gazebo_step(handle, steps=20)                    # was: gazebo_step(20) (a `gz` process)
    gazebo_core.close_gazebo(handle)

Gazebo-only keywords of ``launch_gazebo`` (ROS master ports, xterm, world files, recording, ...)
are accepted and ignored with a debug log; ``max_tries``/``ros_port``/``gazebo_port`` of the other
functions likewise. Functions raise on failure instead of returning ``False``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from multiros.sim.launch import SimulationConnection
from multiros.utils.sim_core import (
    Sim,
    client_of,
    close_sim,
    get_gravity,
    get_physics_properties,
    get_real_time_factor,
    get_time_step,
    launch_sim,
    pause_sim,
    reset_sim,
    set_gravity,
    set_physics_properties,
    set_real_time_factor,
    set_time_step,
    step_sim,
    unpause_sim,
)

_logger = logging.getLogger(__name__)

_IGNORED_LAUNCH_ARGS = frozenset({
    "launch_roscore", "port", "use_sim_time", "extra_gazebo_args", "recording", "debug", "physics", "verbose",
    "output", "respawn_gazebo", "pub_clock_frequency", "server_required", "gui_required", "custom_world_path",
    "custom_world_pkg", "custom_world_name", "launch_new_term",
})
_IGNORED_ARGS = frozenset({"max_tries", "retries", "ros_port", "gazebo_port"})


def _drop(kwargs: dict[str, Any], allowed: frozenset[str], fn: str) -> None:
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        raise TypeError(f"{fn}() got unexpected keyword argument(s) {unknown}")
    if kwargs:
        _logger.debug("%s: ignoring Gazebo-only arguments %s", fn, sorted(kwargs))


def launch_gazebo(
    paused: bool = False,
    gui: bool = False,
    *,
    mode: str = "composed",
    real_time_factor: float = 1.0,
    timestep: float | None = None,
    node_name: str = "mujoco_sim",
    transport: str | None = None,
    timeout_sec: float = 10.0,
    **gazebo_only: Any,
) -> SimulationConnection:
    """MultiROS' ``launch_gazebo``: start a simulation node; see :func:`multiros.utils.sim_core.launch_sim`.

    ``paused`` defaults to ``False`` as in MultiROS (the sim plays in real time until paused);
    envs in lockstep mode pause it themselves.
    """
    _drop(gazebo_only, _IGNORED_LAUNCH_ARGS, "launch_gazebo")
    return launch_sim(mode, node_name=node_name, gui=gui, paused=paused, real_time_factor=real_time_factor,
                      timestep=timestep, transport=transport, timeout_sec=timeout_sec)


def close_gazebo(handle: SimulationConnection, **legacy: Any) -> bool:
    """MultiROS' ``close_gazebo(process)``: stop what :func:`launch_gazebo` started."""
    _drop(legacy, _IGNORED_ARGS, "close_gazebo")
    return close_sim(handle)


def pause_gazebo(sim: Sim, **legacy: Any) -> None:
    """Pause physics."""
    _drop(legacy, _IGNORED_ARGS, "pause_gazebo")
    pause_sim(sim)


def unpause_gazebo(sim: Sim, **legacy: Any) -> None:
    """Play physics in real time."""
    _drop(legacy, _IGNORED_ARGS, "unpause_gazebo")
    unpause_sim(sim)


def reset_gazebo(sim: Sim, reset_type: str = "simulation", **legacy: Any) -> None:
    """``"simulation"`` (state and time, MultiROS' default) or ``"world"`` (state only)."""
    _drop(legacy, _IGNORED_ARGS, "reset_gazebo")
    reset_sim(sim, reset_type)  # type: ignore[arg-type]


def gazebo_step(sim: Sim, steps: int = 1, **legacy: Any) -> None:
    """Advance a paused simulation by ``steps`` physics steps."""
    _drop(legacy, _IGNORED_ARGS, "gazebo_step")
    step_sim(sim, steps)


# gazebo_physics names
def get_gazebo_physics_properties(sim: Sim) -> dict[str, Any]:
    """``{"time_step", "real_time_factor", "gravity"}`` of the node."""
    return get_physics_properties(sim)


def set_gazebo_physics_properties(
    sim: Sim, time_step: float | None = None, max_update_rate: float | None = None,
    gravity: Sequence[float] | None = None,
) -> None:
    """Set time step, real-time factor (MultiROS passed it as ``max_update_rate``) and gravity."""
    set_physics_properties(sim, time_step=time_step, real_time_factor=max_update_rate, gravity=gravity)


def set_gazebo_max_update_rate(sim: Sim, real_time_factor: float) -> None:
    """Despite the name, a real-time factor (as in MultiROS): 1 = real time, n = n times faster."""
    set_real_time_factor(sim, real_time_factor)


def get_gazebo_max_update_rate(sim: Sim) -> float:
    """The real-time factor (see :func:`set_gazebo_max_update_rate`)."""
    return get_real_time_factor(sim)


set_gazebo_time_step = set_time_step
get_gazebo_time_step = get_time_step
set_gazebo_gravity = set_gravity
get_gazebo_gravity = get_gravity
# FRobs_RL (ros_gazebo) spellings
gazebo_pause_physics = pause_gazebo
gazebo_unpause_physics = unpause_gazebo
gazebo_step_physics = gazebo_step
gazebo_set_max_update_rate = set_gazebo_max_update_rate
gazebo_get_max_update_rate = get_gazebo_max_update_rate
gazebo_set_time_step = set_time_step
gazebo_get_time_step = get_time_step


def gazebo_set_gravity(sim: Sim, x: float = 0.0, y: float = 0.0, z: float = -9.81) -> None:
    """FRobs_RL's ``gazebo_set_gravity(x, y, z)``."""
    set_gravity(sim, (x, y, z))


gazebo_get_gravity = get_gravity
close_Gazebo = close_gazebo  # noqa: N816 - FRobs_RL's name (it takes the handle launch_Gazebo returns)


def launch_Gazebo(paused: bool = False, use_sim_time: bool = True, gui: bool = False,  # noqa: N802 - FRobs_RL's
                  **kwargs: Any) -> SimulationConnection:
    """FRobs_RL's ``launch_Gazebo(paused, use_sim_time, gui, ...)``, its positional order kept:
    :func:`launch_gazebo`. ``gui`` defaults to ``False`` here (FRobs_RL: ``True``): the viewer needs a
    display; ``use_sim_time`` is always so (the node publishes ``/clock``)."""
    return launch_gazebo(paused, gui, **kwargs)


def gazebo_set_default_properties(sim: Sim) -> None:
    """FRobs_RL's defaults: time step 1 ms, real time, gravity (0, 0, -9.81); its ODE settings have no
    MuJoCo counterpart (see :func:`set_gazebo_ode_physics`)."""
    set_physics_properties(sim, time_step=0.001, real_time_factor=1.0, gravity=(0.0, 0.0, -9.81))


def set_gazebo_ode_physics(sim: Sim, *ode_config: Any, **ode_settings: Any) -> None:
    """Gazebo's ODE solver settings: MuJoCo has none of them, so the call changes nothing (a warning
    says so). MuJoCo's solver is the model's ``<option>`` (``solver``, ``iterations``, ``tolerance``),
    set in the world MJCF; the time step, speed and gravity are :func:`set_gazebo_physics_properties`'s."""
    _logger.warning("set_gazebo_ode_physics: Gazebo's ODE solver settings have no MuJoCo counterpart; nothing "
                    "was changed (MuJoCo's solver options are the world model's <option>)")


def get_gazebo_ode_physics(sim: Sim) -> dict[str, Any]:
    """Refused: MuJoCo has no ODE solver settings to read (see :func:`set_gazebo_ode_physics`).

    Raises:
        NotImplementedError: always, naming what to read instead.
    """
    raise NotImplementedError("get_gazebo_ode_physics: MuJoCo has no ODE solver settings; read the time step, "
                              "speed and gravity with get_gazebo_physics_properties(sim)")


gazebo_set_ODE_physics = set_gazebo_ode_physics  # noqa: N816 - FRobs_RL's name
gazebo_get_ODE_physics = get_gazebo_ode_physics  # noqa: N816 - FRobs_RL's name


def gazebo_delete_model(sim: Sim, model_name: str, **legacy: Any) -> None:
    """Delete an entity (a spawned robot or object) from the simulation."""
    _drop(legacy, _IGNORED_ARGS, "gazebo_delete_model")
    client_of(sim).delete_entity(model_name)


def gazebo_reset_world(sim: Sim, **legacy: Any) -> None:
    """FRobs_RL: reset state, keep time."""
    reset_gazebo(sim, "world", **legacy)


def gazebo_reset_sim(sim: Sim, **legacy: Any) -> None:
    """FRobs_RL: reset state and time."""
    reset_gazebo(sim, "simulation", **legacy)


__all__ = [
    "launch_gazebo", "close_gazebo", "pause_gazebo", "unpause_gazebo", "reset_gazebo", "gazebo_step",
    "get_gazebo_physics_properties", "set_gazebo_physics_properties", "set_gazebo_max_update_rate",
    "get_gazebo_max_update_rate", "set_gazebo_time_step", "get_gazebo_time_step", "set_gazebo_gravity",
    "get_gazebo_gravity", "gazebo_pause_physics", "gazebo_unpause_physics", "gazebo_step_physics",
    "gazebo_set_max_update_rate", "gazebo_get_max_update_rate", "gazebo_set_time_step", "gazebo_get_time_step",
    "gazebo_set_gravity", "gazebo_get_gravity", "gazebo_reset_world", "gazebo_reset_sim", "launch_Gazebo",
    "close_Gazebo", "gazebo_set_default_properties", "set_gazebo_ode_physics", "get_gazebo_ode_physics",
    "gazebo_set_ODE_physics", "gazebo_get_ODE_physics", "gazebo_delete_model", "launch_sim", "close_sim", "pause_sim",
    "unpause_sim", "reset_sim", "step_sim", "set_gravity", "get_gravity", "get_physics_properties",
    "set_physics_properties",
]
