"""The plain records of the MuJoCo world: options, entity categories, reset scopes, entity and
joint state, the world-internal per-entity record, and the pose/vector validation they share.

Everything here is re-exported by :mod:`multiros.sim.world`; import the public names from there.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from multiros.sim.controller_manager import ControllerManager
from multiros.sim.controllers import RobotHardware
from multiros.sim.description import RobotDescription

__all__ = [
    "WorldOptions",
    "EntityCategory",
    "default_category",
    "ResetScope",
    "EntityInfo",
    "EntityState",
    "JointState",
]


@dataclass(frozen=True)
class WorldOptions:
    """Options of a :class:`~multiros.sim.world.World`.

    Attributes:
        timestep: physics time step in seconds.
        gravity: gravity vector, m/s^2.
        floor: add a ground plane at z = 0.
        lights: add a headlight-like directional light.
        integrator: ``"implicitfast"`` (default, stable with stiff position servos), ``"euler"``,
            ``"implicit"`` or ``"rk4"``.
        default_armature: armature (kg m^2) added to URDF joints that have none, for stability.
        gravity_compensation: default of :meth:`~multiros.sim.world.World.spawn`'s ``gravity_compensation``.
        camera: name of the default free camera pose: ``(lookat xyz, distance, azimuth deg, elevation deg)``.
        floor_color: the floor's tiles in rendered images, ``"light"`` (default) or ``"dark"``
            (:data:`~multiros.sim.world_model.FLOOR_COLORS`; no physics): a pale arm learnt from
            64 x 64 pixels only on the dark one (docs/tasks.md).
    """

    timestep: float = 0.002
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    floor: bool = True
    lights: bool = True
    integrator: str = "implicitfast"
    default_armature: float = 0.01
    gravity_compensation: bool = True
    camera: tuple[tuple[float, float, float], float, float, float] = ((0.0, 0.0, 0.3), 1.5, 135.0, -25.0)
    floor_color: str = "light"


if TYPE_CHECKING:
    from multiros.sim.entity_properties import CommandShaping, EntityProperties


class EntityCategory(enum.IntEnum):
    """Entity categories, numbered as ``simulation_interfaces/msg/EntityCategory``."""

    OBJECT = 0
    ROBOT = 1
    DYNAMIC_OBJECT = 4
    STATIC_OBJECT = 5


def default_category(desc: RobotDescription, floating: bool | None = None) -> EntityCategory:
    """The category of an entity spawned without one: a robot when its description has joints, else a
    static object when it is fixed (``floating=False``), else a dynamic one."""
    if desc.joints:
        return EntityCategory.ROBOT
    return EntityCategory.STATIC_OBJECT if floating is False else EntityCategory.DYNAMIC_OBJECT


class ResetScope(enum.IntFlag):
    """Reset scopes, numbered as ``simulation_interfaces/srv/ResetSimulation`` (a bit field)."""

    DEFAULT = 0  # same as ALL
    TIME = 1
    STATE = 2
    SPAWNED = 4
    ALL = 255


@dataclass(frozen=True)
class EntityInfo:
    """What the world knows about one entity (a plain record).

    Attributes:
        name: unique entity name; also the prefix ``"<name>/"`` of its MuJoCo element names.
        namespace: ROS namespace of the entity's topics (``"/<name>"`` unless given).
        category: see :class:`EntityCategory`.
        fixed_base: True when the root cannot move under physics (fixed robots, static objects).
        initial: True when the entity belongs to the initial world (kept by ``ResetScope.SPAWNED``).
        joint_names: the robot's 1-DoF joints (hinge/slide), in description order.
        frames: link and site names of the entity (unprefixed), usable with :meth:`~multiros.sim.world.World.frame_set`.
        controllers_yaml: the ros2_control controllers file the description referenced, if any.
        description: the URDF text (``robot_description``), or MJCF text for MJCF entities.
    """

    name: str
    namespace: str
    category: EntityCategory
    fixed_base: bool
    initial: bool
    joint_names: tuple[str, ...]
    frames: tuple[str, ...]
    controllers_yaml: Path | None
    description: str


@dataclass
class EntityState:
    """Pose and twist of an entity's root in the world frame.

    Attributes:
        position: (3,) metres.
        orientation: (4,) unit quaternion, **w x y z** (MuJoCo order; the node converts to ROS xyzw).
        linear_velocity: (3,) m/s, world frame.
        angular_velocity: (3,) rad/s, world frame.
    """

    position: np.ndarray
    orientation: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray


@dataclass
class JointState:
    """Joint state of one robot. Arrays are the robot's preallocated buffers, overwritten by the
    next :meth:`~multiros.sim.world.World.joint_state` call for the same robot: copy them if you keep them."""

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


def check_pose(position: Sequence[float] | None, orientation: Sequence[float] | None,
                what: str) -> tuple[np.ndarray | None, np.ndarray | None]:
    pos = quat = None
    if position is not None:
        pos = np.asarray(position, dtype=float).reshape(-1)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValueError(f"{what}: position must be 3 finite numbers, got {list(np.ravel(position))}")
    if orientation is not None:
        quat = np.asarray(orientation, dtype=float).reshape(-1)
        if quat.shape != (4,) or not np.all(np.isfinite(quat)):
            raise ValueError(f"{what}: orientation must be 4 finite numbers (w x y z), got "
                             f"{list(np.ravel(orientation))}")
        norm = float(np.linalg.norm(quat))
        if norm < 1e-9:
            raise ValueError(f"{what}: orientation quaternion is zero; use (1, 0, 0, 0) (w x y z) for identity")
        quat = quat / norm
    return pos, quat


def check_vec3(value: Sequence[float], what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be 3 finite numbers, got {list(np.ravel(value))}")
    return arr


class EntityRecord:
    """World-internal record of one entity: description, spawn state and resolved ids (not public API)."""

    def __init__(self, info: EntityInfo, desc: RobotDescription, pose: tuple[np.ndarray, np.ndarray],
                 floating: bool, initial_q: dict[str, float]) -> None:
        self.info, self.desc, self.floating = info, desc, floating
        self.name = info.name
        self.prefix = f"{info.name}/"
        self.spawn_pos, self.spawn_quat = pose
        self.initial_q = initial_q
        self.recipe: dict = {}  # World.spawn keyword arguments that re-create this entity identically
        self.actuated = desc.actuated_joints if info.category == EntityCategory.ROBOT else ()
        self.hw: RobotHardware | None = None
        self.cm: ControllerManager | None = None
        self.period = 1
        self.countdown = 0
        self.snap_countdown = 0
        self.ff_scale = np.zeros(0)  # kd/kp of position-mode joints: ctrl = q_d + (kd/kp) qdot_d
        self.js: JointState | None = None
        # resolved by world_model.bind_entity_ids after each compile
        self.root_bid = -1
        self.mocap_id = -1
        self.free_qadr = self.free_dadr = -1
        self.body_ids = np.zeros(0, dtype=np.intp)
        self.qpos_idx = np.zeros(0, dtype=np.intp)
        self.dof_idx = np.zeros(0, dtype=np.intp)
        self.jnt_qadr = np.zeros(0, dtype=np.intp)
        self.jnt_dadr = np.zeros(0, dtype=np.intp)
        self.act_ids = np.zeros(0, dtype=np.intp)
        self.act_qadr = np.zeros(0, dtype=np.intp)
        self.act_dadr = np.zeros(0, dtype=np.intp)
        self.effort_slot = np.zeros(0, dtype=np.intp)  # joint index of each actuator
        # set apart from the description (multiros.sim.entity_properties): rows given, command shaping
        self.properties: EntityProperties | None = None
        self.shaping: CommandShaping | None = None
