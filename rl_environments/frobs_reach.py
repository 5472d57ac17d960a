"""FRobs_RL's reacher on an arm file's arm: ``ABBIRB120ReacherEnv-v0`` and its goal and Real twins.

## Description
Move the end-effector within ``tolerance_goal_pos`` (5 cm) of a goal sampled, among reachable points,
in FRobs_RL's goal box (x, y in [-0.5, 0.5], z in [0, 1] m; here at least ``min_goal_height``
above the floor). Config: ``config/irb120_reacher_task_config.yaml`` (keys under ``irb120:``).

## Action space
``Box(-1, 1, (6,))``: joint deltas, ``target = joints + action * max_joint_delta`` (0.1 rad),
clipped to the joint limits. (FRobs_RL declared the whole joint range as the delta bound and
relied on MoveIt's slow execution; the bounded delta is the lockstep equivalent.)

## Observation space
``ABBIRB120ReacherEnv-v0``: ``Box(12,)``, the unit vector from the flange to the goal (3), the goal
position (3), the joint angles (6). ``ABBIRB120ReacherGoalEnv-v0``: ``Dict``, ``observation`` = flange
position (3), joint angles (6), previous action (6); ``achieved_goal`` = flange position;
``desired_goal`` = goal.

## Rewards
``ABBIRB120ReacherEnv-v0`` (FRobs_RL's): ``+reached_goal_reward`` (10) on success; otherwise
``-multiplier_dist_reward * distance + step_reward`` (-1.0 * d - 0.01); plus ``joint_limits_reward``
(-5) when a joint target is at a limit. The goal env: sparse, 0 within tolerance and -1 otherwise
(``reward_type="dense"``: ``-distance``), vectorised for HER.

## Episode end
Terminated on success with ``info["is_success"] = True``; truncated after 100 steps.

The task is FRobs_RL's, not the arm's: the arm (the IRB120, ``config/arms/irb120.yaml``) is the robot
env of its arm file (:func:`rl_environments.arm_envs.robot_env_class`); the Real twins are the same
task on that arm's real robot env, with equal spaces.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.arm_envs import robot_env_class
from rl_environments.reach import parse_reward_type
from rl_environments.reach_task import GoalReachTask, ReachTask, stack_rows
from rl_environments.real_arm_kwargs import TaskJointLimits
from rl_environments.task_config import load_task_config, vector

__all__ = ["FROBS_REACHER_SCHEMA", "FrobsReachTask", "FrobsGoalReachTask", "load_frobs_reacher_config",
           "frobs_reach_settings", "ABBIRB120ReacherEnv", "ABBIRB120ReacherGoalEnv", "ABBIRB120ReacherRealEnv",
           "ABBIRB120ReacherGoalRealEnv"]

#: The reacher config's keys (FRobs_RL's ``reacher_task.yaml``, metres and radians, world frame).
FROBS_REACHER_SCHEMA = {
    "arm_joints": list,
    "min_joint_pos": vector(6),
    "max_joint_pos": vector(6),
    "init_joint_pos": vector(6),
    "max_joint_delta": float,
    "position_goal_min": vector(3),
    "position_goal_max": vector(3),
    "min_goal_height": float,
    "tolerance_goal_pos": float,
    "step_reward": float,
    "multiplier_dist_reward": float,
    "reached_goal_reward": float,
    "joint_limits_reward": float,
}
CONFIG_FILE = "irb120_reacher_task_config.yaml"


def load_frobs_reacher_config(name: str | Path = CONFIG_FILE, section: str = "irb120") -> dict[str, Any]:
    """Load and check a FRobs_RL reacher config (its keys under ``section``)."""
    return load_task_config(name, FROBS_REACHER_SCHEMA, section=section)


def frobs_reach_settings(cfg: dict[str, Any]) -> dict[str, Any]:
    """``ReachTask._setup_reach`` arguments from a reacher config (joint deltas; the goal box with
    ``min_goal_height`` applied)."""
    low = list(cfg["position_goal_min"])
    low[2] = max(low[2], cfg["min_goal_height"])
    return {
        "delta_action": True,
        "ee_action_type": False,
        "delta_coeff": cfg["max_joint_delta"],
        "ee_delta_coeff": 0.0,
        "tolerance": cfg["tolerance_goal_pos"],
        "goal_min": low,
        "goal_max": list(cfg["position_goal_max"]),
    }


class FrobsReachTask(ReachTask):
    """FRobs_RL's reacher (see the module docstring), written once for the simulated robot env and the
    real one. Mix it in before the robot env.

    Args:
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    def __init__(self, config_file: str = CONFIG_FILE, **kwargs: Any) -> None:
        cfg = load_frobs_reacher_config(config_file)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **frobs_reach_settings(cfg))
        obs_low = np.concatenate([-np.ones(3), self.goal_min, self.chain.lower])
        obs_high = np.concatenate([np.ones(3), self.goal_max, self.chain.upper])
        self.observation_space = spaces.Box(obs_low.astype(np.float32), obs_high.astype(np.float32), dtype=np.float32)

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """The observations of N envs and their goal distances."""
        _, dist, unit = cls.goals_to(envs, cls.ee_positions_of(envs, states))
        chains = [env.chain for env in envs]
        q = np.clip(cls.arm_positions_of(states), np.array([c.lower for c in chains]),
                    np.array([c.upper for c in chains]))
        obs = np.concatenate([unit, stack_rows(envs, "goal"), q], axis=1)
        spaces_ = [env.observation_space for env in envs]
        low, high = np.array([sp.low for sp in spaces_]), np.array([sp.high for sp in spaces_])
        return np.clip(obs, low, high).astype(np.float32), dist

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        obs, dist = cls.batch_observe(envs, states)
        n = len(envs)
        reward = np.array([env._score(float(dist[j])) for j, env in enumerate(envs)])
        infos = [env.info for env in envs]
        for info in infos:
            info.setdefault("is_success", False)
        done = np.array([float(dist[j]) <= env.tolerance for j, env in enumerate(envs)], dtype=bool)
        return StepResults(obs, reward, done, np.zeros(n, dtype=bool), infos)

    def _score(self, dist: float) -> float:
        """FRobs_RL's reward of a step that left the end-effector ``dist`` from the goal."""
        self.info["distance"] = dist
        if dist <= self.tolerance:
            self.info["is_success"] = True
            reward = self.cfg["reached_goal_reward"]
        else:
            reward = -self.cfg["multiplier_dist_reward"] * dist + self.cfg["step_reward"]
        if self.at_joint_limits():
            reward += self.cfg["joint_limits_reward"]
        return float(reward)

    # -- the hooks of one env (MultiROS names), through the batch functions -----------------------------
    def _get_obs(self) -> np.ndarray:
        return type(self).batch_observe([self], self.connection.states)[0][0]

    def _get_reward(self) -> float:
        return self._score(float(np.linalg.norm(self.goal - self.ee_position())))

    def _check_if_done(self) -> bool:
        return float(np.linalg.norm(self.goal - self.ee_position())) <= self.tolerance


