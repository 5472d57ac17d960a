"""The Niryo Ned2's simulated envs: ``NED2ReacherSim-v0``, ``NED2ReacherGoalSim-v0``,
``NED2PushSim-v0``, ``NED2PushGoalSim-v0``, ``NED2PnPSim-v0`` and ``NED2PnPGoalSim-v0``.

Every arm's tasks with the Ned2's robot layer (:mod:`rl_environments.ned2.robot`) and its task
configs, ``config/ned2_reach_task_config.yaml`` and ``config/ned2_manipulation_task_config.yaml``.
Reach: the robot on the floor, goals in a box 0.15-0.35 m in front of it. Push and pick-and-place:
the robot on a table 0.30 m high, a 2.5 cm, 17 g cube (Niryo's Gripper 1 opens to 40.7 mm), the
description's ``SCENE`` (``rl_environments.robots.ned2_description``).
"""

from __future__ import annotations

from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, ArmGoalReachTask, ArmReachTask
from rl_environments.ned2.robot import NED2RobotEnv, NED2RobotGoalEnv


class NED2ReacherEnv(ArmReachTask, NED2RobotEnv):
    """``NED2ReacherSim-v0``: the NED2 reaches a random point (the task:
    :mod:`rl_environments.arm_reach`; arguments: :class:`~rl_environments.arm_reach.ArmReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS


class NED2ReacherGoalEnv(ArmGoalReachTask, NED2RobotGoalEnv):
    """``NED2ReacherGoalSim-v0``: the goal-conditioned NED2 reach, for HER (the task:
    :mod:`rl_environments.arm_reach`; arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS


class NED2PushEnv(ArmManipulationTask, NED2RobotEnv):
    """``NED2PushSim-v0``: the NED2 pushes a cube to a goal on the table (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "push"


class NED2PushGoalEnv(ArmGoalManipulationTask, NED2RobotGoalEnv):
    """``NED2PushGoalSim-v0``: the goal-conditioned NED2 push, for HER (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "push"


class NED2PnPEnv(ArmManipulationTask, NED2RobotEnv):
    """``NED2PnPSim-v0``: the NED2 picks a cube and places it at a goal, on the table or in the air
    (the task: :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "pnp"


class NED2PnPGoalEnv(ArmGoalManipulationTask, NED2RobotGoalEnv):
    """``NED2PnPGoalSim-v0``: the goal-conditioned NED2 pick-and-place, for HER (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "pnp"
