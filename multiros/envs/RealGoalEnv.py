"""RealROS import path: ``from multiros.envs.RealGoalEnv import RealGoalEnv`` (RealROS's ``realros.envs``)."""

from multiros.envs.real.envs import RealGoalEnv

__all__ = ["RealGoalEnv"]
