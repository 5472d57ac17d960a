"""Many robots' joint states and frame poses read in one gather per array: the read of a
``StepRobots`` call on a composed node (:class:`~multiros.sim.stepper.ComposedStepper`).

Read robot by robot, a vector env's step at N = 8 spends more time indexing small arrays than the
node spends in anything else outside physics: per robot, a gather and a copy for each of
positions, velocities, efforts, frame positions and orientations. :class:`StateGather` reads them
for all the robots of a call at once into ``(N, ...)`` arrays (:class:`~multiros.robot_state.RobotStates`), whose rows
are the robots' states, equal to what :meth:`World.joint_state_arrays` and
:meth:`FrameSet.pose_arrays` give robot by robot. The index arrays are built once per robot list
and kept while the world's ids are (``World.binding``) and the frame sets are the same objects.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from multiros.robot_state import RobotStates

if TYPE_CHECKING:
    from multiros.sim.frames import FrameSet
    from multiros.sim.world import World

__all__ = ["StateGather"]


class _Indices:
    """The flat index arrays of one robot list (and its frame sets) in one binding of the world."""

    def __init__(self, world: World, names: tuple[str, ...], frame_sets: Sequence[FrameSet | None]) -> None:
        ents = [world._entities[name] for name in names]
        self.joints = len(ents[0].jnt_qadr)
        self.joint_names = world.joint_names(names[0])
        self.valid = all(len(ent.jnt_qadr) == self.joints and ent.hw is not None for ent in ents) and all(
            world.joint_names(name) == self.joint_names for name in names[1:])
        self.frame_sets = tuple(frame_sets)
        sets = [fs for fs in frame_sets if fs is not None]
        self.frames = len(sets[0].names) if sets else 0
        if sets and (len(sets) != len(ents) or any(not fs._bodies_in_order or len(fs.names) != self.frames
                                                    for fs in sets)):
            self.valid = False  # some robot names sites or no frames: read robot by robot
        if not self.valid:
            return
        n, count = self.joints, len(ents)
        # Index arrays shaped as the results: a gather gives the (N, ...) array with no reshape.
        self.qadr = np.array([ent.jnt_qadr for ent in ents], dtype=np.intp).reshape(count, n)
        self.dadr = np.array([ent.jnt_dadr for ent in ents], dtype=np.intp).reshape(count, n)
        self.act_ids = np.concatenate([ent.act_ids for ent in ents])
        self.effort_slot = np.concatenate([j * n + ent.effort_slot for j, ent in enumerate(ents)])
        self.effort_shape = (count, n)
        self.body_ids = (np.array([fs._b_ids for fs in sets], dtype=np.intp).reshape(count, self.frames) if sets
                         else np.zeros((count, 0), dtype=np.intp))


class StateGather:
    """Stacked states of a list of robots of one world (see the module docstring)."""

    def __init__(self, world: World) -> None:
        self._world = world
        # per robot list (a batch's, and each env's alone for its resets): its indices
        self._indices: dict[tuple[int, tuple[str, ...]], _Indices] = {}

    def clear(self) -> None:
        """Forget every robot list's indices (and the frame sets they hold)."""
        self._indices.clear()
        self._last = None

    def read(self, names: Sequence[str], frame_sets: Sequence[FrameSet | None], sim_time: float) -> RobotStates | None:
        """The robots' states stacked, or ``None`` when they cannot be (robots with different joint
        counts, frame lists of different lengths or naming sites): read them one by one then.

        ``frame_sets[j]`` holds the frames named for robot ``names[j]`` (``None``: no frames).
        Raises EntityError for an unknown robot or a frame set whose entity was deleted.
        """
        world = self._world
        last = self._last  # a client stepping one robot list calls again with the same sequences
        if last is not None and last[0] is names and last[1] is frame_sets and last[2] == world.binding:
            idx = last[3]
        else:
            idx = self._lookup(names, frame_sets)
            self._last = (names, frame_sets, world.binding, idx)
        if not idx.valid:
            return None
        d = world.data
        effort = np.zeros(idx.effort_shape)
        if idx.act_ids.size:
            effort.flat[idx.effort_slot] = d.actuator_force[idx.act_ids]
        if idx.frames:
            world.sync_kinematics()
        return RobotStates(sim_time, idx.joint_names, d.qpos[idx.qadr], d.qvel[idx.dadr], effort,
                           d.xpos[idx.body_ids], d.xquat[idx.body_ids])

    _last: tuple[Sequence[str], Sequence[FrameSet | None], int, _Indices] | None = None

    def _lookup(self, names: Sequence[str], frame_sets: Sequence[FrameSet | None]) -> _Indices:
        """The indices of a robot list in the world's current binding (built when new)."""
        world = self._world
        key = (world.binding, tuple(names))
        idx = self._indices.get(key)
        if idx is None or any(a is not b for a, b in zip(idx.frame_sets, frame_sets)):
            for fs in frame_sets:
                if fs is not None:
                    fs._check()
            for name in key[1]:
                world._get(name)
            if len(self._indices) >= 16:  # ids of older bindings, lists no longer stepped
                self._indices.clear()
            idx = self._indices[key] = _Indices(world, key[1], frame_sets)
        return idx
