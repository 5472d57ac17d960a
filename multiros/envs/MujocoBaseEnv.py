"""MultiROS import path: ``from multiros.envs.MujocoBaseEnv import MujocoBaseEnv``."""

from multiros.envs.base_env import MujocoBaseEnv

__all__ = ["MujocoBaseEnv"]
