"""Tasks written batch-first: one numpy pass computes the step of N envs of a task class.

A task class that derives from :class:`BatchTask` writes its step once, for a batch: actions to
commands (:meth:`BatchTask.batch_act`) and observations, rewards, episode ends and infos from the
robots' states (:meth:`BatchTask.batch_results`), on ``(N, ...)`` arrays. A single env is a batch of
one: its ``step`` calls the same two functions with ``[self]``; a vector env
(:mod:`multiros.envs.batch`) calls them with its N envs, once per vector step.

The MultiROS hooks (``_set_action``, ``_get_obs``, ``_compute_reward``, ...) stay: the task
implements them through the same functions, and a subclass (or an env instance) that replaces one
of them steps through its hooks instead (:func:`batch_route`), in a single env and, env by env, in
a batch.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from multiros.robot_state import RobotStates

__all__ = ["BatchTask", "StepResults", "STEP_HOOKS", "act_rows", "batch_route", "uses_own_hooks"]

StepResult = tuple[Any, float, bool, bool, dict[str, Any]]

#: Every name through which a step's hooks can be replaced (MultiROS and FRobs_RL aliases included).
STEP_HOOKS = frozenset({
    "_set_action", "_send_action", "_get_obs", "_get_observation", "_get_achieved_goal", "_get_desired_goal",
    "_get_reward", "_compute_reward", "_is_success", "_check_if_done", "_compute_terminated", "_compute_truncated",
    "compute_reward", "compute_terminated", "compute_truncated", "step", "step_act", "step_result", "_check_action",
    "check_actions",
})


@dataclass
class StepResults:
    """The outcome of one step of N envs.

    Attributes:
        obs: the observations stacked: an ``(N, ...)`` array, or a dict of them (goal envs).
        reward: ``(N,)`` float64.
        terminated, truncated: ``(N,)`` bool.
        infos: the N envs' info dicts.
    """

    obs: Any
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    infos: list[dict[str, Any]]

    def __len__(self) -> int:
        return len(self.infos)

    def obs_row(self, j: int) -> Any:
        """Env ``j``'s observation (views of the stacked arrays)."""
        obs = self.obs
        return {k: v[j] for k, v in obs.items()} if isinstance(obs, dict) else obs[j]

    def row(self, j: int) -> StepResult:
        """Env ``j``'s ``(obs, reward, terminated, truncated, info)`` as its own ``step`` returns it."""
        return (self.obs_row(j), float(self.reward[j]), bool(self.terminated[j]), bool(self.truncated[j]),
                self.infos[j])

    @classmethod
    def of(cls, results: Sequence[StepResult]) -> StepResults:
        """Per-env step results stacked (envs that step through their own hooks)."""
        first = results[0][0]
        if isinstance(first, dict):
            obs: Any = {k: np.array([r[0][k] for r in results]) for k in first}
        else:
            obs = np.array([r[0] for r in results])
        return cls(obs, np.array([r[1] for r in results], dtype=np.float64),
                   np.array([r[2] for r in results], dtype=bool), np.array([r[3] for r in results], dtype=bool),
                   [r[4] for r in results])


class BatchTask:
    """A task written for N envs at once (see the module docstring)."""

    #: Whether this task's batch functions may run for envs of this class (computed by batch_route).
    _batch_functions: ClassVar[bool] = True

    @classmethod
    def batch_act(cls, envs: Sequence[Any], actions: np.ndarray, states: RobotStates) -> None:
        """Each env's action hook: ``actions`` are ``(N, *action shape)`` float64, already checked
        and clipped; ``states`` the robots' current states, in order. The commands go to each env's
        connection (queued for the next simulation step, or sent through a real robot's safety rules)."""
        raise NotImplementedError

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        """Each env's observation, reward, episode end and info from its robot's state after the
        step (``states``: the envs' states as rows, in order)."""
        raise NotImplementedError


_ROUTES: dict[type, type | None] = {}


def batch_route(cls: type) -> type | None:
    """The class whose batch functions (``batch_act``, ``batch_results``) give ``cls``'s step, or ``None``
    when ``cls`` steps through its own hooks: it has no batch functions, or a class more derived than the
    one that defines them, or a robot layer, defines a step hook of its own (:data:`STEP_HOOKS`)."""
    try:
        return _ROUTES[cls]
    except KeyError:
        route = _ROUTES[cls] = _route(cls)
        return route


def _route(cls: type) -> type | None:
    task = next((k for k in cls.__mro__ if "batch_results" in vars(k)), None)
    if task is None or task is BatchTask:
        return None
    allowed = set(task.__mro__) | set(getattr(cls, "_template", object).__mro__)
    own = {id(value) for value in vars(task).values()}
    for name in STEP_HOOKS:
        owner = next((k for k in cls.__mro__ if name in vars(k)), None)
        # a hook below the task steps through hooks, unless it is one of the task's own functions by another name
        if owner is not None and owner not in allowed and id(vars(owner)[name]) not in own:
            return None
    return task


def uses_own_hooks(env: Any) -> bool:
    """Whether this env instance carries a step hook of its own (set on the instance)."""
    return not vars(env).keys().isdisjoint(STEP_HOOKS)  # looks up the few hook names, not every attribute


def act_rows(task: Any, envs: Sequence[Any], actions: np.ndarray, states: RobotStates) -> None:
    """The act half of a batch-first step, for one env (a batch of one) and for a vector env's N alike:
    each env's info emptied and its connection's checks before acting (a robot's watchdog), then the
    task's :meth:`BatchTask.batch_act` on the checked ``actions`` (rows in ``envs``' order)."""
    for env in envs:
        env.info = {}
        env.connection.before_act()
    task.batch_act(envs, actions, states)
