"""RealROS import path: ``from multiros.envs.RealBaseEnv import RealBaseEnv`` (RealROS's ``realros.envs``)."""

from multiros.envs.real.envs import RealBaseEnv

__all__ = ["RealBaseEnv"]
