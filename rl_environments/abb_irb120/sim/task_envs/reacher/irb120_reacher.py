"""``ABBIRB120ReacherEnv-v0``: FRobs_RL's IRB120 reacher on the MuJoCo simulation node.

## Description
Move the flange within ``tolerance_goal_pos`` (5 cm) of a goal sampled, among reachable points,
in FRobs_RL's goal box (x, y in [-0.5, 0.5], z in [0, 1] m; here at least ``min_goal_height``
above the floor). Config: ``config/irb120_reacher_task_config.yaml``.

## Action space
``Box(-1, 1, (6,))``: joint deltas, ``target = joints + action * max_joint_delta`` (0.1 rad),
clipped to the joint limits. (FRobs_RL declared the whole joint range as the delta bound and
relied on MoveIt's slow execution; the bounded delta is the lockstep equivalent.)

## Observation space
``Box(12,)``: unit vector from the flange to the goal (3), goal position (3), joint angles (6).

## Rewards (FRobs_RL's)
``+reached_goal_reward`` (10) on success; otherwise ``-multiplier_dist_reward * distance +
step_reward`` (-1.0 * d - 0.01); plus ``joint_limits_reward`` (-5) when a joint target is at a limit.

## Episode end
Terminated on success with ``info["is_success"] = True``; truncated after 100 steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.abb_irb120.sim.robot_envs.irb120_robot_sim import ABBIRB120RobotEnv
from rl_environments.abb_irb120.sim.task_envs.reacher.config import irb120_reach_settings, load_irb120_reacher_config
from rl_environments.reach_task import ReachTask, stack_rows


class IRB120ReachTask(ReachTask):
    """The IRB120 reacher task (see the module docstring), written once for the simulated robot env
    and ``ABBIRB120ReacherRealEnv-v0``'s real one. Mix it in before the robot env.

    Args:
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    def __init__(self, config_file: str = "irb120_reacher_task_config.yaml", **kwargs: Any) -> None:
        cfg = load_irb120_reacher_config(config_file)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **irb120_reach_settings(cfg))
        obs_low = np.concatenate([-np.ones(3), self.goal_min, self.chain.lower])
        obs_high = np.concatenate([np.ones(3), self.goal_max, self.chain.upper])
        self.observation_space = spaces.Box(obs_low.astype(np.float32), obs_high.astype(np.float32), dtype=np.float32)

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """The observations of N envs and their goal distances."""
        _, dist, unit = cls.goals_to(envs, cls.ee_positions_of(envs, states))
        chains = [env.chain for env in envs]
        q = np.clip(cls.arm_positions_of(states), np.array([c.lower for c in chains]),
                    np.array([c.upper for c in chains]))
        obs = np.concatenate([unit, stack_rows(envs, "goal"), q], axis=1)
        spaces_ = [env.observation_space for env in envs]
        low, high = np.array([sp.low for sp in spaces_]), np.array([sp.high for sp in spaces_])
        return np.clip(obs, low, high).astype(np.float32), dist

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        obs, dist = cls.batch_observe(envs, states)
        n = len(envs)
        reward = np.array([env._score(float(dist[j])) for j, env in enumerate(envs)])
        infos = [env.info for env in envs]
        for info in infos:
            info.setdefault("is_success", False)
        done = np.array([float(dist[j]) <= env.tolerance for j, env in enumerate(envs)], dtype=bool)
        return StepResults(obs, reward, done, np.zeros(n, dtype=bool), infos)

    def _score(self, dist: float) -> float:
        """FRobs_RL's reward of a step that left the flange ``dist`` from the goal."""
        self.info["distance"] = dist
        if dist <= self.tolerance:
            self.info["is_success"] = True
            reward = self.cfg["reached_goal_reward"]
        else:
            reward = -self.cfg["multiplier_dist_reward"] * dist + self.cfg["step_reward"]
        if self.at_joint_limits():
            reward += self.cfg["joint_limits_reward"]
        return float(reward)

    # -- the hooks of one env (MultiROS names), through the batch functions -----------------------------
    def _get_obs(self) -> np.ndarray:
        return type(self).batch_observe([self], self.connection.states)[0][0]

    def _get_reward(self) -> float:
        return self._score(float(np.linalg.norm(self.goal - self.ee_position())))

    def _check_if_done(self) -> bool:
        return float(np.linalg.norm(self.goal - self.ee_position())) <= self.tolerance


class ABBIRB120ReacherEnv(IRB120ReachTask, ABBIRB120RobotEnv):
    """``ABBIRB120ReacherEnv-v0``: the IRB120 reacher on the simulation node (arguments: :class:`IRB120ReachTask`)."""
