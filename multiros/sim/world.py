"""The MuJoCo world of the simulation node: entities, state, controllers, stepping.

Each entity is attached to one ``MjSpec`` under the name prefix ``"<name>/"``: a fixed-base robot
or static object hangs below a mocap body called ``<name>`` (so its base pose can be set without a
recompile); a floating entity's root body gets a free joint (an MJCF root's own free joint is
taken out by the description loader and replaced by this one, placed at the spawn pose). Spawning
and deleting recompile with ``MjSpec.recompile``, which carries the other entities' state over by
name; ids and addresses are then resolved again, once, and the step path uses only preallocated
index arrays. The entities spawned with ``initial=True`` (or marked by ``World.mark_launched``)
form the launched world, which ``reset(ResetScope.ALL)`` spawns again from their recorded recipes.

Collision filtering follows Gazebo's default (``self_collide`` false): robot geoms use
``contype=2, conaffinity=1``, everything else ``contype=1, conaffinity=3``, so robots touch the
floor and objects but not themselves or each other.

Threading: ``World`` starts no threads and holds no lock. The caller (the node) serialises
access; :class:`RealTimeRunner` holds its lock while it steps, and the node takes the same lock
(``runner.lock``) around service callbacks.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import re
import threading
import time as _time
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.controllers import ControllerManager, JointMode, RobotHardware
from multiros.sim.description import MeshCache, RobotDescription, load_description
from multiros.sim.errors import (
    ControllerError,
    DescriptionError,
    EntityError,
    StepInterruptedError,
    UnstableSimulationError,
)
from multiros.sim.limits import STEP_CHUNK
from multiros.sim.packages import PackageIndex, default_index

__all__ = [
    "WorldOptions",
    "EntityCategory",
    "ResetScope",
    "EntityInfo",
    "EntityState",
    "JointState",
    "FrameSet",
    "World",
    "RealTimeRunner",
]


@dataclass(frozen=True)
class WorldOptions:
    """Options of a :class:`World`.

    Attributes:
        timestep: physics time step in seconds.
        gravity: gravity vector, m/s^2.
        floor: add a ground plane at z = 0.
        lights: add a headlight-like directional light.
        integrator: ``"implicitfast"`` (default, stable with stiff position servos), ``"euler"``,
            ``"implicit"`` or ``"rk4"``.
        default_armature: armature (kg m^2) added to URDF joints that have none, for stability.
        gravity_compensation: default of :meth:`World.spawn`'s ``gravity_compensation``.
        camera: name of the default free camera pose: ``(lookat xyz, distance, azimuth deg, elevation deg)``.
    """

    timestep: float = 0.002
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    floor: bool = True
    lights: bool = True
    integrator: str = "implicitfast"
    default_armature: float = 0.01
    gravity_compensation: bool = True
    camera: tuple[tuple[float, float, float], float, float, float] = ((0.0, 0.0, 0.3), 1.5, 135.0, -25.0)


class EntityCategory(enum.IntEnum):
    """Entity categories, numbered as ``simulation_interfaces/msg/EntityCategory``."""

    OBJECT = 0
    ROBOT = 1
    DYNAMIC_OBJECT = 4
    STATIC_OBJECT = 5


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
        frames: link and site names of the entity (unprefixed), usable with :meth:`World.frame_set`.
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
    next :meth:`World.joint_state` call for the same robot: copy them if you keep them."""

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_ROBOT_CONTYPE, _ROBOT_CONAFFINITY = 2, 1
_WORLD_CONTYPE, _WORLD_CONAFFINITY = 1, 3
_SERVO_WN = 50.0  # rad/s: natural frequency of the default position servos (critically damped)
_VELOCITY_GAIN = 1000.0  # 1/s: default velocity servo bandwidth (kv = inertia x this); implicit, so stable
_BAD_WARNINGS = tuple(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
                                       mujoco.mjtWarning.mjWARN_BADQVEL))
_MJ_HINGE, _MJ_SLIDE, _MJ_FREE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE),
                                  int(mujoco.mjtJoint.mjJNT_FREE))
_DEFAULT_CONTROLLERS = {
    "controller_manager": {"ros__parameters": {
        "joint_state_broadcaster": {"type": "joint_state_broadcaster/JointStateBroadcaster"},
        "position_controller": {"type": "position_controllers/JointGroupPositionController"}}},
}


def _check_pose(position: Sequence[float] | None, orientation: Sequence[float] | None,
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


def _check_vec3(value: Sequence[float], what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be 3 finite numbers, got {list(np.ravel(value))}")
    return arr


class _Entity:
    """World-internal record of one entity: description, spawn state and resolved ids."""

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
        # resolved by World._bind
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


class FrameSet:
    """Several frames (links or sites) whose world poses are fetched together, ids resolved once.

    Create with :meth:`World.frame_set`. The world re-resolves the ids after each recompile
    (spawn/delete), so keep using the same object; it raises EntityError once its entity is gone.
    """

    def __init__(self, world: World, frames: Sequence[str], entity: str | None) -> None:
        self._world = world
        self.names = tuple(frames)
        self.entity = entity
        n = len(self.names)
        self._out = np.zeros((n, 7))
        self._pos = np.zeros((n, 3))
        self._stale = ""
        self._bind()

    def _bind(self) -> None:
        world, model = self._world, self._world.model
        bodies, sites = [], []
        if self.entity is not None and not world.has_entity(self.entity):
            self._stale = f"frame set {list(self.names)}: entity '{self.entity}' was deleted"
            return
        ent = world._entities[self.entity] if self.entity is not None else None
        for i, frame in enumerate(self.names):
            if ent is not None:
                body_name = ent.prefix + ent.desc.body_name(frame) if frame in ent.desc.links else None
                site_name = ent.prefix + frame
            else:
                body_name, site_name = frame, frame
            bid = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_BODY), body_name) if body_name else -1
            if bid >= 0:
                bodies.append((i, bid))
                continue
            sid = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_SITE), site_name)
            if sid < 0:
                known = sorted(ent.info.frames) if ent is not None else "(full '<entity>/<frame>' names)"
                where = f"entity '{self.entity}'" if ent is not None else "the world"
                raise EntityError(f"frame '{frame}' is not a link or site of {where}; known frames: {known}")
            sites.append((i, sid))
        self._b_rows = np.array([r for r, _ in bodies], dtype=np.intp)
        self._b_ids = np.array([b for _, b in bodies], dtype=np.intp)
        self._s_rows = [r for r, _ in sites]
        self._s_ids = [s for _, s in sites]
        self._s_ids_arr = np.array(self._s_ids, dtype=np.intp)
        self._s_rows_arr = np.array(self._s_rows, dtype=np.intp)
        self._stale = ""

    def _check(self) -> None:
        if self._stale:
            raise EntityError(self._stale)

    def poses(self) -> np.ndarray:
        """Return an (n, 7) array ``[x, y, z, qw, qx, qy, qz]`` per frame (a preallocated buffer)."""
        self._check()
        data, out = self._world.data, self._out
        if self._b_ids.size:
            out[self._b_rows, :3] = data.xpos[self._b_ids]
            out[self._b_rows, 3:] = data.xquat[self._b_ids]
        for row, sid in zip(self._s_rows, self._s_ids):
            out[row, :3] = data.site_xpos[sid]
            mujoco.mju_mat2Quat(out[row, 3:], data.site_xmat[sid])
        return out

    def positions(self) -> np.ndarray:
        """Return an (n, 3) array of frame positions (a preallocated buffer)."""
        self._check()
        data = self._world.data
        if self._b_ids.size:
            self._pos[self._b_rows] = data.xpos[self._b_ids]
        if self._s_ids_arr.size:
            self._pos[self._s_rows_arr] = data.site_xpos[self._s_ids_arr]
        return self._pos


