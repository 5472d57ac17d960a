"""MultiROS import path: ``from multiros.envs.MujocoGoalEnv import MujocoGoalEnv``."""

from multiros.envs.base_env import MujocoGoalEnv

__all__ = ["MujocoGoalEnv"]
