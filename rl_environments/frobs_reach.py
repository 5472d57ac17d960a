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

The task is FRobs_RL's, not the arm's: a row of the task table (``frobs_reach``) composed with the
IRB120's arm file (``config/arms/irb120.yaml``): ``ABBIRB120ReacherEnv-v0`` is
``ArmSimEnv(arm="IRB120", task="frobs_reach")``; the Real twins are the same task on that arm's robot,
with equal spaces.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.arm import Arm
from rl_environments.arm_task import TaskOptions, rows
from rl_environments.reach_task import ReachTask
from rl_environments.task_config import TaskConfigError, load_task_config, vector

__all__ = ["FROBS_REACHER_SCHEMA", "FrobsReachOptions", "FrobsReachTask", "load_frobs_reacher_config",
           "frobs_reach_settings"]

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


def frobs_reach_settings(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """The reach's settings from a reacher config (joint deltas; the goal box with ``min_goal_height``
    applied)."""
    low = list(cfg["position_goal_min"])
    low[2] = max(low[2], cfg["min_goal_height"])
    return {"delta_action": True, "ee_action_type": False, "delta_coeff": cfg["max_joint_delta"],
            "ee_delta_coeff": 0.0, "tolerance": cfg["tolerance_goal_pos"], "goal_min": low,
            "goal_max": list(cfg["position_goal_max"])}


@dataclasses.dataclass(frozen=True)
class FrobsReachOptions(TaskOptions):
    """The reacher's keyword arguments: ``reward_type`` (goal envs: ``"sparse"`` or ``"dense"``) and
    ``config_file`` (default ``irb120_reacher_task_config.yaml``, keys under ``irb120:``)."""


class FrobsReachTask(ReachTask):
    """FRobs_RL's reacher (see the module docstring): the reach's goals and actions, its own observations
    and reward."""

    NAME = "frobs_reach"
    OPTIONS = FrobsReachOptions
    NUM_SIM_STEPS = None  # the arm's 40 ms
    GOAL_OBS_PARTS = ("ee_position", "arm_positions", "prev_action")

    @classmethod
    def load_config(cls, arm: Arm, options: TaskOptions) -> dict[str, Any]:
        if options.ee_action_type:
            raise ValueError("FRobs_RL's reacher acts in joint deltas: ee_action_type=True does not apply")
        name = options.config_file or CONFIG_FILE
        cfg = load_frobs_reacher_config(name)
        if tuple(cfg["arm_joints"]) != arm.joints:
            raise TaskConfigError(f"{name}: arm_joints {list(cfg['arm_joints'])} are not the {arm.name}'s joints "
                                  f"{list(arm.joints)}: FRobs_RL's reacher is the IRB120's")
        return cfg

    def settings(self) -> dict[str, Any]:
        return frobs_reach_settings(self.cfg)

    def make_observation_space(self) -> spaces.Space[Any]:
        if self.goal_conditioned:  # the end effector's box: the arm's safety box (its arm file's real: workspace)
            real = self.arm.file.real
            low, high = np.asarray(real.workspace_min), np.asarray(real.workspace_max)
            act = self.action_space
            return self.goal_spaces(np.concatenate([low + self.base_position, self.chain.lower, act.low]),
                                    np.concatenate([high + self.base_position, self.chain.upper, act.high]),
                                    slice(0, 3), self.goal_min, self.goal_max)
        obs_low = np.concatenate([-np.ones(3), self.goal_min, self.chain.lower])
        obs_high = np.concatenate([np.ones(3), self.goal_max, self.chain.upper])
        return spaces.Box(obs_low.astype(np.float32), obs_high.astype(np.float32), dtype=np.float32)

    @classmethod
    def observe_rows(cls, tasks: Sequence[ReachTask], states: RobotStates) -> tuple[np.ndarray, np.ndarray,
                                                                                      np.ndarray]:
        """Plain envs: N observations (unit vector to the goal, goal, joints), end effectors and distances."""
        arm = tasks[0].arm
        ee = arm.ee_positions_of(tasks[0].connection, states)
        _, dist, unit = cls.goals_to(tasks, ee)
        chains = [task.chain for task in tasks]
        q = np.clip(arm.positions_of(states), np.array([c.lower for c in chains]),
                    np.array([c.upper for c in chains]))
        obs = np.concatenate([unit, rows(tasks, "goal"), q], axis=1)
        boxes = [task.observation_space for task in tasks]
        low, high = np.array([b.low for b in boxes]), np.array([b.high for b in boxes])  # type: ignore[attr-defined]
        return np.clip(obs, low, high).astype(np.float32), ee, dist

    @classmethod
    def results(cls, tasks: Sequence[ReachTask], states: RobotStates) -> StepResults:
        if tasks[0].goal_conditioned:
            return cls.goal_results(tasks, states)
        obs, _, dist = cls.observe_rows(tasks, states)
        n = len(tasks)
        reward = np.array([cast(FrobsReachTask, task).frobs_score(float(dist[j])) for j, task in enumerate(tasks)])
        infos = [task.info for task in tasks]
        for info in infos:
            info.setdefault("is_success", False)
        done = np.array([float(dist[j]) <= task.tolerance for j, task in enumerate(tasks)], dtype=bool)
        return StepResults(obs, reward, done, np.zeros(n, dtype=bool), infos)

    def frobs_score(self, dist: float) -> float:
        """FRobs_RL's reward of a step that left the end effector ``dist`` from the goal."""
        self.info["distance"] = dist
        if dist <= self.tolerance:
            self.info["is_success"] = True
            reward = self.cfg["reached_goal_reward"]
        else:
            reward = -self.cfg["multiplier_dist_reward"] * dist + self.cfg["step_reward"]
        if self.at_joint_limits():
            reward += self.cfg["joint_limits_reward"]
        return float(reward)


def __getattr__(name: str) -> type:
    """The env class names of earlier releases: the arm env classes with the IRB120 and this task set."""
    from rl_environments.arm_env import arm_env_class

    kinds = {"ABBIRB120ReacherEnv": (False, False), "ABBIRB120ReacherGoalEnv": (False, True),
             "ABBIRB120ReacherRealEnv": (True, False), "ABBIRB120ReacherGoalRealEnv": (True, True)}
    if name not in kinds:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    cls = _ALIASES.get(name)
    if cls is None:
        real, goal = kinds[name]
        cls = _ALIASES[name] = type(name, (arm_env_class(real=real, goal=goal),), {
            "__module__": __name__, "__qualname__": name, "ARM": "IRB120", "TASK": "frobs_reach",
            "__doc__": f"``{name}-v0``'s env: FRobs_RL's reacher on the IRB120."})
    return cls


_ALIASES: dict[str, type] = {}
