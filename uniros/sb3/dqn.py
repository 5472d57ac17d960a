"""``DQN``: sb3_ros_support's / FRobs_RL's DQN wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class DQN(BasicModel):
    """Stable-Baselines3 DQN from a YAML (``dqn_params``); default config ``uniros/sb3/config/dqn.yaml``."""

    algorithm = "dqn"


__all__ = ["DQN"]
