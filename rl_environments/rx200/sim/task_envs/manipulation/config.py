"""The RX200 manipulation tasks' config (``config/rx200_manipulation_task_config.yaml``; every arm's
schema: :func:`rl_environments.arm_manipulation.manipulation_schema`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rl_environments.arm_manipulation import load_manipulation_config, manipulation_schema

RX200_MANIPULATION_SCHEMA = manipulation_schema(5)


def load_rx200_manipulation_config(name: str | Path = "rx200_manipulation_task_config.yaml") -> dict[str, Any]:
    """Load and check the RX200 push / pick-and-place config (keys under ``rx200:``, the scene's from
    ``rx200_description.SCENE``)."""
    from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200Robot

    return load_manipulation_config(RX200Robot, name)
