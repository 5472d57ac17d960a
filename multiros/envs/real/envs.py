"""RealBaseEnv and RealGoalEnv: gymnasium environments on a real robot (RealROS' names).

Both share :class:`multiros.envs.real.core.RealEnvCore`; this module adds the ``step``/``reset``
templates of a plain ``gymnasium.Env`` and of a goal-conditioned ``gymnasium_robotics.GoalEnv``,
with the same hooks as :class:`~multiros.envs.MujocoBaseEnv` / :class:`~multiros.envs.MujocoGoalEnv`.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium_robotics.core import GoalEnv

from multiros.envs.base_env import _GOAL_KEYS, _call
from multiros.envs.core import EnvError
from multiros.envs.real.core import RealEnvCore


class RealBaseEnv(RealEnvCore, gym.Env):
    """A gymnasium ``Env`` driving a real ros2_control robot (RealROS' ``RealBaseEnv``).

    Subclass it twice, as in RealROS: a robot env (namespace, controllers, joints, safety) and a task
    env (spaces, action, observation, reward, termination). Knobs: :class:`~multiros.envs.real.core.RealEnvCore`.
    A step acts (``_set_action`` -> :meth:`send_joint_targets`, through the safety rules), waits the
    control cycle, observes the freshest joint state; ``info["state_age_sec"]`` says how old it is.

    Hooks (canonical names; MultiROS/RealROS names in brackets also work): ``_set_action(action)``
    [``_send_action``], ``_get_obs()`` [``_get_observation``], ``_get_reward()`` [``_get_reward(info)``],
    ``_check_if_done()`` [``_compute_terminated(info)``], optional ``_compute_truncated(info)``,
    ``_set_init_pose()``, ``_set_episode_init_params()`` [``_set_init_params(options)``],
    ``_check_connection_and_readiness()`` [``_check_subs_and_pubs_connection``].
    """

    def __init__(self, **kwargs: Any) -> None:
        gym.Env.__init__(self)
        self._init_real(**kwargs)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        if seed is None and self._pending_seed is not None:
            seed = self._pending_seed
        self._pending_seed = None
        gym.Env.reset(self, seed=seed)
        self._real_reset(RealBaseEnv, options)
        obs = self._observe()
        info = self.info
        info.setdefault("is_success", False)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        action = self._check_action(action)
        self.info = {}
        self._act_and_wait(RealBaseEnv, action)
        obs = self._observe()
        info = self.info
        reward = self._hook(RealBaseEnv, "_get_reward")
        if reward is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _get_reward()")
        reward_value = float(_call(reward, info))
        done = self._hook(RealBaseEnv, "_check_if_done", "_compute_terminated")
        terminated = bool(_call(done, info)) if done is not None else False
        trunc = self._hook(RealBaseEnv, "_compute_truncated")
        truncated = bool(_call(trunc, info)) if trunc is not None else False
        info.setdefault("is_success", False)
        return obs, reward_value, terminated, truncated, info

    def _observe(self) -> Any:
        hook = self._hook(RealBaseEnv, "_get_obs", "_get_observation")
        if hook is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _get_obs()")
        return hook()


class RealGoalEnv(RealEnvCore, GoalEnv):
    """A goal-conditioned env (``gymnasium_robotics.GoalEnv``) on a real robot, ready for HER
    (RealROS' ``RealGoalEnv``).

    Same hooks as :class:`~multiros.envs.MujocoGoalEnv`: ``_set_action``, ``_get_obs() -> dict`` [or
    ``_get_observation``, ``_get_achieved_goal``, ``_get_desired_goal``], ``_compute_reward(achieved_goal,
    desired_goal, info)``, ``_is_success(achieved_goal, desired_goal)``, ``_check_if_done()``,
    ``_set_init_pose()``, ``_set_episode_init_params()`` [``_set_init_params``],
    ``_check_connection_and_readiness()``. ``compute_reward`` and friends read only their arguments.
    """

    def __init__(self, **kwargs: Any) -> None:
        gym.Env.__init__(self)
        self._init_real(**kwargs)

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        hook = self._hook(RealGoalEnv, "_compute_reward")
        if hook is None:
            raise NotImplementedError(
                f"{type(self).__name__} must implement _compute_reward(achieved_goal, desired_goal, info)")
        return hook(achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        hook = self._hook(RealGoalEnv, "_is_success")
        if hook is None:
            return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool) if np.ndim(achieved_goal) > 1 else False
        return hook(achieved_goal, desired_goal)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        if np.ndim(achieved_goal) > 1:
            return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool)
        return False

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if seed is None and self._pending_seed is not None:
            seed = self._pending_seed
        self._pending_seed = None
        GoalEnv.reset(self, seed=seed)
        self._real_reset(RealGoalEnv, options)
        obs = self._observe()
        info = self.info
        info.setdefault("is_success", bool(self.compute_terminated(obs["achieved_goal"], obs["desired_goal"], info)))
        return obs, info

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        action = self._check_action(action)
        self.info = {}
        self._act_and_wait(RealGoalEnv, action)
        obs = self._observe()
        info = self.info
        ag, dg = obs["achieved_goal"], obs["desired_goal"]
        terminated = bool(self.compute_terminated(ag, dg, info))
        info.setdefault("is_success", terminated if self._hook(RealGoalEnv, "_is_success") is not None else False)
        reward = float(self.compute_reward(ag, dg, info))
        extra = self._hook(RealGoalEnv, "_check_if_done")
        if extra is not None:
            terminated = terminated or bool(extra())
        truncated = bool(self.compute_truncated(ag, dg, info))
        return obs, reward, terminated, truncated, info

    def _observe(self) -> dict:
        hook = self._hook(RealGoalEnv, "_get_obs")
        if hook is not None:
            obs = hook()
        else:
            names = ("_get_observation", "_get_achieved_goal", "_get_desired_goal")
            parts = [self._hook(RealGoalEnv, n) for n in names]
            if any(p is None for p in parts):
                raise NotImplementedError(
                    f"{type(self).__name__} must implement _get_obs() returning a dict with {_GOAL_KEYS} "
                    "(or _get_observation(), _get_achieved_goal() and _get_desired_goal())")
            obs = dict(zip(_GOAL_KEYS, (p() for p in parts)))
        if not isinstance(obs, dict) or any(k not in obs for k in _GOAL_KEYS):
            raise EnvError(f"{type(self).__name__}._get_obs() must return a dict with keys {_GOAL_KEYS}")
        return obs
