"""``SAC_GOAL``: sb3_ros_support's goal-env SAC (HER) wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class SAC_GOAL(BasicModel):  # noqa: N801 - sb3_ros_support's name
    """Stable-Baselines3 SAC on a goal env, HER when ``use_her`` or ``use_HER``; default config
    ``uniros/sb3/config/sac_goal.yaml``."""

    algorithm = "sac"
    goal = True


__all__ = ["SAC_GOAL"]
