"""``uniros arm add``: an arm file (:mod:`rl_environments.arm_file`) inferred from a robot description.

A user has a vendor's ROS 2 description package (a sourced workspace, found through
``AMENT_PREFIX_PATH``) and wants the tasks for it without writing Python. This module loads the
description as the simulation node does (xacro with arguments and ``$(find)``, meshes checked),
reads its kinematic tree and writes what it can work out, with a comment on every value it
inferred or guessed, so the user reviews one file instead of starting from a blank one:

* the arm: the longest serial chain of 4 to 7 actuated revolute (or continuous) joints from the
  root, stopping at the first prismatic, mimic or branching joint (the gripper's fingers). Two
  chains of one length (a dual-arm robot): the first in URDF order; the file names the others;
* the gripper: after the arm, one actuated finger joint (prismatic or revolute) and a joint that
  mimics it, in separate branches; open and closed are its limits, closed the one where the
  fingers are nearer each other. None: ``gripper: null`` (reach only);
* the end effector: a link fixed to the last arm link named like ``tcp``/``grasp``/``ee``/``tool``,
  the one nearest the fingers with a gripper; else the link of the hand (the last fixed link);
* the approach axis (the EE frame's axis from the wrist towards the fingers) and the closing axis
  (the fingers' axis, in the EE frame);
* home (zeros clipped into the limits, unless that puts the EE below the base), the workspace
  and reach goal boxes from the forward kinematics of random configurations, the object box where
  :class:`~rl_environments.arm_ik.ChainTopDownIK` reaches the table and the lift height in front of
  the base, a top-down start pose whose joints stay clear of the floor, the table's and the cube's
  sizes from the reach and the gripper's opening (the scene is made from them:
  :mod:`rl_environments.arm_scene`);
* the simulation's controllers (servo gains of :mod:`rl_environments.arm_gains`: from the joints'
  effort limits, the worst gravity torque and the joint-space inertia over random poses, checked by
  holding two poses in MuJoCo);
* the real twin's driver names from the controllers files (``config`` folders) of the packages the
  description names, else the ``<ros2_control>`` tag's hardware plugin where we know its vendor's
  convention, else ROS 2 control's conventional names, each marked ``inferred`` or ``guessed``.

Everything is written to a temporary directory, loaded back, checked against the description and
renamed into place only then; a bad description or a name in use is a one-line
:class:`~rl_environments.arm_file.ArmFileError` and nothing is written.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rl_environments.arm_file import ArmFileError

__all__ = ["ArmDraft", "Inspection", "add_arm", "draft_arm", "inspect_description", "render_arm_file"]

_MOVING = ("revolute", "continuous", "prismatic")
_REVOLUTE = ("revolute", "continuous")
# End-effector link names, most specific first (matched as whole words of the link name).
_EE_NAMES = ("tcp", "grasp", "grasping", "gripper_center", "end_effector", "eef", "ee", "tool", "tool0")
_TCP_FAR = 0.01  # m: a hand link this far from the grasp point gets arm.tcp_offset
_TCP_SHORT = 0.03  # m: a tool frame this far short of the grasp point is a flange frame
_PAD_BACK = 0.01  # m: the grasp point short of the fingertips' ends (the smallest cube, 0.8 cm half size, clears)
_MIN_OPEN_GAP = 0.02  # m: the open fingers' geometry leaves the smallest cube (1.6 cm) and 2 mm a side
_CUBE_DENSITY = 1100.0  # kg/m^3: the shipped cubes' (0.14 kg for 5 cm)
_HOLD_ABOVE = 0.02  # m: the EE above a held cube's centre (the scripted grasp: 3 mm; a cube slips ~2 cm in the pads)
#: Vendors' ros2_control hardware plugins -> (arm controller, gripper controller, gripper interface)
#: of their drivers' launch files; an unknown plugin gets ROS 2 control's conventional names.
_DRIVERS = {
    "ur_robot_driver/": ("scaled_joint_trajectory_controller", "gripper_controller", "gripper_action"),
    "franka_hardware/": ("fr3_arm_controller", "franka_gripper", "gripper_action"),
    "dynamixel_hardware": ("arm_controller", "gripper_controller", "gripper_action"),
    "open_manipulator": ("arm_controller", "gripper_controller", "gripper_action"),
    "interbotix": ("arm_controller", "gripper_controller", "forward"),
    "kinova": ("joint_trajectory_controller", "robotiq_gripper_controller", "gripper_action"),
}


def _fail(where: str, message: str) -> None:
    raise ArmFileError(f"{where}: {message}")


# -- the description's tree -------------------------------------------------------------------------
@dataclass
class _Tree:
    """A URDF's links and joints with the lookups the inference needs."""

    robot: Any  # multiros.sim.urdf_model.Robot
    root: str
    joints: dict[str, Any]
    children: dict[str, list[Any]]
    parent: dict[str, Any]  # child link -> joint
    efforts: dict[str, float]

    def moving(self, joint: Any) -> bool:
        return joint.type in _MOVING and joint.mimic is None

    def subtree_has_motion(self, link: str) -> bool:
        return any(j.type in _MOVING or self.subtree_has_motion(j.child) for j in self.children.get(link, []))

    def transform(self, link: str, q: Mapping[str, float]) -> np.ndarray:
        """``link``'s pose in the root frame with the joints at ``q`` (others at 0, mimics following)."""
        tf = np.eye(4)
        while link in self.parent:
            joint = self.parent[link]
            tf = joint.origin.dot(_motion(joint, self.position(joint, q))).dot(tf)
            link = joint.parent
        return tf

    def position(self, joint: Any, q: Mapping[str, float]) -> float:
        if joint.mimic is not None:
            return joint.mimic.multiplier * q.get(joint.mimic.joint, 0.0) + joint.mimic.offset
        return float(q.get(joint.name, 0.0))

    def fixed_descendants(self, link: str) -> list[str]:
        """``link`` and the links fixed to it, breadth first in URDF order."""
        out, queue = [], [link]
        while queue:
            current = queue.pop(0)
            out.append(current)
            queue += [j.child for j in self.children.get(current, []) if j.type == "fixed"]
        return out

    def descendants(self, link: str) -> list[str]:
        out = [link]
        for j in self.children.get(link, []):
            out += self.descendants(j.child)
        return out


def _motion(joint: Any, value: float) -> np.ndarray:
    tf = np.eye(4)
    if joint.type in _REVOLUTE and value:
        axis = np.asarray(joint.axis, dtype=float)
        axis = axis / np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        tf[:3, :3] = np.eye(3) + math.sin(value) * k + (1 - math.cos(value)) * k.dot(k)
    elif joint.type == "prismatic":
        tf[:3, 3] = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis) * value
    return tf


def _limits(joint: Any) -> tuple[float, float]:
    if joint.type == "continuous" or joint.limit is None or joint.limit.lower is None:
        return -math.inf, math.inf
    return float(joint.limit.lower), float(joint.limit.upper if joint.limit.upper is not None else 0.0)


def _tree(text: str, source: str) -> _Tree:
    import xml.etree.ElementTree as ET

    from multiros.sim.urdf_model import parse_urdf

    robot = parse_urdf(ET.fromstring(text), source)
    joints = {j.name: j for j in robot.joints}
    children: dict[str, list[Any]] = {}
    parent: dict[str, Any] = {}
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)
        parent[j.child] = j
    roots = [link.name for link in robot.links if link.name not in parent]
    efforts = {j.name: float(j.limit.effort or 0.0) if j.limit is not None else 0.0 for j in robot.joints}
    return _Tree(robot, roots[0], joints, children, parent, efforts)


def _chains(tree: _Tree) -> list[tuple[str, ...]]:
    """Every serial run of actuated revolute joints from the root (see the module docstring), in
    URDF order, longest runs kept per path."""
    found: list[tuple[str, ...]] = []

    def walk(link: str, chain: tuple[str, ...], open_: bool) -> None:
        kids = tree.children.get(link, [])
        branches = [j for j in kids if j.type in _MOVING or tree.subtree_has_motion(j.child)]
        if chain and len(branches) > 1:
            open_ = False  # the hand: the fingers branch off here
        ends = True
        for j in kids:
            nxt, still = chain, open_
            if j.type in _MOVING:
                if open_ and j.type in _REVOLUTE and j.mimic is None:
                    nxt = (*chain, j.name)
                elif chain:
                    still = False
            if j.type in _MOVING or tree.subtree_has_motion(j.child):
                ends = False
                walk(j.child, nxt, still)
        if ends and chain and chain not in found:
            found.append(chain)

    walk(tree.root, (), True)
    # A path that ends in a branch records its chain when the walk meets the end of each branch.
    return found


# -- the draft: values and why ----------------------------------------------------------------------
@dataclass
class ArmDraft:
    """An arm file's values (the YAML's sections) with a comment per key, and its controllers file."""

    name: str
    sections: dict[str, Any] = field(default_factory=dict)
    comments: dict[str, str] = field(default_factory=dict)  # "section.key" or "section" -> comment
    header: list[str] = field(default_factory=list)
    controllers_yaml: str = ""
    settle_error: float = math.nan
    check: Any = None  # rl_environments.arm_check.ArmCheck of the drafted file (None: not checked)

    def note(self, key: str, text: str) -> None:
        self.comments[key] = text


