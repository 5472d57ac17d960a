"""``DQN_GOAL``: sb3_ros_support's goal-env DQN (HER) wrapper (see :class:`uniros.sb3.core.BasicModel`)."""

from uniros.sb3.core import BasicModel


class DQN_GOAL(BasicModel):  # noqa: N801 - sb3_ros_support's name
    """Stable-Baselines3 DQN on a goal env, HER when ``use_her`` or ``use_HER``; default config
    ``uniros/sb3/config/dqn_goal.yaml``."""

    algorithm = "dqn"
    goal = True


__all__ = ["DQN_GOAL"]
