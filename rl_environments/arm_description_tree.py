"""A robot description as ``uniros arm add`` reads it: loaded as the simulation node does, and its tree.

A user has a vendor's ROS 2 description package (a sourced workspace, found through
``AMENT_PREFIX_PATH``) and wants the tasks for it without writing Python. :func:`inspect_description`
loads the description as the simulation node does (xacro with arguments and ``$(find)``, meshes
checked) and reads its kinematic tree: what the description says, before any choice
(:class:`Inspection`), from which :mod:`rl_environments.arm_inference` drafts the arm file:

* the tree (``_Tree``): the links and joints, each link's pose by forward kinematics with the
  joints at given positions (mimic joints following), the joints' limits and effort limits;
* the serial chains, the arm's candidates: every run of actuated revolute (or continuous) joints from
  the root, stopping at the first prismatic, mimic or branching joint (the gripper's fingers). The arm
  is the longest of 4 to 7 (:func:`~rl_environments.arm_inference.draft_arm`).

A description that is missing or does not load, or that the tasks cannot serve, is a one-line
:class:`~rl_environments.arm_file.ArmFileError` (``where: message; fix: ...``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from multiros.excerpt import MAX_MESSAGE_LINE, error_line
from rl_environments.arm_file import ArmFileError

if TYPE_CHECKING:
    from multiros.sim.urdf_model import Joint, Robot

__all__ = ["Inspection", "inspect_description"]

_MOVING = ("revolute", "continuous", "prismatic")
_REVOLUTE = ("revolute", "continuous")


def _fail(where: str, message: str) -> None:
    raise ArmFileError(f"{where}: {message}")


@dataclass
class _Tree:
    """A URDF's links and joints with the lookups the inference needs."""

    robot: Robot
    root: str
    joints: dict[str, Joint]
    children: dict[str, list[Joint]]
    parent: dict[str, Joint]  # child link -> joint
    efforts: dict[str, float]

    def moving(self, joint: Joint) -> bool:
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

    def position(self, joint: Joint, q: Mapping[str, float]) -> float:
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


def _motion(joint: Joint, value: float) -> np.ndarray:
    tf = np.eye(4)
    if joint.type in _REVOLUTE and value:
        axis = joint.direction
        axis = axis / np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        tf[:3, :3] = np.eye(3) + math.sin(value) * k + (1 - math.cos(value)) * k.dot(k)
    elif joint.type == "prismatic":
        axis = joint.direction
        tf[:3, 3] = axis / np.linalg.norm(axis) * value
    return tf


def _limits(joint: Joint) -> tuple[float, float]:
    if joint.type == "continuous" or joint.limit is None or joint.limit.lower is None:
        return -math.inf, math.inf
    return float(joint.limit.lower), float(joint.limit.upper if joint.limit.upper is not None else 0.0)


def _tree(text: str, source: str) -> _Tree:
    import xml.etree.ElementTree as ET

    from multiros.sim.urdf_model import parse_urdf

    robot = parse_urdf(ET.fromstring(text), source)
    joints = {j.name: j for j in robot.joints}
    children: dict[str, list[Joint]] = {}
    parent: dict[str, Joint] = {}
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
        _fail(uri, error_line(exc, MAX_MESSAGE_LINE))
    if not path.is_file():
        _fail(uri, f"file {str(path)!r} not found; fix: give an existing URDF or xacro file")
    try:
        desc = load_description(str(path), args=args, index=index)
    except SimError as exc:
        text = error_line(exc, MAX_MESSAGE_LINE)
        missing = bool(getattr(exc, "missing_assets", False))
        fix = ("pass it: --xacro-arg NAME=VALUE" if "undefined argument" in text or "arg" in text.lower()
               and "xacro" in text.lower() else
               "source the workspace with the package, or install the meshes" if missing else
               "fix the description (it must be URDF or xacro of one tree)")
        _fail(uri, f"{text}; fix: {fix}")
    except Exception as exc:  # noqa: BLE001 - xacro, XML and trimesh raise many kinds
        _fail(uri, f"does not load: {error_line(exc, MAX_MESSAGE_LINE)}")
    if desc.format != "urdf":
        _fail(uri, "is MJCF; uniros arm add reads URDF or xacro (the tasks need a URDF chain); fix: give the "
                   "URDF of the robot")
    tree = _tree(desc.text, str(path))
    return Inspection(uri, args, str(path), tree, desc, _chains(tree))
