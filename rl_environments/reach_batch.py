"""The goal-conditioned reach task's step hooks for many envs at once: a batched vector env's
fast path (see ``EnvBatch`` in :mod:`multiros.envs.batch`).

A batched vector env at N = 8 spends more time in the envs' Python than in their physics, and most
of that Python is numpy called on arrays of 3 to 18 numbers, once per env: checking and clipping
the action, making joint targets, building the observation, scoring the goal. This module does each
of those once for the N envs, on ``(N, ...)`` arrays, and gives every env exactly what its own hooks
would have given it: the same operations on the same numbers, row by row, so the results are equal
bit for bit (``tests/vec/test_vec.py`` compares batched envs with separate ones step by step).

It applies only to classes whose step hooks are the stock ones of
:class:`~rl_environments.reach_task.GoalReachTask` (:meth:`GoalReachBatchHooks.for_class`); a
subclass (or an env instance) that replaces any of them steps env by env through its own hooks. Every parameter the
hooks read (action bounds, joint limits, delta coefficient, tolerance, reward type, observation
bounds, goal) is read from each env at each step, so ``set_attr`` on one env is honoured. When a
batch cannot be taken whole (end-effector actions, which run IK per env; mixed settings; a bad
action, whose error the env's own hook raises), the hooks decline and the envs step one by one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from multiros.envs.base_env import GoalStepTemplate, MujocoGoalEnv
from multiros.envs.core import MujocoEnvCore
from rl_environments.arm_robot import ArmRobot
from rl_environments.reach import goal_reward, is_success
from rl_environments.reach_task import GoalReachTask, ReachTask

StepResult = tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]

# The per-env methods the batched hooks reproduce: a class that replaces one of them keeps its own.
_STOCK = {
    "_step_act": MujocoGoalEnv._step_act,
    "_check_action": MujocoEnvCore._check_action,
    "_box_action_bounds": MujocoEnvCore._box_action_bounds,
    "_set_action": ReachTask._set_action,
    "set_arm_targets": ArmRobot.set_arm_targets,
    "send_command": MujocoEnvCore.send_command,
    "_step_result": GoalStepTemplate._step_result,
    "_observe": GoalStepTemplate._observe,
    "_success": GoalStepTemplate._success,
    "_get_obs": GoalReachTask._get_obs,
    "_obs_part": GoalReachTask._obs_part,
    "_goal_obs": GoalReachTask._goal_obs,
    "compute_reward": GoalStepTemplate.compute_reward,
    "compute_terminated": GoalStepTemplate.compute_terminated,
    "compute_truncated": GoalStepTemplate.compute_truncated,
    "_compute_reward": GoalReachTask._compute_reward,
    "_is_success": GoalReachTask._is_success,
}
# An env whose instance carries its own version of one of these steps alone.
_ACT_NAMES = frozenset({"_step_act", "_check_action", "_box_action_bounds", "_set_action", "_send_action",
                        "set_arm_targets", "send_command"})
_RESULT_NAMES = frozenset(_STOCK) - _ACT_NAMES
# Hooks looked up by name (MultiROS aliases included): each must resolve to the stock one.
_HOOKS = {
    ("_set_action", "_send_action"): "_set_action",
    ("_get_obs",): "_get_obs",
    ("_compute_reward",): "_compute_reward",
    ("_is_success",): "_is_success",
    ("_check_if_done",): None,
}


def _stack(values: Sequence[np.ndarray]) -> np.ndarray:
    """``np.stack(values)`` for the envs' small arrays of one shape, in a quarter of its time
    (ValueError for arrays of different shapes)."""
    return np.array(values)


class GoalReachBatchHooks:
    """``act`` and ``results`` of N envs of one :class:`GoalReachTask` class in one numpy pass each."""

    def __init__(self, cls: type) -> None:
        self.cls = cls
        self.parts = tuple(cls.OBS_PARTS)  # type: ignore[attr-defined]

    @classmethod
    def for_class(cls, env_cls: type) -> GoalReachBatchHooks | None:
        """The hooks for ``env_cls``, or ``None`` when it replaces a step hook they reproduce."""
        if not (issubclass(env_cls, GoalReachTask) and issubclass(env_cls, MujocoGoalEnv)):
            return None
        if not getattr(env_cls, "OBS_PARTS", ()):
            return None
        if any(getattr(env_cls, name, None) is not fn for name, fn in _STOCK.items()):
            return None
        if any(env_cls._hook_implemented(MujocoGoalEnv, *names) != name for names, name in _HOOKS.items()):
            return None
        return cls(env_cls)

    # -- actions ----------------------------------------------------------------------------
    def act(self, envs: Sequence[Any], actions: Sequence[Any]) -> bool:
        """Each env's ``_step_act(action)``, for all at once; False (nothing changed) when the batch
        is not one this can take whole, so the envs' own hooks run instead (and raise any error)."""
        e0 = envs[0]
        if any(type(e) is not self.cls or e.ee_action_type or e.delta_action != e0.delta_action
               or not _ACT_NAMES.isdisjoint(vars(e)) for e in envs):
            return False
        shape = (len(envs), *e0.action_space.shape)
        try:
            raw = np.asarray(actions, dtype=np.float64)
            bounds = [e._box_action_bounds() for e in envs]
            low, high = _stack([b[0] for b in bounds]), _stack([b[1] for b in bounds])
        except (AttributeError, TypeError, ValueError):  # not Box spaces, ragged input, spaces of different shapes
            return False
        if raw.shape != shape or not np.isfinite(raw).all():
            return False
        action = np.minimum(np.maximum(raw, low), high)
        if e0.delta_action:
            current = _stack([e.arm_positions() for e in envs])
            coeff = np.array([e.delta_coeff for e in envs])[:, None]
            targets = current + action * coeff
        else:
            targets = action
        lower = _stack([e.min_joint_pos for e in envs])
        upper = _stack([e.max_joint_pos for e in envs])
        if targets.shape != lower.shape:
            return False
        targets = np.minimum(np.maximum(targets, lower), upper)
        if not np.isfinite(targets).all():
            return False  # send_command refuses it, with its message
        for j, env in enumerate(envs):
            env.info = {}
            env.joint_targets = targets[j]
            env._pending_commands[env.ARM_CONTROLLER] = env.joint_targets
            env.prev_action = action[j]
        return True

    # -- observations, rewards, episode ends --------------------------------------------------
    def results(self, envs: Sequence[Any]) -> list[StepResult] | None:
        """Each env's ``_step_result()`` from the state it holds, for all at once; ``None`` (each env
        scores itself) when the envs do not share a reward type or one carries its own hooks."""
        e0 = envs[0]
        if any(e.reward_type != e0.reward_type or not _RESULT_NAMES.isdisjoint(vars(e)) for e in envs):
            return None
        raw = np.concatenate([self._part(name, envs) for name in self.parts], axis=1)
        boxes = [e.observation_space["observation"] for e in envs]
        obs = np.minimum(np.maximum(raw.astype(np.float32), _stack([b.low for b in boxes])),
                         _stack([b.high for b in boxes]))
        achieved = obs[:, :3].copy()
        desired = _stack([e.goal for e in envs]).astype(np.float32)
        tolerance = np.array([e.tolerance for e in envs])
        success = is_success(achieved, desired, tolerance)
        reward = goal_reward(achieved, desired, tolerance, e0.reward_type)
        out: list[StepResult] = []
        for j, env in enumerate(envs):
            done = bool(success[j])
            info = env.info
            info.setdefault("is_success", done)
            observation = {"observation": obs[j], "achieved_goal": achieved[j], "desired_goal": desired[j]}
            out.append((observation, float(reward[j]), done, False, info))
        return out

    @staticmethod
    def _part(name: str, envs: Sequence[Any]) -> np.ndarray:
        return _stack([e._obs_part(name) for e in envs])
