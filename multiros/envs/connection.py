"""The robot-connection seam: what the env core needs from a robot, simulated or real.

One env core (:mod:`multiros.envs.core`) runs every env's hooks, action checks, seeds, info and
episode logic; below it a :class:`RobotConnection` moves the robot:

* :class:`~multiros.envs.sim_connection.SimConnection`: a robot on a simulation node (composed in
  this process and called directly, or over ROS 2): commands travel with the next lockstep step;
* :class:`~multiros.envs.real.connection.RealConnection`: a real ros2_control robot (robot link,
  safety rules, control loop, watchdog): commands go out at once, through the safety rules.

The core never asks which one it has, and neither does the robot layer above it: what a task's robot
does differently on each side (where its base is, its scene, its arm's and gripper's commands, the
clock of its states) is a method here that each connection implements its own way. A vector env
(:mod:`multiros.envs.batch`) steps the connections of many simulated envs with one request per node,
through :meth:`SimConnection.step_spec <multiros.envs.sim_connection.SimConnection.step_spec>` and
``accept``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from multiros.envs.errors import EnvError
from multiros.robot_state import RobotState, RobotStates

__all__ = ["CameraRequest", "RobotConnection", "SceneEntity", "StepStatus", "STEP_OK"]


@dataclass(frozen=True)
class CameraRequest:
    """The camera a task observes through, as the robot layer asks its connection to open it.

    Attributes:
        name: a camera of the robot's description (``"render_camera"``; in a simulation also a world
            camera by its full name, ``"<entity>/<camera>"``), or ``None`` for the task's own view camera.
        position, lookat: the view camera's place (world frame of the task, metres): a simulation spawns
            it there; a robot's camera is where it is mounted.
        fovy: the view camera's vertical field of view (degrees).
        width, height: the images' size; ``None`` (both) for a named camera's own.
        rgb_topic, depth_topic: on a robot, its camera driver's image topics (relative names: in the
            robot's namespace); ``depth_topic`` ``None``: no depth.
    """

    name: str | None
    position: tuple[float, float, float] | None
    lookat: tuple[float, float, float] | None
    fovy: float
    width: int | None
    height: int | None
    rgb_topic: str
    depth_topic: str | None

    def __post_init__(self) -> None:
        if (self.width is None) != (self.height is None):
            raise ValueError(f"camera {self.name or 'view camera'!r}: give both image_width and image_height, or "
                             "neither (the camera's own size)")


@dataclass(frozen=True)
class SceneEntity:
    """An entity of a task's scene (a table, an object to push), as the robot layer asks for it.

    Attributes:
        name: the entity's name (in a simulation: spawned under it, in the robot's namespace).
        uri: its description (``package://`` URI of an MJCF or URDF; a simulation spawns it).
        position: its world position, ``(3,)``.
        frame: the frame of it the task reads (``"<name>/<body>"``).
        movable: an object the robot moves (on a robot: its pose comes from a tracker), not a fixture
            (on a robot: it stands where the task says).
        mjcf: its description as MJCF text, spawned instead of ``uri`` when given (a scene made from
            sizes).
    """

    name: str
    uri: str
    position: tuple[float, float, float]
    frame: str
    movable: bool
    mjcf: str = ""


@dataclass(frozen=True)
class StepStatus:
    """How the robot's last step went.

    Attributes:
        code: 0 when it stepped normally; otherwise the simulation node's ``RobotStepResult`` code
            (104: physics diverged and the robot was restored at rest; 101-103, 105: its commands or
            frames were refused).
        message: the node's explanation.
    """

    code: int = 0
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.code == 0

    @property
    def diverged(self) -> bool:
        return self.code == 104


STEP_OK = StepStatus()


class RobotConnection(ABC):
    """A robot as the env core sees it (see the module docstring).

    Attributes:
        robot_name: the robot's name (its entity in a simulation).
        namespace: its ROS namespace (``"/rx200"``).
        controllers_list: the controllers the robot's env keeps active.
    """

    robot_name: str
    namespace: str
    controllers_list: list[str]

    # -- state ------------------------------------------------------------------------------
    @property
    @abstractmethod
    def state(self) -> RobotState:
        """The robot's state after the last step or reset (``EnvError`` before the first)."""

    @property
    @abstractmethod
    def states(self) -> RobotStates:
        """:attr:`state` as a batch of one (views of its arrays): what a batch-first task reads."""

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints of :attr:`state`, in the order of its arrays."""
        return self.state.names

    @property
    def frames(self) -> tuple[str, ...]:
        """The frames whose poses each state carries (none on a real robot: its env computes them)."""
        return ()

    def frame_index(self, frame: str) -> int:
        """Where ``frame`` sits in the state's frame arrays."""
        raise EnvError(f"frame {frame!r}: robot {self.robot_name!r} reports no frame poses")

    def frame_positions(self, states: RobotStates, frame: str) -> np.ndarray:
        """``(N, 3)`` world positions of ``frame`` in each of ``states`` (this connection's, or a batch of
        connections like it). A simulation returns them with each step; a real robot computes them
        (forward kinematics of the joints, a tracker's pose: :meth:`RealConnection.add_frame_source
        <multiros.envs.real.connection.RealConnection.add_frame_source>`). The robot layer asks here,
        whichever it has."""
        return states.frame_positions[:, self.frame_index(frame)]

    def frame_poses(self, states: RobotStates, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """``(N, 3)`` positions and ``(N, 4)`` orientations ``(w, x, y, z)`` of ``frame`` (as
        :meth:`frame_positions`)."""
        index = self.frame_index(frame)
        return states.frame_positions[:, index], states.frame_orientations[:, index]

    @property
    @abstractmethod
    def base_position(self) -> np.ndarray:
        """World position of the robot's base, ``(3,)`` (a copy): where a simulation spawned it, where a
        real robot's env was told it stands."""

    def observation_time(self, states: RobotStates) -> float:
        """The clock of ``states`` in seconds (finite-difference velocities): simulation time, or on a
        robot the local time its state arrived."""
        return float(states.sim_time)

    # -- a task's scene -------------------------------------------------------------------------
    @abstractmethod
    def add_scene(self, entities: Sequence[SceneEntity]) -> None:
        """Make a task's scene ready and serve its entities' frames to :meth:`frame_positions` and
        :meth:`frame_poses`: a simulation spawns them (in order) and returns their frames with each step;
        on a robot the scene stands already, a movable object's frame is its tracker's pose and a
        fixture's is where the task says it is."""

    def place_entity(self, name: str, position: Sequence[float] | np.ndarray,  # noqa: B027 - optional
                     orientation: Sequence[float] | np.ndarray = (1.0, 0.0, 0.0, 0.0)) -> None:
        """Put a scene entity at an episode's start pose (a simulation teleports it, at rest). A robot
        cannot: nothing moves (the object starts where it lies; ``reset_env_prompt`` asks to put it back)."""

    def use_gripper(self, controller: str, task_range: tuple[float, float]) -> None:  # noqa: B027
        """Commands for ``controller`` drive the gripper, the task's finger positions ``(closed, open)``
        spanning ``task_range``. A simulation has that controller already; a robot's connection reaches the
        gripper's driver (its interface and range are the connection's options) and waits for it."""

    def reset_gripper(self, controller: str, joints: Sequence[str], positions: Sequence[float]) -> None:
        """Put the gripper at an episode's start: its ``joints`` at ``positions`` (a simulation teleports
        them and holds them), or on a robot ``positions[0]`` commanded to the gripper's driver."""
        self.command(controller, np.asarray(positions[:1], dtype=np.float64))

    def limit_joints(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None:  # noqa: B027
        """A task's own joint range for the arm. A robot's safety rules take the tighter of it and theirs; a
        simulation has nothing to tighten (the task keeps its targets in range)."""

    # -- cameras --------------------------------------------------------------------------------
    def open_camera(self, request: CameraRequest) -> tuple[str, tuple[int, int]]:
        """Open the camera a task observes through and read a first image: a simulation renders a camera
        of its world (spawning the view camera first), a robot's connection subscribes to the driver's
        image topics. Returns the name :meth:`read_camera` takes and the images' ``(height, width)``."""
        raise EnvError(f"robot {self.robot_name!r}: this connection has no cameras")

    def read_camera(self, name: str, *, rgb: bool = True, depth: bool = False, width: int | None = None,
                    height: int | None = None, max_age: float = 1.0) -> Any:
        """Camera ``name``'s images now (``.rgb``, ``.depth``), at ``height`` x ``width`` when given."""
        raise EnvError(f"robot {self.robot_name!r}: this connection has no cameras")

    # -- acting and stepping -----------------------------------------------------------------
    @abstractmethod
    def command(self, controller: str, values: np.ndarray) -> None:
        """Command a controller (a 1-D finite vector; ``ValueError`` otherwise, nothing sent)."""

    def command_arm(self, controller: str, targets: np.ndarray, info: dict[str, Any]) -> None:
        """Command the arm's position ``controller`` (``targets`` in its joints' order). A simulation sends it
        with the next step; a robot's connection passes it through its safety rules to the driver's arm
        controller and puts their decision in ``info["safety"]``."""
        self.command(controller, targets)

    def before_act(self) -> None:  # noqa: B027 - optional hook
        """Checks before an action's commands go out (a real robot's watchdog)."""

    @abstractmethod
    def advance(self, info: dict[str, Any]) -> StepStatus:
        """One env step: commands take effect, time passes, the state is read. Adds what the step
        has to say to ``info`` (a real robot's state age and cycle time)."""

    # -- episodes -----------------------------------------------------------------------------
    @abstractmethod
    def reset(self, info: dict[str, Any]) -> None:
        """Before an episode's reset hooks: the world (simulation) or the robot link (real) made ready."""

    @abstractmethod
    def start_episode(self, info: dict[str, Any]) -> None:
        """After the reset hooks: the episode's first state is read."""

    @abstractmethod
    def move_to_initial_pose(self, names: Sequence[str], positions: npt.ArrayLike, tolerance: float = 1e-3) -> None:
        """Bring joints to an episode's initial pose (teleport in simulation, a slow move on a robot)."""

    # -- closing ------------------------------------------------------------------------------
    @abstractmethod
    def close(self) -> None:
        """Release what the connection holds (idempotent)."""
