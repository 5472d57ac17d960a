"""``SAC``: sb3_ros_support's / FRobs_RL's SAC wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class SAC(BasicModel):
    """Stable-Baselines3 SAC from a YAML (``sac_params``); default config ``uniros/sb3/config/sac.yaml``."""

    algorithm = "sac"


__all__ = ["SAC"]
