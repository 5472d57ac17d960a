"""The constructor keywords of the originals (MultiROS, RealROS, FRobs_RL), in one table for the
simulated and the real envs: which ones are renamed, which mean nothing here (ignored with a note),
and which would start something the env must not start (refused with what to do instead).

:func:`sort_knobs` applies the table to a constructor's extra keywords; each env core calls it once.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["KnobTable", "SIM_KNOBS", "REAL_KNOBS", "SIMULATION_ONLY", "sort_knobs"]

_logger = logging.getLogger(__name__)

# MultiROS / FRobs_RL spellings of the simulated envs' knobs.
_SIM_RENAMES = {
    "robot_model_name": "robot_name",
    "model_name_in_gazebo": "robot_name",
    "num_gazebo_steps": "num_sim_steps",
    "sim_step_mode": "step_mode",
    "gazebo_timestep": "sim_timestep",
    "gazebo_max_update_rate": "real_time_factor",
    "ros_controllers_list": "controllers_list",
    "controller_list": "controllers_list",
    "controller_file": "controllers_file",
    "pkg_name": "urdf_pkg_name",
    "urdf_file": "urdf_file_name",
    "model_pos_x": "robot_pos_x",
    "model_pos_y": "robot_pos_y",
    "model_pos_z": "robot_pos_z",
    "model_ori_w": "robot_ori_w",
    "model_ori_x": "robot_ori_x",
    "model_ori_y": "robot_ori_y",
    "model_ori_z": "robot_ori_z",
}
_NO_ROS_MASTER = "there is no ROS master in ROS 2"
_NO_MASTER_PORT = "there is no ROS master port in ROS 2 (set ROS_DOMAIN_ID / UNIROS_ZENOH_ROUTER)"
# Knobs of the Gazebo originals with no meaning for a MuJoCo simulation node.
_SIM_IGNORED = dict.fromkeys(
    ("launch_gazebo", "gazebo_init_paused", "gazebo_use_gui", "gazebo_port", "gazebo_pid", "kill_gazebo",
     "unpause_pause_physics"), "it configures Gazebo; the MuJoCo simulation node needs no equivalent") | {
    "ros_port": _NO_MASTER_PORT,
    "kill_rosmaster": _NO_ROS_MASTER,
    "clean_logs": "ROS 2 logs are not the env's to clean",
    "new_robot_state_term": "the env opens no terminals",
    "robot_state_publisher_max_freq": "the simulation node publishes the robot's state itself",
    "robot_ref_frame": "frame poses are in the world frame",
    "log_internal_state": "use Python logging (logger 'multiros')",
}
# RealROS / ROS 1 knobs with no meaning for a ROS 2 robot env.
_REAL_IGNORED = {
    "kill_rosmaster": _NO_ROS_MASTER,
    "clean_logs": "ROS 2 logs are not the env's to clean",
    "ros_port": _NO_MASTER_PORT,
    "new_roscore": _NO_ROS_MASTER,
    "roscore_port": _NO_MASTER_PORT,
    "default_port": _NO_MASTER_PORT,
    "new_robot_state_term": "the env opens no terminals",
    "robot_state_publisher_max_freq": "robot_state_publisher belongs to the robot's launch",
    "launch_robot_state_pub": "robot_state_publisher belongs to the robot's launch",
    "controllers_file": "controller parameters come from the robot driver's launch (its controllers YAML)",
    "load_urdf": "the description for limits and kinematics is robot_description= (or the robot env's)",
}
_START_DRIVER = "a Real env does not launch the robot: start its ROS 2 driver yourself"
# Knobs that would start something on the robot side: refused when set, with what to do instead.
_REAL_REFUSED = {
    "load_robot": "start the robot's ROS 2 driver yourself (for an Interbotix arm, its ros2_control driver: "
                  "`ros2 launch interbotix_xsarm_ros_control xsarm_ros_control.launch.py robot_model:=rx200`), "
                  "then make the env",
    "robot_pkg_name": _START_DRIVER,
    "robot_launch_file": _START_DRIVER,
    "robot_args": _START_DRIVER,
}
#: Knobs of the simulated envs that mean nothing to a robot (a Real env ignores them with a warning).
SIMULATION_ONLY = frozenset({
    "sim_mode", "sim_node_name", "gui", "num_sim_steps", "sim_timestep", "real_time_factor", "spawn_robot",
    "floor_color", "robot_model_xml", "reset_mode", "step_mode", "frames", "render_camera", "render_width",
    "render_height", "initial_joint_positions",
})


@dataclass(frozen=True)
class KnobTable:
    """How one env core treats the originals' keywords.

    Attributes:
        renames: old name -> the keyword it means here.
        ignored: name -> why it means nothing here (logged, then dropped).
        refused: name -> what to do instead (a ``ValueError`` when given a true value).
        where: the class whose docstring lists the accepted knobs (for messages).
        warn_ignored: log ignored knobs as warnings (a real robot's user should know) or at debug level.
    """

    renames: Mapping[str, str] = field(default_factory=dict)
    ignored: Mapping[str, str] = field(default_factory=dict)
    refused: Mapping[str, str] = field(default_factory=dict)
    where: str = ""
    warn_ignored: bool = False


SIM_KNOBS = KnobTable(_SIM_RENAMES, _SIM_IGNORED, {}, "multiros.envs.sim_env.MujocoEnvCore")
REAL_KNOBS = KnobTable(
    {"ros_controllers_list": "controllers_list", "controller_list": "controllers_list"},
    {**_REAL_IGNORED, **dict.fromkeys(SIMULATION_ONLY, "it configures the simulation, and a Real env drives a robot")},
    _REAL_REFUSED, "multiros.envs.real.core.RealEnvCore", warn_ignored=True,
)


def sort_knobs(table: KnobTable, owner: str, given: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    """``given`` (the constructor's own keywords) updated with ``extra`` (the rest) as ``table`` says.

    Raises:
        ValueError: a refused knob with a true value.
        TypeError: a keyword nobody knows (the message names where the accepted ones are listed).
    """
    out = dict(given)
    extra = dict(extra)
    for key in list(extra):
        if key in table.refused:
            if extra[key]:
                raise ValueError(f"{owner}: {key}={extra[key]!r} is not supported: {table.refused[key]}")
            extra.pop(key)
        elif key in table.renames:
            out[table.renames[key]] = extra.pop(key)
    unknown = sorted(set(extra) - set(table.ignored))
    if unknown:
        raise TypeError(f"{owner} got unexpected keyword argument(s) {unknown}; see {table.where} for the accepted "
                        "knobs")
    for key, value in extra.items():
        _logger.log(logging.WARNING if table.warn_ignored else logging.DEBUG, "%s ignores %s=%r: %s", owner, key,
                    value, table.ignored[key])
    return out
