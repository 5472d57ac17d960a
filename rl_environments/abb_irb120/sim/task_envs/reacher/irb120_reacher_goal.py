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
from gymnasium import spaces

from rl_environments.abb_irb120.sim.robot_envs.irb120_robot_sim import ABBIRB120RobotGoalEnv
from rl_environments.abb_irb120.sim.task_envs.reacher.config import (
    EE_HIGH,
    EE_LOW,
    goal_box,
    load_irb120_reacher_config,
)
from rl_environments.reach import goal_reward, is_success, parse_reward_type
from rl_environments.reach_task import ReachTask


class ABBIRB120ReacherGoalEnv(ReachTask, ABBIRB120RobotGoalEnv):
    """IRB120 reacher, goal-conditioned (see the module docstring).

    Args:
        reward_type: ``"sparse"`` or ``"dense"``.
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs.
    """

    def __init__(
        self, reward_type: str = "sparse", config_file: str = "irb120_reacher_task_config.yaml", **kwargs: Any
    ) -> None:
        cfg = load_irb120_reacher_config(config_file)
        self.reward_type = parse_reward_type(reward_type)
        super().__init__(**kwargs)
        low, high = goal_box(cfg)
        self._setup_reach(
            cfg,
            delta_action=True,
            ee_action_type=False,
            delta_coeff=cfg["max_joint_delta"],
            ee_delta_coeff=0.0,
            tolerance=cfg["tolerance_goal_pos"],
            goal_min=np.asarray(low),
            goal_max=np.asarray(high),
        )
        self.ee_low = (np.asarray(EE_LOW) + self.base_position).astype(np.float32)
        self.ee_high = (np.asarray(EE_HIGH) + self.base_position).astype(np.float32)
        obs_low = np.concatenate([self.ee_low, self.chain.lower, self.action_space.low])
        obs_high = np.concatenate([self.ee_high, self.chain.upper, self.action_space.high])
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(obs_low.astype(np.float32), obs_high.astype(np.float32), dtype=np.float32),
                "achieved_goal": spaces.Box(self.ee_low, self.ee_high, dtype=np.float32),
                "desired_goal": spaces.Box(
                    self.goal_min.astype(np.float32), self.goal_max.astype(np.float32), dtype=np.float32
                ),
            }
        )

    def _get_obs(self) -> dict[str, np.ndarray]:
        # One clip into the declared bounds covers the flange box and the joint limits.
        space = self.observation_space["observation"]
        raw = np.concatenate([self.ee_position(), self.arm_positions(), self.prev_action])
        obs = np.minimum(np.maximum(raw.astype(np.float32), space.low), space.high)
        return {
            "observation": obs,
            "achieved_goal": obs[:3].copy(),
            "desired_goal": self.goal.astype(np.float32),
        }

    def _compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return goal_reward(achieved_goal, desired_goal, self.tolerance, self.reward_type)

    def _is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        return is_success(achieved_goal, desired_goal, self.tolerance)
