"""``RX200PushSim-v0``: the RX200 plain push on the simulation node.

Scene, spaces, rewards and episode end: :mod:`rl_environments.rx200.sim.task_envs.manipulation.rx200_manipulation`.
"""

from __future__ import annotations

from rl_environments.rx200.sim.robot_envs.rx200_robot_sim import RX200RobotEnv
from rl_environments.rx200.sim.task_envs.manipulation.rx200_manipulation import RX200ManipulationTask


class RX200PushEnv(RX200ManipulationTask, RX200RobotEnv):
    """``RX200PushSim-v0`` (arguments: :class:`RX200ManipulationTask`)."""

    TASK = "push"
