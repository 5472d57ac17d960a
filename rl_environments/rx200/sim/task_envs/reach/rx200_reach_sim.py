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

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.reach import goal_reward, parse_reward_type
from rl_environments.reach_task import ReachTask, stack_rows
from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotEnv
from rl_environments.rx200.sim.task_envs.reach.config import (
    REACH_NUM_SIM_STEPS,
    load_rx200_reach_config,
    rx200_reach_settings,
)


class RX200ReachTask(ReachTask):
    """The RX200 reach task, plain observation (see the module docstring), written once for every
    robot layer that provides :class:`~rl_environments.arm_interface.ArmInterface` (this simulated
    one and ``RX200ReacherReal-v0``'s real one). Mix it in before the robot env.

    Args:
        reward_type: ``"dense"`` or ``"sparse"``.
        delta_action: joint deltas (True) or absolute joint targets.
        ee_action_type: end-effector delta actions through IK.
        simple_dense_reward: ``-distance`` (True) or the shaped reward of the original task.
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    def __init__(
        self,
        reward_type: str = "dense",
        delta_action: bool = True,
        ee_action_type: bool = False,
        simple_dense_reward: bool = True,
        config_file: str = "rx200_reach_task_config.yaml",
        **kwargs: Any,
    ) -> None:
        cfg = load_rx200_reach_config(config_file)
        self.reward_type = parse_reward_type(reward_type)
        self.simple_dense_reward = bool(simple_dense_reward)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **rx200_reach_settings(cfg, delta_action=delta_action, ee_action_type=ee_action_type))
        self.ee_low = np.asarray(cfg["position_ee_min"]) + self.base_position
        self.ee_high = np.asarray(cfg["position_ee_max"]) + self.base_position
        self.max_vel = float(cfg["max_joint_vel"])
        n_act = self.action_box.shape[0]
        q_low, q_high = self.chain.lower, self.chain.upper
        max_dist = float(np.linalg.norm(self.ee_high - self.ee_low))
        low = np.concatenate(
            [self.ee_low, -np.ones(3), [0.0], q_low, self.action_box.low, -self.max_vel * np.ones(5)]
        )
        high = np.concatenate([self.ee_high, np.ones(3), [max_dist], q_high, self.action_box.high,
                               self.max_vel * np.ones(5)])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        assert len(low) == 12 + n_act + 5

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The observations of N envs, their end effectors and their goal distances."""
        ee_raw = cls.ee_positions_of(envs, states)
        ee = np.clip(ee_raw, stack_rows(envs, "ee_low"), stack_rows(envs, "ee_high"))
        _, dist, unit = cls.goals_to(envs, ee_raw)
        chains = [env.chain for env in envs]
        q = np.clip(cls.arm_positions_of(states), np.array([c.lower for c in chains]),
                    np.array([c.upper for c in chains]))
        max_vel = stack_rows(envs, "max_vel")[:, None]
        qd = np.clip(cls.arm_velocities_of(states), -max_vel, max_vel)
        obs = np.concatenate([ee, unit, dist[:, None], q, stack_rows(envs, "prev_action"), qd], axis=1)
        spaces_ = [env.observation_space for env in envs]
        low, high = np.array([sp.low for sp in spaces_]), np.array([sp.high for sp in spaces_])
        return np.clip(obs, low, high).astype(np.float32), ee_raw, dist

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        obs, ee, dist = cls.batch_observe(envs, states)
        n = len(envs)
        reward, done = np.zeros(n), np.zeros(n, dtype=bool)
        for j, env in enumerate(envs):
            reward[j], done[j] = env._score(float(dist[j]), ee[j])
        infos = [env.info for env in envs]
        for info in infos:
            info.setdefault("is_success", False)
        return StepResults(obs, reward, done, np.zeros(n, dtype=bool), infos)

    def _score(self, dist: float, ee: np.ndarray) -> tuple[float, bool]:
        """Reward and termination of a step that left the end effector at ``ee``, ``dist`` from the goal."""
        reached = dist <= self.tolerance
        self.info["is_success"] = reached
        self.info["distance"] = dist
        if self.reward_type == "sparse":
            return float(goal_reward(ee, self.goal, self.tolerance, "sparse", (1.0, -1.0))), reached
        if self.simple_dense_reward:
            return -dist, reached
        if reached:
            return self.cfg["reached_goal_reward"], reached
        reward = -self.cfg["multiplier_dist_reward"] * dist + self.cfg["step_reward"]
        if self.at_joint_limits():
            reward += self.cfg["joint_limits_reward"]
        return reward, reached

    # -- the hooks of one env (MultiROS names), through the batch functions -----------------------------
    def _get_obs(self) -> np.ndarray:
        return type(self).batch_observe([self], self.connection.states)[0][0]

    def _get_reward(self) -> float:
        ee = self.ee_position()
        return self._score(float(np.linalg.norm(self.goal - ee)), ee)[0]

    def _check_if_done(self) -> bool:
        return float(np.linalg.norm(self.goal - self.ee_position())) <= self.tolerance


class RX200ReacherEnv(RX200ReachTask, RX200RobotEnv):
    """``RX200ReacherSim-v0``: the RX200 reach task on the simulation node (arguments: :class:`RX200ReachTask`)."""

    NUM_SIM_STEPS = REACH_NUM_SIM_STEPS
