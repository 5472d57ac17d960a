"""MujocoBaseEnv and MujocoGoalEnv: gymnasium environments on the MuJoCo simulation node.

The step and reset of every env are written here once, for both robot connections: the plain
template (:class:`PlainStepTemplate`, a ``gymnasium.Env``'s) and the goal-conditioned one
(:class:`GoalStepTemplate`, a ``gymnasium_robotics.GoalEnv``'s, with the vectorised
``compute_reward`` HER calls). ``MujocoBaseEnv``/``MujocoGoalEnv`` put them on the simulated core
(:class:`~multiros.envs.sim_env.MujocoEnvCore`), ``RealBaseEnv``/``RealGoalEnv``
(:mod:`multiros.envs.real.envs`) on the real one. A task written batch-first
(:mod:`multiros.envs.batch_task`) steps through its batch functions, as a batch of one.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium_robotics.core import GoalEnv

from multiros.envs.batch_task import StepResults, act_rows, batch_route, uses_own_hooks
from multiros.envs.core import EnvCore, EnvError, call_hook
from multiros.envs.errors import StepAfterFailedReset
from multiros.envs.sim_env import MujocoEnvCore

__all__ = ["MujocoBaseEnv", "MujocoGoalEnv", "PlainStepTemplate", "GoalStepTemplate", "StepTemplate"]

_GOAL_KEYS = ("observation", "achieved_goal", "desired_goal")
StepResult = tuple[Any, float, bool, bool, dict]


class StepTemplate(EnvCore):
    """``step`` and ``reset`` of every env (the plain and goal templates add their halves).

    A ``reset`` that raises leaves the env without an episode: the next ``step`` raises
    :class:`StepAfterFailedReset` naming the reset's error, before anything is sent (else a
    wrapper's bookkeeping, such as gymnasium's env checker, fails first with an unrelated error, or
    a real robot would be stepped from an unknown state).
    """

    _template: ClassVar[type]
    _failed_reset: str | None = None  # the error of the last reset, while no reset has succeeded since

    def step(self, action: Any) -> StepResult:
        if self._failed_reset is not None:
            raise StepAfterFailedReset(f"{type(self).__name__}.step() after a reset that failed "
                                       f"({self._failed_reset}); call reset() again and step once it returns")
        cls: Any = type(self)
        if batch_route(cls) is not None and not uses_own_hooks(self):  # the task's batch functions, as a batch of one
            actions = self.check_actions(np.asarray(action, dtype=np.float64)[None], single=True)
            act_rows(cls, [self], actions, self.connection.states)
            self.step_advance()
            return end_on_fault(cls.batch_results([self], self.connection.states)).row(0)
        self.step_act(action)
        self.step_advance()
        return self.step_result()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        try:
            self._reset_gym(self._take_seed(seed))
            self._reset_episode(options)
            obs = self._observe()
            info = self.info
            info.setdefault("is_success", self._reset_success(obs, info))
        except BaseException as exc:
            self._failed_reset = f"{type(exc).__name__}: {exc}"[:300]
            raise
        self._failed_reset = None
        return obs, info

    # -- the halves the templates fill in ---------------------------------------------------------
    def _reset_gym(self, seed: int | None) -> None:
        raise NotImplementedError

    def _reset_success(self, obs: Any, info: dict[str, Any]) -> bool:
        return False

    def _observe(self) -> Any:
        raise NotImplementedError

    def step_result(self) -> StepResult:
        """Observation, reward, termination and info from the state after the action (the hooks)."""
        raise NotImplementedError


def end_on_fault(results: StepResults) -> StepResults:
    """A step the node reported wrong (``info["sim_status"]``) ends that env's episode, truncated."""
    for j, info in enumerate(results.infos):
        if "sim_status" in info:
            results.truncated[j] = True
    return results


class PlainStepTemplate(StepTemplate):
    """Observation, reward and termination of a plain env's step, from its hooks.

    Shared by :class:`MujocoBaseEnv` and :class:`~multiros.envs.real.RealBaseEnv`: ``_template`` is
    the concrete template class, below which hooks are looked up (see :func:`~multiros.envs.core.hook_name`).
    """

    def _reset_gym(self, seed: int | None) -> None:
        gym.Env.reset(self, seed=seed)  # type: ignore[arg-type]

    def step_result(self) -> StepResult:
        base = self._template
        obs = self._observe()
        info = self.info
        reward = self._hook(base, "_get_reward")
        if reward is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _get_reward()")
        reward_value = float(call_hook(reward, info))
        done = self._hook(base, "_check_if_done", "_compute_terminated")
        terminated = bool(call_hook(done, info)) if done is not None else False
        trunc = self._hook(base, "_compute_truncated")
        truncated = bool(call_hook(trunc, info)) if trunc is not None else False
        info.setdefault("is_success", False)
        return obs, reward_value, terminated, truncated or "sim_status" in info, info

    def _observe(self) -> Any:
        hook = self._hook(self._template, "_get_obs", "_get_observation")
        if hook is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _get_obs()")
        return hook()


