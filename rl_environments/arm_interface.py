"""What a task needs from the robot layer of an arm, whichever robot layer it is.

The task classes (:mod:`rl_environments.reach_task`, :mod:`rl_environments.manipulation_task` and the
robots' task mixins) use only these members, so the same task composes with the simulated robot
envs (:class:`~rl_environments.arm_robot.ArmRobot` on :class:`~multiros.envs.MujocoBaseEnv`) and the
real ones (the same class on :class:`~multiros.envs.RealBaseEnv`).

Tasks are written batch-first (:mod:`multiros.envs.batch_task`): the robot layer answers for N envs
of one class at once (``arm_positions_of(states)`` and friends, on ``(N, ...)`` arrays) and for one
env (``arm_positions()``, for scripted policies and user code). Task and robot layer both derive
from :class:`ArmInterface`; its declarations give a type checker the robot's members, and the
robot layer, earlier in every task env's method resolution order, implements them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from multiros.envs.connection import RobotConnection
from multiros.robot_state import RobotState, RobotStates
from multiros.utils.kinematics import KinematicChain
from rl_environments.arm_ik import TopDownIK

__all__ = ["ArmInterface", "ARM_INTERFACE_MEMBERS", "MANIPULATION_MEMBERS"]

# The members a task may use (tests check both robot layers provide them).
ARM_INTERFACE_MEMBERS = (
    "ARM_JOINTS", "EE_LINK", "ARM_CONTROLLER", "kinematic_chain", "base_position", "arm_positions", "arm_velocities",
    "ee_position", "set_arm_targets", "move_to_initial_pose", "node", "info", "np_random", "arm_positions_of",
    "arm_velocities_of", "ee_positions_of", "set_arm_targets_of", "send_command", "robot_state", "joint_positions",
    "joint_velocities",
)
#: What push and pick-and-place use besides (the arm's gripper and scene).
MANIPULATION_MEMBERS = (
    "FINGER_JOINTS", "FINGER_MIMIC", "SCENE", "top_down_ik", "spawn_scene", "object_poses_of", "observation_time",
    "place_object", "open_fingers_at_reset", "command_grippers",
)


class ArmInterface:
    """The robot layer of an arm, as a task sees it (see the module docstring).

    Positions are in the world frame of the task (the robot base at ``base_position``); joint
    arrays follow ``ARM_JOINTS``.
    """

    ROBOT_NAME: ClassVar[str]
    ARM_JOINTS: ClassVar[tuple[str, ...]]
    EE_LINK: ClassVar[str]
    ARM_CONTROLLER: ClassVar[str]
    FINGER_JOINTS: ClassVar[tuple[str, ...]]
    FINGER_MIMIC: ClassVar[float]
    SCENE: ClassVar[Mapping[str, Any]]
    info: dict[str, Any]
    np_random: np.random.Generator
    action_space: spaces.Space[Any]
    observation_space: spaces.Space[Any]

    if TYPE_CHECKING:  # provided by the env core below the robot layer; declared for type checkers only
        node: Any
        robot_name: str
        connection: RobotConnection  # the env classes narrow it (SimConnection, RealConnection), as their cores do

        @property
        def robot_state(self) -> RobotState: ...

        def send_command(self, controller: str, command: Sequence[float] | np.ndarray) -> None: ...

        def move_to_initial_pose(self, names: Sequence[str], positions: npt.ArrayLike,
                                 tolerance: float = 1e-3) -> None: ...

        def joint_positions(self, names: Sequence[str] | None = None) -> np.ndarray: ...

        def frame_position(self, frame: str) -> np.ndarray: ...

        def joint_velocities(self, names: Sequence[str] | None = None) -> np.ndarray: ...

    @property
    def state_space(self) -> spaces.Space[Any]:
        """The observation space of the task's state observation: the observation space, less the
        camera images when the env observes through a camera (:mod:`rl_environments.camera_obs`)."""
        space = self.__dict__.get("_state_space")
        return self.observation_space if space is None else space

    @property
    def action_box(self) -> spaces.Box:
        """The action space, which every arm task makes a Box."""
        space = self.action_space
        if not isinstance(space, spaces.Box):
            raise TypeError(f"{type(self).__name__}: the arm tasks need a Box action space, got {space}")
        return space

    # -- the robot layer, batch-first ---------------------------------------------------------------
    @classmethod
    def kinematic_chain(cls) -> KinematicChain:
        """The arm's chain from its base link to the end effector."""
        raise NotImplementedError

    @classmethod
    def arm_positions_of(cls, states: RobotStates) -> np.ndarray:
        """``(N, arm joints)`` arm joint positions of N robots' states."""
        raise NotImplementedError

    @classmethod
    def arm_velocities_of(cls, states: RobotStates) -> np.ndarray:
        """``(N, arm joints)`` arm joint velocities."""
        raise NotImplementedError

    @classmethod
    def ee_positions_of(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        """``(N, 3)`` end-effector world positions of ``envs``' robots (``states``: their states, in order)."""
        raise NotImplementedError

    @classmethod
    def set_arm_targets_of(cls, envs: Sequence[Any], targets: np.ndarray) -> None:
        """Command each env's arm to its row of ``targets`` (through a real robot's safety rules)."""
        raise NotImplementedError

    # -- the same for one env ------------------------------------------------------------------------
    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot base."""
        raise NotImplementedError

    def arm_positions(self) -> np.ndarray:
        """Arm joint positions observed after the last step."""
        raise NotImplementedError

    def arm_velocities(self) -> np.ndarray:
        """Arm joint velocities observed after the last step."""
        raise NotImplementedError

    def ee_position(self) -> np.ndarray:
        """World position of the end effector after the last step."""
        raise NotImplementedError

    def set_arm_targets(self, targets: np.ndarray) -> None:
        """Command arm joint targets (the real layer passes them through its safety rules)."""
        raise NotImplementedError

    # -- push and pick-and-place: the gripper and the scene (the robot layer's) -------------------------
    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> TopDownIK:
        """The arm's IK with the gripper pointing down, within joint limits ``lower``/``upper``."""
        raise NotImplementedError

    def spawn_scene(self, table: str, table_position: np.ndarray, obj: str, object_position: np.ndarray) -> None:
        """Make the table and the object exist (spawned in simulation; a tracker's on a robot)."""
        raise NotImplementedError

    @classmethod
    def object_poses_of(cls, envs: Sequence[Any], states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """``(N, 3)`` world positions and ``(N, 4)`` orientations ``(w, x, y, z)`` of the envs' objects."""
        raise NotImplementedError

    @classmethod
    def observation_time(cls, envs: Sequence[Any], states: RobotStates) -> float:
        """Seconds on the clock of ``states`` (for finite-difference velocities)."""
        raise NotImplementedError

    def place_object(self, position: np.ndarray, quat: np.ndarray) -> None:
        """Put the object at its episode start (a teleport in simulation)."""
        raise NotImplementedError

    def open_fingers_at_reset(self, opening: float) -> None:
        """Open the fingers to ``opening`` at an episode's start."""
        raise NotImplementedError

    @classmethod
    def command_grippers(cls, envs: Sequence[Any], targets: Sequence[float]) -> None:
        """Send each env's gripper its finger target (the first of ``FINGER_JOINTS``, metres)."""
        raise NotImplementedError
