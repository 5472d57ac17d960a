"""MultiROS import path: ``from multiros.envs.GazeboGoalEnv import GazeboGoalEnv``."""

from multiros.envs.base_env import MujocoGoalEnv

GazeboGoalEnv = MujocoGoalEnv

__all__ = ["GazeboGoalEnv"]
