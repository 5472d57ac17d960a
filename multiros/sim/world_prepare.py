"""A spawn compiled and admitted beside the world, committed under the node's lock in a few milliseconds.

``World.spawn`` recompiles the whole world and the node then runs the admission checks
(:mod:`multiros.sim.world_admission`: overlap, landing, a 100-step trial of the whole world), all
under the node's lock: every other client waited for it (8 ms of compile and 15 ms of trial for a
small box beside four arms, 2 s for a 500-joint description). Here the work is split:

1. :meth:`WorldSpawnPreparation.spawn_snapshot`, under the lock: a copy of the world's spec and
   data (about a millisecond beside four arms);
2. :meth:`WorldSpawnPreparation.prepare_spawn`, outside the lock: the newcomer is added to the
   copy, which is compiled; the world's state as of the snapshot is put into it, the newcomer at its
   spawn state with its controllers; the admission checks run on this candidate world. Errors are
   those of ``World.spawn`` and ``World.admit``; the world is not touched;
3. :meth:`WorldSpawnPreparation.commit_spawn`, under the lock: the candidate becomes the world,
   with the others' state copied in as it is now (they may have stepped meanwhile), then what
   ``World.spawn`` does after its compile (spawn state, controllers at the current time, forward).

MuJoCo compiles the entities in the order they were attached, so the newcomer's bodies, joints,
actuators and equalities come after everyone else's, and the others' state occupies the same
leading slots of each state array in both models: that is checked (:class:`StateLayout`), never
assumed. The commit refuses (returns None) when the world's structure changed since the snapshot
(another spawn, a delete, a reset that removed entities, a new timestep or gravity): the caller then
spawns under the lock as before. The result equals ``World.spawn`` at the time of the commit, bit
for bit (``tests/sim/test_spawn_prepared.py``): the same model, and the same integration state
(``mjSTATE_INTEGRATION``, the fields ``MjSpec.recompile`` carries over).

Not covered, and why: what the others do between the snapshot and the commit is not checked
against the newcomer (a robot may move into the space it was admitted to; the same holds a step
after any admission); a world that keeps changing structure faster than a compile makes every
commit fall back to the locked spawn (correct, as slow as before).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.description import RobotDescription
from multiros.sim.errors import DescriptionError
from multiros.sim.limits import DescriptionLimits
from multiros.sim.world_admission import WorldAdmission
from multiros.sim.world_model import (
    add_to_spec,
    apply_initial,
    bind_entity_ids,
    make_controller_manager,
    write_actuators,
)
from multiros.sim.world_types import EntityCategory, EntityInfo, EntityRecord, WorldOptions

__all__ = ["SpawnSnapshot", "PreparedSpawn", "StateLayout", "WorldSpawnPreparation"]

_OBJECTS = (mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_ACTUATOR,
            mujoco.mjtObj.mjOBJ_EQUALITY)


@dataclasses.dataclass(frozen=True)
class StateLayout:
    """Where a model keeps its integration state: sizes, element names and addresses."""

    nq: int
    nv: int
    na: int
    nu: int
    nbody: int
    nmocap: int
    neq: int
    nuserdata: int
    npluginstate: int
    names: tuple[tuple[str, ...], ...]  # bodies, joints, actuators, equalities (ids in order)
    jnt_qposadr: tuple[int, ...]
    jnt_dofadr: tuple[int, ...]
    actuator_actadr: tuple[int, ...]
    body_mocapid: tuple[int, ...]

    @classmethod
    def of(cls, m: mujoco.MjModel) -> StateLayout:
        names = tuple(tuple(mujoco.mj_id2name(m, obj, i) or "" for i in range(count))
                      for obj, count in zip(_OBJECTS, (m.nbody, m.njnt, m.nu, m.neq)))
        return cls(m.nq, m.nv, m.na, m.nu, m.nbody, m.nmocap, m.neq, m.nuserdata, m.npluginstate, names,
                   tuple(int(a) for a in m.jnt_qposadr), tuple(int(a) for a in m.jnt_dofadr),
                   tuple(int(a) for a in m.actuator_actadr), tuple(int(a) for a in m.body_mocapid))

    def leads(self, other: StateLayout) -> bool:
        """Whether this layout's elements come first in ``other``, at the same slots of every state
        array (``other`` = this model with entities appended)."""
        n = len
        return (self.nuserdata == other.nuserdata and self.npluginstate == other.npluginstate
                and all(other_names[:n(mine)] == mine for mine, other_names in zip(self.names, other.names))
                and other.jnt_qposadr[:n(self.jnt_qposadr)] == self.jnt_qposadr
                and other.jnt_dofadr[:n(self.jnt_dofadr)] == self.jnt_dofadr
                and other.actuator_actadr[:n(self.actuator_actadr)] == self.actuator_actadr
                and other.body_mocapid[:n(self.body_mocapid)] == self.body_mocapid
                and min(other.nq - self.nq, other.nv - self.nv, other.na - self.na, other.nu - self.nu,
                        other.nmocap - self.nmocap, other.neq - self.neq) >= 0)

    def copy_state(self, dst: mujoco.MjData, src: mujoco.MjData) -> None:
        """Put ``src``'s integration state (a model of this layout) into the leading slots of ``dst``."""
        dst.time = src.time
        dst.qpos[:self.nq] = src.qpos
        dst.qvel[:self.nv] = src.qvel
        dst.act[:self.na] = src.act
        dst.qacc_warmstart[:self.nv] = src.qacc_warmstart
        dst.ctrl[:self.nu] = src.ctrl
        dst.qfrc_applied[:self.nv] = src.qfrc_applied
        dst.xfrc_applied[:self.nbody] = src.xfrc_applied
        dst.mocap_pos[:self.nmocap] = src.mocap_pos
        dst.mocap_quat[:self.nmocap] = src.mocap_quat
        dst.eq_active[:self.neq] = src.eq_active
        dst.userdata[:] = src.userdata
        dst.plugin_state[:] = src.plugin_state


