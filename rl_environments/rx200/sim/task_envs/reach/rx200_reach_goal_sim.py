"""``RX200ReacherGoalSim-v0``: the RX200 reach task as a goal-conditioned env, for HER.

Same robot, actions, goals and tolerance as ``RX200ReacherSim-v0`` (see ``rx200_reach_sim``).

## Observation space
``Dict(observation, achieved_goal, desired_goal)``: ``observation`` holds EE position, arm joint
positions, previous action and arm joint velocities (3 + 5 + n_action + 5); ``achieved_goal`` is the
EE position; ``desired_goal`` the goal. Unlike the original MultiROS env, ``observation`` carries no
goal-dependent values (vector or distance to the goal), which HER relabelling would leave stale.

## Rewards
``reward_type="sparse"`` (default): 0 when within ``reach_tolerance`` of the goal, -1 otherwise
(the Fetch convention); ``"dense"``: ``-distance``. ``compute_reward`` is vectorised for HER.

## Episode end
Terminated on success (``compute_terminated``); truncated after 100 steps (registration).
"""

from __future__ import annotations

from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, ArmGoalReachTask
from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotGoalEnv


class RX200GoalReachTask(ArmGoalReachTask):
    """The RX200 reach task, goal-conditioned (see the module docstring): every arm's
    (:class:`~rl_environments.arm_reach.ArmGoalReachTask`) with ``config/rx200_reach_task_config.yaml``,
    for the simulated robot env and ``RX200ReacherGoalReal-v0``'s real one. Mix it in before the robot env."""


class RX200ReacherGoalEnv(RX200GoalReachTask, RX200RobotGoalEnv):
    """``RX200ReacherGoalSim-v0``: the goal-conditioned RX200 reach on the simulation node
    (arguments: :class:`RX200GoalReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS
