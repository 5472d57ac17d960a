"""RealBaseEnv and RealGoalEnv: gymnasium environments on a real robot (RealROS' names).

Both are the one env core on a real robot's connection (:class:`multiros.envs.real.core.RealEnvCore`)
with the simulated envs' own step templates (:mod:`multiros.envs.base_env`): the same hooks, the
same step and reset.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium_robotics.core import GoalEnv

from multiros.envs.base_env import GoalStepTemplate, PlainStepTemplate
from multiros.envs.real.core import RealEnvCore


class RealBaseEnv(RealEnvCore, PlainStepTemplate, gym.Env):
    """A gymnasium ``Env`` driving a real ros2_control robot (RealROS' ``RealBaseEnv``).

    Subclass it twice, as in RealROS: a robot env (namespace, controllers, joints, safety) and a task
    env (spaces, action, observation, reward, termination). Knobs: :class:`~multiros.envs.real.core.RealEnvCore`.
    A step acts (``_set_action`` -> :meth:`send_joint_targets`, through the safety rules), waits the
    control cycle, observes the freshest joint state; ``info["state_age_sec"]`` says how old it is.

    Hooks (canonical names; MultiROS/RealROS names in brackets also work): ``_set_action(action)``
    [``_send_action``], ``_get_obs()`` [``_get_observation``], ``_get_reward()`` [``_get_reward(info)``],
    ``_check_if_done()`` [``_compute_terminated(info)``], optional ``_compute_truncated(info)``,
    ``_set_init_pose()``, ``_set_episode_init_params()`` [``_set_init_params(options)``],
    ``_check_connection_and_readiness()`` [``_check_subs_and_pubs_connection``].
    """

    def __init__(self, **kwargs: Any) -> None:
        gym.Env.__init__(self)
        self._init_real(**kwargs)


class RealGoalEnv(RealEnvCore, GoalStepTemplate, GoalEnv):
    """A goal-conditioned env (``gymnasium_robotics.GoalEnv``) on a real robot, ready for HER
    (RealROS' ``RealGoalEnv``).

    Same hooks as :class:`~multiros.envs.MujocoGoalEnv`: ``_set_action``, ``_get_obs() -> dict`` [or
    ``_get_observation``, ``_get_achieved_goal``, ``_get_desired_goal``], ``_compute_reward(achieved_goal,
    desired_goal, info)``, ``_is_success(achieved_goal, desired_goal)``, ``_check_if_done()``,
    ``_set_init_pose()``, ``_set_episode_init_params()`` [``_set_init_params``],
    ``_check_connection_and_readiness()``. ``compute_reward`` and friends read only their arguments.
    """

    def __init__(self, **kwargs: Any) -> None:
        gym.Env.__init__(self)
        self._init_real(**kwargs)


RealBaseEnv._template = RealBaseEnv
RealGoalEnv._template = RealGoalEnv
