"""MujocoBaseEnv and MujocoGoalEnv: gymnasium environments on the MuJoCo simulation node.

Both share :class:`multiros.envs.core.MujocoEnvCore`; this module adds only what differs: the
``step``/``reset`` templates of a plain ``gymnasium.Env`` and of a goal-conditioned
``gymnasium_robotics.GoalEnv`` (observation dict, vectorised ``compute_reward`` for HER).
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium_robotics.core import GoalEnv

from multiros.envs.core import EnvError, MujocoEnvCore

_GOAL_KEYS = ("observation", "achieved_goal", "desired_goal")


def _call(fn: Any, *args: Any) -> Any:
    """Call a hook with as many of ``args`` as its signature takes (MultiROS hooks take ``info``)."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return fn(*args)
    if any(p.kind is p.VAR_POSITIONAL for p in params):
        return fn(*args)
    n = sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)
    return fn(*args[:n])


class PlainStepTemplate:
    """Observation, reward and termination of a plain env's step, from its hooks.

    Shared by :class:`MujocoBaseEnv` and :class:`~multiros.envs.real.RealBaseEnv`: ``_template`` is
    the concrete template class, below which hooks are looked up (see ``MujocoEnvCore._hook``).
    """

    _template: ClassVar[type]

    def _step_result(self) -> tuple[Any, float, bool, bool, dict]:
        """Observation, reward, termination and info from the state after the action."""
        base = self._template
        obs = self._observe()
        info = self.info
        reward = self._hook(base, "_get_reward")
        if reward is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _get_reward()")
        reward_value = float(_call(reward, info))
        done = self._hook(base, "_check_if_done", "_compute_terminated")
        terminated = bool(_call(done, info)) if done is not None else False
        trunc = self._hook(base, "_compute_truncated")
        truncated = bool(_call(trunc, info)) if trunc is not None else False
        info.setdefault("is_success", False)
        return obs, reward_value, terminated, truncated, info

    def _observe(self) -> Any:
        hook = self._hook(self._template, "_get_obs", "_get_observation")
        if hook is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _get_obs()")
        return hook()


class GoalStepTemplate:
    """The goal-env half shared by :class:`MujocoGoalEnv` and :class:`~multiros.envs.real.RealGoalEnv`:
    vectorised ``compute_reward``/``compute_terminated``/``compute_truncated`` (HER) and the
    observation, reward and termination of a step, from the hooks below ``_template``."""

    _template: ClassVar[type]

    # -- vectorised goal functions (HER) ----------------------------------------------------
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

    # -- one step ---------------------------------------------------------------------------
    def _step_result(self) -> tuple[dict, float, bool, bool, dict]:
        """Observation, reward, termination and info from the state after the action."""
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
        return obs, reward, terminated, truncated, info

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
    :class:`multiros.envs.core.MujocoEnvCore`.

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

    # -- gymnasium API ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        if seed is None and self._pending_seed is not None:
            seed = self._pending_seed
        self._pending_seed = None
        gym.Env.reset(self, seed=seed)
        self._core_reset(MujocoBaseEnv, seed, options)
        obs = self._observe()
        info = self.info
        info.setdefault("is_success", False)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        self._step_act(action)
        self._advance()
        return self._step_result()

    # The two halves of a step around the simulation's advance; a vector env (multiros.envs.batch)
    # runs the first for each of its envs, advances all their robots in one request, then the second.
    def _step_act(self, action: Any) -> None:
        """Check the action and run the action hook (commands become pending)."""
        action = self._check_action(action)
        self.info = {}
        self._set_action_hook(MujocoBaseEnv, action)


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

    # -- gymnasium API ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if seed is None and self._pending_seed is not None:
            seed = self._pending_seed
        self._pending_seed = None
        GoalEnv.reset(self, seed=seed)
        self._core_reset(MujocoGoalEnv, seed, options)
        obs = self._observe()
        info = self.info
        info.setdefault("is_success", self._success(obs, info))
        return obs, info

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        self._step_act(action)
        self._advance()
        return self._step_result()

    def _step_act(self, action: Any) -> None:
        """Check the action and run the action hook (commands become pending)."""
        action = self._check_action(action)
        self.info = {}
        self._set_action_hook(MujocoGoalEnv, action)


MujocoBaseEnv._template = MujocoBaseEnv
MujocoGoalEnv._template = MujocoGoalEnv
