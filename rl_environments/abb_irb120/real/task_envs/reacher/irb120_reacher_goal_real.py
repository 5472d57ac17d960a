"""``ABBIRB120ReacherGoalRealEnv-v0``: the goal-conditioned IRB120 reacher on a real IRB 120.

The task is ``ABBIRB120ReacherGoalEnv-v0``'s, unchanged (:class:`IRB120GoalReachTask`), with equal
spaces, so a model trained in simulation runs here as it is. See ``docs/real_robots.md``.
"""

from __future__ import annotations

from typing import Any

from rl_environments.abb_irb120.real.robot_envs.irb120_robot_real import ABBIRB120RobotRealGoalEnv
from rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher_goal import IRB120GoalReachTask


class ABBIRB120ReacherGoalRealEnv(IRB120GoalReachTask, ABBIRB120RobotRealGoalEnv):
    """Goal-conditioned IRB120 reacher on a real robot. Task arguments: :class:`IRB120GoalReachTask`."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.apply_task_joint_limits(self.min_joint_pos, self.max_joint_pos)
