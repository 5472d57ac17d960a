"""``TD3``: sb3_ros_support's / FRobs_RL's TD3 wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class TD3(BasicModel):
    """Stable-Baselines3 TD3 from a YAML (``td3_params``); default config ``uniros/sb3/config/td3.yaml``."""

    algorithm = "td3"


__all__ = ["TD3"]
