"""The MuJoCo world of the simulation node: entities, their state, controllers, reset.

Each entity is attached to one ``MjSpec`` under the name prefix ``"<name>/"``: a fixed-base robot
or static object hangs below a mocap body called ``<name>`` (so its base pose can be set without a
recompile); a floating entity's root body gets a free joint (an MJCF root's own free joint is
taken out by the description loader and replaced by this one, placed at the spawn pose). Spawning
and deleting recompile with ``MjSpec.recompile``, which carries the other entities' state over by
name; ids and addresses are then resolved again, once, and the step path uses only preallocated
index arrays. The entities spawned with ``initial=True`` (or marked by ``World.mark_launched``)
form the launched world, which ``reset(ResetScope.ALL)`` spawns again from their recorded recipes.

The world is split over a few modules, all re-exported here:

* :mod:`multiros.sim.world_types`: options, categories, reset scopes, entity/joint state records;
* :mod:`multiros.sim.world_model`: spec assembly, id binding, servo gains, actuator writes;
* :mod:`multiros.sim.world_step`: ``time``, ``step`` and divergence recovery (a mixin of World);
* :mod:`multiros.sim.world_admission`: ``admit``, the checks a spawned entity passes before it
  shares the world (a mixin of World);
* :mod:`multiros.sim.world_prepare`: a spawn compiled and admitted beside the world and committed
  under the caller's lock (``spawn_snapshot``, ``prepare_spawn``, ``commit_spawn``; a mixin of World);
* :mod:`multiros.sim.frames`: :class:`FrameSet`;
* :mod:`multiros.sim.realtime`: :class:`RealTimeRunner`.

Threading: ``World`` starts no threads and holds no lock. The caller (the node) serialises
access; :class:`RealTimeRunner` holds its lock while it steps, and the node takes the same lock
(``runner.lock``) around service callbacks.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import re
import weakref
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.controller_manager import ControllerManager
from multiros.sim.description import MeshCache, RobotDescription, load_description
from multiros.sim.entity_properties import SHAPING_PERIOD, apply_rows, check_rows, reapply
from multiros.sim.errors import ControllerError, DescriptionError, EntityError
from multiros.sim.frames import FrameSet
from multiros.sim.packages import PackageIndex, default_index
from multiros.sim.realtime import RealTimeRunner
from multiros.sim.world_admission import WorldAdmission
from multiros.sim.world_model import (
    add_to_spec,
    apply_initial,
    base_spec,
    bind_entity_ids,
    geom_bounds,
    hold_here,
    initial_joint_positions,
    make_controller_manager,
    read_state,
    remove_from_spec,
    root_state,
    set_root_state,
    write_actuators,
)
from multiros.sim.world_prepare import WorldSpawnPreparation
from multiros.sim.world_step import WorldStepping
from multiros.sim.world_types import (
    EntityCategory,
    EntityInfo,
    EntityRecord,
    EntityState,
    JointState,
    ResetScope,
    WorldOptions,
    check_pose,
    check_vec3,
    default_category,
)

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

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: Entities taken out of the spec before the world builds it afresh (see World._rebuild_spec).
_REBUILD_EVERY = 10
_logger = logging.getLogger(__name__)


class World(WorldStepping, WorldAdmission, WorldSpawnPreparation):
    """A MuJoCo world holding robots and objects, each an entity with a name and a namespace.

    ``time`` and ``step`` come from :class:`~multiros.sim.world_step.WorldStepping`, ``admit`` from
    :class:`~multiros.sim.world_admission.WorldAdmission`.

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
        self._entities: dict[str, EntityRecord] = {}
        self._removed: dict[str, str] = {}  # entities the world removed itself, and why (the latest 256)
        self._launched: dict[str, dict] = {}  # the launched world: spawn recipes, in spawn order
        self._frame_sets: weakref.WeakSet[FrameSet] = weakref.WeakSet()
        self._callbacks: list[Callable[[], None]] = []
        self._spec = base_spec(self.options)
        self._removals = 0  # entities taken out of the spec since it was last copied
        self._model = self._spec.compile()
        self._data = mujoco.MjData(self._model)
        self._varying: tuple[EntityRecord, ...] = ()
        self._closed = False
        self.binding = 0  # counts the id bindings (one per compile): ids cached against it stay valid
        self._generation = 0  # counts changes of the model's structure or options (see world_prepare)
        self._bind()

    # ------------------------------------------------------------------ binding (after each compile)
    def _bind(self) -> None:
        m = self._model
        self.binding += 1
        self._generation += 1
        masses = self._masses()
        for ent in self._entities.values():
            self._bind_entity(ent)
        self._refresh_constants(masses)  # an entity's mass rows written again over the compiled masses
        self._varying = self._varying_entities()
        self._sync_warn_counts()
        self._state_spec = int(mujoco.mjtState.mjSTATE_INTEGRATION)
        self._snap = np.zeros(mujoco.mj_stateSize(m, self._state_spec))
        for fs in list(self._frame_sets):
            fs._bind()

    def _masses(self) -> tuple[np.ndarray, np.ndarray]:
        return self._model.body_mass.copy(), self._model.body_inertia.copy()

    def _refresh_constants(self, before: tuple[np.ndarray, np.ndarray]) -> None:
        """Masses or inertias changed since ``before``: the model's constants derived from them
        (subtree masses, the inverse weights that size every constraint's impedance) computed again, as
        MuJoCo asks after such a change (``mj_setConst``). Left stale, a cube of 1.5 times its mass
        was flung metres by its first contact."""
        m = self._model
        if not (np.array_equal(before[0], m.body_mass) and np.array_equal(before[1], m.body_inertia)):
            mujoco.mj_setConst(m, mujoco.MjData(m))  # a scratch MjData: the world's state is untouched

    def _varying_entities(self) -> tuple[EntityRecord, ...]:
        """Robots whose actuator targets change between step calls: time-varying controllers, shaped commands."""
        return tuple(e for e in self._entities.values()
                     if e.cm is not None and (e.cm.time_varying or e.shaping is not None))

    def _bind_entity(self, ent: EntityRecord) -> None:
        bind_entity_ids(self._model, ent)
        reapply(self._model, ent)
        if ent.hw is not None:
            ent.hw.dirty = True
            write_actuators(self._model, self._data, ent)
        self._update_period(ent)

    def _update_period(self, ent: EntityRecord) -> None:
        rate = ent.cm.update_rate if ent.cm is not None else None
        dt = self._model.opt.timestep
        ent.period = max(1, int(round(1.0 / (rate * dt)))) if rate else 1
        if ent.shaping is not None and ent.cm is not None and not ent.cm.time_varying:
            # constant commands, shaped: the shaping's rate, not the controllers' (a step call of 25 physics
            # steps in 3 chunks rather than 25; a lag of tens of milliseconds and more is followed as well)
            ent.period = max(ent.period, int(round(SHAPING_PERIOD / dt)))
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
        self._check_new_name(name)
        ent = self._new_record(name, description, pose=pose, namespace=namespace, category=category,
                               xacro_args=xacro_args, floating=floating, joint_positions=joint_positions,
                               initial=initial)
        gravcomp = self.options.gravity_compensation if gravity_compensation is None else gravity_compensation
        added = add_to_spec(self._spec, ent, self._gravcomp(ent, gravcomp))
        self._entities[name] = ent
        self._removed.pop(name, None)
        try:
            self._recompile()
        except Exception as exc:
            del self._entities[name]
            self._remove_from_spec(ent, added)
            self._recompile()
            raise DescriptionError(f"spawn '{name}': the model does not compile: {exc}",
                                   source=ent.desc.source) from exc
        return self._finish_spawn(ent, controllers, controllers_yaml, joint_positions, gravcomp)

    def _new_record(self, name: str, description: str | Path | RobotDescription, *,
                    pose: tuple[Sequence[float], Sequence[float]] | None, namespace: str | None,
                    category: EntityCategory | None, xacro_args: Mapping[str, str] | None, floating: bool | None,
                    joint_positions: Mapping[str, float] | None, initial: bool) -> EntityRecord:
        """The record of an entity to spawn, its name already checked (pose and description checked
        here; nothing added yet)."""
        pos, quat = check_pose(*(pose if pose is not None else (None, None)), what=f"spawn '{name}' pose")
        pos = np.zeros(3) if pos is None else pos
        quat = np.array([1.0, 0.0, 0.0, 0.0]) if quat is None else quat
        desc = description if isinstance(description, RobotDescription) else load_description(
            description, args=xacro_args, index=self.index, mesh_cache=self.mesh_cache,
            default_armature=self.options.default_armature)
        category = default_category(desc, floating) if category is None else EntityCategory(category)
        if floating is None:
            floating = desc.free_root or (
                category in (EntityCategory.DYNAMIC_OBJECT, EntityCategory.OBJECT) and not desc.joints)
        if category == EntityCategory.STATIC_OBJECT:
            floating = False
        initial_q = initial_joint_positions(name, desc, joint_positions)
        info = EntityInfo(name=name, namespace=namespace if namespace is not None else f"/{name}",
                          category=category, fixed_base=not floating, initial=initial,
                          joint_names=tuple(j.name for j in desc.joints),
                          frames=tuple(desc.links) + tuple(s.name for s in desc.spec.sites
                                                           if s.name not in desc.links),
                          controllers_yaml=desc.controllers_yaml, description=desc.text)
        return EntityRecord(info, desc, (pos, quat), floating, initial_q)

    def _check_new_name(self, name: str) -> None:
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise EntityError(f"entity name {name!r} is invalid; use letters, digits and '_', not starting "
                              f"with a digit")
        if name in self._entities:
            raise EntityError(f"entity '{name}' already exists; delete it first or pick another name")

    @staticmethod
    def _gravcomp(ent: EntityRecord, requested: bool) -> bool:
        """Whether the entity's bodies are gravity compensated: asked for, and a robot on a fixed base."""
        return bool(requested and ent.info.category == EntityCategory.ROBOT and not ent.floating)

    def _finish_spawn(self, ent: EntityRecord, controllers: Sequence[str] | None,
                      controllers_yaml: str | Path | Mapping | None, joint_positions: Mapping[str, float] | None,
                      gravcomp: bool) -> EntityInfo:
        """After the model holding the new entity is the world's: its spawn state, its controllers,
        its recipe (for a reset that spawns the launched world again)."""
        name, category = ent.name, ent.info.category
        try:
            apply_initial(self._model, self._data, ent)
            if category == EntityCategory.ROBOT and ent.actuated:
                self._setup_controllers(ent, controllers, controllers_yaml)
            self._varying = self._varying_entities()
            mujoco.mj_forward(self._model, self._data)
        except Exception:
            self.delete(name)
            raise
        ent.recipe = {"description": ent.desc, "pose": (ent.spawn_pos.copy(), ent.spawn_quat.copy()),
                      "namespace": ent.info.namespace, "category": category, "floating": ent.floating,
                      "joint_positions": dict(joint_positions) if joint_positions else None,
                      "controllers": list(controllers) if controllers is not None else None,
                      "controllers_yaml": controllers_yaml, "gravity_compensation": bool(gravcomp)}
        if ent.info.initial:
            self._launched.pop(name, None)
            self._launched[name] = ent.recipe
        return ent.info

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

    def _remove_from_spec(self, ent: EntityRecord, added: dict | None = None) -> None:
        remove_from_spec(self._spec, ent, added)
        self._removals += 1

    def _recompile(self) -> None:
        self._model, self._data = self._spec.recompile(self._model, self._data)
        if self._removals >= _REBUILD_EVERY:
            self._rebuild_spec()
        self._rebind()

    def _rebuild_spec(self) -> None:
        """Replace the spec by one built afresh from the live entities, the state moved across.

        MuJoCo's spec keeps memory for what was attached and then deleted (about 210 KB for each RX200
        spawned and deleted, with MuJoCo 4.0; its copy keeps it too): a node whose clients spawn and delete
        for weeks would grow without end. A spec made anew from the same entities, in their order, lays the
        model out as the live one; the state (``mjSTATE_INTEGRATION``: time, positions, velocities, controls,
        mocap poses, warm starts) moves to it unchanged, and the bindings after it write the actuators again.
        Where the layouts differ (they should not) the live spec stays.
        """
        self._removals = 0
        spec = base_spec(self.options)
        spec.option.timestep, spec.option.gravity = self._spec.option.timestep, list(self._spec.option.gravity)
        for ent in self._entities.values():
            requested = bool(ent.recipe.get("gravity_compensation", self.options.gravity_compensation))
            add_to_spec(spec, ent, self._gravcomp(ent, requested))
        model = spec.compile()
        old = self._model
        sizes = ("nq", "nv", "nu", "na", "nbody", "njnt", "ngeom", "nsite", "nmocap", "neq", "nsensordata")
        if any(getattr(model, k) != getattr(old, k) for k in sizes) or any(
                model.body(i).name != old.body(i).name for i in range(old.nbody)):
            _logger.warning("world: the rebuilt spec lays the model out otherwise; the live spec stays")
            return
        data = mujoco.MjData(model)
        which = int(mujoco.mjtState.mjSTATE_INTEGRATION)
        state = np.empty(mujoco.mj_stateSize(old, which))
        mujoco.mj_getState(old, self._data, state, which)
        mujoco.mj_setState(model, data, state, which)
        model.opt.timestep, model.opt.gravity[:] = old.opt.timestep, old.opt.gravity
        mujoco.mj_forward(model, data)
        self._spec, self._model, self._data = spec, model, data

    def _rebind(self) -> None:
        """After the world's model was replaced: ids bound again, then the change callbacks."""
        self._bind()
        for callback in list(self._callbacks):
            callback()

    def _setup_controllers(self, ent: EntityRecord, controllers: Sequence[str] | None,
                           config: str | Path | Mapping | None) -> None:
        d = self._data
        cm = make_controller_manager(self._model, d, ent, config)
        cm.refresh_state = lambda: read_state(self._data, ent)
        cm.on_change = lambda: self._controllers_changed(ent)
        self._update_period(ent)
        cm.spawn(controllers, time=d.time)
        ent.js = JointState(ent.info.joint_names, np.zeros(len(ent.info.joint_names)),
                            np.zeros(len(ent.info.joint_names)), np.zeros(len(ent.info.joint_names)))
        write_actuators(self._model, self._data, ent)

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

    def entity_description(self, name: str) -> RobotDescription:
        """The loaded description of entity ``name`` (its links, root, body names; read it, do not
        change it). Raises EntityError if unknown."""
        return self._get(name).desc

    def has_entity(self, name: str) -> bool:
        """True when an entity called ``name`` exists."""
        return name in self._entities

    def _get(self, name: str) -> EntityRecord:
        try:
            return self._entities[name]
        except KeyError:
            raise EntityError(self.unknown_entity_message(name)) from None

    def unknown_entity_message(self, name: str) -> str:
        """Why there is no entity ``name``: the world removed it (and why), or it never was."""
        if name in self._removed:
            return f"entity '{name}' {self._removed[name]}"
        return f"unknown entity '{name}'; entities are {list(self._entities)}"

    def removal_reason(self, name: str) -> str | None:
        """Why the world removed entity ``name`` by itself (physics it cannot simulate), else None."""
        return self._removed.get(name)

    def _forget_entity(self, ent: EntityRecord, reason: str) -> None:
        """Take an entity out of the spec and the world's records, remembering why (no recompile)."""
        self._remove_from_spec(ent)
        del self._entities[ent.name]
        self._removed.pop(ent.name, None)
        self._removed[ent.name] = reason
        while len(self._removed) > 256:
            del self._removed[next(iter(self._removed))]

    def _robot(self, name: str) -> EntityRecord:
        ent = self._get(name)
        if ent.cm is None:
            raise EntityError(f"entity '{name}' is not a robot with actuated joints")
        return ent

    def get_entity_state(self, name: str) -> EntityState:
        """Root pose and twist of an entity in the world frame (fresh arrays)."""
        self.sync_kinematics()
        return root_state(self._data, self._get(name))

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
        pos, quat = check_pose(position, orientation, f"set_entity_state '{name}'")
        lin = check_vec3(linear_velocity, "linear_velocity") if linear_velocity is not None else None
        ang = check_vec3(angular_velocity, "angular_velocity") if angular_velocity is not None else None
        set_root_state(d, ent, pos, quat, lin, ang)
        mujoco.mj_forward(self._model, d)

    def bounds(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned world bounding box ``(lower xyz, upper xyz)`` of an entity's geoms."""
        self.sync_kinematics()
        return geom_bounds(self._model, self._data, self._get(name))

    # ------------------------------------------------------------------ joints
    def joint_names(self, name: str) -> tuple[str, ...]:
        """The robot's joint names (unprefixed), in the order of :meth:`joint_state`."""
        return self._get(name).info.joint_names

    def joint_state_arrays(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Copies of :meth:`joint_state`'s position, velocity and effort arrays."""
        js = self.joint_state(name)
        return js.position.copy(), js.velocity.copy(), js.effort.copy()

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
        if hold:
            hold_here(self._model, d, ent)

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
        """The robot's :class:`~multiros.sim.controller_manager.ControllerManager`.

        Load/configure/switch/unload on it directly; the world is told of switches through the
        manager's hooks. Commands given directly to a controller take effect at the next step.
        """
        return self._robot(name).cm

    def controllers_changed(self, name: str) -> None:
        """Re-read a robot's active controllers and actuator modes. The ControllerManager's hooks
        already do this on every switch; calling it again is harmless."""
        self._controllers_changed(self._robot(name))

    def _controllers_changed(self, ent: EntityRecord) -> None:
        self._update_period(ent)  # a shaped robot's chunks follow whether its commands vary in time
        self._varying = self._varying_entities()
        write_actuators(self._model, self._data, ent)

    def switch_controllers(self, name: str, activate: Sequence[str] = (), deactivate: Sequence[str] = (),
                           *, strict: bool = True) -> list[str]:
        """``ControllerManager.switch`` for a robot, applied to the actuators at once.

        Controllers named in ``activate`` that are not loaded yet are loaded and configured from
        the robot's YAML first. Returns the problems skipped (best effort).
        """
        ent = self._robot(name)
        read_state(self._data, ent)
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
        # No write to ctrl here: every step call writes each robot's actuators before it steps.
        self._robot(name).cm.set_command(controller, command, self._data.time)

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

    # ------------------------------------------------------------------ reset
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
                apply_initial(self._model, d, ent)
        if scope & ResetScope.TIME:
            d.time = 0.0
        mujoco.mj_forward(self._model, d)
        for ent in self._entities.values():
            ent.countdown = 0
            if scope & (ResetScope.STATE | ResetScope.TIME):
                hold_here(self._model, d, ent)
        return ()

    def reset_entity(self, name: str) -> None:
        """Put one entity back in its spawn state (joints at their initial positions, at rest, solver
        warm start cleared, active controllers holding that pose); time and the others are untouched.

        For one entity alone in its world this equals ``reset(ResetScope.STATE)``. Raises EntityError if unknown.
        """
        self.reset_entities((name,))

    def reset_entities(self, names: Sequence[str]) -> None:
        """:meth:`reset_entity` for several entities at once (one forward pass): for a group of
        entities in a shared world (a robot and the objects of its task) it equals what
        ``reset(ResetScope.STATE)`` does to them when they are alone in their world."""
        m, d = self._model, self._data
        ents = [self._get(name) for name in names]
        for ent in ents:
            apply_initial(m, d, ent)
            d.qacc_warmstart[ent.dof_idx] = 0.0
        mujoco.mj_forward(m, d)
        for ent in ents:
            hold_here(m, d, ent)

    def entities_in_namespace(self, namespace: str) -> tuple[str, ...]:
        """The entities whose ROS namespace is ``namespace`` (a robot and the objects spawned into it)."""
        ns = namespace.rstrip("/")
        return tuple(name for name, ent in self._entities.items() if ent.info.namespace.rstrip("/") == ns)

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

    def set_entity_properties(self, name: str, targets: Sequence[str], names: Sequence[str],
                              properties: Sequence[str], values: Sequence[float], *, restore: bool = False) -> int:
        """Set an entity's physical properties apart from its description (domain randomisation; rows and
        their meaning: :mod:`multiros.sim.entity_properties`). ``restore`` first puts back its spawned values.
        Returns the model values written. Raises EntityError (unknown entity) or PropertyError (a bad row:
        nothing changes)."""
        ent = self._get(name)
        rows = check_rows(targets, names, properties, values)
        masses = self._masses()
        changed = apply_rows(self._model, ent, rows, restore=restore)
        self._refresh_constants(masses)
        if ent.hw is not None:
            write_actuators(self._model, self._data, ent)
        self._update_period(ent)
        self._varying = self._varying_entities()
        return changed

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
        self._generation += 1  # a spawn prepared before compiled the old one
        for ent in self._entities.values():
            self._update_period(ent)

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector (3,), settable."""
        return self._model.opt.gravity.copy()

    @gravity.setter
    def gravity(self, value: Sequence[float]) -> None:
        g = check_vec3(value, "gravity")
        self._model.opt.gravity[:] = g
        self._spec.option.gravity = list(g)
        self._generation += 1

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
        """Release the model, its data and spec, and the entities' records; the world is unusable
        afterwards. A node's objects refer to each other (services to their node, the node to its
        world), so the garbage collector, not reference counting, frees them, and only at a full
        collection: released here, the megabytes of MuJoCo memory go at once (a camera env's make and
        close left ~4.6 MB per cycle behind otherwise)."""
        self._closed = True
        self._callbacks.clear()
        self._entities.clear()
        self._launched.clear()
        self._varying = ()
        self._spec = self._model = self._data = None  # type: ignore[assignment]