@dataclass
class Inspection:
    """What a description says, before any choice: its tree, the joints' data and the MuJoCo model."""

    uri: str
    xacro_args: dict[str, str]
    source: str
    tree: _Tree
    description: Any  # multiros.sim.description.RobotDescription
    chains: list[tuple[str, ...]]


def inspect_description(uri: str, xacro_args: Mapping[str, str] | None = None) -> Inspection:
    """Load ``uri`` (``package://``, a path; xacro run with ``xacro_args``) as the simulation node does
    and read its tree.

    Raises:
        ArmFileError: the description, a package or a mesh is missing, or it does not parse.
    """
    from multiros.sim.description import load_description
    from multiros.sim.errors import SimError
    from multiros.sim.packages import default_index

    args = {str(k): str(v) for k, v in (xacro_args or {}).items()}
    index = default_index()
    try:
        path = index.resolve_uri(uri) if "://" in uri else Path(uri).expanduser().absolute()
    except SimError as exc:
        _fail(uri, _first(exc))
    if not path.is_file():
        _fail(uri, f"file {str(path)!r} not found; fix: give an existing URDF or xacro file")
    try:
        desc = load_description(str(path), args=args, index=index)
    except SimError as exc:
        text = _first(exc)
        missing = bool(getattr(exc, "missing_assets", False))
        fix = ("pass it: --xacro-arg NAME=VALUE" if "undefined argument" in text or "arg" in text.lower()
               and "xacro" in text.lower() else
               "source the workspace with the package, or install the meshes" if missing else
               "fix the description (it must be URDF or xacro of one tree)")
        _fail(uri, f"{text}; fix: {fix}")
    except Exception as exc:  # noqa: BLE001 - xacro, XML and trimesh raise many kinds
        _fail(uri, f"does not load: {_first(exc)}")
    if desc.format != "urdf":
        _fail(uri, "is MJCF; uniros arm add reads URDF or xacro (the tasks need a URDF chain); fix: give the "
                   "URDF of the robot")
    tree = _tree(desc.text, str(path))
    return Inspection(uri, args, str(path), tree, desc, _chains(tree))


def _first(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _pick_chain(ins: Inspection) -> tuple[tuple[str, ...], str]:
    tree, chains = ins.tree, ins.chains
    moving = [j for j in tree.robot.joints if j.type in _MOVING and j.mimic is None]
    if not moving:
        _fail(ins.uri, "has no actuated joints; fix: uniros serves serial arms of 4 to 7 revolute joints")
    if all(j.type == "prismatic" for j in moving):
        _fail(ins.uri, f"its actuated joints {[j.name for j in moving]} are all prismatic; fix: uniros serves "
                       "serial arms of 4 to 7 revolute joints (write the arm file by hand for another kind)")
    best = max(chains, key=len) if chains else ()
    if len(best) < 4:
        _fail(ins.uri, f"has no serial chain of 4 to 7 revolute joints from {tree.root!r} (the longest is "
                       f"{list(best)}); fix: uniros serves serial arms of 4 to 7 joints")
    if len(best) > 7:
        _fail(ins.uri, f"its serial chain from {tree.root!r} has {len(best)} revolute joints {list(best)}; fix: "
                       "uniros serves 4 to 7: write the arm file by hand naming 7 of them (docs/add_your_arm.md)")
    others = [c for c in chains if c != best and len(c) >= 4]
    why = f"inferred: the serial chain of {len(best)} revolute joints from {tree.root!r}"
    if others:
        why += (f"; also found {[list(c) for c in others]}: the longest is taken, ties by URDF order "
                "(edit to choose another)")
    return best, why


def _base_link(tree: _Tree, first: str) -> str:
    """The link the arm stands on: up from the first arm joint through fixed joints."""
    link = tree.joints[first].parent
    while link in tree.parent and tree.parent[link].type == "fixed":
        link = tree.parent[link].parent
    return link


def _moving_above(tree: _Tree, link: str) -> list[str]:
    """The moving joints between the root and ``link`` (a torso, a mobile base's): the tasks drive none."""
    found = []
    while link in tree.parent:
        joint = tree.parent[link]
        if joint.type in _MOVING or joint.type in ("floating", "planar"):
            found.append(joint.name)
        link = joint.parent
    return found[::-1]


@dataclass
class _Gripper:
    joint: str
    follower: str
    mimic: float
    closed: float
    open: float
    opening: float  # m: the gap's change from closed to open
    midpoint: np.ndarray  # root frame, fingers open, arm at zero
    closing_direction: np.ndarray  # root frame
    pads: tuple[float, float] | None = None  # m: the gap between the fingers' geometry (closed, open)
    notes: list[str] = field(default_factory=list)  # what else the file should say of the gripper
    independent: bool = False  # both joints driven (no <mimic> ties them)
    grasp_point: np.ndarray | None = None  # root frame: between the open fingertips, _PAD_BACK short of their ends


class _Hand:
    """The description compiled, to measure the fingers by their geometry: MuJoCo's distance between
    the two fingers' collision geoms (meshes as their convex hulls, as the simulation collides them),
    and the fingertips as the geoms' centres (a mesh geom sits at its mesh's centroid)."""

    def __init__(self, ins: Inspection) -> None:
        import mujoco

        self.ins = ins
        self.model = ins.description.spec.copy().compile()
        self.data = mujoco.MjData(self.model)

    def geoms(self, link: str) -> list[int]:
        """The collision geoms of ``link`` and its descendants (all geoms when none collides)."""
        model = self.model
        bodies = {int(model.body(self.ins.description.body_name(n)).id) for n in self.ins.tree.descendants(link)}
        found = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies]
        solid = [g for g in found if model.geom_contype[g] or model.geom_conaffinity[g]]
        return solid or found

    def solid(self, link: str) -> bool:
        """Whether ``link`` or a link below it has collision geometry."""
        model = self.model
        return any(model.geom_contype[g] or model.geom_conaffinity[g] for g in self.geoms(link))

    def drive(self, lead: Any, value: float, *more: tuple[Any, float]) -> None:
        """Every joint at zero but ``lead`` at ``value`` (and each ``(joint, value)`` of ``more``), the joints
        mimicking them where their mimic puts them."""
        import mujoco

        model, data = self.model, self.data
        data.qpos[:] = model.qpos0
        for driven, at in ((lead, value), *more):
            data.qpos[model.joint(driven.name).qposadr[0]] = at
            for j in self.ins.tree.robot.joints:
                if j.mimic is not None and j.mimic.joint == driven.name and j.type in _MOVING:
                    data.qpos[model.joint(j.name).qposadr[0]] = j.mimic.multiplier * at + j.mimic.offset
        mujoco.mj_kinematics(model, data)

    def gap(self, first: list[int], second: list[int]) -> float:
        """The smallest distance between two sets of geoms in the pose of the last :meth:`drive`."""
        import mujoco

        fromto = np.zeros(6)
        return float(min(mujoco.mj_geomDistance(self.model, self.data, a, b, 1.0, fromto)
                         for a in first for b in second))

    def tip(self, geoms: list[int], hand: np.ndarray) -> list[int]:
        """The fingertip's geoms: those of the body whose geom lies farthest from the hand's origin
        ``hand`` (a linkage's distal link, not its knuckles), in the pose of the last :meth:`drive`."""
        centres = self.data.geom_xpos[geoms]
        body = int(self.model.geom_bodyid[geoms[int(np.argmax(np.linalg.norm(centres - hand, axis=1)))]])
        return [g for g in geoms if int(self.model.geom_bodyid[g]) == body]

    def extent(self, geoms: list[int], direction: np.ndarray) -> float:
        """How far ``geoms`` reach along the unit ``direction`` (the largest projection of their vertices: a
        mesh's own, a primitive's bounding box corners), in the pose of the last :meth:`drive`."""
        model, data = self.model, self.data
        best = -math.inf
        for g in geoms:
            rot = data.geom_xmat[g].reshape(3, 3)
            mesh = int(model.geom_dataid[g]) if int(model.geom_type[g]) == 7 else -1  # mjGEOM_MESH
            if mesh >= 0:
                start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
                local = np.asarray(model.mesh_vert[start:start + count], dtype=float)
            else:
                centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
                local = centre + half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
            best = max(best, float(np.max((data.geom_xpos[g] + local.dot(rot.T)).dot(direction))))
        return best

    def grasp_point(self, first: list[int], second: list[int], hand: np.ndarray) -> np.ndarray:
        """Between two fingertips (open, as posed by the last :meth:`drive`): the midpoint of their centres
        moved along the hand -> fingers direction to ``_PAD_BACK`` short of the nearer fingertip's end (a
        mesh's centre lies wherever its volume is, often back in the finger's slide)."""
        middle = (self.centre(first) + self.centre(second)) / 2
        out = middle - hand
        u = out / max(float(np.linalg.norm(out)), 1e-9)
        ends = min(self.extent(first, u), self.extent(second, u))
        return middle + (ends - _PAD_BACK - float(middle.dot(u))) * u

    def centre(self, geoms: list[int]) -> np.ndarray:
        """The mean centre of ``geoms`` in the pose of the last :meth:`drive`."""
        return np.asarray(self.data.geom_xpos[geoms], dtype=float).mean(axis=0)


