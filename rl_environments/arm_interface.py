"""What a reach-type task needs from the robot layer, whichever robot layer it is.

The task classes (:mod:`rl_environments.reach_task` and the RX200/IRB120 task mixins) use only
these members, so the same task composes with the simulated robot envs
(:class:`~rl_environments.arm_robot.ArmRobot` on :class:`~multiros.envs.MujocoBaseEnv`) and the real
ones (:class:`~rl_environments.real_arm_robot.RealArmRobot` on :class:`~multiros.envs.RealBaseEnv`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from multiros.utils.kinematics import KinematicChain

# The members a task may use (tests check both robot layers provide them).
ARM_INTERFACE_MEMBERS = (
    "ARM_JOINTS", "kinematic_chain", "base_position", "arm_positions", "arm_velocities", "ee_position",
    "set_arm_targets", "move_to_initial_pose", "node", "info", "np_random",
)


@runtime_checkable
class ArmInterface(Protocol):
    """The robot layer of an arm, as a task sees it.

    Positions are in the world frame of the task (the robot base at ``base_position``); joint
    arrays follow ``ARM_JOINTS``.
    """

    ARM_JOINTS: ClassVar[tuple[str, ...]]
    node: Any  # a multiros.ros Node (goal markers)
    info: dict[str, Any]  # this step's info dict

    @classmethod
    def kinematic_chain(cls) -> KinematicChain:
        """The arm's chain from its base link to the end effector."""
        ...

    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot base."""
        ...

    def arm_positions(self) -> np.ndarray:
        """Arm joint positions observed after the last step."""
        ...

    def arm_velocities(self) -> np.ndarray:
        """Arm joint velocities observed after the last step."""
        ...

    def ee_position(self) -> np.ndarray:
        """World position of the end effector after the last step."""
        ...

    def set_arm_targets(self, targets: np.ndarray) -> None:
        """Command arm joint targets (the real layer passes them through its safety rules)."""
        ...

    def move_to_initial_pose(self, names: Sequence[str], positions: Sequence[float], tolerance: float = 1e-3) -> None:
        """Bring the arm to an episode's initial pose (teleport in simulation, a slow move on a robot)."""
        ...
