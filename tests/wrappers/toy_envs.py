"""Small gymnasium envs for the wrapper tests (no simulation node)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium_robotics.core import GoalEnv


class BoxEnv(gym.Env):
    """Observation = last action (so the obs stays in bounds); reward 0; never terminates."""

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, low: Any = (-2.0, 0.0, 10.0), high: Any = (4.0, 0.5, 30.0), dtype: Any = np.float64,
                 terminate_at: int | None = None, success: bool | None = None) -> None:
        self.action_space = spaces.Box(np.asarray(low, dtype), np.asarray(high, dtype), dtype=dtype)
        self.observation_space = spaces.Box(np.asarray(low, dtype), np.asarray(high, dtype), dtype=dtype)
        self.received: list[np.ndarray] = []
        self.terminate_at = terminate_at
        self.success = success
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.steps = 0
        return self.observation_space.low.copy(), {"reset_info": 1}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.steps += 1
        action = np.asarray(action)
        self.received.append(action)
        info: dict[str, Any] = {}
        if self.success is not None:
            info["is_success"] = self.success
        terminated = self.terminate_at is not None and self.steps >= self.terminate_at
        return action.astype(self.observation_space.dtype), 0.0, terminated, False, info


class ToyGoalEnv(GoalEnv):
    """A point that moves by its action inside a box; reward -distance or sparse."""

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, threshold: float = 0.05) -> None:
        self.threshold = threshold
        bound = np.array([1.0, 2.0, 0.5], dtype=np.float32)
        goal = spaces.Box(-bound, bound, dtype=np.float32)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(-bound, bound, dtype=np.float32),
            "achieved_goal": goal,
            "desired_goal": goal,
        })
        self.action_space = spaces.Box(-0.1, 0.1, shape=(3,), dtype=np.float32)
        self.pos = np.zeros(3, dtype=np.float32)
        self.goal = np.zeros(3, dtype=np.float32)
        self.bound = bound

    def _obs(self) -> dict[str, np.ndarray]:
        return {"observation": self.pos.copy(), "achieved_goal": self.pos.copy(), "desired_goal": self.goal.copy()}

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        self.pos = np.zeros(3, dtype=np.float32)
        self.goal = self.np_random.uniform(-self.bound / 2, self.bound / 2).astype(np.float32)
        return self._obs(), {"is_success": False}

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        self.pos = np.clip(self.pos + np.asarray(action, dtype=np.float32), -self.bound, self.bound).astype(np.float32)
        obs = self._obs()
        info = {"is_success": bool(self.compute_terminated(obs["achieved_goal"], obs["desired_goal"], {}))}
        reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], info))
        return obs, reward, info["is_success"], False, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return -np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1) < self.threshold

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool) if np.ndim(achieved_goal) > 1 else False