def _drive_range(lead: Any, followers: Sequence[Any]) -> tuple[float, float]:
    """The driven joint's limits narrowed to where every joint mimicking it stays inside its own
    limits (a follower whose multiplier maps the drive's range past its limits)."""
    lo, hi = _limits(lead)
    for f in followers:
        f_lo, f_hi = _limits(f)
        k, o = f.mimic.multiplier, f.mimic.offset
        if k == 0 or not (math.isfinite(f_lo) and math.isfinite(f_hi)):
            continue
        a, b = sorted(((f_lo - o) / k, (f_hi - o) / k))
        lo, hi = max(lo, a), min(hi, b)
    return lo, hi


def _gripper(ins: Inspection, hand_model: _Hand, last_arm_joint: str) -> tuple[_Gripper | None, str]:
    """The parallel gripper after the arm (see the module docstring), measured on its geometry."""
    tree = ins.tree
    hand = tree.joints[last_arm_joint].child
    below = [tree.joints[n] for n in tree.joints if n != last_arm_joint
             and tree.joints[n].type in _MOVING and tree.joints[n].parent in tree.descendants(hand)]
    leaders = [j for j in below if j.mimic is None]
    if not leaders:
        return None, "no actuated joint after the arm: reach only (push and pick-and-place need a gripper)"
    if len(leaders) > 1:
        return _independent_fingers(ins, hand_model, hand, leaders)
    lead = leaders[0]
    followers = [j for j in below if j.mimic is not None and j.mimic.joint == lead.name]
    own = set(tree.descendants(lead.child))
    # The other finger: a follower outside the driven finger's own links (a linkage's knuckles and
    # fingertip on the same side are not), the one whose links' gap to the driven finger's changes most.
    others = [j for j in followers if j.child not in own and j.type in _MOVING]
    top = [j for j in others if not any(j.parent in tree.descendants(o.child) for o in others if o is not j)]
    if not top:
        return None, (f"finger joint {lead.name!r} has no joint on another finger mimicking it (a parallel gripper's "
                      "second finger): reach only")
    lo, hi = _drive_range(lead, followers)
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo <= 1e-6:
        return None, (f"finger joint {lead.name!r} has no finite range in which it and the joints mimicking it stay "
                      "inside their limits: reach only; fix the limits or the <mimic> multipliers")
    if not hand_model.geoms(lead.child):
        return None, f"finger joint {lead.name!r} moves no geometry: reach only"
    bare = [j.name for j in (lead, *top) if not hand_model.solid(j.child)]
    if bare:
        return None, (f"the fingers of {bare} have no <collision> geometry, so the simulation cannot grasp with "
                      "them: reach only; add collision geometry to the finger links")
    hand_origin = tree.transform(hand, {})[:3, 3]
    hand_model.drive(lead, lo)
    lead_tip = hand_model.tip(hand_model.geoms(lead.child), hand_origin)

    def stroke(follower: Any) -> tuple[list[int], float, float]:
        """The follower's fingertip and its gap to the driven fingertip at the drive's two limits."""
        theirs = hand_model.geoms(follower.child)
        if not theirs:
            return [], 0.0, 0.0
        hand_model.drive(lead, lo)
        tip = hand_model.tip(theirs, hand_origin)
        g_lo = hand_model.gap(lead_tip, tip)
        hand_model.drive(lead, hi)
        return tip, g_lo, hand_model.gap(lead_tip, tip)

    strokes = {j.name: stroke(j) for j in top}
    follower = max(top, key=lambda j: (abs(strokes[j.name][2] - strokes[j.name][1]), -top.index(j)))
    other_tip, g_lo, g_hi = strokes[follower.name]
    if abs(g_hi - g_lo) < 1e-4:
        return None, (f"finger joint {lead.name!r} and {follower.name!r} keep their gap when driven: not a "
                      "parallel gripper; reach only")
    closed, opened = (lo, hi) if g_lo <= g_hi else (hi, lo)
    hand_model.drive(lead, opened)
    a, b = hand_model.centre(lead_tip), hand_model.centre(other_tip)
    direction = a - b
    if lead.type == "prismatic":
        direction = tree.transform(lead.parent, {})[:3, :3].dot(np.asarray(lead.axis, float))
    pads = (min(g_lo, g_hi), max(g_lo, g_hi))
    found = _Gripper(lead.name, follower.name, float(follower.mimic.multiplier), closed, opened,
                     pads[1] - pads[0], (a + b) / 2, direction / max(np.linalg.norm(direction), 1e-9), pads,
                     grasp_point=hand_model.grasp_point(lead_tip, other_tip, hand_origin))
    why = (f"inferred: finger joint {lead.name!r} ({lead.type}) and {follower.name!r} on the other finger mimicking "
           f"it (x {found.mimic:g}); closed = the limit where the fingers' geometry is nearer")
    if len(followers) > 1:
        why += f"; {len(followers) - 1} more joint(s) follow it (a linkage)"
    if (lo, hi) != _limits(lead):
        found.notes.append(f"the drive's range is narrowed to [{lo:.4g}, {hi:.4g}] so that every joint mimicking it "
                           "stays inside its own limits")
    listed = {j.name for j in ins.description.ros2_control}
    if listed and lead.name not in listed:
        found.notes.append(f"{lead.name!r} is not in the description's <ros2_control> tag (another driver runs the "
                           "gripper): the simulation actuates it within its URDF limits")
    return found, why


def _independent_fingers(ins: Inspection, hand_model: _Hand, hand: str,
                         leaders: Sequence[Any]) -> tuple[_Gripper | None, str]:
    """Two finger joints driven independently (no ``<mimic>`` ties them): the pair on separate fingers
    whose fingertips' gap changes most, closed where both are nearer. The simulation's gripper
    controller drives both, the second at the ratio of their strokes (``gripper.independent``)."""
    tree = ins.tree
    hand_origin = tree.transform(hand, {})[:3, 3]
    pairs = [(a, b) for i, a in enumerate(leaders) for b in leaders[i + 1:]
             if a.child not in tree.descendants(b.child) and b.child not in tree.descendants(a.child)
             and hand_model.solid(a.child) and hand_model.solid(b.child)]
    names = [j.name for j in leaders]
    best: tuple[float, Any, Any, dict[tuple[float, float], float], list[int], list[int]] | None = None
    for a, b in pairs:
        (alo, ahi), (blo, bhi) = _limits(a), _limits(b)
        if not all(map(math.isfinite, (alo, ahi, blo, bhi))) or ahi - alo <= 1e-6 or bhi - blo <= 1e-6:
            continue
        hand_model.drive(a, alo, (b, blo))
        tip_a = hand_model.tip(hand_model.geoms(a.child), hand_origin)
        tip_b = hand_model.tip(hand_model.geoms(b.child), hand_origin)
        gaps = {}
        for va in (alo, ahi):
            for vb in (blo, bhi):
                hand_model.drive(a, va, (b, vb))
                gaps[(va, vb)] = hand_model.gap(tip_a, tip_b)
        stroke = max(gaps.values()) - min(gaps.values())
        if best is None or stroke > best[0]:
            best = (stroke, a, b, gaps, tip_a, tip_b)
    if best is None or best[0] < 1e-4:
        return None, (f"the joints after the arm {names} are driven independently (no <mimic> ties them) but no two "
                      "of them on separate fingers with <collision> geometry and finite limits change the fingers' "
                      "gap: reach only")
    _, a, b, gaps, tip_a, tip_b = best
    closed_pair = min(gaps, key=lambda k: gaps[k])
    open_pair = max(gaps, key=lambda k: gaps[k])
    if closed_pair[0] == open_pair[0] or closed_pair[1] == open_pair[1]:
        return None, (f"finger joints {a.name!r} and {b.name!r} are driven independently, but the fingers do not "
                      "close by moving both (one finger's limit opens the gap whatever the other does): reach only")
    (ca, cb), (oa, ob) = closed_pair, open_pair
    mimic = (ob - cb) / (oa - ca)
    if abs(cb - mimic * ca) > 1e-6:
        return None, (f"finger joints {a.name!r} ({ca:g} closed, {oa:g} open) and {b.name!r} ({cb:g}, {ob:g}) are "
                      "driven independently and no multiplier maps one onto the other (closed is not at zero for "
                      "both): reach only; write the gripper by hand")
    hand_model.drive(a, oa, (b, ob))
    pa, pb = hand_model.centre(tip_a), hand_model.centre(tip_b)
    direction = pa - pb
    if a.type == "prismatic":
        direction = tree.transform(a.parent, {})[:3, :3].dot(np.asarray(a.axis, float))
    found = _Gripper(a.name, b.name, mimic, ca, oa, gaps[open_pair] - gaps[closed_pair], (pa + pb) / 2,
                     direction / max(np.linalg.norm(direction), 1e-9), (gaps[closed_pair], gaps[open_pair]),
                     independent=True, grasp_point=hand_model.grasp_point(tip_a, tip_b, hand_origin))
    why = (f"inferred: finger joints {a.name!r} and {b.name!r} ({a.type}) driven independently (no <mimic> ties "
           f"them): both commanded, {b.name!r} at {mimic:g} x {a.name!r}; closed = the limits where the fingers' "
           "geometry is nearer")
    if len(leaders) > 2:
        why += f"; the other driven joints {[n for n in names if n not in (a.name, b.name)]} are left at rest"
    listed = {j.name for j in ins.description.ros2_control}
    outside = [n for n in (a.name, b.name) if listed and n not in listed]
    if outside:  # actuated in simulation only through <ros2_control> (or as the drive of a <mimic>)
        return None, (f"finger joints {outside} are driven independently but not in the description's "
                      "<ros2_control> tag, so the simulation cannot drive them: reach only; add them to the tag")
    return found, why




