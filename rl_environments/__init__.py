"""Robots and tasks for uniros, registered as gymnasium IDs on import.

Task envs (two layers each: a robot env and a task env):

=============================  ========================================================================
ID                             entry point
=============================  ========================================================================
``RX200ReacherSim-v0``         ``rl_environments.rx200.sim.task_envs.reach.rx200_reach_sim:RX200ReacherEnv``
``RX200ReacherGoalSim-v0``     ``...reach.rx200_reach_goal_sim:RX200ReacherGoalEnv``
``ABBIRB120ReacherEnv-v0``     ``rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher:ABBIRB120ReacherEnv``
``ABBIRB120ReacherGoalEnv-v0`` ``...reacher.irb120_reacher_goal:ABBIRB120ReacherGoalEnv``
=============================  ========================================================================

All have ``max_episode_steps=100``. Robot description packages (``rx200_description``,
``abb_irb120_description``) live in ``rl_environments.robots``.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

ENV_SPECS: dict[str, str] = {
    "RX200ReacherSim-v0": "rl_environments.rx200.sim.task_envs.reach.rx200_reach_sim:RX200ReacherEnv",
    "RX200ReacherGoalSim-v0": "rl_environments.rx200.sim.task_envs.reach.rx200_reach_goal_sim:RX200ReacherGoalEnv",
    "ABBIRB120ReacherEnv-v0": "rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher:ABBIRB120ReacherEnv",
    "ABBIRB120ReacherGoalEnv-v0": (
        "rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher_goal:ABBIRB120ReacherGoalEnv"
    ),
}
ENV_IDS: tuple[str, ...] = tuple(ENV_SPECS)
GOAL_ENV_IDS: tuple[str, ...] = ("RX200ReacherGoalSim-v0", "ABBIRB120ReacherGoalEnv-v0")
MAX_EPISODE_STEPS = 100


def register_envs() -> None:
    """Register every uniros env ID with gymnasium (idempotent)."""
    for env_id, entry_point in ENV_SPECS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, max_episode_steps=MAX_EPISODE_STEPS)


register_envs()

__all__ = ["ENV_IDS", "ENV_SPECS", "GOAL_ENV_IDS", "register_envs"]
