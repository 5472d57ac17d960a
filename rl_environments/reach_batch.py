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

From a composed node the envs' states arrive as rows of stacked arrays
(:class:`~multiros.sim.state_gather.StackedStates`): the joint and end-effector parts of the
observations, and the next step's delta targets while no env was reset in between, are sliced from
them whole. Envs that read their state their own way (``_STATE_READERS`` replaced) are asked
through their own methods.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import Any

import numpy as np

from multiros.envs.base_env import GoalStepTemplate, MujocoGoalEnv
from multiros.envs.core import MujocoEnvCore
from multiros.sim.state_gather import StackedStates
from rl_environments.arm_robot import ArmRobot
from rl_environments.reach import goal_distance, reward_from_distance
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
# What the observation parts read from the robot's state: where a class or an env instance replaces
# one of these, the parts come from each env's ``_obs_part`` instead of the stacked states.
_STATE_READERS = {
    "_accept_state": MujocoEnvCore._accept_state,
    "robot_state": MujocoEnvCore.robot_state,
    "frame_position": MujocoEnvCore.frame_position,
    "_frame": MujocoEnvCore._frame,
    "joint_positions": MujocoEnvCore.joint_positions,
    "joint_velocities": MujocoEnvCore.joint_velocities,
    "_select": MujocoEnvCore._select,
    "_joint_indices": MujocoEnvCore._joint_indices,
    "arm_positions": ArmRobot.arm_positions,
    "arm_velocities": ArmRobot.arm_velocities,
    "ee_position": ArmRobot.ee_position,
}
_STATE_NAMES = frozenset({*_STATE_READERS, "ARM_JOINTS", "EE_LINK"})
_RESULT_OR_STATE_NAMES = _RESULT_NAMES | _STATE_NAMES
_ACT_OR_STATE_NAMES = _ACT_NAMES | _STATE_NAMES
_STATE_OF = operator.attrgetter("_state")
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
        self.reads_stacked = all(getattr(cls, name, None) is fn for name, fn in _STATE_READERS.items())
        # (envs, their states, stacked) of each results call since the last act (one per node)
        self._held: list[tuple[list[Any], list[Any], StackedStates]] = []

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
        held, self._held = self._held, []
        e0 = envs[0]
        cls, delta = self.cls, e0.delta_action
        stock_reads = self.reads_stacked
        for e in envs:
            if type(e) is not cls or e.ee_action_type or e.delta_action != delta:
                return False
            own = vars(e).keys()
            if not own.isdisjoint(_ACT_OR_STATE_NAMES):
                if not own.isdisjoint(_ACT_NAMES):
                    return False
                stock_reads = False  # it reads its state its own way: its arm_positions() is asked
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
        if delta:
            current = self._held_positions(envs, held) if stock_reads else None
            if current is None:
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

    @staticmethod
    def _held_positions(envs: Sequence[Any], held: Sequence[tuple[list[Any], list[Any], StackedStates]]
                        ) -> np.ndarray | None:
        """Each env's ``arm_positions()``, sliced from the stacked states :meth:`results` read last
        step (one per node) if the envs still hold those states (none was reset since); else
        ``None``. The caller has checked that the envs read their states the stock way."""
        if not held or sum(len(group) for group, _, _ in held) != len(envs):
            return None
        e0 = envs[0]
        arm = e0._joint_indices(e0.ARM_JOINTS)
        current = np.empty((len(envs), len(arm)))
        index = {id(group[0]): None for group, _, _ in held}
        for j, e in enumerate(envs):
            if id(e) in index:
                index[id(e)] = j
        for group, states, stacked in held:
            j0 = index[id(group[0])]
            if j0 is None:
                return None
            part = envs[j0:j0 + len(group)]
            if part != group or not all(map(operator.is_, map(_STATE_OF, part), states)):
                return None
            current[j0:j0 + len(group)] = stacked.position[:, arm]
        return current

    # -- observations, rewards, episode ends --------------------------------------------------
    def results(self, envs: Sequence[Any], stacked: StackedStates | None = None) -> list[StepResult] | None:
        """Each env's ``_step_result()`` from the state it holds, for all at once; ``None`` (each env
        scores itself) when the envs do not share a reward type or one carries its own hooks.

        ``stacked`` holds the states the envs hold as rows of one array each (a composed node's
        read): the joint and frame parts of the observations are then sliced from it whole.
        """
        e0 = envs[0]
        reward_type, names, frames = e0.reward_type, e0.robot_state.names, e0.frames
        alike = stacked is not None and self.reads_stacked and len(envs) == len(stacked.position)
        for e in envs:
            if e.reward_type != reward_type:
                return None
            own = vars(e).keys()
            if not own.isdisjoint(_RESULT_OR_STATE_NAMES):
                if not own.isdisjoint(_RESULT_NAMES):
                    return None
                alike = False  # the env reads its state its own way: its parts come from _obs_part
            elif alike and (e.robot_state.names != names or e.frames != frames):
                alike = False
        sliced = self._stacked_parts(e0, stacked) if alike and stacked is not None else {}
        raw = np.concatenate([sliced[name] if name in sliced else self._part(name, envs) for name in self.parts],
                             axis=1)
        boxes = [e.observation_space["observation"] for e in envs]
        obs = np.minimum(np.maximum(raw.astype(np.float32), _stack([b.low for b in boxes])),
                         _stack([b.high for b in boxes]))
        achieved = obs[:, :3].copy()
        desired = _stack([e.goal for e in envs]).astype(np.float32)
        tolerance = np.array([e.tolerance for e in envs])
        distance = goal_distance(achieved, desired)  # what is_success and goal_reward each compute
        success = distance <= tolerance
        reward = reward_from_distance(distance, tolerance, reward_type)
        out: list[StepResult] = []
        for j, env in enumerate(envs):
            done = bool(success[j])
            info = env.info
            info.setdefault("is_success", done)
            observation = {"observation": obs[j], "achieved_goal": achieved[j], "desired_goal": desired[j]}
            out.append((observation, float(reward[j]), done, False, info))
        if alike and stacked is not None:
            self._held.append((list(envs), [e._state for e in envs], stacked))
        return out

    @staticmethod
    def _part(name: str, envs: Sequence[Any]) -> np.ndarray:
        return _stack([e._obs_part(name) for e in envs])

    @staticmethod
    def _stacked_parts(e0: Any, stacked: StackedStates) -> dict[str, np.ndarray]:
        """The observation parts read from the robot state (``ee_position``, ``arm_positions``,
        ``arm_velocities``), sliced from the stacked states of envs alike ``e0``."""
        arm = e0._joint_indices(e0.ARM_JOINTS)
        return {"ee_position": stacked.frame_positions[:, e0._frame(e0.EE_LINK)],
                "arm_positions": stacked.position[:, arm], "arm_velocities": stacked.velocity[:, arm]}