@dataclasses.dataclass
class SpawnSnapshot:
    """The world as a spawn found it (:meth:`WorldSpawnPreparation.spawn_snapshot`)."""

    generation: int
    name: str
    spec: mujoco.MjSpec  # a copy
    model: mujoco.MjModel  # the world's then (a reference: the world replaces its model, never reshapes it)
    data: mujoco.MjData  # a copy
    gains: tuple[np.ndarray, np.ndarray]  # the others' actuator gain and bias parameters (set at run time)
    entities: dict[str, EntityRecord]  # shallow copies: ids as bound to the world's model


@dataclasses.dataclass
class PreparedSpawn:
    """A candidate world holding the newcomer, admitted (:meth:`WorldSpawnPreparation.prepare_spawn`)."""

    generation: int
    spec: mujoco.MjSpec
    model: mujoco.MjModel
    data: mujoco.MjData
    layout: StateLayout
    ent: EntityRecord
    controllers: Sequence[str] | None
    controllers_yaml: str | Path | Mapping | None
    gravcomp: bool  # gravity compensation as asked for (World.spawn's recipe)
    joint_positions: dict[str, float] | None = None  # as asked for (World.spawn's recipe)


class _Candidate(WorldAdmission):
    """The admission checks, run on a candidate world instead of the world."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, entities: dict[str, EntityRecord]) -> None:
        self._model, self._data, self._entities = model, data, entities


class WorldSpawnPreparation:
    """Spawning in three steps, two of them under the caller's lock (a mixin of World)."""

    _spec: mujoco.MjSpec
    _model: mujoco.MjModel
    _data: mujoco.MjData
    _entities: dict[str, EntityRecord]
    _removed: dict[str, str]
    _generation: int
    options: WorldOptions
    _check_new_name: Callable[..., None]
    _new_record: Callable[..., EntityRecord]
    _gravcomp: Callable[[EntityRecord, bool], bool]
    _rebind: Callable[[], None]
    _finish_spawn: Callable[..., EntityInfo]

    def spawn_snapshot(self, name: str) -> SpawnSnapshot:
        """Under the lock: what :meth:`prepare_spawn` needs of the world, copied (about a millisecond).

        Raises:
            EntityError: ``name`` is invalid or taken.
        """
        self._check_new_name(name)
        m = self._model
        data = mujoco.MjData(m)
        mujoco.mj_copyData(data, m, self._data)
        return SpawnSnapshot(self._generation, name, self._spec.copy(), m, data,
                             (m.actuator_gainprm.copy(), m.actuator_biasprm.copy()),
                             {n: copy.copy(e) for n, e in self._entities.items()})

    def prepare_spawn(self, snapshot: SpawnSnapshot, description: str | Path | RobotDescription, *,
                      pose: tuple[Sequence[float], Sequence[float]] | None = None, namespace: str | None = None,
                      controllers: Sequence[str] | None = None,
                      controllers_yaml: str | Path | Mapping | None = None,
                      limits: DescriptionLimits | None = None,
                      joint_positions: Mapping[str, float] | None = None) -> PreparedSpawn | None:
        """Outside the lock: the candidate world with the newcomer, admitted. ``World.spawn``'s
        arguments (category, floating and gravity compensation by default). None when the candidate
        does not keep the others' state slots (then spawn under the lock).

        Raises:
            what ``World.spawn`` and ``World.admit`` raise; the world is not touched.
        """
        ent = self._new_record(snapshot.name, description, pose=pose, namespace=namespace,
                               category=None, xacro_args=None, floating=None, joint_positions=joint_positions,
                               initial=False)  # the name: checked by spawn_snapshot
        requested = bool(self.options.gravity_compensation)
        spec = snapshot.spec
        add_to_spec(spec, ent, self._gravcomp(ent, requested))
        try:
            model = spec.compile()
        except Exception as exc:
            raise DescriptionError(f"spawn '{ent.name}': the model does not compile: {exc}",
                                   source=ent.desc.source) from exc
        before = StateLayout.of(snapshot.model)
        if not before.leads(StateLayout.of(model)):
            return None  # never seen: MuJoCo appends an attached entity's elements
        data = mujoco.MjData(model)
        before.copy_state(data, snapshot.data)
        nu = before.nu
        model.actuator_gainprm[:nu], model.actuator_biasprm[:nu] = snapshot.gains
        bind_entity_ids(model, ent)
        apply_initial(model, data, ent)
        if ent.info.category == EntityCategory.ROBOT and ent.actuated:
            _trial_controllers(model, data, ent, controllers, controllers_yaml)
        _Candidate(model, data, {**snapshot.entities, ent.name: ent}).admit(ent.name, limits)
        return PreparedSpawn(snapshot.generation, spec, model, data, before, ent, controllers,
                             controllers_yaml, requested, dict(joint_positions) if joint_positions else None)

    def commit_spawn(self, prepared: PreparedSpawn) -> EntityInfo | None:
        """Under the lock: the candidate becomes the world, the others' state as it is now. None
        when the world's structure changed since the snapshot (then spawn under the lock)."""
        ent = prepared.ent
        if prepared.generation != self._generation or ent.name in self._entities:
            return None
        prepared.layout.copy_state(prepared.data, self._data)
        ent.hw = ent.cm = None  # the trial's; the world's come with the commit
        self._spec, self._model, self._data = prepared.spec, prepared.model, prepared.data
        self._entities[ent.name] = ent
        self._removed.pop(ent.name, None)
        self._rebind()
        return self._finish_spawn(ent, prepared.controllers, prepared.controllers_yaml,
                                  prepared.joint_positions, prepared.gravcomp)


def _trial_controllers(m: mujoco.MjModel, d: mujoco.MjData, ent: EntityRecord, controllers: Sequence[str] | None,
                       config: str | Path | Mapping | None) -> None:
    """The newcomer's controllers in the candidate world, holding its spawn pose for the trial (the
    world's are made again at the commit, by ``World._setup_controllers``)."""
    make_controller_manager(m, d, ent, config).spawn(controllers, time=d.time)
    write_actuators(m, d, ent)
