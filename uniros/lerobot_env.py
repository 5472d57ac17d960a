"""uniros envs in LeRobot's evaluation and training scripts: the gym side of the ``gym_uniros`` plugin.

LeRobot (0.4.4) makes an eval env as ``gym.make(f"gym_{type}/{task}")`` after importing the package
``gym_<type>``, and feeds the observations through ``lerobot.envs.utils.preprocess_observation``, which
knows a fixed set of keys. :class:`LeRobotEnv` wraps any uniros env into that layout::

    agent_pos           the state vector: a goal env's "observation", or the plain observation
                        -> observation.state
    environment_state   the other state keys, concatenated in key order (a goal env: achieved_goal,
                        desired_goal)                                   -> observation.environment_state
    pixels              {camera: H x W x 3 uint8} (rgb_plus_normal_obs)  -> observation.images.<camera>

and adds what LeRobot's rollout reads: ``task_description`` (the task in words, as ``uniros record``
writes it), ``_max_episode_steps``, and ``info["is_success"]`` on every step. :func:`lerobot_features`
gives the env's features in LeRobot's terms; the ``gym_uniros`` package turns them into LeRobot's
``EnvConfig`` registered as ``--env.type=uniros`` (docs/lerobot.md).

This module does not import LeRobot (only gymnasium and uniros), so it is usable and tested without it.
"""

from __future__ import annotations

from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from uniros.recording import STATE_KEYS, environment_state, environment_state_keys, is_vector_space

__all__ = ["NAMESPACE", "LeRobotEnv", "LeRobotLayoutError", "control_fps", "lerobot_features", "make_lerobot_env",
           "register_ids"]

#: The gym namespace LeRobot looks the IDs up in (``EnvConfig.package_name`` of ``--env.type=uniros``).
NAMESPACE = "gym_uniros"


class LeRobotLayoutError(ValueError):
    """An env's observations do not fit LeRobot's layout (the message names the key and the fix)."""


def _is_image(space: Any) -> bool:
    if not isinstance(space, spaces.Box) or len(space.shape) != 3:
        return False
    return bool(space.dtype == np.uint8 and space.shape[2] in (1, 3))


class _Layout:
    """Where each key of an env's observation goes in LeRobot's layout."""

    def __init__(self, space: Any) -> None:
        self.state: str | None = None  # the state key ("" for a plain Box observation)
        self.extra: list[str] = []  # the other vector keys -> environment_state
        self.cameras: dict[str, str] = {}  # camera name -> observation key
        if isinstance(space, spaces.Box) and is_vector_space(space):
            self.state = ""
        elif isinstance(space, spaces.Dict):
            for key in sorted(space.spaces):
                sub = space.spaces[key]
                if _is_image(sub):
                    self.cameras["rgb" if key in STATE_KEYS else key] = key
                elif is_vector_space(sub) and key in STATE_KEYS and self.state is None:
                    self.state = key
                elif not is_vector_space(sub):
                    raise LeRobotLayoutError(
                        f"observation key {key!r} ({sub}) has no place in LeRobot's observations, which take "
                        "state vectors and H x W x 3 uint8 images: make the env without it (a depth image: use "
                        "rgb_plus_normal_obs)")
        else:
            raise LeRobotLayoutError(f"a {type(space).__name__} observation space has no LeRobot layout: uniros "
                                     "gives LeRobot Box or Dict observations")
        self.extra = environment_state_keys(space)  # as uniros record writes observation.environment_state
        if self.state is None and not self.cameras:
            raise LeRobotLayoutError("the env's observations have neither a state vector nor a camera image")

    def space(self, space: Any) -> spaces.Dict:
        out: dict[str, spaces.Space[Any]] = {}
        if self.state is not None:
            sub = space if self.state == "" else space.spaces[self.state]
            out["agent_pos"] = spaces.Box(sub.low.astype(np.float32), sub.high.astype(np.float32), dtype=np.float32)
        if self.extra:
            low = np.concatenate([space.spaces[k].low for k in self.extra]).astype(np.float32)
            high = np.concatenate([space.spaces[k].high for k in self.extra]).astype(np.float32)
            out["environment_state"] = spaces.Box(low, high, dtype=np.float32)
        if self.cameras:
            out["pixels"] = spaces.Dict({cam: space.spaces[key] for cam, key in self.cameras.items()})
        return spaces.Dict(out)

    def __call__(self, obs: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.state is not None:
            out["agent_pos"] = np.asarray(obs if self.state == "" else obs[self.state], dtype=np.float32)
        if self.extra:
            out["environment_state"] = environment_state(obs, self.extra)
        if self.cameras:
            out["pixels"] = {cam: np.asarray(obs[key], dtype=np.uint8) for cam, key in self.cameras.items()}
        return out


def control_fps(env: Any) -> int:
    """Steps per second of ``env``: one over its control period (a simulation's physics steps per env
    step), else its ``render_fps``, else 25."""
    connection = getattr(env.unwrapped, "connection", None)
    try:
        period = float(getattr(connection, "control_period", 0.0) or 0.0)
    except (TypeError, ValueError):
        period = 0.0
    if period > 0.0:
        return max(1, round(1.0 / period))
    fps = env.metadata.get("render_fps") if isinstance(getattr(env, "metadata", None), dict) else None
    return max(1, round(float(fps))) if fps else 25


class LeRobotEnv(gym.Env[dict[str, Any], np.ndarray]):
    """A uniros env with LeRobot's observation layout (module docstring), for ``lerobot-eval``.

    Args:
        env: the uniros env (``uniros.make(ID, ...)``), closed with this one.
        env_id: its ID (the task description of envs without a task kind).
    """

    def __init__(self, env: gym.Env[Any, Any], env_id: str) -> None:
        from uniros.recording import task_text

        self.env, self.env_id = env, env_id
        self._layout = _Layout(env.observation_space)
        self.observation_space: spaces.Dict = self._layout.space(env.observation_space)
        self.action_space = env.action_space
        self.render_mode = env.render_mode
        self.metadata = {**env.metadata, "render_fps": control_fps(env)}
        spec = env.spec
        self._max_episode_steps = int(spec.max_episode_steps) if spec is not None and spec.max_episode_steps else 1000
        self.task_description = task_text(env, env_id)
        self.task = self.task_description

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None,
              ) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        obs, info = self.env.reset(seed=seed, options=options)
        return self._layout(obs), {**info, "is_success": bool(info.get("is_success", False))}

    def step(self, action: np.ndarray) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(np.asarray(action, dtype=self.action_space.dtype))
        info = {**info, "is_success": bool(info.get("is_success", False))}
        return self._layout(obs), float(reward), bool(terminated), bool(truncated), info

    def render(self) -> Any:
        return self.env.render()

    def close(self) -> None:
        self.env.close()


