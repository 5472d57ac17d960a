"""sb3_ros_support's and FRobs_RL's trainer classes, on uniros' one trainer.

``from uniros.sb3 import TD3`` or, as the originals' module paths, ``from uniros.sb3.td3 import TD3``
(sb3_ros_support: ``sb3_ros_support.td3``; FRobs_RL: ``frobs_rl.models.td3``) and
``from uniros.sb3.sac_goal import SAC_GOAL``::

    model = TD3(env, save_path, log_path, config_file_pkg="my_pkg", config_filename="td3.yaml")
    model.train()
    model.save_model()
    model.close_env()

Goal classes (``SAC_GOAL``, ``TD3_GOAL``, ``DDPG_GOAL``, ``DQN_GOAL``) use HER when ``use_her=True`` or the
YAML says ``use_HER: True``. See docs/training.md, "Trainer classes".
"""

from uniros.sb3.a2c import A2C
from uniros.sb3.core import BasicModel
from uniros.sb3.ddpg import DDPG
from uniros.sb3.ddpg_goal import DDPG_GOAL
from uniros.sb3.dqn import DQN
from uniros.sb3.dqn_goal import DQN_GOAL
from uniros.sb3.ppo import PPO
from uniros.sb3.sac import SAC
from uniros.sb3.sac_goal import SAC_GOAL
from uniros.sb3.td3 import TD3
from uniros.sb3.td3_goal import TD3_GOAL

__all__ = ["A2C", "BasicModel", "DDPG", "DDPG_GOAL", "DQN", "DQN_GOAL", "PPO", "SAC", "SAC_GOAL", "TD3", "TD3_GOAL"]
