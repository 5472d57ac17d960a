"""MyTaskGoalEnv: the task layer of a goal-conditioned, HER-ready environment (template).

Inherits ``MyRobotGoalEnv``. Observations are dicts with ``observation``, ``achieved_goal`` and
``desired_goal``; ``_compute_reward`` and ``_is_success`` must be **vectorised** (SB3's
``HerReplayBuffer`` calls them with batches of goals, shape ``(batch, goal_dim)``) and **pure**
(read only their arguments: no ROS calls, no markers). Importing this module registers
``MyTaskGoalEnv-v0``.

Fill in every block between ``# BLANK(<name>)`` and ``# END BLANK``. ``info["is_success"]`` is
set on every step from ``_is_success``; the episode terminates on success.
Use ``self.np_random`` for randomness and give the spaces bounds that really hold.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from .MyRobotGoalEnv import MyRobotGoalEnv

ENV_ID = "MyTaskGoalEnv-v0"
if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point=f"{__name__}:MyTaskGoalEnv", max_episode_steps=100)


class MyTaskGoalEnv(MyRobotGoalEnv):
    """The goal-conditioned task. Keyword arguments go to the robot env and the base env."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        # BLANK(spaces) ------------------------------------------------------------------------
        # Example for reaching a 3-D point with joint-delta actions:
        #   n = len(self.arm_joints)
        #   self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        #   goal = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        #   self.observation_space = spaces.Dict({
        #       "observation": spaces.Box(-np.pi, np.pi, shape=(n,), dtype=np.float32),
        #       "achieved_goal": goal, "desired_goal": goal})
        #   self.goal_low, self.goal_high = np.array([0.15, -0.2, 0.1]), np.array([0.35, 0.2, 0.35])
        #   self.tolerance = 0.02
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        goal = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32),
            "achieved_goal": goal,
            "desired_goal": goal,
        })
        self.tolerance = 0.02
        # END BLANK ------------------------------------------------------------------------------

    # -- task-layer hooks -----------------------------------------------------------------------
    def _set_init_pose(self) -> None:
        """Task-side reset: sample this episode's goal with ``self.np_random``."""
        # BLANK(init_pose) ---------------------------------------------------------------------
        # self.goal = self.np_random.uniform(self.goal_low, self.goal_high)
        pass
        # END BLANK ------------------------------------------------------------------------------
        if getattr(self, "goal", None) is not None:
            self.show_goal(self.goal, diameter=2 * self.tolerance)  # the green sphere in videos and RViz

    def _set_action(self, action: np.ndarray) -> None:
        """Turn a (clipped, checked) action into controller commands."""
        # BLANK(set_action) --------------------------------------------------------------------
        # self.set_joint_targets(self.get_joint_positions() + 0.05 * action)
        raise NotImplementedError("MyTaskGoalEnv._set_action: fill in BLANK(set_action)")
        # END BLANK ------------------------------------------------------------------------------

    def _get_obs(self) -> dict[str, np.ndarray]:
        """The observation dict, from the state cached by the last step."""
        # BLANK(get_obs) -----------------------------------------------------------------------
        # return {"observation": self.get_joint_positions().astype(np.float32),
        #         "achieved_goal": self.get_ee_position().astype(np.float32),
        #         "desired_goal": self.goal.astype(np.float32)}
        raise NotImplementedError("MyTaskGoalEnv._get_obs: fill in BLANK(get_obs)")
        # END BLANK ------------------------------------------------------------------------------

    def _compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """Vectorised reward: works on one goal pair and on batches (``axis=-1``)."""
        distance = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        # BLANK(compute_reward) ----------------------------------------------------------------
        # Dense: the negative distance. Sparse: -(distance > self.tolerance).astype(np.float32)
        return -distance
        # END BLANK ------------------------------------------------------------------------------

    def _is_success(self, achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
        """Vectorised success test; also the termination condition."""
        distance = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return distance < self.tolerance
