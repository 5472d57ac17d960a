"""MyTaskEnv: the task layer of a MultiROS-style environment (template).

Inherits the robot layer (``MyRobotEnv``) and defines the gymnasium contract: spaces, how an
action moves the robot, the observation, the reward and when an episode ends. Importing this
module registers ``MyTaskEnv-v0``; then ``uniros.make("MyTaskEnv-v0")`` (or ``gymnasium.make``).

Fill in every block between ``# BLANK(<name>)`` and ``# END BLANK``. Hook order: ``reset`` runs
``_check_connection_and_readiness`` -> ``_set_init_pose`` -> ``_set_episode_init_params``, then
``_get_obs``; ``step`` runs ``_set_action`` -> physics -> ``_get_obs`` -> ``_get_reward`` ->
``_check_if_done``. Put ``info["is_success"]`` in ``self.info`` when your task has a success notion.

Use ``self.np_random`` (seeded once by ``reset(seed=...)``) for randomness, never ``np.random``.
The observation must stay inside ``observation_space``: give it bounds that really hold.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from .MyRobotEnv import MyRobotEnv

ENV_ID = "MyTaskEnv-v0"
if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point=f"{__name__}:MyTaskEnv", max_episode_steps=100)


class MyTaskEnv(MyRobotEnv):
    """The task. Keyword arguments go to the robot env and the base env (see ``MyRobotEnv``)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        # BLANK(spaces) ------------------------------------------------------------------------
        # Spaces (float32 for SB3) and task parameters. Example for a joint-delta reach task:
        #   n = len(self.arm_joints)
        #   self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        #   high = np.concatenate([np.full(n, np.pi), np.ones(6)]).astype(np.float32)
        #   self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        #   self.goal_low, self.goal_high = np.array([0.15, -0.2, 0.1]), np.array([0.35, 0.2, 0.35])
        #   self.tolerance = 0.02
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        # END BLANK ------------------------------------------------------------------------------

    # -- task-layer hooks -----------------------------------------------------------------------
    def _set_init_pose(self) -> None:
        """Task-side reset: e.g. sample this episode's target with ``self.np_random``."""
        # BLANK(init_pose) ---------------------------------------------------------------------
        # self.goal = self.np_random.uniform(self.goal_low, self.goal_high)
        pass
        # END BLANK ------------------------------------------------------------------------------
        if getattr(self, "goal", None) is not None:
            self.show_goal(self.goal, diameter=2 * getattr(self, "tolerance", 0.02))  # the green sphere in videos

    def _set_action(self, action: np.ndarray) -> None:
        """Turn a (clipped, checked) action into controller commands."""
        # BLANK(set_action) --------------------------------------------------------------------
        # q = self.get_joint_positions() + 0.05 * action
        # self.set_joint_targets(q)
        raise NotImplementedError("MyTaskEnv._set_action: fill in BLANK(set_action)")
        # END BLANK ------------------------------------------------------------------------------

    def _get_obs(self) -> np.ndarray:
        """The observation, from the state cached by the last step (no extra calls)."""
        # BLANK(get_obs) -----------------------------------------------------------------------
        # return np.concatenate([self.get_joint_positions(), self.get_ee_position(), self.goal]).astype(np.float32)
        raise NotImplementedError("MyTaskEnv._get_obs: fill in BLANK(get_obs)")
        # END BLANK ------------------------------------------------------------------------------

    def _get_reward(self) -> float:
        """The reward of the last step (``self.info`` is this step's info dict)."""
        # BLANK(get_reward) --------------------------------------------------------------------
        # distance = float(np.linalg.norm(self.get_ee_position() - self.goal))
        # self.info["is_success"] = distance < self.tolerance
        # return -distance
        raise NotImplementedError("MyTaskEnv._get_reward: fill in BLANK(get_reward)")
        # END BLANK ------------------------------------------------------------------------------

    def _check_if_done(self) -> bool:
        """Whether the episode terminated (time limits are the registration's ``max_episode_steps``)."""
        # BLANK(check_if_done) -----------------------------------------------------------------
        # return bool(self.info.get("is_success", False))
        return False
        # END BLANK ------------------------------------------------------------------------------
