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

from typing import Any

import numpy as np

from rl_environments.reach import parse_reward_type
from rl_environments.reach_task import GoalReachTask
from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotGoalEnv
from rl_environments.rx200.sim.task_envs.reach.config import (
    REACH_NUM_SIM_STEPS,
    load_rx200_reach_config,
    rx200_reach_settings,
)


class RX200GoalReachTask(GoalReachTask):
    """The RX200 reach task, goal-conditioned (see the module docstring), written once for the
    simulated robot env and ``RX200ReacherGoalReal-v0``'s real one. Mix it in before the robot env.

    Args:
        reward_type: ``"sparse"`` or ``"dense"``.
        delta_action: joint deltas (True) or absolute joint targets.
        ee_action_type: end-effector delta actions through IK.
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    OBS_PARTS = ("ee_position", "arm_positions", "prev_action", "arm_velocities")

    def __init__(
        self,
        reward_type: str = "sparse",
        delta_action: bool = True,
        ee_action_type: bool = False,
        config_file: str = "rx200_reach_task_config.yaml",
        **kwargs: Any,
    ) -> None:
        cfg = load_rx200_reach_config(config_file)
        self.reward_type = parse_reward_type(reward_type)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **rx200_reach_settings(cfg, delta_action=delta_action, ee_action_type=ee_action_type))
        ee_low = np.asarray(cfg["position_ee_min"]) + self.base_position
        ee_high = np.asarray(cfg["position_ee_max"]) + self.base_position
        vel = cfg["max_joint_vel"] * np.ones(5)
        self._setup_goal_spaces(
            np.concatenate([ee_low, self.chain.lower, self.action_box.low, -vel]),
            np.concatenate([ee_high, self.chain.upper, self.action_box.high, vel]),
        )



class RX200ReacherGoalEnv(RX200GoalReachTask, RX200RobotGoalEnv):
    """``RX200ReacherGoalSim-v0``: the goal-conditioned RX200 reach on the simulation node
    (arguments: :class:`RX200GoalReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS
