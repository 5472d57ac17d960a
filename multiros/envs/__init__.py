"""Gymnasium environments on the MuJoCo simulation node.

``MujocoBaseEnv`` (a ``gymnasium.Env``) and ``MujocoGoalEnv`` (a ``gymnasium_robotics.GoalEnv``),
importable under their MultiROS names too: ``multiros.envs.GazeboBaseEnv.GazeboBaseEnv`` and
``multiros.envs.GazeboGoalEnv.GazeboGoalEnv``.

``RealBaseEnv`` and ``RealGoalEnv`` (RealROS' names, :mod:`multiros.envs.real`) drive a real
ros2_control robot with the same hooks; ``multiros.envs.RealBaseEnv.RealBaseEnv`` works too.
"""

from multiros.envs import _third_party  # noqa: F401  (gymnasium_robotics without its AdroitHand notice)
from multiros.envs.base_env import MujocoBaseEnv, MujocoGoalEnv
from multiros.envs.config import SpawnPose, StepConfig
from multiros.envs.core import EnvError, ResetError
from multiros.envs.errors import StepAfterFailedReset
from multiros.envs.real import RealBaseEnv, RealGoalEnv, SafetyRules
from multiros.sim.client import SimulationNodeError

__all__ = [
    "EnvError",
    "MujocoBaseEnv",
    "MujocoGoalEnv",
    "RealBaseEnv",
    "RealGoalEnv",
    "ResetError",
    "SafetyRules",
    "SimulationNodeError",
    "SpawnPose",
    "StepAfterFailedReset",
    "StepConfig",
]
