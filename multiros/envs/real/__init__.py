"""Gymnasium environments on real ros2_control robots: RealROS' ``RealBaseEnv`` and ``RealGoalEnv``.

Modules: :mod:`~multiros.envs.real.robot_link` (the robot's standard ROS 2 interfaces),
:mod:`~multiros.envs.real.control_loop` (the real-time loop), :mod:`~multiros.envs.real.safety`
(the rules every command passes), :mod:`~multiros.envs.real.core` and :mod:`~multiros.envs.real.envs`
(the env classes). RealROS import paths work too: ``multiros.envs.RealBaseEnv.RealBaseEnv``.
"""

from multiros.envs.real.control_loop import ControlLoop
from multiros.envs.real.envs import RealBaseEnv, RealGoalEnv
from multiros.envs.real.errors import (
    ControllerNotActiveError,
    RobotConnectionError,
    StaleStateError,
    TrajectoryGoalError,
    UnsafeCommandError,
)
from multiros.envs.real.robot_link import JointSample, JointStateCache, RobotLink
from multiros.envs.real.safety import SafetyDecision, SafetyRules, description_joint_limits

__all__ = [
    "ControlLoop",
    "ControllerNotActiveError",
    "JointSample",
    "JointStateCache",
    "RealBaseEnv",
    "RealGoalEnv",
    "RobotConnectionError",
    "RobotLink",
    "SafetyDecision",
    "SafetyRules",
    "StaleStateError",
    "TrajectoryGoalError",
    "UnsafeCommandError",
    "description_joint_limits",
]
