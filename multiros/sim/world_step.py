"""Stepping the MuJoCo world, and recovering from a diverging entity.

:class:`WorldStepping` is a mixin of :class:`~multiros.sim.world.World` holding ``time``,
``step`` and their internals. A step call snapshots the integration state, writes every robot's
actuator commands, then advances in chunks bounded by the next controller update of each
time-varying robot. When MuJoCo reports a bad qpos/qvel/qacc, :meth:`WorldStepping._recover`
replays the call one physics step at a time from the snapshot (deterministic), restores the entity
that diverges to its pre-call state at rest, lets the others complete the call, and raises
:class:`~multiros.sim.errors.UnstableSimulationError` naming the culprits. An entity that diverges
again from its own spawn state at rest cannot be simulated at this time step at all (a joint
stiffness far beyond what its inertia allows, say): it is removed from the world there and then,
so that it cannot stall everyone else's steps call after call, and the error names it in
``removed``. None of this costs anything on a step call where nothing diverges (one comparison
of MuJoCo's three warning counters per call).
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from multiros.sim.errors import StepInterruptedError, UnstableSimulationError
from multiros.sim.limits import STEP_CHUNK
from multiros.sim.world_model import apply_initial, hold_here, write_actuators
from multiros.sim.world_types import EntityRecord

#: Why an entity was removed (the rest of a step call's error message, and of later requests naming it).
REMOVED_REASON = ("diverged again from its own spawn state at rest, so it cannot be simulated at this time step; "
                  "it was removed from the world (check its joint stiffness and damping against its link masses, "
                  "and its gains, or lower the time step)")

_BAD_WARNINGS = tuple(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
                                       mujoco.mjtWarning.mjWARN_BADQVEL))


class WorldStepping:
    """Stepping and divergence recovery of :class:`~multiros.sim.world.World` (a mixin: the world
    owns the attributes below and calls :meth:`_sync_warn_counts` after each compile)."""

    _model: mujoco.MjModel
    _data: mujoco.MjData
    _entities: dict[str, EntityRecord]
    _varying: tuple[EntityRecord, ...]  # robots whose controllers change commands over time
    _snap: np.ndarray  # integration state at the start of the current step call
    _state_spec: int
    _warn_counts: np.ndarray
    _kinematics_stale: bool = False  # frame poses trail qpos by one physics step (after a step call)
    _recompile: Callable[[], None]
    _forget_entity: Callable[[EntityRecord, str], None]  # take out of the spec and the entities, with a reason

    @property
    def time(self) -> float:
        """Simulation time in seconds."""
        return float(self._data.time)

    def step(self, n: int = 1, *, should_stop: Callable[[], bool] | None = None, chunk: int = STEP_CHUNK) -> None:
        """Advance ``n`` physics steps; controllers update at their rate within the steps.

        Args:
            n: physics steps.
            should_stop: with more than ``chunk`` steps, they run in chunks of that many
                (bit-identical to one call) and ``should_stop()`` is asked before each chunk;
                True stops the call there (the node passes its shutdown flag, and lets other
                requests have their turn there).
            chunk: steps per chunk (default ``limits.STEP_CHUNK``).

        Raises:
            UnstableSimulationError: physics diverged; the named entities were restored to the
                state they had before this call (before the chunk, when chunked), their velocities
                zeroed, or removed (``removed``: they diverged again from their spawn state); the
                others continue.
            StepInterruptedError: ``should_stop()`` returned True; ``steps_done`` steps were done.
        """
        if n < 0:
            raise ValueError(f"step count must be >= 0, got {n}")
        chunk = max(1, int(chunk))
        if should_stop is None or n <= chunk:
            self._step(n)
            return
        done = 0
        while done < n:
            if should_stop():
                raise StepInterruptedError(f"stepping stopped after {done} of {n} steps (shutting down)",
                                           steps_done=done)
            part = min(chunk, n - done)
            self._step(part)
            done += part

    def _step(self, n: int) -> None:
        if n == 0:
            return
        m, d = self._model, self._data
        for ent in self._entities.values():
            ent.snap_countdown = ent.countdown
            if ent.hw is not None:
                write_actuators(m, d, ent)  # before the snapshot: a replay from it uses these commands
        mujoco.mj_getState(m, d, self._snap, self._state_spec)
        self._kinematics_stale = True
        self._advance(n)
        if self._warnings_changed():
            self._recover(n)

    def step_start_state(self) -> np.ndarray:
        """The integration state (``mjSTATE_INTEGRATION``) the last step call started from, commands
        written (a copy). ``mj_setState`` of it and ``mj_step`` of that call's steps repeat its physics:
        how benchmarks time the physics alone on the states a run actually steps from."""
        return self._snap.copy()

    def sync_kinematics(self) -> None:
        """Bring frame poses (bodies, sites, geoms, cameras) up to the joint positions, once per step call.

        ``mj_step`` computes positions before it integrates, so after a step call the frame poses
        trail ``qpos`` (and the joint states read from it) by one physics step: about 2 mm of end
        effector travel for an arm in motion. Frame readers call this first. It changes no physics:
        the next ``mj_step`` recomputes positions from ``qpos`` anyway.
        """
        if self._kinematics_stale:
            mujoco.mj_kinematics(self._model, self._data)
            mujoco.mj_camlight(self._model, self._data)  # cameras and lights on moving links
            self._kinematics_stale = False

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
                    command = hw.command if ent.shaping is None else ent.shaping.shape(hw.command, hw.mode, d.time)
                    d.ctrl[ent.act_ids] = command + ent.ff_scale * hw.command_velocity
                    ent.countdown = ent.period
                if ent.countdown < chunk:
                    chunk = ent.countdown
            mujoco.mj_step(m, d, chunk)
            for ent in varying:
                ent.countdown -= chunk
            remaining -= chunk

    def _warnings_changed(self) -> bool:
        stats, data = self._warn_stats
        if data is not self._data:  # the warning records of this MjData, fetched once (a third of the time)
            stats = tuple(self._data.warning[w] for w in _BAD_WARNINGS)
            self._warn_stats = (stats, self._data)
        counts = self._warn_counts
        return stats[0].number != counts[0] or stats[1].number != counts[1] or stats[2].number != counts[2]

    _warn_stats: tuple[tuple, object] = ((), None)

    def _diverged(self) -> list[EntityRecord]:
        d = self._data
        out = []
        for ent in self._entities.values():
            q, v = d.qpos[ent.qpos_idx], d.qvel[ent.dof_idx]
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))) or (v.size and np.max(np.abs(v)) > 1e9):
                out.append(ent)
        return out

    def _recover(self, n: int) -> None:
        """Replay the step call one physics step at a time from the snapshot (deterministic), find
        the entity that diverges first, restore it to its pre-call state at rest (a second time: to
        its spawn state; a third: remove it), and go on; the other entities complete all ``n``
        steps as if nothing happened."""
        mujoco.mj_setState(self._model, self._data, self._snap, self._state_spec)
        for ent in self._entities.values():
            ent.countdown = ent.snap_countdown
        self._sync_warn_counts()
        strikes: dict[str, int] = {}
        removed: list[str] = []
        good = np.empty_like(self._snap)
        done, attempts = 0, 0
        while done < n:
            m, d = self._model, self._data
            mujoco.mj_getState(m, d, good, self._state_spec)
            counts = {e.name: e.countdown for e in self._entities.values()}
            self._advance(1)
            if not self._warnings_changed() and not self._diverged():
                done += 1
                continue
            # Blame, in order: entities already bad before this physics step (NaN can leak into the
            # others through the solver), the owners of the index MuJoCo warned about, the bad ones after.
            after, warned = self._diverged(), self._warned()
            mujoco.mj_setState(m, d, good, self._state_spec)
            named = self._diverged() or warned or after
            bad = named or list(self._entities.values())
            for ent in self._entities.values():
                ent.countdown = counts[ent.name]
            attempts += 1
            doomed = []
            for ent in bad:
                strikes[ent.name] = strikes.get(ent.name, 0) + 1
                if strikes[ent.name] == 1:
                    d.qpos[ent.qpos_idx] = self._snap_qpos_of(ent)
                    d.qvel[ent.dof_idx] = 0.0
                elif strikes[ent.name] == 2 or not named:  # restoring did not help: back to the spawn state
                    apply_initial(m, d, ent)
                else:  # it diverges from its own spawn state at rest: it cannot be simulated here
                    doomed.append(ent)
                d.qacc_warmstart[ent.dof_idx] = 0.0
            if doomed:
                self._remove_diverging(doomed, d.time)
                removed += [ent.name for ent in doomed]
                bad = [ent for ent in bad if ent not in doomed]
                m, d = self._model, self._data
                good = np.empty_like(self._snap)
            mujoco.mj_forward(m, d)
            for ent in bad:
                hold_here(m, d, ent)
            self._sync_warn_counts()
            if attempts > 3 * max(1, len(self._entities) + len(removed)):  # nobody to blame: all back at rest
                mujoco.mj_setState(m, d, self._snap, self._state_spec)
                for ent in self._entities.values():
                    apply_initial(m, d, ent)
                mujoco.mj_forward(m, d)
                break
        self._sync_warn_counts()
        names = tuple(strikes)
        kept = [name for name in names if name not in removed]
        message = (f"physics diverged (MuJoCo bad qpos/qvel/qacc) in entity(s) {list(names)} near "
                   f"t={self._data.time:.4f}s")
        if kept:
            message += (f"; {kept} were restored to their state before this step call, at rest, while the other "
                        f"entities stepped on. Lower the timestep, the gains or the commanded efforts")
        if removed:
            message += f"; {removed} {REMOVED_REASON}"
        raise UnstableSimulationError(message + ".", entities=names, removed=tuple(removed))

    def _remove_diverging(self, doomed: list[EntityRecord], time: float) -> None:
        """Take entities out of the world in the middle of a recovery; the others keep their state
        (``MjSpec.recompile`` carries it over by name) and their pre-call snapshot."""
        pre_call = {e.name: self._snap_qpos_of(e) for e in self._entities.values() if e not in doomed}
        for ent in doomed:
            self._forget_entity(ent, f"{REMOVED_REASON} (at t={time:.4f} s)")
        self._recompile()
        self._snap = np.empty(mujoco.mj_stateSize(self._model, self._state_spec))
        mujoco.mj_getState(self._model, self._data, self._snap, self._state_spec)
        for ent in self._entities.values():
            self._snap[1 + ent.qpos_idx] = pre_call[ent.name]

    def _warned(self) -> list[EntityRecord]:
        """Owners of the index a new bad-state warning reported: bad qpos/qvel first (they name the
        source; a bad qacc follows from MuJoCo's reset of the whole data), else bad qacc."""
        d = self._data
        for kinds in ((1, 2), (0,)):  # (_BAD_WARNINGS: QACC, QPOS, QVEL)
            out: list[EntityRecord] = []
            for k in kinds:
                warning = d.warning[_BAD_WARNINGS[k]]
                if warning.number == self._warn_counts[k]:
                    continue
                index = int(warning.lastinfo)
                out += [e for e in self._entities.values()
                        if index in (e.qpos_idx if k == 1 else e.dof_idx) and e not in out]
            if out:
                return out
        return []

    def _snap_qpos_of(self, ent: EntityRecord) -> np.ndarray:
        # mjSTATE_INTEGRATION starts with time (1), then qpos (nq)
        q = self._snap[1:1 + self._model.nq][ent.qpos_idx]
        return np.where(np.isfinite(q), q, self._model.qpos0[ent.qpos_idx])

    def _sync_warn_counts(self) -> None:
        self._warn_counts = np.array([self._data.warning[w].number for w in _BAD_WARNINGS])