class World:
    """A MuJoCo world holding robots and objects, each an entity with a name and a namespace.

    Args:
        options: physics and scene options.
        package_index: resolves ``package://`` and ``$(find ...)``; the default index otherwise.
        mesh_cache: directory for converted meshes (default ``$XDG_CACHE_HOME/uniros/meshes``).
    """

    def __init__(self, options: WorldOptions | None = None, *, package_index: PackageIndex | None = None,
                 mesh_cache: Path | None = None) -> None:
        self.options = options or WorldOptions()
        if not self.options.timestep > 0:
            raise ValueError(f"timestep must be > 0, got {self.options.timestep}")
        self.index = package_index or default_index()
        self.mesh_cache = MeshCache(mesh_cache)
        self._entities: dict[str, _Entity] = {}
        self._launched: dict[str, dict] = {}  # the launched world: spawn recipes, in spawn order
        self._frame_sets: weakref.WeakSet[FrameSet] = weakref.WeakSet()
        self._callbacks: list[Callable[[], None]] = []
        self._spec = self._base_spec()
        self._model = self._spec.compile()
        self._data = mujoco.MjData(self._model)
        self._varying: tuple[_Entity, ...] = ()
        self._closed = False
        self._bind()

    def _base_spec(self) -> mujoco.MjSpec:
        opts = self.options
        spec = mujoco.MjSpec()
        spec.modelname = "uniros_world"
        spec.compiler.degree = False
        spec.option.timestep = opts.timestep
        spec.option.gravity = list(_check_vec3(opts.gravity, "gravity"))
        integrators = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "rk4": mujoco.mjtIntegrator.mjINT_RK4,
                       "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                       "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
        if opts.integrator not in integrators:
            raise ValueError(f"integrator '{opts.integrator}' is not one of {sorted(integrators)}")
        spec.option.integrator = int(integrators[opts.integrator])
        # MuJoCo would reset *all* of mjData on a bad state; we restore only the affected entity.
        spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        spec.visual.global_.offwidth = 1920
        spec.visual.global_.offheight = 1080
        if opts.floor:
            spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                                    rgba=[0.8, 0.8, 0.8, 1], contype=_WORLD_CONTYPE,
                                    conaffinity=_WORLD_CONAFFINITY)
        if opts.lights:
            spec.worldbody.add_light(name="sun", pos=[0, 0, 3], dir=[0, 0, -1], diffuse=[0.8, 0.8, 0.8])
        return spec

    # ------------------------------------------------------------------ binding (after each compile)
    def _bind(self) -> None:
        m = self._model
        for ent in self._entities.values():
            self._bind_entity(ent)
        self._varying = tuple(e for e in self._entities.values() if e.cm is not None and e.cm.time_varying)
        self._sync_warn_counts()
        self._state_spec = int(mujoco.mjtState.mjSTATE_INTEGRATION)
        self._snap = np.zeros(mujoco.mj_stateSize(m, self._state_spec))
        for fs in list(self._frame_sets):
            fs._bind()

    def _bind_entity(self, ent: _Entity) -> None:
        m = self._model
        if ent.floating:
            ent.root_bid = m.body(ent.prefix + ent.desc.body_name(ent.desc.root)).id
            free = m.body_jntadr[ent.root_bid]
            ent.free_qadr, ent.free_dadr = int(m.jnt_qposadr[free]), int(m.jnt_dofadr[free])
            ent.mocap_id = -1
        else:
            ent.root_bid = m.body(ent.name).id
            ent.mocap_id = int(m.body_mocapid[ent.root_bid])
        ent.body_ids = np.flatnonzero(m.body_rootid == ent.root_bid).astype(np.intp)
        jnts = np.flatnonzero(np.isin(m.jnt_bodyid, ent.body_ids))
        q, dof = [], []
        for j in jnts:
            width = {_MJ_FREE: 7, 1: 4}.get(int(m.jnt_type[j]), 1)
            q.extend(range(m.jnt_qposadr[j], m.jnt_qposadr[j] + width))
            dof.extend(range(m.jnt_dofadr[j], m.jnt_dofadr[j] + {_MJ_FREE: 6, 1: 3}.get(int(m.jnt_type[j]), 1)))
        ent.qpos_idx, ent.dof_idx = np.array(q, dtype=np.intp), np.array(dof, dtype=np.intp)
        names = ent.info.joint_names
        ent.jnt_qadr = np.array([m.jnt_qposadr[m.joint(ent.prefix + n).id] for n in names], dtype=np.intp)
        ent.jnt_dadr = np.array([m.jnt_dofadr[m.joint(ent.prefix + n).id] for n in names], dtype=np.intp)
        ent.act_ids = np.array([m.actuator(ent.prefix + n).id for n in ent.actuated], dtype=np.intp)
        slot = {n: i for i, n in enumerate(names)}
        ent.effort_slot = np.array([slot[n] for n in ent.actuated], dtype=np.intp)
        ent.act_qadr = ent.jnt_qadr[ent.effort_slot] if ent.actuated else np.zeros(0, dtype=np.intp)
        ent.act_dadr = ent.jnt_dadr[ent.effort_slot] if ent.actuated else np.zeros(0, dtype=np.intp)
        if ent.hw is not None:
            ent.hw.dirty = True
            self._write_actuators(ent)
        self._update_period(ent)

    def _update_period(self, ent: _Entity) -> None:
        rate = ent.cm.update_rate if ent.cm is not None else None
        dt = self._model.opt.timestep
        ent.period = max(1, int(round(1.0 / (rate * dt)))) if rate else 1
        ent.countdown = 0

    # ------------------------------------------------------------------ entities
    def spawn(self, name: str, description: str | Path | RobotDescription, *,
              pose: tuple[Sequence[float], Sequence[float]] | None = None,
              namespace: str | None = None, category: EntityCategory | None = None,
              xacro_args: Mapping[str, str] | None = None, floating: bool | None = None,
              joint_positions: Mapping[str, float] | None = None,
              controllers: Sequence[str] | None = None, controllers_yaml: str | Path | Mapping | None = None,
              gravity_compensation: bool | None = None, initial: bool = False) -> EntityInfo:
        """Add an entity; the other entities keep their state (qpos, qvel, controllers, time).

        Args:
            name: unique entity name (letters, digits, ``_``, not starting with a digit).
            description: a path or URI (``package://``, ``file://``) to a ``.urdf``, ``.xacro``,
                ``.urdf.xacro`` or MJCF ``.xml`` file; an XML string (URDF, xacro or MJCF); or a
                :class:`~multiros.sim.description.RobotDescription`.
            pose: ``(xyz, quat wxyz)`` of the root in the world; identity when None.
            namespace: ROS namespace (default ``"/<name>"``).
            category: default ROBOT for descriptions with joints, DYNAMIC_OBJECT for a floating
                body without joints, STATIC_OBJECT for a fixed one.
            xacro_args: ``$(arg ...)`` values for xacro.
            floating: give the root a free joint (default: True for MJCF whose root body has a
                free joint and for objects without joints, False for other robots and static objects).
                A free entity's pose is the free joint's; its base is never welded.
            joint_positions: initial joint positions by joint name (also the reset state); default
                the ``<ros2_control>`` ``initial_value``, else 0 clamped into the limits.
            controllers: controllers to load and activate (default: all the YAML defines, in order,
                skipping those whose command interfaces are already claimed).
            controllers_yaml: ros2_control YAML (path or parsed mapping); default: the file the
                description references (``<gazebo><plugin><parameters>``), else a joint state
                broadcaster plus a ``position_controller`` (JointGroupPositionController) on all joints.
            gravity_compensation: compensate gravity on the bodies of a fixed-base robot (default
                from options; free-floating entities always feel gravity).
            initial: part of the launched world: kept by ``reset(ResetScope.SPAWNED)``, spawned
                again as now by ``reset(ResetScope.ALL)`` (see :meth:`mark_launched`).

        Returns:
            The new entity's :class:`EntityInfo`.

        Raises:
            EntityError: the name is taken or invalid.
            DescriptionError: the description cannot be loaded (``missing_assets`` tells meshes apart).
            ValueError: invalid pose (zero or non-finite quaternion, non-finite position) or
                joint positions outside limits.
            ControllerError: the controllers YAML or list is invalid.
        """
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise EntityError(f"entity name {name!r} is invalid; use letters, digits and '_', not starting "
                              f"with a digit")
        if name in self._entities:
            raise EntityError(f"entity '{name}' already exists; delete it first or pick another name")
        pos, quat = _check_pose(*(pose if pose is not None else (None, None)), what=f"spawn '{name}' pose")
        pos = np.zeros(3) if pos is None else pos
        quat = np.array([1.0, 0.0, 0.0, 0.0]) if quat is None else quat
        desc = description if isinstance(description, RobotDescription) else load_description(
            description, args=xacro_args, index=self.index, mesh_cache=self.mesh_cache,
            default_armature=self.options.default_armature)
        if category is None:
            category = EntityCategory.ROBOT if desc.joints else (
                EntityCategory.STATIC_OBJECT if floating is False else EntityCategory.DYNAMIC_OBJECT)
        category = EntityCategory(category)
        if floating is None:
            floating = desc.free_root or (
                category in (EntityCategory.DYNAMIC_OBJECT, EntityCategory.OBJECT) and not desc.joints)
        if category == EntityCategory.STATIC_OBJECT:
            floating = False
        initial_q = self._initial_joint_positions(name, desc, joint_positions)
        info = EntityInfo(name=name, namespace=namespace if namespace is not None else f"/{name}",
                          category=category, fixed_base=not floating, initial=initial,
                          joint_names=tuple(j.name for j in desc.joints),
                          frames=tuple(desc.links) + tuple(s.name for s in desc.spec.sites
                                                           if s.name not in desc.links),
                          controllers_yaml=desc.controllers_yaml, description=desc.text)
        ent = _Entity(info, desc, (pos, quat), floating, initial_q)
        gravcomp = self.options.gravity_compensation if gravity_compensation is None else gravity_compensation
        added = self._add_to_spec(ent, gravcomp and category == EntityCategory.ROBOT and not floating)
        self._entities[name] = ent
        try:
            self._recompile()
        except Exception as exc:
            del self._entities[name]
            self._remove_from_spec(ent, added)
            self._recompile()
            raise DescriptionError(f"spawn '{name}': the model does not compile: {exc}", source=desc.source) from exc
        try:
            self._apply_initial(ent)
            if category == EntityCategory.ROBOT and ent.actuated:
                self._setup_controllers(ent, controllers, controllers_yaml)
            self._varying = tuple(e for e in self._entities.values() if e.cm is not None and e.cm.time_varying)
            mujoco.mj_forward(self._model, self._data)
        except Exception:
            self.delete(name)
            raise
        ent.recipe = {"description": desc, "pose": (pos.copy(), quat.copy()), "namespace": info.namespace,
                      "category": category, "floating": floating,
                      "joint_positions": dict(joint_positions) if joint_positions else None,
                      "controllers": list(controllers) if controllers is not None else None,
                      "controllers_yaml": controllers_yaml, "gravity_compensation": bool(gravcomp)}
        if initial:
            self._launched.pop(name, None)
            self._launched[name] = ent.recipe
        return info

    def mark_launched(self, names: Sequence[str] | None = None) -> tuple[str, ...]:
        """Make entities part of the launched world (default: every entity present now).

        ``reset(ResetScope.ALL)`` deletes every entity and spawns the launched ones again, in their
        spawn order, exactly as they were spawned (pose, initial joint positions, controllers);
        ``reset(ResetScope.SPAWNED)`` keeps them. Equivalent to spawning with ``initial=True``.
        Returns the names marked.

        Raises:
            EntityError: an unknown entity.
        """
        chosen = list(self._entities) if names is None else list(names)
        ents = [self._get(n) for n in chosen]
        for ent in sorted(ents, key=lambda e: list(self._entities).index(e.name)):
            ent.info = dataclasses.replace(ent.info, initial=True)
            self._launched.pop(ent.name, None)
            self._launched[ent.name] = ent.recipe
        return tuple(chosen)

    def launched_entities(self) -> tuple[str, ...]:
        """Names of the launched world's entities (what ``reset(ResetScope.ALL)`` brings back)."""
        return tuple(self._launched)

    def _initial_joint_positions(self, name: str, desc: RobotDescription,
                                 given: Mapping[str, float] | None) -> dict[str, float]:
        joints = {j.name: j for j in desc.joints}
        out = {}
        for rc in desc.ros2_control:
            if rc.initial_position is not None and rc.name in joints:
                out[rc.name] = rc.initial_position
        for jname, value in (given or {}).items():
            if jname not in joints:
                raise EntityError(f"spawn '{name}': unknown joint '{jname}' in joint_positions; joints are "
                                  f"{list(joints)}")
            out[jname] = float(value)
        for jname, value in out.items():
            j = joints[jname]
            if not math.isfinite(value) or (j.limited and not j.lower <= value <= j.upper):
                raise ValueError(f"spawn '{name}': initial position {value} of joint '{jname}' is outside "
                                 f"[{j.lower}, {j.upper}]")
        for j in desc.joints:
            if j.name not in out and j.limited and not j.lower <= 0.0 <= j.upper:
                out[j.name] = min(max(0.0, j.lower), j.upper)
        return out

    def _add_to_spec(self, ent: _Entity, gravcomp: bool) -> dict:
        spec, desc = self._spec, ent.desc
        child = desc.spec.copy()
        robot = ent.info.category == EntityCategory.ROBOT
        for geom in child.geoms:
            if geom.contype or geom.conaffinity:
                geom.contype, geom.conaffinity = ((_ROBOT_CONTYPE, _ROBOT_CONAFFINITY) if robot
                                                  else (_WORLD_CONTYPE, _WORLD_CONAFFINITY))
        if gravcomp:
            for body in child.bodies:
                if body is not child.worldbody:
                    body.gravcomp = 1.0
        src_root = child.worldbody.first_body()
        if ent.floating:
            frame = spec.worldbody.add_frame(pos=ent.spawn_pos, quat=ent.spawn_quat)
            root = frame.attach_body(src_root, ent.prefix, "")
            root.add_freejoint(name=ent.prefix + "__free__")
            holder = root
        else:
            holder = spec.worldbody.add_body(name=ent.name, pos=ent.spawn_pos, quat=ent.spawn_quat, mocap=True)
            holder.add_frame().attach_body(src_root, ent.prefix, "")
        actuators = []
        efforts = {j.name: j.effort for j in desc.joints}
        for jname in ent.actuated:
            act = spec.add_actuator(name=ent.prefix + jname, target=ent.prefix + jname,
                                    trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            act.ctrllimited = int(mujoco.mjtLimited.mjLIMITED_FALSE)
            if efforts.get(jname, 0.0) > 0:
                act.forcelimited = int(mujoco.mjtLimited.mjLIMITED_TRUE)
                act.forcerange = [-efforts[jname], efforts[jname]]
            actuators.append(act)
        return {"holder": holder, "actuators": actuators}

    def _remove_from_spec(self, ent: _Entity, added: dict | None = None) -> None:
        spec = self._spec
        for act in list(spec.actuators):
            if act.name.startswith(ent.prefix):
                spec.delete(act)
        holder = spec.body(ent.name) if not ent.floating else spec.body(ent.prefix + ent.desc.body_name(ent.desc.root))
        if holder is not None:
            parent_frame = holder.frame if ent.floating else None
            spec.delete(holder)
            if parent_frame is not None:
                try:
                    spec.delete(parent_frame)
                except Exception:  # the frame is deleted with its body in some MuJoCo versions
                    pass
        for collection in (spec.meshes, spec.materials, spec.textures):
            for element in list(collection):
                if element.name.startswith(ent.prefix):
                    spec.delete(element)

    def _recompile(self) -> None:
        self._model, self._data = self._spec.recompile(self._model, self._data)
        self._bind()
        for callback in list(self._callbacks):
            callback()

    def _apply_initial(self, ent: _Entity) -> None:
        """Put an entity in its spawn state (joints at their initial positions, at rest)."""
        d = self._data
        m = self._model
        d.qpos[ent.qpos_idx] = m.qpos0[ent.qpos_idx]
        d.qvel[ent.dof_idx] = 0.0
        for i, jname in enumerate(ent.info.joint_names):
            if jname in ent.initial_q:
                d.qpos[ent.jnt_qadr[i]] = ent.initial_q[jname]
        if ent.mocap_id >= 0:
            d.mocap_pos[ent.mocap_id] = ent.spawn_pos
            d.mocap_quat[ent.mocap_id] = ent.spawn_quat

    def _setup_controllers(self, ent: _Entity, controllers: Sequence[str] | None,
                           config: str | Path | Mapping | None) -> None:
        m, d = self._model, self._data
        mujoco.mj_forward(m, d)
        joints = {j.name: j for j in ent.desc.joints}
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        mass = full[ent.act_dadr, ent.act_dadr]  # joint-space inertia (with armature) at the spawn pose
        lower = np.array([joints[j].lower for j in ent.actuated])
        upper = np.array([joints[j].upper for j in ent.actuated])
        effort = np.array([joints[j].effort for j in ent.actuated])
        velocity = np.array([joints[j].velocity for j in ent.actuated])
        damping = np.array([joints[j].damping for j in ent.actuated])
        kp, kd = mass * _SERVO_WN ** 2, 2.0 * mass * _SERVO_WN
        kv = mass * _VELOCITY_GAIN + 20.0 * damping  # stiff enough to dominate joint damping/friction
        ent.hw = RobotHardware(ent.actuated, lower, upper, effort, velocity, kp, kd, kv=kv)
        self._read_state(ent)
        if config is None:
            config = ent.desc.controllers_yaml if ent.desc.controllers_yaml is not None else _DEFAULT_CONTROLLERS
        ent.cm = ControllerManager(ent.hw, config)
        ent.cm.refresh_state = lambda: self._read_state(ent)
        ent.cm.on_change = lambda: self._controllers_changed(ent)
        self._update_period(ent)
        ent.cm.spawn(controllers, time=d.time)
        ent.js = JointState(ent.info.joint_names, np.zeros(len(ent.info.joint_names)),
                            np.zeros(len(ent.info.joint_names)), np.zeros(len(ent.info.joint_names)))
        self._write_actuators(ent)

    def _read_state(self, ent: _Entity) -> None:
        hw, d = ent.hw, self._data
        hw.position[:] = d.qpos[ent.act_qadr]
        hw.velocity[:] = d.qvel[ent.act_dadr]
        hw.effort[:] = d.actuator_force[ent.act_ids]

    def _write_actuators(self, ent: _Entity) -> None:
        hw = ent.hw
        if hw is None:
            return
        if hw.dirty:
            m = self._model
            for i, act in enumerate(ent.act_ids):
                mode = int(hw.mode[i])
                gain, bias = m.actuator_gainprm[act], m.actuator_biasprm[act]
                gain[:] = 0.0
                bias[:] = 0.0
                if mode == int(JointMode.POSITION):
                    gain[0], bias[1], bias[2] = hw.kp[i], -hw.kp[i], -hw.kd[i]
                elif mode == int(JointMode.VELOCITY):
                    gain[0], bias[2] = hw.kv[i], -hw.kv[i]
                else:
                    gain[0] = 1.0
            pos = hw.mode == int(JointMode.POSITION)
            ent.ff_scale = np.where(pos, hw.kd / np.where(hw.kp > 0, hw.kp, 1.0), 0.0)
            hw.dirty = False
        self._data.ctrl[ent.act_ids] = hw.command + ent.ff_scale * hw.command_velocity

    def delete(self, name: str) -> None:
        """Remove an entity; the others keep their state. Raises EntityError if unknown."""
        ent = self._get(name)
        self._remove_from_spec(ent)
        del self._entities[name]
        self._recompile()
        mujoco.mj_forward(self._model, self._data)

    def entity_names(self) -> tuple[str, ...]:
        """Names of all entities, in spawn order."""
        return tuple(self._entities)

    def entity(self, name: str) -> EntityInfo:
        """The :class:`EntityInfo` of ``name``. Raises EntityError if unknown."""
        return self._get(name).info

    def has_entity(self, name: str) -> bool:
        """True when an entity called ``name`` exists."""
        return name in self._entities

    def _get(self, name: str) -> _Entity:
        try:
            return self._entities[name]
        except KeyError:
            raise EntityError(f"unknown entity '{name}'; entities are {list(self._entities)}") from None

    def _robot(self, name: str) -> _Entity:
        ent = self._get(name)
        if ent.cm is None:
            raise EntityError(f"entity '{name}' is not a robot with actuated joints")
        return ent

    def get_entity_state(self, name: str) -> EntityState:
        """Root pose and twist of an entity in the world frame (fresh arrays)."""
        ent, d = self._get(name), self._data
        if ent.floating:
            a, v = ent.free_qadr, ent.free_dadr
            quat = d.qpos[a + 3:a + 7].copy()
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, quat)
            return EntityState(d.qpos[a:a + 3].copy(), quat, d.qvel[v:v + 3].copy(),
                               rot.reshape(3, 3) @ d.qvel[v + 3:v + 6])
        return EntityState(d.xpos[ent.root_bid].copy(), d.xquat[ent.root_bid].copy(), np.zeros(3), np.zeros(3))

    def set_entity_state(self, name: str, *, position: Sequence[float] | None = None,
                         orientation: Sequence[float] | None = None,
                         linear_velocity: Sequence[float] | None = None,
                         angular_velocity: Sequence[float] | None = None) -> None:
        """Teleport an entity's root and/or set its twist. None leaves a field unchanged.

        Fixed-base robots and static objects move their base (their twist must be zero).
        The quaternion (wxyz) is normalised; a zero or non-finite one raises ValueError.

        Raises:
            EntityError: unknown entity.
            ValueError: bad quaternion/position, or a non-zero twist for a fixed-base entity.
        """
        ent, d = self._get(name), self._data
        pos, quat = _check_pose(position, orientation, f"set_entity_state '{name}'")
        lin = _check_vec3(linear_velocity, "linear_velocity") if linear_velocity is not None else None
        ang = _check_vec3(angular_velocity, "angular_velocity") if angular_velocity is not None else None
        if ent.floating:
            a, v = ent.free_qadr, ent.free_dadr
            if pos is not None:
                d.qpos[a:a + 3] = pos
            if quat is not None:
                d.qpos[a + 3:a + 7] = quat
            if lin is not None:
                d.qvel[v:v + 3] = lin
            if ang is not None:
                rot = np.zeros(9)
                mujoco.mju_quat2Mat(rot, d.qpos[a + 3:a + 7])
                d.qvel[v + 3:v + 6] = rot.reshape(3, 3).T @ ang
        else:
            if (lin is not None and np.any(lin)) or (ang is not None and np.any(ang)):
                raise ValueError(f"entity '{name}' has a fixed base; it cannot be given a non-zero twist")
            if pos is not None:
                d.mocap_pos[ent.mocap_id] = pos
            if quat is not None:
                d.mocap_quat[ent.mocap_id] = quat
        mujoco.mj_forward(self._model, d)

    def bounds(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned world bounding box ``(lower xyz, upper xyz)`` of an entity's geoms."""
        ent, m, d = self._get(name), self._model, self._data
        geoms = np.flatnonzero(np.isin(m.geom_bodyid, ent.body_ids))
        if geoms.size == 0:
            p = d.xpos[ent.root_bid].copy()
            return p, p.copy()
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        pts = []
        for g in geoms:
            center, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
            local = center + signs * half
            pts.append(d.geom_xpos[g] + local @ d.geom_xmat[g].reshape(3, 3).T)
        allpts = np.vstack(pts)
        return allpts.min(axis=0), allpts.max(axis=0)

    # ------------------------------------------------------------------ joints
    def joint_names(self, name: str) -> tuple[str, ...]:
        """The robot's joint names (unprefixed), in the order of :meth:`joint_state`."""
        return self._get(name).info.joint_names

    def joint_state(self, name: str) -> JointState:
        """Positions, velocities and efforts (actuator forces) of the robot's joints."""
        ent, d = self._get(name), self._data
        js = ent.js
        if js is None:
            n = len(ent.info.joint_names)
            js = ent.js = JointState(ent.info.joint_names, np.zeros(n), np.zeros(n), np.zeros(n))
        js.position[:] = d.qpos[ent.jnt_qadr]
        js.velocity[:] = d.qvel[ent.jnt_dadr]
        if ent.act_ids.size:
            js.effort[ent.effort_slot] = d.actuator_force[ent.act_ids]
        return js

    def set_joint_positions(self, name: str, names: Sequence[str], positions: Sequence[float],
                            velocities: Sequence[float] | None = None, *, hold: bool = True) -> None:
        """Teleport joints (no physics) and run forward kinematics.

        Args:
            name: robot entity.
            names: joint names (unprefixed); any subset of the robot's joints.
            positions: new positions, within the joint limits.
            velocities: new velocities (default zero).
            hold: make the new positions the setpoints of active position/trajectory controllers.

        Raises:
            EntityError: unknown entity or joint name.
            ValueError: NaN/inf or outside the limits, or lengths differ.
        """
        ent, d = self._get(name), self._data
        names = list(names)
        pos = np.asarray(positions, dtype=float).reshape(-1)
        vel = np.zeros(len(names)) if velocities is None or len(velocities) == 0 else \
            np.asarray(velocities, dtype=float).reshape(-1)
        if pos.shape[0] != len(names) or vel.shape[0] != len(names):
            raise ValueError(f"set_joint_positions '{name}': {len(names)} names, {pos.shape[0]} positions, "
                             f"{vel.shape[0]} velocities; the lengths must match")
        slot = {n: i for i, n in enumerate(ent.info.joint_names)}
        unknown = [n for n in names if n not in slot]
        if unknown:
            raise EntityError(f"entity '{name}' has no joint(s) {unknown}; joints are {list(slot)}")
        joints = {j.name: j for j in ent.desc.joints}
        for n, p, v in zip(names, pos, vel):
            j = joints[n]
            if not (math.isfinite(p) and math.isfinite(v)):
                raise ValueError(f"joint '{n}': position/velocity must be finite, got {p}, {v}")
            if j.limited and not j.lower - 1e-9 <= p <= j.upper + 1e-9:
                raise ValueError(f"joint '{n}': position {p} is outside its limits [{j.lower}, {j.upper}]")
        idx = np.array([slot[n] for n in names], dtype=np.intp)
        d.qpos[ent.jnt_qadr[idx]] = pos
        d.qvel[ent.jnt_dadr[idx]] = vel
        mujoco.mj_forward(self._model, d)
        if hold and ent.cm is not None:
            self._read_state(ent)
            ent.cm.hold(d.time)
            self._write_actuators(ent)

    # ------------------------------------------------------------------ frames
    def frame_set(self, frames: Sequence[str], entity: str | None = None) -> FrameSet:
        """Resolve link/site names once for fast per-step pose reads.

        Args:
            frames: link or site names; unprefixed when ``entity`` is given, else full names
                (``"<entity>/<link>"``) or world-level site names.
            entity: the entity the names belong to.

        Raises:
            EntityError: an unknown entity or frame (the message lists the known frames).
        """
        if entity is not None:
            self._get(entity)
        fs = FrameSet(self, frames, entity)
        self._frame_sets.add(fs)
        return fs

    def frame_pose(self, frame: str, entity: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World pose ``(xyz, quat wxyz)`` of one frame (convenience; use a FrameSet per step)."""
        pose = FrameSet(self, [frame], entity).poses()[0]
        return pose[:3].copy(), pose[3:].copy()

    # ------------------------------------------------------------------ controllers
    def controller_manager(self, name: str) -> ControllerManager:
        """The robot's :class:`~multiros.sim.controllers.ControllerManager`.

        Load/configure/switch/unload on it directly; the world is told of switches through the
        manager's hooks. Commands given directly to a controller take effect at the next step.
        """
        return self._robot(name).cm

    def controllers_changed(self, name: str) -> None:
        """Re-read a robot's active controllers and actuator modes. The ControllerManager's hooks
        already do this on every switch; calling it again is harmless."""
        self._controllers_changed(self._robot(name))

    def _controllers_changed(self, ent: _Entity) -> None:
        self._varying = tuple(e for e in self._entities.values() if e.cm is not None and e.cm.time_varying)
        ent.countdown = 0
        self._write_actuators(ent)

    def switch_controllers(self, name: str, activate: Sequence[str] = (), deactivate: Sequence[str] = (),
                           *, strict: bool = True) -> list[str]:
        """``ControllerManager.switch`` for a robot, applied to the actuators at once.

        Controllers named in ``activate`` that are not loaded yet are loaded and configured from
        the robot's YAML first. Returns the problems skipped (best effort).
        """
        ent = self._robot(name)
        self._read_state(ent)
        cm = ent.cm
        for cname in activate:
            if cname not in {c.name for c in cm.list_controllers()} and cname in cm.types:
                cm.load(cname)
                cm.configure(cname)
        return cm.switch(activate, deactivate, strict=strict, time=self._data.time)

    def set_command(self, name: str, controller: str, command: Sequence[float]) -> None:
        """Send a command vector to a controller ("" = the robot's default command controller).

        Raises:
            EntityError: unknown entity; ControllerError: unknown or inactive controller;
            CommandError: wrong length, NaN/inf (nothing is applied).
        """
        ent = self._robot(name)
        ent.cm.set_command(controller, command, self._data.time)
        self._write_actuators(ent)

    def set_trajectory(self, name: str, controller: str, joint_names: Sequence[str],
                       positions: Sequence[Sequence[float]], times_from_start: Sequence[float],
                       velocities: Sequence[Sequence[float]] | None = None) -> None:
        """Give a JointTrajectoryController a trajectory starting now (sim time).

        Raises:
            ControllerError: not a joint trajectory controller / not active; CommandError: bad trajectory.
        """
        ent = self._robot(name)
        ctrl = ent.cm.default_command_controller if controller == "" else ent.cm.get(controller)
        if ctrl is None or ctrl.state != "active" or not hasattr(ctrl, "set_trajectory"):
            raise ControllerError(f"controller '{controller}' of '{name}' is not an active "
                                  f"JointTrajectoryController")
        ctrl.set_trajectory(joint_names, positions, times_from_start, velocities, time=self._data.time)
        ent.countdown = 0

    # ------------------------------------------------------------------ time
    @property
    def time(self) -> float:
        """Simulation time in seconds."""
        return float(self._data.time)

    def step(self, n: int = 1, *, should_stop: Callable[[], bool] | None = None) -> None:
        """Advance ``n`` physics steps; controllers update at their rate within the steps.

        Args:
            n: physics steps.
            should_stop: with more than ``limits.STEP_CHUNK`` steps, they run in chunks of that
                many (bit-identical to one call) and ``should_stop()`` is asked before each chunk;
                True stops the call there (the node passes its shutdown flag).

        Raises:
            UnstableSimulationError: physics diverged; the named entities were restored to the
                state they had before this call (before the chunk, when chunked), their velocities
                zeroed, the others continue.
            StepInterruptedError: ``should_stop()`` returned True; ``steps_done`` steps were done.
        """
        if n < 0:
            raise ValueError(f"step count must be >= 0, got {n}")
        if should_stop is None or n <= STEP_CHUNK:
            self._step(n)
            return
        done = 0
        while done < n:
            if should_stop():
                raise StepInterruptedError(f"stepping stopped after {done} of {n} steps (shutting down)",
                                           steps_done=done)
            chunk = min(STEP_CHUNK, n - done)
            self._step(chunk)
            done += chunk

    def _step(self, n: int) -> None:
        if n == 0:
            return
        m, d = self._model, self._data
        mujoco.mj_getState(m, d, self._snap, self._state_spec)
        for ent in self._entities.values():
            ent.snap_countdown = ent.countdown
            if ent.hw is not None:
                self._write_actuators(ent)
        self._advance(n)
        if self._warnings_changed():
            self._recover(n)

    def _advance(self, n: int) -> None:
        m, d = self._model, self._data
        varying = self._varying
        remaining = n
        while remaining > 0:
            chunk = remaining
            for ent in varying:
                if ent.countdown <= 0:
                    ent.cm.update(d.time)
                    hw = ent.hw
                    d.ctrl[ent.act_ids] = hw.command + ent.ff_scale * hw.command_velocity
                    ent.countdown = ent.period
                if ent.countdown < chunk:
                    chunk = ent.countdown
            mujoco.mj_step(m, d, chunk)
            for ent in varying:
                ent.countdown -= chunk
            remaining -= chunk

    def _warnings_changed(self) -> bool:
        w = self._data.warning
        return (w[_BAD_WARNINGS[0]].number != self._warn_counts[0]
                or w[_BAD_WARNINGS[1]].number != self._warn_counts[1]
                or w[_BAD_WARNINGS[2]].number != self._warn_counts[2])

    def _diverged(self) -> list[_Entity]:
        d = self._data
        out = []
        for ent in self._entities.values():
            q, v = d.qpos[ent.qpos_idx], d.qvel[ent.dof_idx]
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))) or (v.size and np.max(np.abs(v)) > 1e9):
                out.append(ent)
        return out

    def _recover(self, n: int) -> None:
        """Replay the step call one physics step at a time from the snapshot (deterministic), find
        the entity that diverges first, restore it to its pre-call state at rest, and go on; the
        other entities complete all ``n`` steps as if nothing happened."""
        m, d = self._model, self._data
        mujoco.mj_setState(m, d, self._snap, self._state_spec)
        for ent in self._entities.values():
            ent.countdown = ent.snap_countdown
        self._sync_warn_counts()
        culprits: dict[str, int] = {}
        good = np.empty_like(self._snap)
        done, attempts = 0, 0
        while done < n:
            mujoco.mj_getState(m, d, good, self._state_spec)
            counts = {e.name: e.countdown for e in self._entities.values()}
            self._advance(1)
            if not self._warnings_changed() and not self._diverged():
                done += 1
                continue
            bad = self._diverged()
            if not bad:  # a warning without a NaN left behind: blame the owner of the reported dof
                dof = int(d.warning[_BAD_WARNINGS[0]].lastinfo)
                bad = [e for e in self._entities.values() if dof in e.dof_idx] or list(self._entities.values())
            mujoco.mj_setState(m, d, good, self._state_spec)
            for ent in self._entities.values():
                ent.countdown = counts[ent.name]
            attempts += 1
            for ent in bad:
                culprits[ent.name] = culprits.get(ent.name, 0) + 1
                if culprits[ent.name] == 1:
                    d.qpos[ent.qpos_idx] = self._snap_qpos_of(ent)
                    d.qvel[ent.dof_idx] = 0.0
                else:  # restoring did not help: back to the spawn state
                    self._apply_initial(ent)
                d.qacc_warmstart[ent.dof_idx] = 0.0
            mujoco.mj_forward(m, d)
            for ent in bad:
                if ent.cm is not None:
                    self._read_state(ent)
                    ent.cm.hold(d.time)
                    self._write_actuators(ent)
            self._sync_warn_counts()
            if attempts > 2 * max(1, len(self._entities)):
                mujoco.mj_setState(m, d, self._snap, self._state_spec)
                for ent in self._entities.values():
                    self._apply_initial(ent)
                mujoco.mj_forward(m, d)
                break
        self._sync_warn_counts()
        names = tuple(culprits)
        raise UnstableSimulationError(
            f"physics diverged (MuJoCo bad qpos/qvel/qacc) in entity(s) {list(names)} near t={d.time:.4f}s; "
            f"they were restored to their state before this step call, at rest, while the other entities "
            f"stepped on. Lower the timestep, the gains or the commanded efforts.", entities=names)

    def _snap_qpos_of(self, ent: _Entity) -> np.ndarray:
        # mjSTATE_INTEGRATION starts with time (1), then qpos (nq)
        q = self._snap[1:1 + self._model.nq][ent.qpos_idx]
        return np.where(np.isfinite(q), q, self._model.qpos0[ent.qpos_idx])

    def _sync_warn_counts(self) -> None:
        self._warn_counts = np.array([self._data.warning[w].number for w in _BAD_WARNINGS])

    def reset(self, scope: int = ResetScope.ALL) -> tuple[str, ...]:
        """Reset by ``ResetSimulation`` scope bits.

        * ``ALL`` (255) and ``DEFAULT`` (0): as if the world was closed and launched again: every
          entity is deleted, time and all physics state go back to zero, and the launched world
          (entities spawned with ``initial=True`` or marked by :meth:`mark_launched`) is spawned
          again from what was recorded at its spawn: pose, initial joint positions, controllers
          loaded and active as then. Deleted launched entities come back; physics properties set
          since (time step, gravity) are kept.
        * Any other combination of ``TIME`` (time to 0), ``STATE`` (every entity back to its
          spawn pose and joint positions at rest; active controllers hold that state) and
          ``SPAWNED`` (delete the entities that are not launched ones).

        Returns:
            The names of the entities created anew (``ALL`` only; empty otherwise): objects held
            for them (controller managers, ROS interfaces) must be fetched again.

        Raises:
            ValueError: unknown scope bits.
        """
        scope = int(scope)
        if scope & ~int(ResetScope.ALL):
            raise ValueError(f"reset scope {scope} has unknown bits; use 1 (time), 2 (state), 4 (spawned), "
                             f"a combination, or 255 (all)")
        if scope in (int(ResetScope.DEFAULT), int(ResetScope.ALL)):
            return self._relaunch()
        if scope & ResetScope.SPAWNED:
            doomed = [n for n, e in self._entities.items() if not e.info.initial]
            for n in doomed:
                self._remove_from_spec(self._entities.pop(n))
            if doomed:
                self._recompile()
        d = self._data
        if scope & ResetScope.STATE:
            keep_time = d.time
            mujoco.mj_resetData(self._model, d)
            self._warn_counts[:] = 0
            if not scope & ResetScope.TIME:
                d.time = keep_time
            for ent in self._entities.values():
                self._apply_initial(ent)
        if scope & ResetScope.TIME:
            d.time = 0.0
        mujoco.mj_forward(self._model, d)
        for ent in self._entities.values():
            if ent.cm is not None:
                ent.countdown = 0
                if scope & (ResetScope.STATE | ResetScope.TIME):
                    self._read_state(ent)
                    ent.cm.hold(d.time)
                    self._write_actuators(ent)
        return ()

    def _relaunch(self) -> tuple[str, ...]:
        for ent in self._entities.values():
            self._remove_from_spec(ent)
        self._entities.clear()
        self._recompile()
        mujoco.mj_resetData(self._model, self._data)
        self._sync_warn_counts()
        for name, recipe in list(self._launched.items()):
            self.spawn(name, initial=True, **recipe)
        mujoco.mj_forward(self._model, self._data)
        return tuple(self._launched)

    # ------------------------------------------------------------------ physics properties
    @property
    def timestep(self) -> float:
        """Physics time step in seconds (settable, > 0)."""
        return float(self._model.opt.timestep)

    @timestep.setter
    def timestep(self, value: float) -> None:
        value = float(value)
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"timestep must be a finite number > 0, got {value}")
        self._model.opt.timestep = value
        self._spec.option.timestep = value
        for ent in self._entities.values():
            self._update_period(ent)

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector (3,), settable."""
        return self._model.opt.gravity.copy()

    @gravity.setter
    def gravity(self, value: Sequence[float]) -> None:
        g = _check_vec3(value, "gravity")
        self._model.opt.gravity[:] = g
        self._spec.option.gravity = list(g)

    # ------------------------------------------------------------------ access for render/benchmarks
    @property
    def model(self) -> mujoco.MjModel:
        """The current ``mujoco.MjModel`` (replaced on spawn/delete)."""
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        """The current ``mujoco.MjData`` (replaced on spawn/delete)."""
        return self._data

    def add_change_callback(self, callback: Callable[[], None]) -> None:
        """Call ``callback()`` after every recompile (spawn/delete), e.g. to drop renderers."""
        self._callbacks.append(callback)

    def close(self) -> None:
        """Release the model; the world is unusable afterwards."""
        self._closed = True
        self._callbacks.clear()
        self._entities.clear()


class RealTimeRunner:
    """Runs a world's physics in a background thread at a real-time factor.

    Deadline-based: after each chunk the thread waits until ``start_wall + sim_elapsed / rtf``
    (not a fixed sleep); if it falls more than ``max_lag`` seconds behind it restarts the deadline
    rather than bursting to catch up.

    Args:
        world: the world to step.
        real_time_factor: 1.0 = wall clock, > 1 faster, <= 0 as fast as possible.
        chunk_steps: physics steps per chunk (the callback runs after each chunk).
        on_chunk: ``callback(world)`` after each chunk, with the lock held (publish /clock, joint states).
        on_error: ``callback(exc)`` for an exception raised by a chunk (the runner keeps running
            after UnstableSimulationError, stops after anything else).
        lock: the lock to hold while stepping (default: a new RLock, exposed as ``lock``).
        max_lag: seconds behind the deadline before the pacing restarts from now.
    """

    def __init__(self, world: World, *, real_time_factor: float = 1.0, chunk_steps: int = 10,
                 on_chunk: Callable[[World], None] | None = None,
                 on_error: Callable[[BaseException], None] | None = None,
                 lock: threading.RLock | None = None, max_lag: float = 0.25) -> None:
        if chunk_steps < 1:
            raise ValueError(f"chunk_steps must be >= 1, got {chunk_steps}")
        self.world = world
        self.lock = lock if lock is not None else threading.RLock()
        self.chunk_steps = int(chunk_steps)
        self.on_chunk, self.on_error = on_chunk, on_error
        self.max_lag = max_lag
        self._rtf = float(real_time_factor)
        self._stop = threading.Event()
        self._rebase = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    @property
    def real_time_factor(self) -> float:
        """Settable while running; the deadline restarts from now."""
        return self._rtf

    @real_time_factor.setter
    def real_time_factor(self, value: float) -> None:
        self._rtf = float(value)
        self._rebase.set()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start the thread (no-op when running)."""
        if self.running:
            return
        self._stop.clear()
        self.error = None
        self._thread = threading.Thread(target=self._run, name="uniros-realtime", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop and join the thread within ``timeout`` seconds.

        Raises:
            TimeoutError: the thread did not stop in time (a callback is blocking).
        """
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
            if thread.is_alive():
                raise TimeoutError(f"real-time runner did not stop within {timeout} s; a chunk callback "
                                   f"is blocking")
        self._thread = None

    def _run(self) -> None:
        wall0, sim0 = _time.monotonic(), self.world.time
        while not self._stop.is_set():
            try:
                with self.lock:
                    if self._rebase.is_set() or self.world.time < sim0:  # rtf change or reset rewound time
                        self._rebase.clear()
                        wall0, sim0 = _time.monotonic(), self.world.time
                    try:
                        self.world.step(self.chunk_steps)
                    except UnstableSimulationError as exc:
                        if self.on_error is not None:
                            self.on_error(exc)
                    if self.on_chunk is not None:
                        self.on_chunk(self.world)
                    sim_elapsed = self.world.time - sim0
            except BaseException as exc:  # stop the loop, report, never die silently
                self.error = exc
                if self.on_error is not None:
                    self.on_error(exc)
                return
            rtf = self._rtf
            if rtf <= 0:
                wall0, sim0 = _time.monotonic(), self.world.time
                continue
            delay = wall0 + sim_elapsed / rtf - _time.monotonic()
            if delay < -self.max_lag:
                wall0, sim0 = _time.monotonic(), self.world.time
            elif delay > 0:
                self._stop.wait(delay)
