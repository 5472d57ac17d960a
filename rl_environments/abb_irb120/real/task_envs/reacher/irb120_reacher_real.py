"""``ABBIRB120ReacherRealEnv-v0``: the IRB120 reacher on a real IRB 120 (or a stand-in).

The task is ``ABBIRB120ReacherEnv-v0``'s, unchanged (:class:`IRB120ReachTask`), with equal spaces.
See ``docs/real_robots.md``.
"""

from __future__ import annotations

from typing import Any

from rl_environments.abb_irb120.real.robot_envs.irb120_robot_real import ABBIRB120RobotRealEnv
from rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher import IRB120ReachTask


class ABBIRB120ReacherRealEnv(IRB120ReachTask, ABBIRB120RobotRealEnv):
    """IRB120 reacher on a real robot. Task arguments: :class:`IRB120ReachTask`."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.apply_task_joint_limits(self.min_joint_pos, self.max_joint_pos)
