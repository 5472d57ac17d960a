"""The TF tree of one entity, as ``robot_state_publisher`` publishes a robot's: the frames ROS tools
look up (rviz2's RobotModel, ``tf2_echo``, MoveIt) by the description's link names.

Why not every link in the ``world`` frame (what the node once published): tools find a robot's links
by the URDF's names and walk parent -> child transforms; a frame called ``<entity>/<link>`` in the
world frame is found by nobody. Here:

* each link's frame is the link's name, with a frame prefix only where the node was asked for one
  (:func:`prefixed`: never applied twice, so ``rx200/`` before ``rx200/base_link`` adds nothing);
* each link but the root hangs from its parent link: a fixed joint is a *static* transform
  (``/tf_static``), a movable one a dynamic one (``/tf``), as robot_state_publisher sends them;
* the root hangs from ``world``: static for a fixed-base entity (it moves only when someone sets its
  pose, and is then sent again), dynamic for a floating one. A root link called ``world`` *is* the
  world frame: it gets no transform of its own, and its children hang from ``world`` at their true
  place (so a robot spawned away from the origin is still where the simulation has it);
* each camera sensor's optical frame (z forward, x right, y down: REP 103's ``_optical_frame``)
  hangs from the link carrying the camera, static. Its name is the sensor's ``<frame_name>``
  (default ``<sensor>_optical_frame``) under the entity's prefix, ``<entity>/`` unless the node has
  a prefix: two robots with the same camera never share a frame. A ``<frame_name>`` that is a link of
  the description is that link's frame (the description places it; no transform is added).

Poses come from the simulation's own bodies and cameras (MuJoCo ``xpos``/``xquat``, ``cam_xpos``):
what the images and joint states show. Pure computation; the ROS side is
:mod:`multiros.sim.tf_publisher`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

__all__ = ["WORLD", "Edge", "EntityFrames", "prefixed"]

WORLD = "world"
_OPTICAL = np.array([0.0, 1.0, 0.0, 0.0])  # (w x y z) half a turn about x: MuJoCo camera -> optical frame
_FIXED_CAMERA = int(mujoco.mjtCamLight.mjCAMLIGHT_FIXED)


def prefixed(prefix: str, name: str) -> str:
    """``name`` under ``prefix``, unless it already starts with it (a prefix is never applied twice)."""
    name = name.lstrip("/")
    return name if not prefix or name.startswith(prefix) else prefix + name


@dataclass(frozen=True)
class Edge:
    """One transform of the tree: ``parent`` -> ``child``.

    Attributes:
        static: constant while nobody moves the entity (sent on ``/tf_static``).
        parent_body: MuJoCo body of the parent frame; ``""`` for the world.
        child_body: MuJoCo body of the child frame; ``""`` for a camera's optical frame.
        camera: the MuJoCo camera whose optical frame the child is (else ``""``).
    """

    parent: str
    child: str
    static: bool
    parent_body: str
    child_body: str
    camera: str = ""


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamilton products of (n, 4) ``w x y z`` quaternions."""
    aw, ax, ay, az = a.T
    bw, bx, by, bz = b.T
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=1)