def make_lerobot_env(uniros_id: str, episode_length: int | None = None, **kwargs: Any) -> LeRobotEnv:
    """``uniros.make(uniros_id, **kwargs)`` in LeRobot's layout (the entry point of ``gym_uniros/<ID>``).

    ``episode_length`` (steps) overrides the ID's step limit. (Not ``max_episode_steps``: ``gym.make``
    would take that itself and put its own time limit outside the wrapper, hiding its attributes.)
    """
    import uniros

    if episode_length is not None:
        kwargs["max_episode_steps"] = int(episode_length)
    return LeRobotEnv(uniros.make(uniros_id, **kwargs), uniros_id)


def register_ids() -> list[str]:
    """Register every uniros ID as ``gym_uniros/<ID>`` (LeRobot's ``EnvConfig.gym_id``); returns them."""
    import rl_environments

    ids = []
    for env_id in rl_environments.ENV_IDS:
        name = f"{NAMESPACE}/{env_id}"
        if name not in gym.registry:
            gym.register(name, entry_point=cast(Any, make_lerobot_env), kwargs={"uniros_id": env_id},
                         order_enforce=False, disable_env_checker=True)
        ids.append(name)
    return ids


def lerobot_features(env: LeRobotEnv) -> tuple[dict[str, tuple[str, tuple[int, ...]]], dict[str, str]]:
    """The env's features as LeRobot's ``EnvConfig`` declares them: ``{key: (FeatureType name, shape)}``
    and ``features_map`` (``{key: LeRobot's feature name}``), keys as in the wrapper's observations."""
    feats: dict[str, tuple[str, tuple[int, ...]]] = {"action": ("ACTION", tuple(env.action_space.shape or ()))}
    fmap = {"action": "action"}
    space = env.observation_space.spaces
    if "agent_pos" in space:
        feats["agent_pos"], fmap["agent_pos"] = ("STATE", tuple(space["agent_pos"].shape or ())), "observation.state"
    if "environment_state" in space:
        feats["environment_state"] = ("ENV", tuple(space["environment_state"].shape or ()))
        fmap["environment_state"] = "observation.environment_state"
    pixels = space.get("pixels")
    if isinstance(pixels, spaces.Dict):
        for cam, sub in pixels.spaces.items():
            feats[f"pixels/{cam}"] = ("VISUAL", tuple(sub.shape or ()))
            fmap[f"pixels/{cam}"] = f"observation.images.{cam}"
    return feats, fmap
