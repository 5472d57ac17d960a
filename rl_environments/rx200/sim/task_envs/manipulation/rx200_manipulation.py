"""The RX200 push and pick-and-place tasks, plain and goal-conditioned: every arm's
(:mod:`rl_environments.arm_manipulation`) with the RX200's config and scene (the four env modules
only bind them to the simulated robot env and pick push or pick-and-place).

## Scene
The RX200 stands on a table (``package://rx200_description/mjcf/table.xml``, spawned through
SpawnEntity) with a 3 cm, 30 g cube (``mjcf/cube.xml``); both are free MJCF bodies. Each reset
puts the arm at its start pose (gripper 10 cm above the table, pointing down, open), samples the
cube's start (on the table, yawed within 0.3 rad of square to the fingers) and the goal, never
closer than ``min_object_goal_distance`` (8 cm, more than the 5 cm success distance), and sets the
cube there through SetEntityState. Push goals lie on the table; pick-and-place goals are lifted
up to 15 cm with probability 0.5 (Fetch's ``target_in_the_air``).

## Action space
``Box(-1, 1, (4,))`` (default, ``ee_action_type=True``): end-effector deltas ``action[:3] *
ee_delta_coeff`` (2 cm per step) in the base frame, the gripper kept pointing down by closed-form IK,
targets clipped into the workspace box (finger tips at least 2 mm above the table); ``action[3]``
the gripper, -1 closed, +1 open (clipped to ``[-1, 1]``). ``ee_action_type=False``: ``Box(-1, 1,
(6,))``, five joint deltas ``* delta_coeff`` (0.05 rad) and the gripper.

## Observation space
Goal envs: ``Dict(observation=Box(30), achieved_goal=Box(3), desired_goal=Box(3))``. ``observation``
(Fetch's 25 values plus the 5 arm joints): EE position, object position, object minus EE, the two
finger joints, object roll/pitch/yaw, object linear and angular velocity, EE velocity, finger
velocities, arm joints. ``achieved_goal`` is the object's position, ``desired_goal`` the goal. Plain
envs: ``Box(36)``: the same 30 values, the goal, and goal minus object. World frame throughout;
values are clipped into the declared bounds.

## Rewards
``reward_type="sparse"`` (goal envs' default): 0 when the object is within ``distance_threshold``
(5 cm, Fetch's) of the goal, else -1; ``"dense"`` (plain envs' default): ``-distance(object,
goal)``. ``compute_reward`` is vectorised for HER.

## Episode end
50 steps (2 s of simulated time at 40 ms per step), truncated, as Fetch's 50 steps of 40 ms:
the scripted policies finish pushes in about 25 steps and pick-and-place in about 35. Success
does not end the episode (``terminate_on_success=False``, Fetch's convention): ``is_success`` of
the last step says whether the object is *at* the goal, not whether it passed through it. Faults
truncate early with ``info["truncated_reason"]``: ``"object_fell_off_table"``,
``"object_out_of_reach"``, ``"sim_diverged"`` (see :mod:`rl_environments.manipulation_task`).
"""

from __future__ import annotations

from rl_environments.arm_manipulation import EPISODE_STEPS, ArmGoalManipulationTask, ArmManipulationTask

__all__ = ["EPISODE_STEPS", "RX200GoalManipulationTask", "RX200ManipulationTask"]


class RX200ManipulationTask(ArmManipulationTask):
    """RX200 push or pick-and-place as a plain env (``config/rx200_manipulation_task_config.yaml``;
    arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""


class RX200GoalManipulationTask(ArmGoalManipulationTask):
    """RX200 push or pick-and-place as a goal-conditioned env for HER (arguments:
    :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""
