"""``RX200ReacherSim-v0``: the RX200 reaches a random point; a plain gymnasium env.

## Description
The end effector (``rx200/ee_gripper_link``) must come within ``reach_tolerance`` (2 cm) of a goal
sampled inside the goal box of ``config/rx200_reach_task_config.yaml``, among points the arm can
reach. One env step is one lockstep round trip to the simulation node: 25 physics steps of 4 ms,
100 ms, the control period of MultiROS' RX200 (10 Hz loop, 0.1 s action cycle) and of the Real twin,
long enough for the arm to settle on each 0.05 rad joint target (``num_sim_steps`` changes it).
Episodes start at ``init_joint_pos``, with the end effector at the goal box's centre.

## Action space
``Box(-1, 1, (5,))``: joint deltas, ``target = joints + action * delta_coeff`` (0.05 rad), clipped
to the joint range. ``delta_action=False``: absolute joint targets in ``[min_joint_pos,
max_joint_pos]``. ``ee_action_type=True``: ``Box(-1, 1, (3,))`` end-effector deltas
(``ee_delta_coeff`` metres) solved by damped-least-squares IK.

## Observation space
``Box(float32)`` of 3 + 3 + 1 + 5 + n_action + 5 values: EE position, unit vector EE -> goal,
distance, arm joint positions, previous action, arm joint velocities. Every value lies inside the
declared bounds (EE position and velocities are clipped to them).

## Rewards
``reward_type="dense"`` (default): ``-distance`` (``simple_dense_reward=True``), or the shaped
reward ``+reached_goal_reward`` on success, else ``multiplier_dist_reward * -distance +
step_reward``, plus ``joint_limits_reward`` when a joint target is at a limit.
``reward_type="sparse"``: +1 on success, -1 otherwise.

## Episode end
Terminated on success (``info["is_success"] = True``); truncated after 100 steps (registration).
"""

from __future__ import annotations

from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, ArmReachTask
from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotEnv


class RX200ReachTask(ArmReachTask):
    """The RX200 reach task, plain observation (see the module docstring): every arm's
    (:class:`~rl_environments.arm_reach.ArmReachTask`) with ``config/rx200_reach_task_config.yaml``,
    for the simulated robot env and ``RX200ReacherReal-v0``'s real one. Mix it in before the robot env."""


class RX200ReacherEnv(RX200ReachTask, RX200RobotEnv):
    """``RX200ReacherSim-v0``: the RX200 reach task on the simulation node (arguments: :class:`RX200ReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS
