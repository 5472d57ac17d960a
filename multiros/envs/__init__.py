"""Gymnasium environments on the MuJoCo simulation node.

``MujocoBaseEnv`` (a ``gymnasium.Env``) and ``MujocoGoalEnv`` (a ``gymnasium_robotics.GoalEnv``),
importable under their MultiROS names too: ``multiros.envs.GazeboBaseEnv.GazeboBaseEnv`` and
``multiros.envs.GazeboGoalEnv.GazeboGoalEnv``.
"""

from multiros.envs.base_env import MujocoBaseEnv, MujocoGoalEnv
from multiros.envs.config import SpawnPose, StepConfig
from multiros.envs.core import EnvError, ResetError

__all__ = ["EnvError", "MujocoBaseEnv", "MujocoGoalEnv", "ResetError", "SpawnPose", "StepConfig"]
