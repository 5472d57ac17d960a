"""The RX200 reach task's config schema (``config/rx200_reach_task_config.yaml``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rl_environments.task_config import load_task_config, vector

# Physics steps of 4 ms per env step for the reach envs: a 100 ms control period (MultiROS' RX200 ran
# its loop at 10 Hz with a 0.1 s action cycle; the Real twins' loop is 10 Hz too). The arm then ends
# each step on its joint target (within ~0.005 rad of a 0.05 rad delta, moving < 0.4 rad/s); with
# the robot default of 40 ms it lagged or overshot the target by 20-50 % and was still moving, and
# HER + SAC needed more steps (docs/tasks.md "Learning speed").
REACH_NUM_SIM_STEPS = 25

RX200_REACH_SCHEMA = {
    "arm_joints": list,
    "min_joint_pos": vector(5),
    "max_joint_pos": vector(5),
    "init_joint_pos": vector(5),
    "delta_coeff": float,
    "ee_delta_coeff": float,
    "position_ee_min": vector(3),
    "position_ee_max": vector(3),
    "position_goal_min": vector(3),
    "position_goal_max": vector(3),
    "reach_tolerance": float,
    "step_reward": float,
    "multiplier_dist_reward": float,
    "reached_goal_reward": float,
    "joint_limits_reward": float,
    "max_joint_vel": float,
}


def load_rx200_reach_config(name: str | Path = "rx200_reach_task_config.yaml") -> dict[str, Any]:
    """Load and check the RX200 reach config (keys under ``rx200:``)."""
    return load_task_config(name, RX200_REACH_SCHEMA, section="rx200")


def rx200_reach_settings(cfg: dict[str, Any], *, delta_action: bool, ee_action_type: bool) -> dict[str, Any]:
    """``ReachTask._setup_reach`` arguments from an RX200 reach config."""
    return {
        "delta_action": delta_action,
        "ee_action_type": ee_action_type,
        "delta_coeff": cfg["delta_coeff"],
        "ee_delta_coeff": cfg["ee_delta_coeff"],
        "tolerance": cfg["reach_tolerance"],
        "goal_min": cfg["position_goal_min"],
        "goal_max": cfg["position_goal_max"],
    }
