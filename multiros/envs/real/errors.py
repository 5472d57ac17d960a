"""Errors of the real-robot envs. Each names what is wrong and what to do."""

from __future__ import annotations

from multiros.envs.core import EnvError


class RobotConnectionError(EnvError):
    """The robot's ROS 2 interfaces cannot be reached (no joint_states, no controller manager, ...)."""


class StaleStateError(RobotConnectionError):
    """``joint_states`` stopped arriving (or only malformed messages arrive): the env stopped commanding."""


class ControllerNotActiveError(EnvError):
    """A controller the env commands is not loaded or not active in the robot's controller manager."""


class UnsafeCommandError(EnvError, ValueError):
    """A command was refused before it left the process (NaN, infinite, wrong length or out of range)."""


class TrajectoryGoalError(EnvError):
    """The JointTrajectoryController rejected or aborted a FollowJointTrajectory goal."""
