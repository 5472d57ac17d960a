"""The ViperX 300 6DOF's simulated envs: ``VX300SReacherSim-v0``, ``VX300SReacherGoalSim-v0``,
``VX300SPushSim-v0``, ``VX300SPushGoalSim-v0``, ``VX300SPnPSim-v0`` and ``VX300SPnPGoalSim-v0``.

Every arm's tasks with the VX300S's robot layer (:mod:`rl_environments.vx300s.robot`) and its task
configs, ``config/vx300s_reach_task_config.yaml`` and ``config/vx300s_manipulation_task_config.yaml``.
Reach: the robot on the floor, goals in a box 0.25-0.55 m in front of it. Push and pick-and-place:
the robot on a table 0.40 m high, a 4 cm, 70 g cube (the Interbotix gripper opens to 75 mm), the
description's ``SCENE`` (``rl_environments.robots.vx300s_description``).
"""

from __future__ import annotations

from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, ArmGoalReachTask, ArmReachTask
from rl_environments.vx300s.robot import VX300SRobotEnv, VX300SRobotGoalEnv


class VX300SReacherEnv(ArmReachTask, VX300SRobotEnv):
    """``VX300SReacherSim-v0``: the VX300S reaches a random point (the task:
    :mod:`rl_environments.arm_reach`; arguments: :class:`~rl_environments.arm_reach.ArmReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS


class VX300SReacherGoalEnv(ArmGoalReachTask, VX300SRobotGoalEnv):
    """``VX300SReacherGoalSim-v0``: the goal-conditioned VX300S reach, for HER (the task:
    :mod:`rl_environments.arm_reach`; arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS


class VX300SPushEnv(ArmManipulationTask, VX300SRobotEnv):
    """``VX300SPushSim-v0``: the VX300S pushes a cube to a goal on the table (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "push"


class VX300SPushGoalEnv(ArmGoalManipulationTask, VX300SRobotGoalEnv):
    """``VX300SPushGoalSim-v0``: the goal-conditioned VX300S push, for HER (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "push"


class VX300SPnPEnv(ArmManipulationTask, VX300SRobotEnv):
    """``VX300SPnPSim-v0``: the VX300S picks a cube and places it at a goal, on the table or in the air
    (the task: :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "pnp"


class VX300SPnPGoalEnv(ArmGoalManipulationTask, VX300SRobotGoalEnv):
    """``VX300SPnPGoalSim-v0``: the goal-conditioned VX300S pick-and-place, for HER (the task:
    :mod:`rl_environments.arm_manipulation`; arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "pnp"
