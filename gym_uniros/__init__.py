"""LeRobot's plugin for uniros envs: ``lerobot-eval --env.discover_packages_path=gym_uniros --env.type=uniros``.

LeRobot (0.4.4) finds an env type by its ``EnvConfig`` subclass, registered under a name before the
command line is parsed (``--env.discover_packages_path=PACKAGE`` imports ``PACKAGE`` first), and makes
the env with ``gym.make(f"gym_{type}/{task}")``, importing ``gym_<type>`` if that ID is unknown. This
package is both: importing it registers :class:`UnirosEnv` as ``--env.type=uniros`` and every uniros ID
as ``gym_uniros/<ID>`` (:mod:`uniros.lerobot_env`: the wrapper, the observation layout). It imports
LeRobot, so only LeRobot imports it; uniros itself never does.

``--env.task`` is the uniros ID; ``fps`` and the features (joint state, goals, camera images, action)
come from the env itself, made once when the config is built (docs/lerobot.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig

from uniros.lerobot_env import NAMESPACE, control_fps, lerobot_features, make_lerobot_env, register_ids

__all__ = ["UnirosEnv"]

register_ids()


@EnvConfig.register_subclass("uniros")
@dataclass
class UnirosEnv(EnvConfig):
    """``--env.type=uniros``: ``--env.task`` a uniros ID, ``--env.episode_length`` its step limit (the ID's
    own by default), ``--env.env_kwargs='{"rgb_plus_normal_obs": true}'`` other ``uniros.make`` keywords;
    ``render_mode`` ``rgb_array`` (lerobot-eval writes videos of the first episodes)."""

    task: str | None = "RX200ReacherGoalSim-v0"
    fps: int = 25
    episode_length: int | None = None
    render_mode: str | None = "rgb_array"  # lerobot-eval renders the first episodes into videos
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.task:
            raise ValueError("--env.task must be a uniros ID (e.g. RX200ReacherGoalSim-v0)")
        env = make_lerobot_env(self.task, **self.gym_kwargs)
        try:
            feats, fmap = lerobot_features(env)
            self.fps = control_fps(env.env)
        finally:
            env.close()
        self.features = {key: PolicyFeature(type=FeatureType[kind], shape=shape)
                         for key, (kind, shape) in feats.items()}
        self.features_map = fmap

    @property
    def package_name(self) -> str:
        return NAMESPACE

    @property
    def gym_kwargs(self) -> dict[str, Any]:
        out = {"render_mode": self.render_mode, **self.env_kwargs}
        if self.episode_length is not None:
            out["episode_length"] = self.episode_length
        return out
