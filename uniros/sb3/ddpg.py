"""``DDPG``: sb3_ros_support's / FRobs_RL's DDPG wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class DDPG(BasicModel):
    """Stable-Baselines3 DDPG from a YAML (``ddpg_params``); default config ``uniros/sb3/config/ddpg.yaml``."""

    algorithm = "ddpg"


__all__ = ["DDPG"]
