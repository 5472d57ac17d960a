"""The gripper after an arm, measured on its geometry, and the end effector (``uniros arm add``).

* the gripper: after the arm, one actuated finger joint (prismatic or revolute) and a joint that
  mimics it, in separate branches (or two finger joints driven independently, no ``<mimic>`` tying
  them: ``gripper.independent``); open and closed are its limits, closed the one where the fingers
  are nearer each other, measured on their collision geometry as MuJoCo collides it (``_Hand``).
  None: ``gripper: null`` (reach only);
* the end effector: a link fixed to the last arm link named like ``tcp``/``grasp``/``ee``/``tool``,
  the one nearest the fingers with a gripper; else the link of the hand (the last fixed link). The
  grasp point lies between the open fingertips, ``_PAD_BACK`` short of their ends; an end-effector
  link away from it gets ``arm.tcp_offset``, which makes that point the end effector.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rl_environments.arm_description_tree import _MOVING, Inspection, _limits, _Tree

if TYPE_CHECKING:
    from multiros.sim.urdf_model import Joint

# End-effector link names, most specific first (matched as whole words of the link name).
_EE_NAMES = ("tcp", "grasp", "grasping", "gripper_center", "end_effector", "eef", "ee", "tool", "tool0")
_TCP_FAR = 0.01  # m: a hand link this far from the grasp point gets arm.tcp_offset
_TCP_SHORT = 0.03  # m: a tool frame this far short of the grasp point is a flange frame
_PAD_BACK = 0.01  # m: the grasp point short of the fingertips' ends (the smallest cube, 0.8 cm half size, clears)
_MIN_OPEN_GAP = 0.02  # m: the open fingers' geometry leaves the smallest cube (1.6 cm) and 2 mm a side


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

    def drive(self, lead: Joint, value: float, *more: tuple[Joint, float]) -> None:
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


def _drive_range(lead: Joint, followers: Sequence[Joint]) -> tuple[float, float]:
    """The driven joint's limits narrowed to where every joint mimicking it stays inside its own
    limits (a follower whose multiplier maps the drive's range past its limits)."""
    lo, hi = _limits(lead)
    for f in followers:
        f_lo, f_hi = _limits(f)
        if f.mimic is None:
            continue
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
    factor = {j.name: j.mimic.multiplier for j in below if j.mimic is not None and j.mimic.joint == lead.name}
    followers = [j for j in below if j.name in factor]
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

    def stroke(follower: Joint) -> tuple[list[int], float, float]:
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
        direction = tree.transform(lead.parent, {})[:3, :3].dot(lead.direction)
    pads = (min(g_lo, g_hi), max(g_lo, g_hi))
    found = _Gripper(lead.name, follower.name, float(factor[follower.name]), closed, opened,
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
                         leaders: Sequence[Joint]) -> tuple[_Gripper | None, str]:
    """Two finger joints driven independently (no ``<mimic>`` ties them): the pair on separate fingers
    whose fingertips' gap changes most, closed where both are nearer. The simulation's gripper
    controller drives both, the second at the ratio of their strokes (``gripper.independent``)."""
    tree = ins.tree
    hand_origin = tree.transform(hand, {})[:3, 3]
    pairs = [(a, b) for i, a in enumerate(leaders) for b in leaders[i + 1:]
             if a.child not in tree.descendants(b.child) and b.child not in tree.descendants(a.child)
             and hand_model.solid(a.child) and hand_model.solid(b.child)]
    names = [j.name for j in leaders]
    best: tuple[float, Joint, Joint, dict[tuple[float, float], float], list[int], list[int]] | None = None
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
        direction = tree.transform(a.parent, {})[:3, :3].dot(a.direction)
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
    tf = tree.transform(best, {})
    # How far the link lies short of the grasp point, along the wrist -> fingers direction.
    short = reach_out - float(np.dot(tf[:3, 3] - wrist, out / max(reach_out, 1e-9)))
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
