"""uniros: robot RL on ROS 2 with a MuJoCo simulation node.

``import uniros as gym`` works like gymnasium for the library's envs::

    import uniros as gym
    env = gym.make("RX200ReacherGoalSim-v0")
    obs, info = env.reset(seed=0)

``make`` is gymnasium's, with errors that list the uniros IDs and the accepted keyword arguments;
``register``, ``spec``, ``spaces``, ``Env`` and ``Wrapper`` are gymnasium's own.
"""

from gymnasium import Env, Wrapper, register, spaces, spec

import rl_environments
from uniros.factory import make, make_vec

__version__ = "0.1.0"
ENV_IDS = rl_environments.ENV_IDS

__all__ = ["ENV_IDS", "Env", "Wrapper", "make", "make_vec", "register", "spaces", "spec"]
