"""``RX200ReacherGoalReal-v0``: the goal-conditioned RX200 reach on a real RX200 (or a stand-in).

The task is ``RX200ReacherGoalSim-v0``'s, unchanged (:class:`RX200GoalReachTask`): its observation
and action spaces equal the simulated env's, so a model trained on ``RX200ReacherGoalSim-v0`` runs
here as it is (``uniros eval MODEL --env RX200ReacherGoalReal-v0``). See ``docs/real_robots.md``.
"""

from __future__ import annotations

from typing import Any

from rl_environments.rx200.real.robot_envs.rx200_robot_real import RX200RobotRealGoalEnv
from rl_environments.rx200.sim.task_envs.reach.rx200_reach_goal_sim import RX200GoalReachTask


class RX200ReacherGoalRealEnv(RX200GoalReachTask, RX200RobotRealGoalEnv):
    """Goal-conditioned RX200 reach on a real robot. Task arguments: :class:`RX200GoalReachTask`."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.apply_task_joint_limits(self.min_joint_pos, self.max_joint_pos)