def _ee_link(tree: _Tree, last_arm_joint: str, gripper: _Gripper | None) -> tuple[str, str, np.ndarray]:
    """The end-effector link, why, and the grasp point in its frame (``arm.tcp_offset``; zeros: its origin)."""
    fixed = tree.fixed_descendants(tree.joints[last_arm_joint].child)

    def named(link: str) -> int | None:
        words = set(re.split(r"[^a-z0-9]+", link.lower()))
        joined = link.lower()
        for rank, key in enumerate(_EE_NAMES):
            if key in words or ("_" in key and key in joined):
                return rank
        return None

    candidates = [n for n in fixed if named(n) is not None]
    if gripper is None:
        if candidates:
            best = min(candidates, key=lambda n: (named(n), fixed.index(n)))
            return best, "inferred: the link fixed to the last arm link named like a tool frame", np.zeros(3)
        return fixed[-1], "guessed: no link named tcp/grasp/ee/tool: the last link fixed to the arm's last link", \
            np.zeros(3)

    grasp = gripper.midpoint if gripper.grasp_point is None else gripper.grasp_point

    def dist(link: str) -> float:
        return float(np.linalg.norm(tree.transform(link, {})[:3, 3] - grasp))

    best = min(candidates or fixed, key=lambda n: (round(dist(n), 3), -fixed.index(n)))  # ties: the deeper link
    wrist = tree.transform(tree.joints[last_arm_joint].child, {})[:3, 3]
    out = grasp - wrist
    reach_out = float(np.linalg.norm(out))
    # How far the link lies short of the grasp point, along the wrist -> fingers direction.
    short = reach_out - float(np.dot(tree.transform(best, {})[:3, 3] - wrist, out / max(reach_out, 1e-9)))
    tf = tree.transform(best, {})
    offset = tf[:3, :3].T.dot(grasp - tf[:3, 3])
    where = f"{_PAD_BACK * 100:g} cm short of the open fingertips' ends, between them"
    if candidates and short <= _TCP_SHORT:  # the vendor's tool frame: the grasp point it means
        return best, (f"inferred: the link named like a tool frame nearest the fingers ({dist(best) * 100:.1f} cm "
                      f"from the point {where}); check it lies between the fingertips"), np.zeros(3)
    if candidates:  # a flange frame (tool0, end_effector_link at the wrist): the grasp point is further out
        return best, (f"inferred: the link named like a tool frame nearest the fingers lies {short * 100:.1f} cm short "
                      f"of the point {where} (a flange frame): arm.tcp_offset makes that point the end effector"), \
            offset
    if dist(best) <= _TCP_FAR:
        return best, (f"guessed: no link named tcp/grasp/ee/tool: the hand's link nearest the fingers "
                      f"({dist(best) * 100:.1f} cm from the point {where})"), np.zeros(3)
    return best, (f"inferred: no link named tcp/grasp/ee/tool: the hand's link nearest the fingers, "
                  f"{dist(best) * 100:.1f} cm from the point {where}, which arm.tcp_offset makes the end effector"), \
        offset


def _axis_name(vec: np.ndarray, exclude: str | None = None) -> tuple[str, float]:
    order = np.argsort(-np.abs(vec))
    for i in order:
        name = "xyz"[int(i)]
        if name != exclude:
            return name, float(vec[int(i)])
    raise AssertionError("unreachable")


def _r(value: float, digits: int = 4) -> float:
    out = round(float(value), digits)
    return 0.0 if out == 0 else out


def _rl(values: Sequence[float] | np.ndarray, digits: int = 4) -> list[float]:
    return [_r(v, digits) for v in values]


def _rl_within(values: Sequence[float] | np.ndarray, lower: Sequence[float] | np.ndarray,
               upper: Sequence[float] | np.ndarray) -> list[float]:
    """Joint positions rounded as written, kept inside the limits as written (``reach.min_joint_pos``'s
    5 digits): a pose at a limit must not round past it."""
    lo, hi = _rl(lower, 5), _rl(upper, 5)
    return [float(min(max(v, a), b)) for v, a, b in zip(_rl(values), lo, hi)]


