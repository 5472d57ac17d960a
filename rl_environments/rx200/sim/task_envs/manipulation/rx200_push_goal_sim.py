"""``RX200PushGoalSim-v0``: the RX200 goal-conditioned push (HER) on the simulation node.

Scene, spaces, rewards and episode end: :mod:`rl_environments.rx200.sim.task_envs.manipulation.rx200_manipulation`.
"""

from __future__ import annotations

from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotGoalEnv
from rl_environments.rx200.sim.task_envs.manipulation.rx200_manipulation import RX200GoalManipulationTask


class RX200PushGoalEnv(RX200GoalManipulationTask, RX200RobotGoalEnv):
    """``RX200PushGoalSim-v0`` (arguments: :class:`RX200GoalManipulationTask`)."""

    TASK = "push"
