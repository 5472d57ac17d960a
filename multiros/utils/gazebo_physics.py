"""MultiROS' ``multiros.utils.gazebo_physics`` import path: its functions, defined in
:mod:`multiros.utils.gazebo_core` with the simulation as their first argument."""

from __future__ import annotations

from multiros.utils.gazebo_core import (
    get_gazebo_gravity,
    get_gazebo_max_update_rate,
    get_gazebo_ode_physics,
    get_gazebo_physics_properties,
    get_gazebo_time_step,
    set_gazebo_gravity,
    set_gazebo_max_update_rate,
    set_gazebo_ode_physics,
    set_gazebo_physics_properties,
    set_gazebo_time_step,
)

__all__ = [
    "get_gazebo_gravity", "get_gazebo_max_update_rate", "get_gazebo_ode_physics", "get_gazebo_physics_properties",
    "get_gazebo_time_step", "set_gazebo_gravity", "set_gazebo_max_update_rate", "set_gazebo_ode_physics",
    "set_gazebo_physics_properties", "set_gazebo_time_step",
]
