"""``RX200ReacherReal-v0``: the RX200 reach task on a real RX200 (or a stand-in).

The task is ``RX200ReacherSim-v0``'s, unchanged (:class:`RX200ReachTask`): same action and
observation spaces, rewards and success. Only the robot layer differs: joint states from the
driver, the end effector by forward kinematics, commands through the safety rules to the
``arm_controller`` JointTrajectoryController, one step per control cycle (10 Hz by default). See
``docs/real_robots.md``.
"""

from __future__ import annotations

from typing import Any

from rl_environments.rx200.real.robot_envs.rx200_robot_real import RX200RobotRealEnv
from rl_environments.rx200.sim.task_envs.reach.rx200_reach_sim import RX200ReachTask


class RX200ReacherRealEnv(RX200ReachTask, RX200RobotRealEnv):
    """RX200 reach on a real robot. Task arguments: :class:`RX200ReachTask`; robot and loop knobs:
    :class:`~multiros.envs.real.core.RealEnvCore` and :meth:`RealArmRobot.real_robot_kwargs`."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.apply_task_joint_limits(self.min_joint_pos, self.max_joint_pos)
