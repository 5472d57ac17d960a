"""The four robot envs of an arm, once for every arm: on the simulation node (plain and goal) and on a
real robot (plain and goal). Each is the one robot layer, :class:`~rl_environments.arm_robot.ArmRobot`,
over an env core; an arm's robot envs are its constants mixed in front of these::

    class UR5eRobotGoalEnv(UR5eRobot, ArmRobotGoalEnv): ...
    class UR5eRobotRealGoalEnv(UR5eRealRobot, ArmRobotRealGoalEnv): ...

The arm's constants class comes first, so its class attributes win; the env core is given the
keyword arguments the constants make of the user's (:meth:`ArmRobot.robot_kwargs
<rl_environments.arm_robot.ArmRobot.robot_kwargs>`, :meth:`ArmRobot.real_robot_kwargs
<rl_environments.arm_robot.ArmRobot.real_robot_kwargs>`): that, and the connection the core builds, is all
that differs between the sides.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from multiros.envs import MujocoBaseEnv, MujocoGoalEnv
from multiros.envs.real import RealBaseEnv, RealGoalEnv
from rl_environments.arm_robot import ArmRobot
from rl_environments.real_arm_kwargs import SETUP_KEY, RealArmSetup

if TYPE_CHECKING:
    from multiros.envs.real.connection import RealConnection
    from multiros.envs.sim_connection import SimConnection


class ArmRobotEnv(ArmRobot, MujocoBaseEnv):
    """An arm's robot layer for plain task envs on the simulation node."""

    connection: SimConnection  # the env core's

    def __init__(self, **kwargs: Any) -> None:
        MujocoBaseEnv.__init__(self, **self.robot_kwargs(kwargs))


class ArmRobotGoalEnv(ArmRobot, MujocoGoalEnv):
    """An arm's robot layer for goal-conditioned task envs on the simulation node."""

    connection: SimConnection  # the env core's

    def __init__(self, **kwargs: Any) -> None:
        MujocoGoalEnv.__init__(self, **self.robot_kwargs(kwargs))


def _real_kwargs(cls: type[ArmRobot], kwargs: dict[str, Any]) -> tuple[dict[str, Any], RealArmSetup]:
    opts = cls.real_robot_kwargs(kwargs)
    return opts, opts.pop(SETUP_KEY)


class ArmRobotRealEnv(ArmRobot, RealBaseEnv):
    """A real arm's robot layer for plain task envs."""

    connection: RealConnection  # the env core's

    def __init__(self, **kwargs: Any) -> None:
        opts, setup = _real_kwargs(type(self), kwargs)
        RealBaseEnv.__init__(self, **opts)
        setup.apply(self.connection)


class ArmRobotRealGoalEnv(ArmRobot, RealGoalEnv):
    """A real arm's robot layer for goal-conditioned task envs."""

    connection: RealConnection  # the env core's

    def __init__(self, **kwargs: Any) -> None:
        opts, setup = _real_kwargs(type(self), kwargs)
        RealGoalEnv.__init__(self, **opts)
        setup.apply(self.connection)
