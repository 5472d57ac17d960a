"""CustomTaskEnv: the task layer of a FRobs_RL-style environment (template).

Inherits ``CustomRobotEnv`` and implements FRobs_RL's task hooks. Importing this module registers
``CustomTaskEnv-v0``. Train it as FRobs_RL's example does::

    env = gymnasium.make("CustomTaskEnv-v0")
    env = NormalizeActionWrapper(env)             # multiros.wrappers
    env = NormalizeObservWrapper(env)
    env = TimeLimitWrapper(env, max_steps=100)

Fill in every block between ``# BLANK(<name>)`` and ``# END BLANK``. Use ``self.np_random`` for
randomness; on success set ``self.info["is_success"] = 1.0``.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from .CustomRobotEnv import CustomRobotEnv

ENV_ID = "CustomTaskEnv-v0"
if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point=f"{__name__}:CustomTaskEnv", max_episode_steps=10000)


class CustomTaskEnv(CustomRobotEnv):
    """Custom task env: implements a task with the robot of ``CustomRobotEnv``."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        # BLANK(spaces) ------------------------------------------------------------------------
        # self.action_space = spaces.Box(low=-1, high=1, shape=(n_joints,), dtype=np.float32)
        # self.observation_space = spaces.Box(low=..., high=..., dtype=np.float32)
        self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Box(low=-1.0, high=1.0, shape=(1,), dtype=np.float32)
        # END BLANK ------------------------------------------------------------------------------

    def _set_episode_init_params(self) -> None:
        """Set the episode's initial parameters (robot pose, goal) at each reset."""
        # BLANK(init_params) -------------------------------------------------------------------
        # self.move_to_initial_pose(self.joint_names_arm, [0.0] * len(self.joint_names_arm))
        # self.goal = self.np_random.uniform([0.15, -0.2, 0.1], [0.35, 0.2, 0.35])
        pass
        # END BLANK ------------------------------------------------------------------------------
        if getattr(self, "goal", None) is not None:
            self.show_goal(self.goal, diameter=2 * getattr(self, "tolerance", 0.02))  # the green sphere in videos

    def _send_action(self, action: np.ndarray) -> None:
        """Send an action to the robot."""
        # BLANK(send_action) -------------------------------------------------------------------
        raise NotImplementedError("CustomTaskEnv._send_action: fill in BLANK(send_action)")
        # END BLANK ------------------------------------------------------------------------------

    def _get_observation(self) -> np.ndarray:
        """The observation."""
        # BLANK(get_observation) ---------------------------------------------------------------
        raise NotImplementedError("CustomTaskEnv._get_observation: fill in BLANK(get_observation)")
        # END BLANK ------------------------------------------------------------------------------

    def _get_reward(self) -> float:
        """The reward of the last step."""
        # BLANK(get_reward) --------------------------------------------------------------------
        raise NotImplementedError("CustomTaskEnv._get_reward: fill in BLANK(get_reward)")
        # END BLANK ------------------------------------------------------------------------------

    def _check_if_done(self) -> bool:
        """Whether the episode is done; on success also set ``self.info["is_success"] = 1.0``."""
        # BLANK(check_if_done) -----------------------------------------------------------------
        return False
        # END BLANK ------------------------------------------------------------------------------
