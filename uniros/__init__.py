"""uniros: robot RL on ROS 2 with a MuJoCo simulation node.

``import uniros as gym`` works like gymnasium for the library's envs::

    import uniros as gym
    env = gym.make("RX200ReacherGoalSim-v0")
    obs, info = env.reset(seed=0)

``make`` is gymnasium's, with errors that list the uniros IDs and the accepted keyword arguments;
``register_arm(path)`` registers an arm file's IDs (docs/add_your_arm.md); ``register``, ``spec``,
``spaces``, ``Env`` and ``Wrapper`` are gymnasium's own.
"""

from pathlib import Path as _Path

from gymnasium import Env, Wrapper, register, spaces, spec

import rl_environments
from multiros.envs.real import RealBaseEnv, RealGoalEnv
from rl_environments._checkout import map_checkout_package as _map_checkout_package
from rl_environments.arm_registry import register_arm
from uniros.factory import make, make_vec
from uniros.multitask import MultiTaskEnv, MultiTaskGoalEnv

# From a source checkout, templates/ is not inside this package (an install maps it): map it.
_map_checkout_package("uniros.templates", _Path(__file__).resolve().parent.parent / "templates")

__version__ = "0.1.0"
ENV_IDS = rl_environments.ENV_IDS

__all__ = [
    "ENV_IDS", "Env", "MultiTaskEnv", "MultiTaskGoalEnv", "RealBaseEnv", "RealGoalEnv", "Wrapper", "make", "make_vec",
    "register", "register_arm", "spaces", "spec",
]