def draft_arm(ins: Inspection, name: str, *, seed: int = 0) -> ArmDraft:
    """Every value of the arm file for ``name`` from an inspected description (see the module docstring)."""
    from multiros.utils.kinematics import KinematicChain
    from rl_environments.arm_ik import ChainTopDownIK

    tree = ins.tree
    draft = ArmDraft(name)
    joints, why_chain = _pick_chain(ins)
    base = _base_link(tree, joints[0])
    moving = _moving_above(tree, base)
    if moving:
        _fail(ins.uri, f"the arm's base {base!r} hangs from moving joint(s) {moving} (a torso, a mobile base) that "
                       "the tasks neither drive nor hold; fix: load the description with the arm on a fixed base "
                       "(its xacro arguments), or write the arm file by hand")
    gripper, why_gripper = _gripper(ins, _Hand(ins), joints[-1])
    if gripper is not None and gripper.pads is not None and gripper.pads[1] < _MIN_OPEN_GAP:
        why_gripper = (f"the open fingers' collision geometry leaves {gripper.pads[1] * 100:.1f} cm between them "
                       "(MuJoCo collides a mesh as its convex hull), too little for the smallest cube (1.6 cm): "
                       "reach only; fix: give the finger links primitive <collision> pads on their inner faces")
        gripper = None
    ee, why_ee, tcp = _ee_link(tree, joints[-1], gripper)
    try:
        chain = KinematicChain.from_urdf(ins.description.text, base, ee, tip_offset=tcp)
    except ValueError as exc:
        _fail(ins.uri, f"the chain {base!r} -> {ee!r}: {_first(exc)}")
    if tuple(chain.joint_names) != joints:  # a moving joint between the base and the arm: not served
        _fail(ins.uri, f"the moving joints from {base!r} to {ee!r} are {list(chain.joint_names)}, not the arm's "
                       f"{list(joints)}; fix: write the arm file by hand")
    rng = np.random.default_rng(seed)
    n = len(joints)
    lower = np.array([max(_limits(tree.joints[j])[0], -math.pi) for j in joints])
    upper = np.array([min(_limits(tree.joints[j])[1], math.pi) for j in joints])
    wide = [j for j in joints if _limits(tree.joints[j])[0] < -math.pi or _limits(tree.joints[j])[1] > math.pi]

    # Reach: forward kinematics of random configurations.
    qs = rng.uniform(lower, upper, size=(20000, n))
    pts = chain.fk_position(qs)
    radial = np.hypot(pts[:, 0], pts[:, 1])
    reach = float(np.percentile(radial, 99.5))
    if reach < 0.05:
        _fail(ins.uri, f"the arm reaches {reach:.3f} m from its base; fix: check the description's units (metres)")

    # Home: zeros clipped, unless that puts the EE below the base.
    home = np.clip(np.zeros(n), lower, upper)
    why_home = "inferred: zeros clipped into the joint limits (the EE stays above the base)"
    if chain.fk_position(home[None])[0][2] < 0.1 * reach:
        above = qs[pts[:, 2] > 0.3 * reach]
        if len(above):
            home = above[np.argmin(np.linalg.norm(above - home, axis=1))]
        why_home = ("guessed: zeros put the EE below the base, so the sampled pose nearest zeros with the EE "
                    "above it")

    # Axes of the EE frame.
    zero = {j: 0.0 for j in joints}
    if gripper is not None:
        zero[gripper.joint] = gripper.open
        if gripper.independent:
            zero[gripper.follower] = gripper.mimic * gripper.open
    ee_tf = tree.transform(ee, zero)
    wrist = tree.transform(tree.joints[joints[-1]].child, zero)[:3, 3]
    target = gripper.midpoint if gripper is not None else ee_tf[:3, 3]
    out = target - wrist
    k = len(joints) - 2
    while np.linalg.norm(out) < 0.01 and k >= 0:  # the EE at the wrist: from a joint further back
        out = target - tree.transform(tree.joints[joints[k]].child, zero)[:3, 3]
        k -= 1
    approach, sign = _axis_name(ee_tf[:3, :3].T.dot(out))
    why_approach = "inferred: the EE frame's axis from the wrist towards the " + ("fingers" if gripper else "EE")
    if sign < 0:
        why_approach += (f"; it points along -{approach}, and the tasks point +{approach} down: choose an EE link "
                         "whose axis points out of the tool")
    if gripper is not None:
        closing, _ = _axis_name(ee_tf[:3, :3].T.dot(gripper.closing_direction), exclude=approach)
        why_closing = "inferred: the fingers' axis in the EE frame"
    else:
        closing, _ = _axis_name(np.array([1.0, 1.0, 1.0]) * [1, 0.9, 0.8], exclude=approach)
        why_closing = "guessed: no fingers; any axis other than the approach axis"

    # Boxes, in the base frame, scaled by the reach and checked against the samples.
    goal_min = np.array([0.35 * reach, -0.3 * reach, 0.05])
    goal_max = np.array([0.7 * reach, 0.3 * reach, max(0.1, 0.55 * reach)])
    inside = float(np.mean(np.all((pts >= goal_min) & (pts <= goal_max), axis=1)))
    if inside < 0.002:
        _fail(ins.uri, f"random configurations of the chain {list(joints)} reach the goal box {goal_min.round(2)} .. "
                       f"{goal_max.round(2)} in {inside:.2%} of samples; fix: check the joint limits")
    ee_min = [-reach - 0.05, -reach - 0.05, 0.0]
    ee_max = [reach + 0.05, reach + 0.05, float(np.max(pts[:, 2])) + 0.05]
    vel = chain.velocity_limits
    max_vel = float(np.max(vel[np.isfinite(vel)])) if np.any(np.isfinite(vel)) else 6.0
    max_vel = max(max_vel, 1.0)

    # A top-down start pose above the middle of the goal box.
    ik = ChainTopDownIK(chain, approach, closing, home.tolist(), home=home.tolist(), lower=lower.tolist(),
                        upper=upper.tolist())
    start = np.array([0.5 * reach, 0.0, 0.3 * reach])
    base_z = tree.transform(base, {})[2, 3]

    def lowest(q: np.ndarray) -> float:
        values = dict(zip(joints, q))
        return min(tree.transform(tree.joints[j].child, values)[2, 3] for j in joints) - base_z

    seed_q, err = _top_down(ik, chain, start, rng, approach, 0.1 * reach, lowest)
    why_seed = (f"inferred: top-down pose (ChainTopDownIK) with the EE at {_rl(start, 3)} in the base frame"
                if err < 0.005 else f"guessed: the nearest top-down pose found misses {_rl(start, 3)} by "
                f"{err * 100:.1f} cm")

    draft.header = [
        f"{name}: an arm file written by `uniros arm add {ins.uri}`: check every value marked guessed.",
        "An arm file (format 1): see docs/add_your_arm.md for every key.",
        *(f"The description: {note}." for note in tree.robot.notes),
    ]
    draft.sections["format"] = 1
    draft.sections["name"] = name
    draft.sections["robot_name"] = re.sub(r"[^a-z0-9_]", "_", name.lower())
    draft.sections["description"] = {"uri": ins.uri, "xacro_args": dict(ins.xacro_args),
                                     "controllers": f"{name}/controllers.yaml"}
    draft.note("description.controllers", "written by uniros arm add: servo gains from the efforts and masses")
    controllers = ["joint_state_broadcaster", "arm_position_controller"]
    if gripper is not None:
        controllers.append("gripper_position_controller")
    draft.sections["arm"] = {
        "joints": list(joints), "base_link": base, "ee_link": ee, **({"tcp_offset": _rl(tcp)} if np.any(
            np.abs(tcp) > 0) else {}), "home": _rl_within(home, lower, upper),
        "controller": "arm_position_controller", "controllers": controllers,
        "approach_axis": approach, "closing_axis": closing, "ik_seed": _rl_within(seed_q, lower, upper),
    }
    draft.note("arm.joints", why_chain)
    draft.note("arm.base_link", "inferred: the link the first arm joint hangs from (through fixed joints)")
    draft.note("arm.ee_link", why_ee)
    if np.any(np.abs(tcp) > 0):
        draft.note("arm.tcp_offset", f"inferred: between the open fingertips, {_PAD_BACK * 100:g} cm short of their "
                                     "ends (measured on their geometry), in arm.ee_link's frame, metres")
    draft.note("arm.home", why_home)
    draft.note("arm.approach_axis", why_approach)
    draft.note("arm.closing_axis", why_closing)
    draft.note("arm.ik_seed", why_seed)
    if gripper is None:
        draft.sections["gripper"] = None
        draft.note("gripper", why_gripper)
    else:
        draft.sections["gripper"] = {"joints": [gripper.joint, gripper.follower], "mimic": _r(gripper.mimic),
                                     "closed": _r(gripper.closed), "open": _r(gripper.open),
                                     "controller": "gripper_position_controller",
                                     **({"independent": True} if gripper.independent else {})}
        draft.note("gripper", why_gripper)
        draft.note("gripper.open", f"inferred: the other limit; the gap opens by {gripper.opening * 100:.1f} cm")
        if gripper.notes:
            draft.note("gripper.closed", "; ".join(gripper.notes))
    draft.sections["camera"] = {"render_camera": "", "view": {
        "lookat": _rl([0.45 * reach, 0.0, 0.25 * reach], 3), "distance": _r(2.0 * reach + 0.1, 3),
        "azimuth": 140.0, "elevation": -25.0}}
    draft.note("camera.render_camera", "guessed: the description has no camera sensor; renders use the view below")
    limits_why = "inferred: the URDF limits" + (f", {wide} clipped to [-pi, pi] (guessed)" if wide else "")
    draft.sections["reach"] = {
        "min_joint_pos": _rl(lower, 5), "max_joint_pos": _rl(upper, 5),
        "init_joint_pos": _rl_within(seed_q, lower, upper),
        "delta_coeff": 0.05, "ee_delta_coeff": _r(float(np.clip(0.025 * reach / 0.9, 0.015, 0.03)), 3),
        "position_ee_min": _rl(ee_min, 3), "position_ee_max": _rl(ee_max, 3),
        "position_goal_min": _rl(goal_min, 3), "position_goal_max": _rl(goal_max, 3),
        "reach_tolerance": 0.02, "step_reward": -0.5, "multiplier_dist_reward": 2.0, "reached_goal_reward": 20.0,
        "joint_limits_reward": -2.0, "max_joint_vel": _r(max_vel, 3),
    }
    draft.note("reach", f"the reach is {reach:.3f} m (99.5th percentile of the EE's distance from the base axis "
                        "over 20,000 random configurations); the boxes scale with it")
    draft.note("reach.min_joint_pos", limits_why)
    draft.note("reach.init_joint_pos", "inferred: the top-down pose of arm.ik_seed")
    draft.note("reach.position_goal_min", f"inferred: in front of the base; {inside:.1%} of random "
                                          "configurations land in the box")
    draft.note("reach.max_joint_vel", "inferred: the largest URDF velocity limit")

    if gripper is not None:
        init = _manipulation(draft, ik, chain, gripper, reach, lower, upper, seed_q, max_vel, rng)
        if err >= 0.005:  # the first target was out of the top-down IK's reach: the episodes' start is not
            q, err2 = _top_down(ik, chain, init, rng, approach, 0.1 * reach, lowest)
            if err2 < err:
                seed_q, err = q, err2
                ik.seed = ik.home = np.asarray(seed_q)
                draft.sections["arm"]["ik_seed"] = draft.sections["reach"]["init_joint_pos"] = \
                    _rl_within(seed_q, lower, upper)
                draft.note("arm.ik_seed", f"inferred: top-down pose (ChainTopDownIK) with the EE at {_rl(init, 3)} "
                                          "(manipulation.init_ee_position) in the base frame")
    _real(draft, ins, joints, gripper, ee_min, ee_max)
    _controllers(draft, ins, joints, gripper, home, seed_q, rng)
    return draft


