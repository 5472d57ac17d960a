"""``DDPG_GOAL``: sb3_ros_support's goal-env DDPG (HER) wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class DDPG_GOAL(BasicModel):  # noqa: N801 - sb3_ros_support's name
    """Stable-Baselines3 DDPG on a goal env, HER when ``use_her`` or ``use_HER``; default config
    ``uniros/sb3/config/ddpg_goal.yaml``."""

    algorithm = "ddpg"
    goal = True


__all__ = ["DDPG_GOAL"]
