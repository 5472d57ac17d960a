"""``ABBIRB120ReacherGoalEnv-v0``: the IRB120 reacher as a goal-conditioned env, for HER.

Same robot, actions, goals and 5 cm tolerance as ``ABBIRB120ReacherEnv-v0``.

## Observation space
``Dict``: ``observation`` = flange position (3), joint angles (6), previous action (6);
``achieved_goal`` = flange position; ``desired_goal`` = goal.

## Rewards
Sparse: 0 within tolerance, -1 otherwise (``reward_type="dense"``: ``-distance``), vectorised.

## Episode end
Terminated on success; truncated after 100 steps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rl_environments.abb_irb120.sim.robot_envs.irb120_robot_sim import ABBIRB120RobotGoalEnv
from rl_environments.abb_irb120.sim.task_envs.reacher.config import (
    EE_HIGH,
    EE_LOW,
    irb120_reach_settings,
    load_irb120_reacher_config,
)
from rl_environments.reach import parse_reward_type
from rl_environments.reach_task import GoalReachTask


class IRB120GoalReachTask(GoalReachTask):
    """The IRB120 reacher, goal-conditioned (see the module docstring), written once for the simulated
    robot env and ``ABBIRB120ReacherGoalRealEnv-v0``'s real one. Mix it in before the robot env.

    Args:
        reward_type: ``"sparse"`` or ``"dense"``.
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs.
    """

    OBS_PARTS = ("ee_position", "arm_positions", "prev_action")

    def __init__(
        self, reward_type: str = "sparse", config_file: str = "irb120_reacher_task_config.yaml", **kwargs: Any
    ) -> None:
        cfg = load_irb120_reacher_config(config_file)
        self.reward_type = parse_reward_type(reward_type)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **irb120_reach_settings(cfg))
        self._setup_goal_spaces(
            np.concatenate([np.asarray(EE_LOW) + self.base_position, self.chain.lower, self.action_box.low]),
            np.concatenate([np.asarray(EE_HIGH) + self.base_position, self.chain.upper, self.action_box.high]),
        )



class ABBIRB120ReacherGoalEnv(IRB120GoalReachTask, ABBIRB120RobotGoalEnv):
    """``ABBIRB120ReacherGoalEnv-v0``: the goal-conditioned IRB120 reacher on the simulation node
    (arguments: :class:`IRB120GoalReachTask`)."""
