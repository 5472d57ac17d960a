"""The IRB120 reacher task's config schema (``config/irb120_reacher_task_config.yaml``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rl_environments.task_config import load_task_config, vector

IRB120_REACHER_SCHEMA = {
    "arm_joints": list,
    "min_joint_pos": vector(6),
    "max_joint_pos": vector(6),
    "init_joint_pos": vector(6),
    "max_joint_delta": float,
    "position_goal_min": vector(3),
    "position_goal_max": vector(3),
    "min_goal_height": float,
    "tolerance_goal_pos": float,
    "step_reward": float,
    "multiplier_dist_reward": float,
    "reached_goal_reward": float,
    "joint_limits_reward": float,
}

# End-effector bounds: the flange reaches at most ~0.65 m from the shoulder axis (0.29 m high).
EE_LOW = (-0.75, -0.75, -0.1)
EE_HIGH = (0.75, 0.75, 1.0)


def load_irb120_reacher_config(name: str | Path = "irb120_reacher_task_config.yaml") -> dict[str, Any]:
    """Load and check the IRB120 reacher config (keys under ``irb120:``)."""
    return load_task_config(name, IRB120_REACHER_SCHEMA, section="irb120")


def irb120_reach_settings(cfg: dict[str, Any]) -> dict[str, Any]:
    """``ReachTask._setup_reach`` arguments from an IRB120 reacher config (joint deltas; the goal
    box with ``min_goal_height`` applied)."""
    low = list(cfg["position_goal_min"])
    low[2] = max(low[2], cfg["min_goal_height"])
    return {
        "delta_action": True,
        "ee_action_type": False,
        "delta_coeff": cfg["max_joint_delta"],
        "ee_delta_coeff": 0.0,
        "tolerance": cfg["tolerance_goal_pos"],
        "goal_min": low,
        "goal_max": list(cfg["position_goal_max"]),
    }
