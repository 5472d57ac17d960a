"""The RX200 manipulation tasks' config schema (``config/rx200_manipulation_task_config.yaml``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rl_environments.task_config import load_task_config, vector

RX200_MANIPULATION_SCHEMA = {
    "arm_joints": list,
    "min_joint_pos": vector(5),
    "max_joint_pos": vector(5),
    "robot_height": float,
    "table_center": vector(3),
    "table_top": float,
    "table_half_extents": vector(2),
    "object_half_size": float,
    "init_ee_position": vector(3),
    "delta_coeff": float,
    "ee_delta_coeff": float,
    "position_ee_min": vector(3),
    "position_ee_max": vector(3),
    "gripper_min": float,
    "gripper_max": float,
    "object_xy_min": vector(2),
    "object_xy_max": vector(2),
    "object_yaw_range": float,
    "goal_xy_min": vector(2),
    "goal_xy_max": vector(2),
    "target_in_the_air": float,
    "target_height_max": float,
    "min_object_goal_distance": float,
    "distance_threshold": float,
    "fall_margin": float,
    "max_object_distance": float,
    "max_linear_velocity": float,
    "max_angular_velocity": float,
    "max_joint_vel": float,
}


def load_rx200_manipulation_config(name: str | Path = "rx200_manipulation_task_config.yaml") -> dict[str, Any]:
    """Load and check the RX200 push / pick-and-place config (keys under ``rx200:``)."""
    return load_task_config(name, RX200_MANIPULATION_SCHEMA, section="rx200")
