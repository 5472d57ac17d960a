"""A task's scene on a real robot: what a simulation spawns and returns with each step, from the robot's side.

A push or pick-and-place task asks its connection for a scene (a table, an object) and reads their frames;
a simulation spawns them. On a robot the scene stands already:

* the movable object's pose comes from a tracker (a motion-capture system, a fiducial or a vision node)
  as ``geometry_msgs/PoseStamped`` on ``object_pose_topic``, in the robot's base frame
  (``object_pose_frame``; ``None`` accepts any frame). A pose older than ``object_pose_timeout`` is stale:
  the env stops and raises, as for stale joint states; malformed poses (NaN, not a unit quaternion,
  another frame) are dropped and named in that error;
* a fixture (the table) stands where the task says it is;
* the gripper takes the task's finger target through its driver's interface
  (:class:`~multiros.envs.real.gripper.RealGripper`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from multiros.envs.connection import SceneEntity
from multiros.envs.errors import EnvError
from multiros.envs.real.errors import RobotConnectionError, StaleStateError
from multiros.envs.real.gripper import RealGripper
from multiros.robot_state import RobotStates

__all__ = ["RealScene", "RealSceneOptions", "SceneConnection"]


class SceneConnection(Protocol):
    """What a real scene uses of its robot's connection (:class:`~multiros.envs.real.connection.RealConnection`):
    its node and driver link, the startup bound, where the base stands, the frames it serves, the
    controllers it routes, and the fault that stops the env."""

    node: Any
    link: Any
    startup_timeout: float
    fault: BaseException | None

    @property
    def base_position(self) -> np.ndarray: ...

    def add_frame_source(self, frame: str, poses: Callable[[RobotStates], Any]) -> None: ...

    def route_controller(self, controller: str, send: Callable[[np.ndarray], None]) -> None: ...


@dataclass(frozen=True)
class RealSceneOptions:
    """How a real robot's scene is reached (see the module docstring).

    Attributes:
        object_pose_topic: the tracker's ``PoseStamped`` topic (relative names: in the robot's namespace).
        object_pose_frame: the frame its poses must be in (``None``: any).
        object_pose_timeout: seconds after which a pose is stale.
        gripper_interface: how the driver takes gripper commands
            (:data:`~multiros.envs.real.gripper.GRIPPER_INTERFACES`).
        gripper_controller: the driver's gripper controller.
        gripper_joint: the joint a gripper trajectory commands.
        gripper_range: the driver's values at the task's (closed, open) fingers (``None``: the same).
        gripper_max_effort: a GripperCommand goal's effort limit (N; 0: the driver's default).
        gripper_followers: ``(joint, multiplier)`` of joints a trajectory or forward command drives
            with ``gripper_joint``, each at its multiplier times ``gripper_joint``'s value (a gripper
            whose two fingers are driven independently).
    """

    object_pose_topic: str = "/object_pose"
    object_pose_frame: str | None = None
    object_pose_timeout: float = 0.5
    gripper_interface: str = "forward"
    gripper_controller: str = "gripper_controller"
    gripper_joint: str = ""
    gripper_range: tuple[float, float] | None = None
    gripper_max_effort: float = 0.0
    gripper_followers: tuple[tuple[str, float], ...] = ()


def _standing(position: Sequence[float]) -> Callable[[RobotStates], tuple[np.ndarray, None]]:
    """A fixture's frame source: where the task says it stands (orientation: identity)."""
    where = np.asarray(position, dtype=np.float64).reshape(1, 3)

    def pose(states: RobotStates) -> tuple[np.ndarray, None]:
        return np.repeat(where, len(states.position), axis=0), None

    return pose


class RealScene:
    """One real robot's scene: its object tracker, its fixtures' frames and its gripper's driver."""

    def __init__(self, connection: SceneConnection, options: RealSceneOptions) -> None:
        self.connection = connection
        self.options = options
        self.object_pose: Any = None  # the tracker's PoseTopic, once the scene is added
        self.gripper: RealGripper | None = None

    def add(self, entities: Sequence[SceneEntity]) -> None:
        """Serve the entities' frames: the one movable object's from the tracker (waiting up to
        ``startup_timeout`` for its first pose), each fixture's where the task put it."""
        from multiros.envs.real.sensor_link import PoseTopic

        movable = [e for e in entities if e.movable]
        if len(movable) > 1:
            raise EnvError(f"a real robot's scene tracks one object, the task asks for {[e.name for e in movable]}")
        connection, opts = self.connection, self.options
        for entity in entities:
            if not entity.movable:
                connection.add_frame_source(entity.frame, _standing(entity.position))
        if not movable:
            return
        if self.object_pose is not None:  # a scene added again: the earlier tracker subscription goes
            self.object_pose.close()
        self.object_pose = PoseTopic(connection.node, connection.link.resolve(opts.object_pose_topic),
                                     opts.object_pose_frame)
        self.object_pose.wait_first(connection.startup_timeout)
        connection.add_frame_source(movable[0].frame, lambda _states: self._object_pose_latest())

    def _object_pose_latest(self) -> tuple[np.ndarray, np.ndarray]:
        """The tracker's newest object pose in the task's world, ``(1, 3)`` and ``(1, 4)``; a stale one
        stops the env (:class:`~multiros.envs.real.sensor_link.StaleSensorError`)."""
        try:
            position, quat = self.object_pose.latest(self.options.object_pose_timeout)
        except StaleStateError as exc:
            self.connection.fault = exc
            raise
        base = self.connection.base_position
        return (np.asarray(position, dtype=np.float64) + base)[None], np.asarray(quat, np.float64)[None]

    def use_gripper(self, controller: str, task_range: tuple[float, float]) -> None:
        """Reach the gripper's driver (waiting up to ``startup_timeout``) and route ``controller``'s
        commands to it."""
        opts, connection = self.options, self.connection
        if self.gripper is not None:
            self.gripper.close()
        self.gripper = RealGripper(connection, opts.gripper_interface, opts.gripper_controller, opts.gripper_joint,
                                   task_range, opts.gripper_range, opts.gripper_max_effort, opts.gripper_followers)
        wait = connection.startup_timeout
        if not self.gripper.wait_ready(wait):
            raise RobotConnectionError(
                f"nobody serves the gripper's {opts.gripper_interface} interface of controller "
                f"{opts.gripper_controller!r} within {wait:g} s: is the gripper driver running? "
                "(gripper_interface=, gripper_controller= name it)")
        gripper = self.gripper
        connection.route_controller(controller, lambda values: gripper.command(float(values[0])))

    def reset_gripper(self, controller: str, positions: Sequence[float]) -> None:
        """Command the gripper's episode start (the first finger's position) to its driver."""
        if self.gripper is None:
            raise EnvError(f"controller {controller!r}: the robot's gripper is not in use (use_gripper)")
        self.gripper.command(float(positions[0]))

    def close(self) -> None:
        """Release the tracker's subscription and the gripper's client."""
        for part in (self.object_pose, self.gripper):
            if part is not None:
                part.close()
        self.object_pose = self.gripper = None
