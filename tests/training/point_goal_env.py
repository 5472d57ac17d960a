"""A tiny goal env for training-layer tests (SB3's tests use ``BitFlippingEnv`` the same way): a
point in the plane moves by ``0.1 * action`` towards a goal drawn in ``[-1, 1]^2``; sparse reward,
success within 0.1, 10 steps. Importing this module registers ``UnirosTestPointGoal-v0`` (use it as
``point_goal_env:UnirosTestPointGoal-v0`` with this folder on ``sys.path``)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium_robotics.core import GoalEnv

ENV_ID = "UnirosTestPointGoal-v0"


class PointGoalEnv(GoalEnv):
    """Reach a goal point with velocity actions (vectorised ``compute_reward`` for HER)."""

    def __init__(self, render_mode: str | None = None) -> None:
        box = spaces.Box(-2.0, 2.0, shape=(2,), dtype=np.float32)
        self.observation_space = spaces.Dict({"observation": box, "achieved_goal": box, "desired_goal": box})
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.render_mode = render_mode
        self.point = np.zeros(2, np.float32)
        self.goal = np.zeros(2, np.float32)

    def _obs(self) -> dict[str, np.ndarray]:
        return {"observation": self.point.copy(), "achieved_goal": self.point.copy(), "desired_goal": self.goal.copy()}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        super().reset(seed=seed)
        self.point = np.zeros(2, np.float32)
        self.goal = self.np_random.uniform(-1.0, 1.0, 2).astype(np.float32)
        return self._obs(), {"is_success": False}

    def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict]:
        self.point = np.clip(self.point + 0.1 * np.clip(action, -1, 1), -2, 2).astype(np.float32)
        success = bool(np.linalg.norm(self.point - self.goal) < 0.1)
        info = {"is_success": success}
        return self._obs(), float(self.compute_reward(self.point, self.goal, info)), success, False, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        distance = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return -(distance >= 0.1).astype(np.float32)


if ENV_ID not in gym.registry:
    gym.register(ENV_ID, entry_point=f"{__name__}:PointGoalEnv", max_episode_steps=10)
