"""The Universal Robots UR5e's simulated envs: ``UR5eReacherSim-v0``, ``UR5eReacherGoalSim-v0``,
``UR5ePushSim-v0``, ``UR5ePushGoalSim-v0``, ``UR5ePnPSim-v0`` and ``UR5ePnPGoalSim-v0``.

Every arm's tasks with the UR5e's robot layer (:mod:`rl_environments.ur5e.robot`) and its task
configs, ``config/ur5e_reach_task_config.yaml`` and ``config/ur5e_manipulation_task_config.yaml``.
Reach: the robot on the floor, goals in a box 0.30-0.65 m in front of it. Push and pick-and-place:
the robot on a table 0.40 m high, a 5 cm, 140 g cube (the 2F-85-like gripper opens to 85 mm), the
description's ``SCENE`` (``rl_environments.robots.ur5e_description``).
"""

from __future__ import annotations

from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, ArmGoalReachTask, ArmReachTask
from rl_environments.ur5e.robot import UR5eRobotEnv, UR5eRobotGoalEnv


class UR5eReacherEnv(ArmReachTask, UR5eRobotEnv):
    """``UR5eReacherSim-v0``: the UR5e reaches a random point (the task:
    :mod:`rl_environments.arm_reach`; arguments: :class:`~rl_environments.arm_reach.ArmReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS


class UR5eReacherGoalEnv(ArmGoalReachTask, UR5eRobotGoalEnv):
    """``UR5eReacherGoalSim-v0``: the goal-conditioned UR5e reach, for HER (the task:
    :mod:`rl_environments.arm_reach`; arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS


class UR5ePushEnv(ArmManipulationTask, UR5eRobotEnv):
    """``UR5ePushSim-v0``: the UR5e pushes a cube to a goal on the table (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "push"


class UR5ePushGoalEnv(ArmGoalManipulationTask, UR5eRobotGoalEnv):
    """``UR5ePushGoalSim-v0``: the goal-conditioned UR5e push, for HER (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "push"


class UR5ePnPEnv(ArmManipulationTask, UR5eRobotEnv):
    """``UR5ePnPSim-v0``: the UR5e picks a cube and places it at a goal, on the table or in the air
    (the task: :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "pnp"


class UR5ePnPGoalEnv(ArmGoalManipulationTask, UR5eRobotGoalEnv):
    """``UR5ePnPGoalSim-v0``: the goal-conditioned UR5e pick-and-place, for HER (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "pnp"