def _top_down(ik: Any, chain: Any, target: np.ndarray, rng: np.random.Generator, approach: str, clearance: float,
              lowest: Any = None) -> tuple[np.ndarray, float]:
    """The top-down IK's pose for ``target`` from its seed and random seeds: (q, error). Of the poses
    that meet it, the one whose joints all stay ``clearance`` above the base (``lowest(q)``: the lowest joint's
    height), then the one nearest home; a redundant (7-joint) arm's, the one in its usual posture: each
    pose's redundancy resolved toward home, then the pose whose joints (the tool's roll aside) sit nearest
    the middle of their ranges, not a twisted elbow a random start left."""
    axis = "xyz".index(approach)
    redundant = chain.n_joints > 6
    mid, half = (ik.lower + ik.upper) / 2, np.maximum((ik.upper - ik.lower) / 2, 1e-6)

    def posture(q: np.ndarray) -> float:
        if not redundant:
            return float(np.linalg.norm(q - ik.home))
        away = ((q - mid) / half)[:-1]
        return float(away.dot(away))

    found: list[tuple[float, tuple[bool, float], np.ndarray]] = []
    for s in [None, *chain.sample_configurations(rng, 12)]:
        q = np.asarray(ik.solve(target, q0=s), dtype=float)
        if redundant:  # from there, the redundancy resolved toward home (a seed's null-space pull)
            seed, ik.seed = ik.seed, q
            try:
                q = np.asarray(ik.solve(target), dtype=float)
            finally:
                ik.seed = seed
        tf = chain.fk_matrix(q)
        err = float(np.linalg.norm(tf[:3, 3] - target)) + 0.05 * float(np.linalg.norm(tf[:3, axis] - [0, 0, -1]))
        below = lowest is not None and lowest(q) < clearance
        found.append((err, (below, posture(q)), q))
        if not redundant and sum(f[0] < 0.002 and not f[1][0] for f in found) >= 3:
            break
    good = [f for f in found if f[0] < 0.002]
    err, _, q = min(good, key=lambda f: f[1]) if good else min(found, key=lambda f: f[0])
    return q, err


def _manipulation(draft: ArmDraft, ik: Any, chain: Any, gripper: _Gripper, reach: float, lower: np.ndarray,
                  upper: np.ndarray, seed_q: np.ndarray, max_vel: float, rng: np.random.Generator) -> np.ndarray:
    """The push / pick-and-place settings and scene: a table under the base, a cube the fingers grip;
    returns the start of the episodes (``init_ee_position``), where the top-down IK reaches."""
    gap = gripper.pads[1] if gripper.pads is not None else gripper.opening
    half = float(np.clip(round(0.3 * gap, 3), 0.008, 0.025))
    grips = gripper.pads is None or gripper.pads[0] < 2 * half - 0.004
    robot_height = 0.4 if reach > 0.6 else 0.3
    target_height = _r(0.25 * reach, 3)
    axis = "xyz".index(draft.sections["arm"]["approach_axis"])

    def miss(target: np.ndarray, q0: np.ndarray) -> tuple[float, np.ndarray]:
        q = np.asarray(ik.solve(target, q0=q0), dtype=float)
        tf = chain.fk_matrix(q)
        return float(np.linalg.norm(tf[:3, 3] - target)) + 0.05 * float(np.linalg.norm(tf[:3, axis] - [0, 0, -1])), q

    def carried(height: float) -> float:
        """The EE's height holding the cube at a goal ``height`` above the table: the cube's centre
        (``half`` above the goal's floor) plus where the EE sits on a held cube, slip included."""
        return height + half + _HOLD_ABOVE

    # Along the x axis in front of the base: where the top-down IK reaches the table, and carries the
    # cube to target_height_max (pick-and-place goals in the air).
    x_lo = x_hi = math.nan
    for _ in range(2):
        xs = np.linspace(0.3 * reach, 0.65 * reach, 8)  # not over the base, nor at full stretch (as shipped)
        ok, q_low, q_high = [], seed_q, seed_q
        for x in xs:
            e_low, q_low = miss(np.array([x, 0.0, half + 0.003]), q_low)
            e_high, q_high = miss(np.array([x, 0.0, carried(target_height)]), q_high)
            ok.append(e_low < 0.005 and e_high < 0.005)
            if len(ok) > 1 and ok[-2] and not ok[-1]:
                break  # past the reachable band (it is one band in front of a serial arm)
        runs: list[tuple[int, int]] = []
        for i, good in enumerate(ok):
            if good and (not runs or runs[-1][1] != i - 1):
                runs.append((i, i))
            elif good:
                runs[-1] = (runs[-1][0], i)
        if runs:
            first, last = max(runs, key=lambda r: r[1] - r[0])
            x_lo, x_hi = float(xs[first]), float(xs[last])
            if x_hi - x_lo < 0.04 * reach:  # one sample: a box around it
                x_lo, x_hi = x_lo - 0.02 * reach, x_hi + 0.02 * reach
            break
        target_height = _r(0.5 * target_height, 3)  # the arm may not lift that high top-down
    if math.isnan(x_lo):
        x_lo, x_hi = 0.37 * reach, 0.65 * reach
    # The box lies inside the band's ring: its far corners at radius x_hi, not beyond.
    y_half = min(0.26 * reach, 0.6 * (x_hi - x_lo))
    x_hi = math.sqrt(max(x_hi ** 2 - y_half ** 2, (x_lo + 0.02 * reach) ** 2))
    # Then the corners, narrowing the box's width until the IK reaches them all.
    worst = math.inf
    for _ in range(4):
        corners = [np.array([x, y, z]) for x in (x_lo, x_hi) for y in (-y_half, y_half)
                   for z in (half + 0.003, carried(target_height))]
        worst = max(miss(c, seed_q)[0] for c in corners)
        if worst < 0.01:
            break
        y_half *= 0.6
    why_box = ("inferred: the top-down IK reaches its corners at the table and carrying the cube at target_height_max"
               if worst < 0.01 else
               f"guessed: the top-down IK misses a corner by {worst * 100:.1f} cm; shrink the box")
    init = [_r((x_lo + x_hi) / 2, 3), 0.0, _r(max(0.6 * target_height, min(2 * half + 0.05, target_height)), 3)]
    m: dict[str, Any] = {
        "robot_height": robot_height,
        "table_center": _rl([0.3 * reach, 0.0, -robot_height / 2 - 0.0005], 4),
        "table_half_extents": _rl([0.58 * reach + 0.05, 0.68 * reach + 0.05, robot_height / 2 - 0.0005], 4),
        "table_top": -0.001,
        "object_half_size": half,
        "object_mass": _r(_CUBE_DENSITY * (2 * half) ** 3, 4),
        "init_ee_position": init,
        "object_xy_min": _rl([x_lo, -y_half], 3), "object_xy_max": _rl([x_hi, y_half], 3),
        "goal_xy_min": _rl([x_lo, -y_half], 3), "goal_xy_max": _rl([x_hi, y_half], 3),
        "target_height_max": target_height,
        "position_ee_min": _rl([x_lo - 0.16 * reach, -0.5 * reach, max(0.01, half)], 3),
        "position_ee_max": _rl([x_hi + 0.14 * reach, 0.5 * reach, 2 * target_height], 3),
        "max_object_distance": _r(0.85 * reach, 3),
        "min_joint_pos": _rl(lower, 5), "max_joint_pos": _rl(upper, 5),
        "delta_coeff": 0.05, "ee_delta_coeff": _r(float(np.clip(0.04 * reach / 0.95, 0.015, 0.04)), 3),
        "gripper_min": _r(gripper.closed), "gripper_max": _r(gripper.open),
        "object_yaw_range": 0.3, "target_in_the_air": 0.5,
        "min_object_goal_distance": _r(min(0.08, 0.2 * reach, 0.5 * math.hypot(x_hi - x_lo, 2 * y_half)), 3),
        "distance_threshold": 0.05, "fall_margin": 0.05,
        "max_linear_velocity": 2.0, "max_angular_velocity": 20.0, "max_joint_vel": _r(max_vel, 3),
    }
    draft.sections["manipulation"] = m
    draft.note("manipulation.robot_height", "guessed: the table's height; the base stands on its top")
    what = "gap between the open fingers' geometry" if gripper.pads is not None else "opening"
    draft.note("manipulation.object_half_size", f"inferred: 30 % of the gripper's {gap * 100:.1f} cm {what} "
                                                "(0.8 .. 2.5 cm)" + ("" if grips or gripper.pads is None else
                                                f"; the closed fingers stay {gripper.pads[0] * 100:.1f} cm apart "
                                                "(wider than the cube): guessed, check the grasp"))
    draft.note("manipulation.object_mass", f"inferred: a cube of {_CUBE_DENSITY:g} kg/m^3, as the shipped ones")
    draft.note("manipulation.object_xy_min", why_box)
    draft.note("manipulation.gripper_min", "the closed fingers (gripper.closed)")
    draft.note("manipulation.table_half_extents", "the table and the cube are made from these sizes (no scene: "
                                                  "files to keep in step with them)")
    start = np.array(init)
    return start


#: A vendor package's controllers files read for the driver's names: at most this many, this large.
_MAX_CONTROLLER_FILES, _MAX_CONTROLLER_FILE_BYTES = 64, 256 * 1024
#: ros2_control controller types -> the Real twin's gripper interface.
_GRIPPER_TYPES = {"joint_trajectory_controller/JointTrajectoryController": "trajectory",
                  "position_controllers/GripperActionController": "gripper_action",
                  "parallel_gripper_action_controller/GripperActionController": "gripper_action",
                  "forward_command_controller/ForwardCommandController": "forward",
                  "position_controllers/JointGroupPositionController": "forward"}