class GoalStepTemplate(StepTemplate):
    """The goal-env half shared by :class:`MujocoGoalEnv` and :class:`~multiros.envs.real.RealGoalEnv`:
    vectorised ``compute_reward``/``compute_terminated``/``compute_truncated`` (HER) and the
    observation, reward and termination of a step, from the hooks below ``_template``."""

    def _reset_gym(self, seed: int | None) -> None:
        GoalEnv.reset(self, seed=seed)  # type: ignore[arg-type]

    def _reset_success(self, obs: Any, info: dict[str, Any]) -> bool:
        return self._success(obs, info)

    # -- vectorised goal functions (HER) ----------------------------------------------------------
    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        hook = self._hook(self._template, "_compute_reward")
        if hook is None:
            raise NotImplementedError(
                f"{type(self).__name__} must implement _compute_reward(achieved_goal, desired_goal, info)"
            )
        return hook(achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        hook = self._hook(self._template, "_is_success")
        if hook is None:
            return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool) if np.ndim(achieved_goal) > 1 else False
        return hook(achieved_goal, desired_goal)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        if np.ndim(achieved_goal) > 1:
            return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool)
        return False

    # -- one step -------------------------------------------------------------------------------
    def step_result(self) -> StepResult:
        base = self._template
        obs = self._observe()
        info = self.info
        ag, dg = obs["achieved_goal"], obs["desired_goal"]
        success = self._success(obs, info)
        info.setdefault("is_success", success)
        reward = float(self.compute_reward(ag, dg, info))
        if type(self).compute_terminated is GoalStepTemplate.compute_terminated and self._hook(
            base, "_is_success"
        ) is not None:
            terminated = success  # the default compute_terminated is _is_success: already computed
        else:
            terminated = bool(self.compute_terminated(ag, dg, info))
        extra = self._hook(base, "_check_if_done")
        if extra is not None:
            terminated = terminated or bool(extra())
        truncated = bool(self.compute_truncated(ag, dg, info))
        return obs, reward, terminated, truncated or "sim_status" in info, info

    def _success(self, obs: dict, info: dict) -> bool:
        hook = self._hook(self._template, "_is_success")
        if hook is not None:
            return bool(hook(obs["achieved_goal"], obs["desired_goal"]))
        return bool(self.compute_terminated(obs["achieved_goal"], obs["desired_goal"], info))

    def _observe(self) -> dict:
        base = self._template
        hook = self._hook(base, "_get_obs")
        if hook is not None:
            obs = hook()
        else:
            names = ("_get_observation", "_get_achieved_goal", "_get_desired_goal")
            parts = [self._hook(base, n) for n in names]
            if any(p is None for p in parts):
                raise NotImplementedError(
                    f"{type(self).__name__} must implement _get_obs() returning a dict with {_GOAL_KEYS} "
                    "(or _get_observation(), _get_achieved_goal() and _get_desired_goal())"
                )
            obs = dict(zip(_GOAL_KEYS, (p() for p in parts)))
        if not isinstance(obs, dict) or any(k not in obs for k in _GOAL_KEYS):
            raise EnvError(f"{type(self).__name__}._get_obs() must return a dict with keys {_GOAL_KEYS}")
        return obs


class MujocoBaseEnv(MujocoEnvCore, PlainStepTemplate, gym.Env):
    """A gymnasium ``Env`` whose robot lives in the MuJoCo simulation node.

    Subclass it twice, as in MultiROS: a robot env (spawning, controllers, readiness) and a task env
    (spaces, action, observation, reward, termination). Constructor knobs are documented on
    :class:`multiros.envs.sim_env.MujocoEnvCore`.

    Hooks to implement (canonical names; MultiROS/FRobs_RL names in brackets also work):
        ``_set_action(action)`` [``_send_action``], ``_get_obs()`` [``_get_observation``],
        ``_get_reward()`` [``_get_reward(info)``], ``_check_if_done()`` [``_compute_terminated(info)``],
        optional ``_compute_truncated(info)``, ``_set_init_pose()``, ``_set_episode_init_params()``
        [``_set_init_params(options)``], ``_check_connection_and_readiness()``
        [``_check_subs_and_pubs_connection``].
    """

    def __init__(self, **kwargs: Any) -> None:
        gym.Env.__init__(self)
        self._init_core(**kwargs)


class MujocoGoalEnv(MujocoEnvCore, GoalStepTemplate, GoalEnv):
    """A goal-conditioned env (``gymnasium_robotics.GoalEnv``) on the MuJoCo simulation node, ready for HER.

    The observation is a dict with ``observation``, ``achieved_goal`` and ``desired_goal``;
    ``compute_reward``, ``compute_terminated`` and ``compute_truncated`` accept batches (arrays of
    goals with a leading batch axis and a list of infos), as SB3's ``HerReplayBuffer`` calls them.
    They must read only their arguments: no ROS calls, no side effects.

    Hooks to implement (canonical; MultiROS names in brackets):
        ``_set_action(action)``, ``_get_obs() -> dict`` [or ``_get_observation()``,
        ``_get_achieved_goal()``, ``_get_desired_goal()``], ``_compute_reward(achieved_goal,
        desired_goal, info)`` [``compute_reward``], ``_is_success(achieved_goal, desired_goal)``
        (vectorised; default termination), ``_check_if_done()`` (extra, goal-independent
        termination), ``_set_init_pose()``, ``_set_episode_init_params()`` [``_set_init_params``],
        ``_check_connection_and_readiness()``.
    """

    def __init__(self, **kwargs: Any) -> None:
        gym.Env.__init__(self)
        self._init_core(**kwargs)


MujocoBaseEnv._template = MujocoBaseEnv
MujocoGoalEnv._template = MujocoGoalEnv
