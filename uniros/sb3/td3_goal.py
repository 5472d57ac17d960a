"""``TD3_GOAL``: sb3_ros_support's goal-env TD3 (HER) wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class TD3_GOAL(BasicModel):  # noqa: N801 - sb3_ros_support's name
    """Stable-Baselines3 TD3 on a goal env, HER when ``use_her`` or ``use_HER``; default config
    ``uniros/sb3/config/td3_goal.yaml``."""

    algorithm = "td3"
    goal = True


__all__ = ["TD3_GOAL"]