def _rotate_inverse(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise ``R(q)^T v`` for (n, 4) unit quaternions and (n, 3) vectors."""
    w, u = q[:, :1], -q[:, 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


class EntityFrames:
    """The TF edges of one entity of a world (see the module docstring).

    Args:
        world: the :class:`~multiros.sim.world.World` holding the entity.
        name: the entity.
        prefix: the frame prefix of its links (``""``: the description's names).
        cameras: ``(MuJoCo camera name, declared frame name or "")`` of its camera sensors.

    Attributes:
        link_frames: each link's frame name.
        camera_frames: each camera's frame name (what its image headers carry).
        edges: every transform, static and dynamic.
    """

    def __init__(self, world: Any, name: str, prefix: str = "", cameras: Iterable[tuple[str, str]] = ()) -> None:
        desc, info, model = world.entity_description(name), world.entity(name), world.model
        self.name, self.prefix = name, prefix
        ent_prefix = f"{name}/"
        body_of = {link: ent_prefix + desc.body_name(link) for link in desc.links}
        link_of_body = {body: link for link, body in body_of.items()}
        self.link_frames = {link: prefixed(prefix, link) for link in desc.links}
        fixed_base = bool(info.fixed_base)
        root_is_world = self.link_frames[desc.root] == WORLD

        def parent_of(bid: int) -> tuple[str | None, bool]:
            """The nearest link body above body ``bid`` (None: none, the root) and whether no joint
            moves ``bid`` against it."""
            jointless = int(model.body_jntnum[bid]) == 0
            parent = int(model.body_parentid[bid])
            while parent > 0:
                link = link_of_body.get(model.body(parent).name)
                if link is not None:
                    return link, jointless
                jointless = jointless and int(model.body_jntnum[parent]) == 0
                parent = int(model.body_parentid[parent])
            return None, jointless

        def anchor(link: str | None, static: bool) -> tuple[str, str, bool]:
            """(parent frame, parent body, static) of a frame fixed (or not) to ``link``."""
            if link is None:
                return WORLD, "", False
            if self.link_frames[link] == WORLD:  # the root called world: place against the world itself
                return WORLD, "", static and fixed_base
            return self.link_frames[link], body_of[link], static

        edges: list[Edge] = []
        for link in desc.links:
            bid = model.body(body_of[link]).id
            if link == desc.root:
                if not root_is_world:
                    edges.append(Edge(WORLD, self.link_frames[link], fixed_base, "", body_of[link]))
                continue
            parent_link, jointless = parent_of(bid)
            parent, parent_body, static = anchor(parent_link, jointless)
            edges.append(Edge(parent, self.link_frames[link], static, parent_body, body_of[link]))
        self.camera_frames: dict[str, str] = {}
        for camera, declared in cameras:
            declared = declared.strip().lstrip("/")
            if declared in self.link_frames:
                self.camera_frames[camera] = self.link_frames[declared]
                continue
            cid = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_CAMERA), camera)
            if cid < 0:
                continue
            short = camera[len(ent_prefix):] if camera.startswith(ent_prefix) else camera
            frame = prefixed(prefix or ent_prefix, declared or f"{short}_optical_frame")
            body_link = link_of_body.get(model.body(int(model.cam_bodyid[cid])).name)
            parent, parent_body, static = anchor(body_link, int(model.cam_mode[cid]) == _FIXED_CAMERA)
            edges.append(Edge(parent, frame, static, parent_body, "", camera))
            self.camera_frames[camera] = frame
        self.edges = tuple(edges)
        self._binding = -1
        self._ids: dict[str, int] = {}

    @property
    def children(self) -> tuple[str, ...]:
        """Every child frame of this entity's tree."""
        return tuple(edge.child for edge in self.edges)

    def drop(self, children: Sequence[str]) -> None:
        """Leave out the transforms to ``children`` (frames another entity publishes)."""
        gone = set(children)
        self.edges = tuple(e for e in self.edges if e.child not in gone)
        self.camera_frames = {c: f for c, f in self.camera_frames.items() if f not in gone}

    def _id(self, model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
        if not name:
            return -1
        key = f"{int(kind)}:{name}"
        if key not in self._ids:
            self._ids[key] = mujoco.mj_name2id(model, int(kind), name)
        return self._ids[key]

    def transforms(self, world: Any, static: bool) -> tuple[list[Edge], np.ndarray, np.ndarray]:
        """The static (or dynamic) edges with their translations (n, 3) and rotations (n, 4,
        ``w x y z``) now, each relative to its parent frame (caller holds the node's lock)."""
        edges = [e for e in self.edges if e.static == static]
        if not edges:
            return [], np.zeros((0, 3)), np.zeros((0, 4))
        model, data = world.model, world.data
        if self._binding != world.binding:  # ids change with every recompile (spawn/delete)
            self._ids.clear()
            self._binding = world.binding
        world.sync_kinematics()
        n = len(edges)
        ppos, pquat = np.zeros((n, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        cpos, cquat = np.zeros((n, 3)), np.zeros((n, 4))
        for i, edge in enumerate(edges):
            pid = self._id(model, mujoco.mjtObj.mjOBJ_BODY, edge.parent_body)
            if pid >= 0:
                ppos[i], pquat[i] = data.xpos[pid], data.xquat[pid]
            if edge.camera:
                cid = self._id(model, mujoco.mjtObj.mjOBJ_CAMERA, edge.camera)
                cpos[i] = data.cam_xpos[cid]
                mujoco.mju_mat2Quat(cquat[i], data.cam_xmat[cid])
            else:
                bid = self._id(model, mujoco.mjtObj.mjOBJ_BODY, edge.child_body)
                cpos[i], cquat[i] = data.xpos[bid], data.xquat[bid]
        cameras = np.array([bool(e.camera) for e in edges])
        if cameras.any():
            cquat[cameras] = _qmul(cquat[cameras], np.tile(_OPTICAL, (int(cameras.sum()), 1)))
        inverse = pquat * np.array([1.0, -1.0, -1.0, -1.0])
        translation = _rotate_inverse(pquat, cpos - ppos)
        rotation = _qmul(inverse, cquat)
        rotation /= np.linalg.norm(rotation, axis=1, keepdims=True)
        return edges, translation, rotation
