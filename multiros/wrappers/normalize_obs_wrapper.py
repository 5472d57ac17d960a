"""``NormalizeObservWrapper``: observations mapped from their ``Box`` bounds to ``[-1, 1]``.

FRobs_RL's wrapper handles a ``Box``; MultiROS' (``NormalizeObservationWrapper``) also a goal
``Dict`` with ``normalize_goal_spaces``. Differences, all deliberate:

* the declared space of every normalised key becomes ``Box(-1, 1)`` (MultiROS left goal sub-spaces
  un-normalised even when it normalised the goals);
* ``reset`` keeps the env's ``info`` (FRobs_RL returned ``{}``);
* with ``normalize_goal_spaces``, ``compute_reward``/``compute_terminated``/``compute_truncated``
  called on this wrapper (SB3's ``check_env``, ``HerReplayBuffer`` through ``env_method``) map the
  goals back to env units first, so HER relabelling stays correct, and ``step`` returns the reward
  recomputed from the normalised goals (equal to the env's up to float rounding). Code that calls
  ``env.unwrapped.compute_reward`` directly must pass goals in env units
  (:meth:`NormalizeObservWrapper.denormalize_goal`);
* infinite bounds are refused (they have no normalisation).

No clipping: a value outside the declared bounds maps outside ``[-1, 1]``, so observation-bound
bugs stay visible (``gymnasium.utils.env_checker`` warns about them).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from multiros.wrappers._goal import GoalPassthrough
from multiros.wrappers._spaces import BoxScaler

GOAL_KEYS = ("achieved_goal", "desired_goal")


class NormalizeObservWrapper(GoalPassthrough, gym.ObservationWrapper):
    """Normalise a ``Box`` observation, or the ``observation`` (and optionally goal) entries of a ``Dict``.

    Args:
        env: an env whose observation space is a bounded ``Box`` or a ``Dict`` (goal envs:
            ``observation``, ``achieved_goal``, ``desired_goal``).
        normalize_goal_spaces: also normalise ``achieved_goal`` and ``desired_goal``; the goal
            functions of this wrapper then take normalised goals.

    Raises:
        TypeError: the space (or a normalised entry) is not a ``Box``, or a ``Dict`` lacks ``observation``.
        ValueError: a normalised space has infinite bounds.
    """

    def __init__(self, env: gym.Env, normalize_goal_spaces: bool = False) -> None:
        gym.ObservationWrapper.__init__(self, env)
        self.normalize_goal_spaces = bool(normalize_goal_spaces)
        space = env.observation_space
        self.scalers: dict[str | None, BoxScaler] = {}
        if isinstance(space, spaces.Dict):
            if "observation" not in space.spaces:
                raise TypeError(f"a Dict observation space needs an 'observation' entry to normalise, got {space}")
            keys = ["observation"]
            if self.normalize_goal_spaces:
                missing = [k for k in GOAL_KEYS if k not in space.spaces]
                if missing:
                    raise TypeError(f"normalize_goal_spaces=True but the observation space has no {missing}")
                keys += list(GOAL_KEYS)
            self.scalers = {k: BoxScaler(space.spaces[k], f"observation space entry {k!r}") for k in keys}
            self.observation_space = spaces.Dict({
                k: (self.scalers[k].normalized_space() if k in self.scalers else sub)
                for k, sub in space.spaces.items()
            })
        else:
            if self.normalize_goal_spaces:
                raise TypeError("normalize_goal_spaces=True needs a Dict (goal env) observation space")
            self.scalers = {None: BoxScaler(space, "observation space")}
            self.observation_space = self.scalers[None].normalized_space()

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        obs = self.observation(obs)
        if self.normalize_goal_spaces:
            # Recompute from the goals the agent sees, so that the step reward is exactly what HER
            # (and SB3's check_env) get from compute_reward on the stored observation; it differs
            # from the env's own reward by float rounding of the normalisation at most.
            reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], info))
        return obs, reward, terminated, truncated, info

    # -- observations -------------------------------------------------------------------------
    def observation(self, observation: Any) -> Any:
        """Env observation -> normalised observation."""
        if None in self.scalers:
            return self._norm(None, observation)
        out = dict(observation)
        for key in self.scalers:
            out[key] = self._norm(key, observation[key])
        return out

    def denormalize_observation(self, observation: Any) -> Any:
        """Normalised observation -> env observation (exact inverse of :meth:`observation`)."""
        if None in self.scalers:
            return self._denorm(None, observation)
        out = dict(observation)
        for key in self.scalers:
            out[key] = self._denorm(key, observation[key])
        return out

    def _norm(self, key: str | None, value: Any) -> np.ndarray:
        scaler = self.scalers[key]
        return scaler.normalize(value).astype(scaler.dtype, copy=False)

    def _denorm(self, key: str | None, value: Any) -> np.ndarray:
        scaler = self.scalers[key]
        return scaler.denormalize(value).astype(scaler.space.dtype, copy=False)

    def denormalize_goal(self, goal: Any, key: str = "desired_goal") -> np.ndarray:
        """A (batch of) normalised goal(s) in env units; identity unless ``normalize_goal_spaces``."""
        if key not in self.scalers:
            return np.asarray(goal)
        return self.scalers[key].denormalize(goal)

    # -- goal functions in the wrapper's (normalised) goal units -------------------------------
    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        ag, dg = self._goals(achieved_goal, desired_goal)
        return super().compute_reward(ag, dg, info)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        ag, dg = self._goals(achieved_goal, desired_goal)
        return super().compute_terminated(ag, dg, info)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        ag, dg = self._goals(achieved_goal, desired_goal)
        return super().compute_truncated(ag, dg, info)

    def _goals(self, achieved_goal: Any, desired_goal: Any) -> tuple[Any, Any]:
        if not self.normalize_goal_spaces:
            return achieved_goal, desired_goal
        return (self.denormalize_goal(achieved_goal, "achieved_goal"),
                self.denormalize_goal(desired_goal, "desired_goal"))


#: MultiROS name of the same wrapper.
NormalizeObservationWrapper = NormalizeObservWrapper

__all__ = ["NormalizeObservWrapper", "NormalizeObservationWrapper"]

