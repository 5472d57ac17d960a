"""MultiROS import path: ``from multiros.envs.GazeboBaseEnv import GazeboBaseEnv``."""

from multiros.envs.base_env import MujocoBaseEnv

GazeboBaseEnv = MujocoBaseEnv

__all__ = ["GazeboBaseEnv"]