class FrobsGoalReachTask(GoalReachTask):
    """FRobs_RL's reacher, goal-conditioned (see the module docstring). Mix it in before the robot env.

    Args:
        reward_type: ``"sparse"`` or ``"dense"``.
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs.
    """

    OBS_PARTS = ("ee_position", "arm_positions", "prev_action")

    def __init__(self, reward_type: str = "sparse", config_file: str = CONFIG_FILE, **kwargs: Any) -> None:
        cfg = load_frobs_reacher_config(config_file)
        self.reward_type = parse_reward_type(reward_type)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **frobs_reach_settings(cfg))
        # The end-effector's observation box: the arm's safety box (its arm file's real: workspace).
        real = self.ARM_FILE.real  # type: ignore[attr-defined]
        low, high = np.asarray(real.workspace_min), np.asarray(real.workspace_max)
        self._setup_goal_spaces(
            np.concatenate([low + self.base_position, self.chain.lower, self.action_box.low]),
            np.concatenate([high + self.base_position, self.chain.upper, self.action_box.high]),
        )


# The IRB120's robot envs, from its arm file (config/arms/irb120.yaml).
_SIM: Any = robot_env_class("IRB120")
_SIM_GOAL: Any = robot_env_class("IRB120", goal=True)
_REAL: Any = robot_env_class("IRB120", real=True)
_REAL_GOAL: Any = robot_env_class("IRB120", goal=True, real=True)


class ABBIRB120ReacherEnv(FrobsReachTask, _SIM):
    """``ABBIRB120ReacherEnv-v0``: FRobs_RL's reacher on the IRB120, on the simulation node
    (arguments: :class:`FrobsReachTask`)."""


class ABBIRB120ReacherGoalEnv(FrobsGoalReachTask, _SIM_GOAL):
    """``ABBIRB120ReacherGoalEnv-v0``: the goal-conditioned IRB120 reacher on the simulation node
    (arguments: :class:`FrobsGoalReachTask`)."""


class ABBIRB120ReacherRealEnv(TaskJointLimits, FrobsReachTask, _REAL):
    """``ABBIRB120ReacherRealEnv-v0``: ``ABBIRB120ReacherEnv-v0``'s task on a real IRB 120 (or a stand-in),
    with equal spaces (see ``docs/real_robots.md``). Task arguments: :class:`FrobsReachTask`."""


class ABBIRB120ReacherGoalRealEnv(TaskJointLimits, FrobsGoalReachTask, _REAL_GOAL):
    """``ABBIRB120ReacherGoalRealEnv-v0``: the goal-conditioned IRB120 reacher on a real IRB 120, with
    ``ABBIRB120ReacherGoalEnv-v0``'s spaces, so a model trained in simulation runs here as it is.
    Task arguments: :class:`FrobsGoalReachTask`."""