@dataclass
class _Driver:
    """The names a vendor's own controllers file gives its driver (``None``: not found there)."""

    source: str
    namespace: str
    arm_controller: str
    gripper_controller: str | None = None
    gripper_interface: str | None = None


def _source_packages(ins: Inspection) -> list[str]:
    """The packages the description's xacro files name (``$(find pkg)``, ``package://pkg``), its own first."""
    from multiros.sim.packages import default_index

    names: list[str] = []
    for parent in Path(ins.source).resolve().parents:  # the package the description is in comes first
        manifest = parent / "package.xml"
        if manifest.is_file():
            own = re.search(r"<name>\s*([A-Za-z0-9_]+)\s*</name>", manifest.read_text(errors="replace")[:100_000])
            if own:
                names.append(own.group(1))
            break
    index = default_index()
    seen: set[Path] = set()
    queue = [Path(ins.source)]
    while queue and len(seen) < 64:  # the description's files, following $(find ...) includes
        path = queue.pop(0)
        if path in seen or not path.is_file():
            continue
        seen.add(path)
        try:
            text = path.read_text(errors="replace")[:2_000_000]
        except OSError:
            continue
        for pkg, rest in re.findall(r"(?:\$\(find |package://)([A-Za-z0-9_]+)\)?(/[^\s\"'<>]*)?", text):
            if pkg not in names:
                names.append(pkg)
            if rest and rest.endswith(".xacro"):
                try:
                    queue.append(index.find_package_share(pkg) / rest.lstrip("/"))
                except Exception:  # noqa: BLE001 - a package we cannot find names no file
                    pass
    return names


def _config_files(share: Path) -> list[Path]:
    """The YAML files in ``config`` folders of a package (``config/``, or deeper as Kinova's
    ``arms/gen3_lite/6dof/config/``), at most ``_MAX_CONTROLLER_FILES``, 4 folders deep."""
    found: list[Path] = []
    for depth in range(4):
        pattern = "/".join(["*"] * depth + ["config", "**", "*.yaml"])
        found += sorted(p for p in share.glob(pattern) if p.is_file() and p not in found)
        if len(found) >= _MAX_CONTROLLER_FILES:
            break
    return found[:_MAX_CONTROLLER_FILES]


def _vendor_driver(ins: Inspection, joints: Sequence[str], gripper: _Gripper | None) -> _Driver | None:
    """The arm's trajectory controller (and the gripper's) from the controllers files of the packages
    the description names (``config/**/*.yaml``): the controller whose joints are the arm's, its
    controller manager's namespace (``/lbr/controller_manager:`` -> ``/lbr``)."""
    import yaml

    from multiros.sim.packages import default_index

    index = default_index()
    files: list[Path] = []
    for pkg in _source_packages(ins):
        try:
            share = index.find_package_share(pkg)
        except Exception:  # noqa: BLE001 - not installed here: nothing to read
            continue
        files += _config_files(share)
    found: _Driver | None = None
    grip: tuple[str, str] | None = None
    for path in files[:_MAX_CONTROLLER_FILES]:
        try:
            if path.stat().st_size > _MAX_CONTROLLER_FILE_BYTES:
                continue
            doc = yaml.safe_load(path.read_text(errors="replace"))
        except (OSError, yaml.YAMLError):
            continue
        if not isinstance(doc, dict):
            continue
        types: dict[str, str] = {}
        namespace = ""
        for key, value in doc.items():
            if str(key).rstrip("/").endswith("controller_manager") and isinstance(value, dict):
                prefix = str(key).rsplit("controller_manager", 1)[0].strip("/*")  # "/lbr/", "/**/", ""
                namespace = f"/{prefix}" if prefix else ""
                params = value.get("ros__parameters") or {}
                types.update({k: v["type"] for k, v in params.items() if isinstance(v, dict) and "type" in v})
        for key, value in doc.items():
            name = str(key).strip("/").rsplit("/", 1)[-1]
            params = value.get("ros__parameters") if isinstance(value, dict) else None
            if name not in types or not isinstance(params, dict):
                continue
            joints_of = params.get("joints", [params["joint"]] if isinstance(params.get("joint"), str) else None)
            if not isinstance(joints_of, list):  # a GripperActionController names its one joint as `joint`
                continue
            listed = [str(j) for j in joints_of]
            if found is None and types[name].endswith("JointTrajectoryController") and set(listed) == set(joints):
                found = _Driver(path.name, namespace, name)
            elif gripper is not None and listed in ([gripper.joint], [gripper.joint, gripper.follower]) \
                    and types[name] in _GRIPPER_TYPES:
                grip = (name, _GRIPPER_TYPES[types[name]])
    if found is not None and grip is not None:
        found.gripper_controller, found.gripper_interface = grip
    return found


def _real(draft: ArmDraft, ins: Inspection, joints: Sequence[str], gripper: _Gripper | None,
          ee_min: Sequence[float], ee_max: Sequence[float]) -> None:
    """The real twin's driver names: the vendor's controllers file's where the description's packages
    have one, else a known vendor plugin's, else ROS 2 control's conventional ones."""
    import xml.etree.ElementTree as ET

    plugins = [p.text.strip() for p in ET.fromstring(ins.description.text).iter("plugin")
               if p.text and p.text.strip() and p.find("*") is None]
    known = next(((prefix, names) for p in plugins for prefix, names in _DRIVERS.items() if prefix in p), None)
    rc = {j.name for j in ins.description.ros2_control}
    if known is not None:
        arm_ctrl, grip_ctrl, grip_iface = known[1]
        why = f"guessed: the names {known[0].rstrip('/')}'s driver launches (ros2_control plugin {plugins[0]!r})"
    else:
        arm_ctrl, grip_ctrl, grip_iface = "joint_trajectory_controller", "gripper_controller", "gripper_action"
        why = "guessed: ROS 2 control's conventional names" + (
            " (the ros2_control tag names no plugin we know)" if rc else " (the description has no ros2_control tag)")
    real = {"namespace": "", "arm_controller": arm_ctrl, "controllers": [], "command_interface": "topic",
            "check_controllers": True, "joint_states_topic": "/joint_states",
            "gripper_controller": grip_ctrl if gripper is not None else "",
            "gripper_interface": grip_iface if gripper is not None else "none",
            "workspace_min": _rl(ee_min, 3), "workspace_max": _rl(ee_max, 3), "floor_z": 0.02,
            "max_joint_delta": 0.15}
    if gripper is not None:
        real["gripper_joint"] = gripper.joint
    missing = [j for j in joints if rc and j not in rc]
    vendor = _vendor_driver(ins, joints, gripper)
    grip_why = "guessed: as real.arm_controller" if gripper else "no gripper"
    if vendor is not None:
        real["arm_controller"] = vendor.arm_controller
        real["namespace"] = vendor.namespace
        why = f"inferred: the JointTrajectoryController of the arm's joints in the package's {vendor.source}"
        if vendor.namespace:
            draft.note("real.namespace", f"inferred: its controller manager's namespace in {vendor.source}")
            real["joint_states_topic"] = f"{vendor.namespace}/joint_states"
        if gripper is not None and vendor.gripper_controller:
            real["gripper_controller"] = vendor.gripper_controller
            real["gripper_interface"] = vendor.gripper_interface
            grip_why = f"inferred: the controller of {gripper.joint!r} in the package's controllers files"
    draft.sections["real"] = real
    draft.note("real.arm_controller", why + "; a JointTrajectoryController")
    draft.note("real.joint_states_topic", "guessed: the joint_state_broadcaster's default topic" +
               (f"; the ros2_control tag lacks {missing}" if missing else ""))
    draft.note("real.gripper_controller", grip_why)
    draft.note("real.workspace_min", "inferred: the reach's EE box (the safety box the Real env clips to)")


