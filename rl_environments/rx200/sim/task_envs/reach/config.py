"""The RX200 reach task's config (``config/rx200_reach_task_config.yaml``; every arm's schema:
:func:`rl_environments.arm_reach.reach_schema`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, load_reach_config, reach_schema, reach_settings

__all__ = ["REACH_NUM_SIM_STEPS", "RX200_REACH_SCHEMA", "load_rx200_reach_config", "rx200_reach_settings"]

RX200_REACH_SCHEMA = reach_schema(5)
rx200_reach_settings = reach_settings


def load_rx200_reach_config(name: str | Path = "rx200_reach_task_config.yaml") -> dict[str, Any]:
    """Load and check the RX200 reach config (keys under ``rx200:``)."""
    from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200Robot

    return load_reach_config(RX200Robot, name)
