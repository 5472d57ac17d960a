"""Admission of a spawned entity into a shared world: the checks that keep robots apart.

One world holds the robots of several clients. A description can be within every numeric limit
and still harm the others: a joint whose stiffness is far beyond its link's inertia diverges on
every physics step (the others' steps then failed or stalled, call after call), a box spawned
through a robot's arm is thrown out by the contact solver and throws the arm, and a heavy box
spawned above a robot falls onto it. :meth:`WorldAdmission.admit` runs right after a spawn,
before any step, and refuses such an entity (:class:`~multiros.sim.errors.SpawnRefusedError`;
the node then deletes it, so the world is as before):

* **overlap**: a contact of the newcomer's collision geometry with another entity's deeper than
  ``max_penetration`` (MuJoCo only reports pairs that collide at all: robots' links, which do
  not collide with other robots', never count);
* **landing**: a free (floating) newcomer whose fall line (straight down from the middle and the
  corners of its bounding box) meets a movable entity (robot links, free objects) lighter than
  the newcomer's mass divided by ``max_load_ratio``; the floor and static objects are fine;
* **trial**: ``trial_steps`` physics steps of a scratch copy of the whole world (commands held)
  in which nothing may diverge; the real world does not move.

Everything here runs at spawn only: the step path gains nothing. What the checks do not cover,
and why: entities touching later because of what their owners command (that is physics in a
shared world; vector envs give each robot a slot of its own), and ``SetEntityState`` moves (a
client that can send requests can delete entities too; a private graph or access control is the
boundary there, see ``docs/simulation_node.md``).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from multiros.sim.errors import EntityError, SpawnRefusedError
from multiros.sim.limits import DescriptionLimits
from multiros.sim.world_model import geom_bounds
from multiros.sim.world_types import EntityRecord

__all__ = ["WorldAdmission"]

_WARNINGS = tuple(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
                                   mujoco.mjtWarning.mjWARN_BADQVEL))
_DOWN = np.array([0.0, 0.0, -1.0])
_MAX_RAY_HOPS = 32  # geoms a fall line may pass through (own geoms, visual-only ones) before giving up


class WorldAdmission:
    """The admission checks of :class:`~multiros.sim.world.World` (a mixin)."""

    _model: mujoco.MjModel
    _data: mujoco.MjData
    _entities: dict[str, EntityRecord]

    def admit(self, name: str, limits: DescriptionLimits | None = None) -> None:
        """Check that entity ``name``, just spawned, may share the world (see the module docstring).

        Raises:
            SpawnRefusedError: it overlaps another entity, would fall onto a lighter one, or makes
                the world diverge; the caller deletes it.
            EntityError: unknown entity.
        """
        limits = limits or DescriptionLimits()
        ent = self._entities.get(name)
        if ent is None:
            raise EntityError(f"unknown entity '{name}'")
        m, d = self._model, self._data
        mujoco.mj_forward(m, d)  # contacts and poses at the spawn state
        owner = self._body_owners()
        if math.isfinite(limits.max_penetration):
            self._check_overlap(ent, owner, limits.max_penetration)
        if ent.floating and math.isfinite(limits.max_load_ratio):
            self._check_landing(ent, owner, limits.max_load_ratio)
        if limits.trial_steps > 0:
            self._check_trial(ent, owner, int(limits.trial_steps))

    # ------------------------------------------------------------------ helpers
    def _body_owners(self) -> list[EntityRecord | None]:
        owner: list[EntityRecord | None] = [None] * self._model.nbody
        for ent in self._entities.values():
            for b in ent.body_ids:
                owner[int(b)] = ent
        return owner

    def _movable(self, body: int) -> bool:
        """Whether a body has a degree of freedom in its chain to the world (mocap bases do not)."""
        m = self._model
        while body > 0:
            if m.body_dofnum[body] > 0:
                return True
            body = int(m.body_parentid[body])
        return False

    def _entity_mass(self, ent: EntityRecord) -> float:
        return float(self._model.body_subtreemass[ent.root_bid])

    # ------------------------------------------------------------------ overlap
    def _check_overlap(self, ent: EntityRecord, owner: list[EntityRecord | None], tolerance: float) -> None:
        m, d = self._model, self._data
        worst: tuple[float, int, int] | None = None
        for i in range(d.ncon):
            contact = d.contact[i]
            g1, g2 = int(contact.geom[0]), int(contact.geom[1])
            o1, o2 = owner[int(m.geom_bodyid[g1])], owner[int(m.geom_bodyid[g2])]
            if (o1 is ent) == (o2 is ent) or o1 is None or o2 is None:  # not newcomer vs another entity
                continue
            if contact.dist < -tolerance and (worst is None or contact.dist < worst[0]):
                worst = (float(contact.dist), g1, g2) if o1 is ent else (float(contact.dist), g2, g1)
        if worst is not None:
            depth, mine, theirs = worst
            other = owner[int(m.geom_bodyid[theirs])]
            raise SpawnRefusedError(
                f"spawn '{ent.name}': its geom {_geom_label(m, mine)} reaches {-depth * 1000:.1f} mm into entity "
                f"'{other.name}' (geom {_geom_label(m, theirs)}; at most {tolerance * 1000:g} mm is accepted): "
                f"spawn it where it touches no other entity", reason="overlap")

    # ------------------------------------------------------------------ landing
    def _check_landing(self, ent: EntityRecord, owner: list[EntityRecord | None], ratio: float) -> None:
        m, d = self._model, self._data
        own_geoms = np.flatnonzero(np.isin(m.geom_bodyid, ent.body_ids))
        if own_geoms.size == 0:
            return
        contype = int(np.bitwise_or.reduce(m.geom_contype[own_geoms]))
        conaffinity = int(np.bitwise_or.reduce(m.geom_conaffinity[own_geoms]))
        mass = self._entity_mass(ent)
        low, high = geom_bounds(m, d, ent)
        inset = 0.1 * (high - low)
        xs = (low[0] + inset[0], 0.5 * (low[0] + high[0]), high[0] - inset[0])
        ys = (low[1] + inset[1], 0.5 * (low[1] + high[1]), high[1] - inset[1])
        points = [(xs[1], ys[1])] + [(x, y) for x in (xs[0], xs[2]) for y in (ys[0], ys[2])]
        geom_id = np.zeros(1, dtype=np.int32)
        for x, y in points:
            start = np.array([x, y, low[2] - 1e-6])
            fallen = 0.0
            for _ in range(_MAX_RAY_HOPS):
                dist = mujoco.mj_ray(m, d, start, _DOWN, None, 1, -1, geom_id)
                if dist < 0:
                    break  # nothing below
                g = int(geom_id[0])
                body = int(m.geom_bodyid[g])
                other = owner[body]
                collides = (contype & int(m.geom_conaffinity[g])) or (int(m.geom_contype[g]) & conaffinity)
                if other is ent or not collides:  # look on below it
                    start = start + _DOWN * (dist + 1e-6)
                    fallen += dist
                    continue
                if other is not None and self._movable(body):
                    below = self._entity_mass(other)
                    if mass > ratio * below:
                        raise SpawnRefusedError(
                            f"spawn '{ent.name}' ({mass:g} kg) would fall {fallen + dist:.2f} m onto entity "
                            f"'{other.name}' ({below:g} kg); an object may land on the floor, static objects, or "
                            f"entities at least 1/{ratio:g} of its mass: spawn it elsewhere", reason="landing")
                break

    # ------------------------------------------------------------------ trial
    def _check_trial(self, ent: EntityRecord, owner: list[EntityRecord | None], steps: int) -> None:
        m = self._model
        scratch = mujoco.MjData(m)
        mujoco.mj_copyData(scratch, m, self._data)
        counts = [scratch.warning[w].number for w in _WARNINGS]
        for step in range(steps):
            mujoco.mj_step(m, scratch)
            warned = [k for k, w in enumerate(_WARNINGS) if scratch.warning[w].number != counts[k]]
            bad = not (np.all(np.isfinite(scratch.qpos)) and np.all(np.isfinite(scratch.qvel)))
            if not warned and not bad:
                continue
            culprits = self._trial_culprits(scratch, owner, warned)
            t = (step + 1) * m.opt.timestep
            if not culprits or culprits == [ent.name]:
                what = f"diverges within {t:.3f} s of simulated time"
            else:
                what = f"makes {culprits} diverge within {t:.3f} s of simulated time"
            raise SpawnRefusedError(
                f"spawn '{ent.name}': it {what} at this node's {m.opt.timestep:g} s time step (MuJoCo bad "
                f"qpos/qvel/qacc): check its joint stiffness and damping against its link masses and inertias, "
                f"its gains, and what it touches", reason="unstable")

    def _trial_culprits(self, scratch: mujoco.MjData, owner: list[EntityRecord | None], warned: list[int]) -> list[str]:
        m = self._model
        names: list[str] = []
        for k in warned:  # the DOF (QACC, QVEL) or qpos index (QPOS) MuJoCo warned about
            index = int(scratch.warning[_WARNINGS[k]].lastinfo)
            if k == 1:
                joints = np.flatnonzero(m.jnt_qposadr <= index)
                body = int(m.jnt_bodyid[joints[-1]]) if joints.size else -1
            else:
                body = int(m.dof_bodyid[index]) if 0 <= index < m.nv else -1
            other = owner[body] if 0 <= body < m.nbody else None
            if other is not None and other.name not in names:
                names.append(other.name)
        return names


def _geom_label(m: mujoco.MjModel, geom: int) -> str:
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if name:
        return f"'{name}'"
    body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[geom])) or f"#{int(m.geom_bodyid[geom])}"
    return f"#{geom} of body '{body}'"