def _controllers(draft: ArmDraft, ins: Inspection, joints: Sequence[str], gripper: _Gripper | None,
                 home: np.ndarray, start: np.ndarray, rng: np.random.Generator) -> None:
    """The simulation's controllers YAML: servo gains per joint, checked by a settle test."""
    from rl_environments.arm_gains import SAG, servo_gains, settle_error

    model = ins.description.spec.copy().compile()
    lower = np.array([max(_limits(ins.tree.joints[j])[0], -math.pi) for j in joints])
    upper = np.array([min(_limits(ins.tree.joints[j])[1], math.pi) for j in joints])
    effort = [ins.tree.efforts.get(j, 0.0) for j in joints]
    servo = servo_gains(model, joints, effort, lower, upper, rng)
    weak = list(servo.weak)
    gains = {j: {"p": _r(p, 1), "d": _r(d, 2)} for j, p, d in zip(joints, servo.p, servo.d)}
    err = settle_error(model, joints, servo, effort, (home, start))
    draft.settle_error = err
    fingers: dict[str, dict[str, float]] = {}
    if gripper is not None:
        f_effort = ins.tree.efforts.get(gripper.joint, 0.0) or 20.0
        prismatic = ins.tree.joints[gripper.joint].type == "prismatic"
        # A squeeze of at most 20 N (or the effort limit) over the full stroke: the shipped grippers'
        # ~25 N; a stiffer one overpowers the second finger's <mimic> and flings the cube.
        stroke = abs(gripper.open - gripper.closed)
        p = float(np.clip(min(f_effort, 20.0 if prismatic else 2.0) / max(stroke, 1e-3), 20.0, 2000.0))
        fingers[gripper.joint] = {"p": _r(p, 1), "d": _r(0.02 * p, 2)}
        if gripper.independent:  # both fingers driven: the second squeezes as hard over its own stroke
            f_p = float(np.clip(p / abs(gripper.mimic), 20.0, 2000.0))
            fingers[gripper.follower] = {"p": _r(f_p, 1), "d": _r(0.02 * f_p, 2)}
    lines = [
        f"# ros2_control controllers of the {draft.name} in simulation (written by uniros arm add).",
        "#",
        "# arm_position_controller: the group position controller the lockstep envs command;",
        "# gripper_position_controller the commanded finger (the second follows its URDF <mimic>). The",
        f"# real driver's trajectory controller ({draft.sections['real']['arm_controller']}) is declared too, for",
        "# uniros-fake-robot; it is not started in simulation.",
        "#",
        "# gains: position-servo stiffness p (N m/rad, N/m) and damping d of the simulation node's joint",
        f"# servos: p = max(worst gravity torque / {SAG} rad, inertia x (2 pi 4 Hz)^2) over 200 random poses,",
        "# capped where a 4 ms step stays stable; d critically damps the largest inertia. Forces are clamped",
        "# to the URDF efforts. The finger's p squeezes with at most 20 N (or its effort) over the full stroke.",
        "# Settle check (gravity compensation off, 1 s at home and at the start pose):",
        f"# largest tracking error {err:.4f} rad.",
    ]
    if weak:
        lines.append(f"# NOTE: the effort limits of {weak} are below their worst gravity torque.")
    arm_ctrl = draft.sections["real"]["arm_controller"]
    doc: dict[str, Any] = {"controller_manager": {"ros__parameters": {
        "update_rate": 500,
        "joint_state_broadcaster": {"type": "joint_state_broadcaster/JointStateBroadcaster"},
        "arm_position_controller": {"type": "position_controllers/JointGroupPositionController"},
    }}}
    cm = doc["controller_manager"]["ros__parameters"]
    if gripper is not None:
        cm["gripper_position_controller"] = {"type": "position_controllers/JointGroupPositionController"}
    if arm_ctrl not in cm:
        cm[arm_ctrl] = {"type": "joint_trajectory_controller/JointTrajectoryController"}
    doc["joint_state_broadcaster"] = {"ros__parameters": {
        "joints": [*joints, *(list(fingers) if gripper else [])]}}
    doc["arm_position_controller"] = {"ros__parameters": {"joints": list(joints), "gains": gains}}
    if arm_ctrl != "arm_position_controller":
        doc[arm_ctrl] = {"ros__parameters": {
            "joints": list(joints), "command_interfaces": ["position"], "state_interfaces": ["position", "velocity"],
            "state_publish_rate": 100.0, "action_monitor_rate": 20.0, "allow_partial_joints_goal": False,
            "gains": gains}}
    if gripper is not None:
        doc["gripper_position_controller"] = {"ros__parameters": {"joints": list(fingers), "gains": fingers}}
    import yaml

    class _NoAliases(yaml.SafeDumper):
        def ignore_aliases(self, data: Any) -> bool:
            return True

    draft.controllers_yaml = "\n".join(lines) + "\n" + yaml.dump(doc, Dumper=_NoAliases, sort_keys=False,
                                                                 default_flow_style=None, width=110)


# -- writing -------------------------------------------------------------------------------------------
def _flow(value: Any) -> str:
    import yaml

    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return yaml.safe_dump(value, default_style=None).strip().removesuffix("...").strip() if value else "''"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_flow(v)}" for k, v in value.items()) + "}"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def render_arm_file(draft: ArmDraft) -> str:
    """The YAML text of a draft: one key a line, its comment beside it."""
    lines = [f"# {h}" for h in draft.header]

    def comment(key: str) -> str:
        text = draft.comments.get(key)
        return f"  # {text}" if text else ""

    for section, value in draft.sections.items():
        if not isinstance(value, dict):
            lines.append(f"{section}: {_flow(value)}{comment(section)}")
            continue
        if section in draft.comments and section not in ("gripper",):
            lines.append(f"# {draft.comments[section]}")
        lines.append(f"{section}:{comment(section) if section == 'gripper' else ''}")
        for key, item in value.items():
            if isinstance(item, dict) and item:
                lines.append(f"  {key}:{comment(f'{section}.{key}')}")
                lines += [f"    {k}: {_flow(v)}" for k, v in item.items()]
            else:
                lines.append(f"  {key}: {_flow(item)}{comment(f'{section}.{key}')}")
    return "\n".join(lines) + "\n"


def add_arm(uri: str, name: str, *, xacro_args: Mapping[str, str] | None = None, output: str | Path = ".",
            force: bool = False, register: bool = True, check: bool = True) -> tuple[Path, list[str], ArmDraft]:
    """``uniros arm add``: write ``output/NAME.yaml`` (and ``output/NAME/``: controllers, table, cube)
    from a description, check it, register it.

    With ``check`` (the default) the drafted file is tried first with the scripted policies
    (:func:`rl_environments.arm_check.check_arm`: reach, and push and pick-and-place with a gripper,
    on a few seeds); a task they cannot do is an :class:`ArmFileError` and nothing is written. The
    check's figures are ``draft.check``.

    Returns:
        the arm file, its registered IDs (empty with ``register=False``), the draft.

    Raises:
        ArmFileError: a bad name, a name in use, an existing file without ``force``, a description
            that does not load or has no chain the tasks serve, or a drafted file the scripted policies
            fail on. Nothing is written then.
    """
    from gymnasium.envs.registration import registry

    import rl_environments  # noqa: F401 - registers the shipped arms, so their names are taken
    from rl_environments.arm_file import load_arm_file
    from rl_environments.arm_registry import check_description, register_arm, registered_arms

    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name or ""):
        _fail("--name", f"{name!r} must be letters, digits and _ starting with a letter (it prefixes the IDs, "
                        "e.g. MyArmReacherSim-v0)")
    out_dir = Path(output).expanduser().absolute()
    target = out_dir / f"{name}.yaml"
    if target.exists() and not force:
        _fail(str(target), "exists; fix: pass --force to replace it, or another --name or --output")
    taken = registered_arms().get(name)
    if taken is not None and taken.path != target.resolve():
        _fail("--name", f"{name!r} is the name of the registered arm {taken.path}; fix: choose another --name")
    if taken is None and (f"{name}ReacherSim-v0" in registry or f"{name}ReacherReal-v0" in registry):
        _fail("--name", f"{name!r} gives IDs already registered ({name}ReacherSim-v0); fix: choose another --name")
    shipped = {n.lower() for n in registered_arms()}
    if taken is None and name.lower() in shipped:
        _fail("--name", f"{name!r} differs only in case from a registered arm; fix: choose another --name")

    ins = inspect_description(uri if "://" in uri else str(Path(uri).expanduser().absolute()), xacro_args)
    draft = draft_arm(ins, name)
    if "://" not in uri:  # a path: relative to the arm file, so the folder moves as one
        draft.sections["description"]["uri"] = os.path.relpath(ins.source, out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=out_dir))
    try:
        (tmp / name).mkdir()
        (tmp / name / "controllers.yaml").write_text(draft.controllers_yaml)
        if "://" not in uri:
            draft.sections["description"]["uri"] = os.path.relpath(ins.source, tmp)
        text = render_arm_file(draft)
        (tmp / f"{name}.yaml").write_text(text)
        spec = load_arm_file(tmp / f"{name}.yaml")  # what we wrote loads, and holds its chain
        check_description(spec)
        if check:  # and works: the scripted policies do every task on it
            from rl_environments.arm_check import check_arm, refusal

            draft.check = check_arm(tmp / f"{name}.yaml")
            if not draft.check.passed:
                raise refusal(draft.check)
        if "://" not in uri:
            draft.sections["description"]["uri"] = os.path.relpath(ins.source, out_dir)
            (tmp / f"{name}.yaml").write_text(render_arm_file(draft))
        folder = out_dir / name
        if folder.exists():
            if not force:
                _fail(str(folder), "exists; fix: pass --force to replace it, or another --name or --output")
            old = out_dir / f".{name}.old.{os.getpid()}"
            os.replace(folder, old)
            shutil.rmtree(old, ignore_errors=True)
        os.replace(tmp / name, folder)
        os.replace(tmp / f"{name}.yaml", target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ids = register_arm(target, replace=True) if register else []
    return target, ids, draft
