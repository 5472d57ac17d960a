"""``PPO``: sb3_ros_support's / FRobs_RL's PPO wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class PPO(BasicModel):
    """Stable-Baselines3 PPO from a YAML (``ppo_params``); default config ``uniros/sb3/config/ppo.yaml``."""

    algorithm = "ppo"


__all__ = ["PPO"]
