"""Frame sets: several links or sites of a :class:`~multiros.sim.world.World` whose world poses are
read together, their MuJoCo ids resolved once (and again by the world after each recompile).

Re-exported by :mod:`multiros.sim.world`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from multiros.sim.errors import EntityError

if TYPE_CHECKING:
    from multiros.sim.world import World

__all__ = ["FrameSet"]


class FrameSet:
    """Several frames (links or sites) whose world poses are fetched together, ids resolved once.

    With an ``entity``, a frame that is not one of its own may name another entity's frame as
    ``"<entity>/<frame>"`` (e.g. ``"cube/object"``, the root body of an object spawned as ``cube``),
    so one StepRobot round trip returns a robot's frames and the poses of the objects it handles.

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
        self._others: set[str] = set()  # other entities whose frames this set reads
        self._bodies_in_order = False
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
                if body_name is None and frame not in ent.info.frames:
                    other = self._other_entity(frame)
                    if other is not None:  # "<entity>/<frame>" of another entity (an object's pose)
                        if not world.has_entity(other[0]):
                            self._stale = f"frame set {list(self.names)}: entity '{other[0]}' was deleted"
                            return
                        oent = world._entities[other[0]]
                        body_name = oent.prefix + oent.desc.body_name(other[1]) if other[1] in oent.desc.links else None
                        site_name = oent.prefix + other[1]
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
                raise EntityError(f"frame '{frame}' is not a link or site of {where}; known frames: {known}"
                                  + ("; another entity's frame is named '<entity>/<frame>'" if ent is not None else ""))
            sites.append((i, sid))
        self._b_rows = np.array([r for r, _ in bodies], dtype=np.intp)
        self._b_ids = np.array([b for _, b in bodies], dtype=np.intp)
        self._s_rows = [r for r, _ in sites]
        self._s_ids = [s for _, s in sites]
        self._s_ids_arr = np.array(self._s_ids, dtype=np.intp)
        self._s_rows_arr = np.array(self._s_rows, dtype=np.intp)
        self._bodies_in_order = not sites and self._b_rows.tolist() == list(range(len(self.names)))
        self._stale = ""

    def _other_entity(self, frame: str) -> tuple[str, str] | None:
        """``(entity, frame)`` when ``frame`` is ``"<other entity>/<frame>"`` and that entity exists
        (or existed when this set was first bound), else None."""
        head, sep, rest = frame.partition("/")
        if not sep or not rest or head == self.entity:
            return None
        if self._world.has_entity(head) or head in self._others:
            self._others.add(head)
            return head, rest
        return None

    @property
    def stale(self) -> bool:
        """Whether an entity this set reads was deleted (reading it raises; build a new set)."""
        return bool(self._stale)

    def _check(self) -> None:
        if self._stale:
            raise EntityError(self._stale)

    def poses(self) -> np.ndarray:
        """Return an (n, 7) array ``[x, y, z, qw, qx, qy, qz]`` per frame (a preallocated buffer)."""
        self._check()
        self._world.sync_kinematics()
        data, out = self._world.data, self._out
        if self._b_ids.size:
            out[self._b_rows, :3] = data.xpos[self._b_ids]
            out[self._b_rows, 3:] = data.xquat[self._b_ids]
        for row, sid in zip(self._s_rows, self._s_ids):
            out[row, :3] = data.site_xpos[sid]
            mujoco.mju_mat2Quat(out[row, 3:], data.site_xmat[sid])
        return out

    def pose_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Fresh ``(n, 3)`` positions and ``(n, 4)`` ``(w, x, y, z)`` orientations: :meth:`poses`
        split into new arrays, gathered straight from MuJoCo's when every frame is a link."""
        if self._bodies_in_order:
            self._check()
            self._world.sync_kinematics()
            data = self._world.data
            return data.xpos[self._b_ids], data.xquat[self._b_ids]
        rows = self.poses()
        return rows[:, :3].copy(), rows[:, 3:].copy()

    def positions(self) -> np.ndarray:
        """Return an (n, 3) array of frame positions (a preallocated buffer)."""
        self._check()
        self._world.sync_kinematics()
        data = self._world.data
        if self._b_ids.size:
            self._pos[self._b_rows] = data.xpos[self._b_ids]
        if self._s_ids_arr.size:
            self._pos[self._s_rows_arr] = data.site_xpos[self._s_ids_arr]
        return self._pos
