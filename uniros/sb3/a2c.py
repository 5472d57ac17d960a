"""``A2C``: sb3_ros_support's / FRobs_RL's A2C wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class A2C(BasicModel):
    """Stable-Baselines3 A2C from a YAML (``a2c_params``); default config ``uniros/sb3/config/a2c.yaml``."""

    algorithm = "a2c"


__all__ = ["A2C"]
