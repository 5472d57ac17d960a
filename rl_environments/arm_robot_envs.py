"""The four robot envs of an arm, once for every arm: on the simulation node (plain and goal) and on a
real robot (plain and goal). An arm's robot envs are its constants mixed in front of these::

    class UR5eRobotGoalEnv(UR5eRobot, ArmRobotGoalEnv): ...
    class UR5eRobotRealGoalEnv(UR5eRealRobot, ArmRobotRealGoalEnv): ...

The arm's constants class comes first, so its class attributes win; the base env is given the
keyword arguments the constants make of the user's (:meth:`ArmRobot.robot_kwargs`,
:meth:`RealArmRobot.real_robot_kwargs`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from multiros.envs import MujocoBaseEnv, MujocoGoalEnv
from multiros.envs.real import RealBaseEnv, RealGoalEnv
from rl_environments.arm_robot import SimArmRobot
from rl_environments.real_arm_robot import RealArmRobot

if TYPE_CHECKING:
    from multiros.envs.real.connection import RealConnection
    from multiros.envs.sim_connection import SimConnection


class ArmRobotEnv(SimArmRobot, MujocoBaseEnv):
    """An arm's robot layer for plain task envs on the simulation node."""

    connection: SimConnection  # the robot layer's and the env core's, one type

    def __init__(self, **kwargs: Any) -> None:
        MujocoBaseEnv.__init__(self, **self.robot_kwargs(kwargs))


class ArmRobotGoalEnv(SimArmRobot, MujocoGoalEnv):
    """An arm's robot layer for goal-conditioned task envs on the simulation node."""

    connection: SimConnection  # the robot layer's and the env core's, one type

    def __init__(self, **kwargs: Any) -> None:
        MujocoGoalEnv.__init__(self, **self.robot_kwargs(kwargs))


class ArmRobotRealEnv(RealArmRobot, RealBaseEnv):
    """A real arm's robot layer for plain task envs."""

    connection: RealConnection  # the robot layer's and the env core's, one type

    def __init__(self, **kwargs: Any) -> None:
        RealBaseEnv.__init__(self, **self._take_base(self.real_robot_kwargs(kwargs)))
        self.serve_frames()


class ArmRobotRealGoalEnv(RealArmRobot, RealGoalEnv):
    """A real arm's robot layer for goal-conditioned task envs."""

    connection: RealConnection  # the robot layer's and the env core's, one type

    def __init__(self, **kwargs: Any) -> None:
        RealGoalEnv.__init__(self, **self._take_base(self.real_robot_kwargs(kwargs)))
        self.serve_frames()
