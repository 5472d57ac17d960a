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
from gymnasium import spaces

from rl_environments.reach import goal_reward, is_success, parse_reward_type
from rl_environments.reach_task import ReachTask
from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotGoalEnv
from rl_environments.rx200.sim.task_envs.reach.config import load_rx200_reach_config


class RX200ReacherGoalEnv(ReachTask, RX200RobotGoalEnv):
    """RX200 reach task, goal-conditioned (see the module docstring).

    Args:
        reward_type: ``"sparse"`` or ``"dense"``.
        delta_action: joint deltas (True) or absolute joint targets.
        ee_action_type: end-effector delta actions through IK.
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

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
        self._setup_reach(
            cfg,
            delta_action=delta_action,
            ee_action_type=ee_action_type,
            delta_coeff=cfg["delta_coeff"],
            ee_delta_coeff=cfg["ee_delta_coeff"],
            tolerance=cfg["reach_tolerance"],
            goal_min=np.asarray(cfg["position_goal_min"]),
            goal_max=np.asarray(cfg["position_goal_max"]),
        )
        self.ee_low = (np.asarray(cfg["position_ee_min"]) + self.base_position).astype(np.float32)
        self.ee_high = (np.asarray(cfg["position_ee_max"]) + self.base_position).astype(np.float32)
        self.max_vel = float(cfg["max_joint_vel"])
        low = np.concatenate([self.ee_low, self.chain.lower, self.action_space.low, -self.max_vel * np.ones(5)])
        high = np.concatenate([self.ee_high, self.chain.upper, self.action_space.high, self.max_vel * np.ones(5)])
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32),
                "achieved_goal": spaces.Box(self.ee_low, self.ee_high, dtype=np.float32),
                "desired_goal": spaces.Box(
                    self.goal_min.astype(np.float32), self.goal_max.astype(np.float32), dtype=np.float32
                ),
            }
        )

    def _get_obs(self) -> dict[str, np.ndarray]:
        # One clip into the declared bounds covers the EE box, joint limits and velocity bounds.
        space = self.observation_space["observation"]
        raw = np.concatenate([self.ee_position(), self.arm_positions(), self.prev_action, self.arm_velocities()])
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
