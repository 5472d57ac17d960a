"""A small URDF reader: links, joints, inertials, geometry and materials as plain records.

Why not yourdfpy here: importing it imports trimesh and scipy, about 1.8 s of every simulation
node's start-up (DESIGN §5 asks for <= 1.5 s from ``uniros.make`` to the first observation), and
the description builder needs only the elements below. yourdfpy stays the reference reader in the
tests, and trimesh is still used, lazily, for mesh conversion.

Records mirror yourdfpy's attribute names (``robot.links[i].inertial.origin`` is a 4x4 matrix,
``joint.limit.lower``, ``visual.geometry.box.size``, ...). Malformed numbers, numbers that are
not finite and numbers outside the bounds of :class:`~multiros.sim.limits.DescriptionLimits`
(positions, sizes, masses, inertias, joint limits and parameters) raise
:class:`~multiros.sim.errors.DescriptionError` naming the element and the attribute.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from multiros.sim.errors import DescriptionError
from multiros.sim.limits import DescriptionLimits

__all__ = ["Robot", "parse_urdf"]


@dataclass
class Color:
    rgba: np.ndarray


@dataclass
class Material:
    name: str | None
    color: Color | None


@dataclass
class Box:
    size: np.ndarray


@dataclass
class Cylinder:
    radius: float
    length: float


@dataclass
class Sphere:
    radius: float


@dataclass
class Mesh:
    filename: str
    scale: np.ndarray | None


@dataclass
class Geometry:
    box: Box | None = None
    cylinder: Cylinder | None = None
    sphere: Sphere | None = None
    mesh: Mesh | None = None


@dataclass
class Visual:
    geometry: Geometry | None
    origin: np.ndarray
    material: Material | None = None


@dataclass
class Collision:
    geometry: Geometry | None
    origin: np.ndarray


@dataclass
class Inertial:
    mass: float
    inertia: np.ndarray
    origin: np.ndarray


@dataclass
class Link:
    name: str
    inertial: Inertial | None
    visuals: list[Visual] = field(default_factory=list)
    collisions: list[Collision] = field(default_factory=list)


@dataclass
class Limit:
    lower: float | None
    upper: float | None
    effort: float | None
    velocity: float | None


@dataclass
class Dynamics:
    damping: float | None
    friction: float | None


@dataclass
class Mimic:
    joint: str
    multiplier: float
    offset: float


@dataclass
class Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray | None
    limit: Limit | None
    dynamics: Dynamics | None
    mimic: Mimic | None

    @property
    def direction(self) -> np.ndarray:
        """The axis, URDF's default ``(1, 0, 0)`` where the joint has no ``<axis>``."""
        return np.array([1.0, 0.0, 0.0]) if self.axis is None else np.asarray(self.axis, dtype=float)


@dataclass
class Robot:
    name: str
    links: list[Link]
    joints: list[Joint]
    materials: list[Material]
    #: What the reader took otherwise than written, one line each (a non-positive effort read as unknown).
    notes: list[str] = field(default_factory=list)

    def mimic_leaders(self) -> tuple[str, ...]:
        """The 1-DoF joints a 1-DoF ``<mimic>`` joint follows (a gripper's drive), once each, in file order.

        Such a joint is commandable even where a ``<ros2_control>`` tag leaves it out: vendors leave the
        gripper out of the arm's hardware block when another driver runs it, and unactuated the
        linkage could never move (the simulation node and the fake robot both follow this rule).
        """
        movable = {j.name for j in self.joints if j.type in ("revolute", "continuous", "prismatic")}
        led = {j.mimic.joint for j in self.joints
               if j.mimic is not None and j.name in movable and j.mimic.joint != j.name}
        return tuple(j.name for j in self.joints if j.name in led and j.name in movable)


_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


class _Reader:
    def __init__(self, source: str, limits: DescriptionLimits) -> None:
        self.source = source
        self.limits = limits
        self.notes: list[str] = []

    def fail(self, what: str) -> DescriptionError:
        return DescriptionError(f"{self.source}: invalid URDF: {what}", source=self.source)

    def floats(self, text: str | None, n: int, what: str, default: tuple[float, ...] | None = None) -> np.ndarray:
        if text is None:
            if default is None:
                raise self.fail(f"{what} is missing")
            return np.array(default, dtype=float)
        try:
            values = np.array([float(v) for v in text.split()], dtype=float)
        except ValueError:
            raise self.fail(f"{what} {text!r} is not {n} numbers") from None
        if values.shape != (n,):
            raise self.fail(f"{what} {text!r} is not {n} numbers")
        if not np.all(np.isfinite(values)):
            raise self.fail(f"{what} {text!r} is not finite")
        return values

    def bounded(self, values: np.ndarray | float, low: float, high: float, what: str) -> None:
        """Raise unless every value is within ``[low, high]``."""
        arr = np.asarray(values, dtype=float)
        if not (np.all(arr >= low) and np.all(arr <= high)):
            shown = arr.tolist() if arr.ndim else float(arr)
            raise self.fail(f"{what} {shown} is outside [{low:g}, {high:g}]")

    def number(self, elem: ET.Element, attr: str, what: str, default: float | None = None) -> float | None:
        text = elem.get(attr)
        if text is None:
            return default
        try:
            value = float(text)
        except ValueError:
            raise self.fail(f"{what} {attr}={text!r} is not a number") from None
        if not math.isfinite(value):
            raise self.fail(f"{what} {attr}={text!r} is not finite")
        return value

    def origin(self, elem: ET.Element | None, what: str) -> np.ndarray:
        tf = np.eye(4)
        if elem is None:
            return tf
        xyz = self.floats(elem.get("xyz"), 3, f"{what} origin xyz", (0.0, 0.0, 0.0))
        self.bounded(xyz, -self.limits.max_position, self.limits.max_position, f"{what} origin xyz")
        r, p, y = self.floats(elem.get("rpy"), 3, f"{what} origin rpy", (0.0, 0.0, 0.0))
        cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
        tf[:3, :3] = [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
        tf[:3, 3] = xyz
        return tf

    def material(self, elem: ET.Element | None) -> Material | None:
        if elem is None:
            return None
        color = elem.find("color")
        rgba = None
        if color is not None:
            what = f"material {elem.get('name')!r} color rgba"
            rgba = Color(self.floats(color.get("rgba"), 4, what))
            self.bounded(rgba.rgba, 0.0, 1.0, what)
        return Material(elem.get("name"), rgba)

    def geometry(self, elem: ET.Element | None, what: str) -> Geometry | None:
        if elem is None:
            return None
        geo = Geometry()
        size_max = self.limits.max_size
        if (box := elem.find("box")) is not None:
            geo.box = Box(self.floats(box.get("size"), 3, f"{what} box size"))
            self.bounded(geo.box.size, 0.0, size_max, f"{what} box size")
        elif (cyl := elem.find("cylinder")) is not None:
            radius = self.number(cyl, "radius", f"{what} cylinder")
            length = self.number(cyl, "length", f"{what} cylinder")
            if radius is None or length is None:
                raise self.fail(f"{what} cylinder needs radius and length")
            self.bounded(radius, 0.0, size_max, f"{what} cylinder radius")
            self.bounded(length, 0.0, size_max, f"{what} cylinder length")
            geo.cylinder = Cylinder(radius, length)
        elif (sph := elem.find("sphere")) is not None:
            radius = self.number(sph, "radius", f"{what} sphere")
            if radius is None:
                raise self.fail(f"{what} sphere needs a radius")
            self.bounded(radius, 0.0, size_max, f"{what} sphere radius")
            geo.sphere = Sphere(radius)
        elif (mesh := elem.find("mesh")) is not None:
            filename = mesh.get("filename")
            if not filename:
                raise self.fail(f"{what} mesh has no filename")
            scale = mesh.get("scale")
            geo.mesh = Mesh(filename, None if scale is None else self.floats(scale, 3, f"{what} mesh scale"))
            if geo.mesh.scale is not None:
                self.bounded(geo.mesh.scale, -size_max, size_max, f"{what} mesh scale")
        return geo

    def link(self, elem: ET.Element) -> Link:
        name = elem.get("name")
        if not name:
            raise self.fail("a <link> has no name")
        inertial = None
        if (ine := elem.find("inertial")) is not None:
            mass_elem = ine.find("mass")
            mass = self.number(mass_elem, "value", f"link {name!r} mass", 0.0) if mass_elem is not None else 0.0
            self.bounded(mass, 0.0, self.limits.max_mass, f"link {name!r} mass value")
            tensor = np.zeros((3, 3))
            if (inertia := ine.find("inertia")) is not None:
                v = {k: self.number(inertia, k, f"link {name!r} inertia", 0.0) for k in
                     ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
                lim = self.limits.max_inertia
                for key, value in v.items():
                    self.bounded(value, 0.0 if key in ("ixx", "iyy", "izz") else -lim, lim,
                                 f"link {name!r} inertia {key}")
                tensor = np.array([[v["ixx"], v["ixy"], v["ixz"]],
                                   [v["ixy"], v["iyy"], v["iyz"]],
                                   [v["ixz"], v["iyz"], v["izz"]]], dtype=float)
            inertial = Inertial(float(mass), tensor, self.origin(ine.find("origin"), f"link {name!r} inertial"))
        visuals = [
            Visual(self.geometry(v.find("geometry"), f"link {name!r} visual"),
                   self.origin(v.find("origin"), f"link {name!r} visual"), self.material(v.find("material")))
            for v in elem.findall("visual")
        ]
        collisions = [
            Collision(self.geometry(c.find("geometry"), f"link {name!r} collision"),
                      self.origin(c.find("origin"), f"link {name!r} collision"))
            for c in elem.findall("collision")
        ]
        return Link(name, inertial, visuals, collisions)

    def joint(self, elem: ET.Element) -> Joint:
        name = elem.get("name")
        jtype = elem.get("type")
        if not name:
            raise self.fail("a <joint> has no name")
        if jtype not in _JOINT_TYPES:
            raise self.fail(f"joint {name!r} has type {jtype!r}; expected one of {_JOINT_TYPES}")
        parent, child = elem.find("parent"), elem.find("child")
        if parent is None or child is None or not parent.get("link") or not child.get("link"):
            raise self.fail(f"joint {name!r} needs <parent link=...> and <child link=...>")
        axis_elem = elem.find("axis")
        axis = None if axis_elem is None else self.floats(axis_elem.get("xyz"), 3, f"joint {name!r} axis", (1, 0, 0))
        limit = None
        if (lim := elem.find("limit")) is not None:
            what = f"joint {name!r} limit"
            limit = Limit(self.number(lim, "lower", what), self.number(lim, "upper", what),
                          self.number(lim, "effort", what), self.number(lim, "velocity", what))
            pmax, jmax = self.limits.max_position, self.limits.max_joint_parameter
            for attr in ("lower", "upper"):
                if getattr(limit, attr) is not None:
                    self.bounded(getattr(limit, attr), -pmax, pmax, f"{what} {attr}")
            for attr in ("effort", "velocity"):
                value = getattr(limit, attr)
                if value is not None and value <= 0.0:
                    # ROS tools load these (urdfdom keeps them; some vendors write effort="-1" for "no
                    # limit given"): unknown, as if left out, and said, rather than a refused description.
                    setattr(limit, attr, None)
                    self.notes.append(f"joint {name!r} limit {attr} {value:g} <= 0 is read as unknown (no limit)")
                elif value is not None:
                    self.bounded(value, 0.0, jmax, f"{what} {attr}")
            if limit.lower is not None and limit.upper is not None and limit.lower > limit.upper:
                raise self.fail(f"{what} lower {limit.lower:g} > upper {limit.upper:g}; limits must be ordered")
        elif jtype in ("revolute", "prismatic"):
            raise self.fail(f"{jtype} joint {name!r} needs a <limit>")
        dynamics = None
        if (dyn := elem.find("dynamics")) is not None:
            what = f"joint {name!r} dynamics"
            dynamics = Dynamics(self.number(dyn, "damping", what), self.number(dyn, "friction", what))
            for attr in ("damping", "friction"):
                if getattr(dynamics, attr) is not None:
                    self.bounded(getattr(dynamics, attr), 0.0, self.limits.max_joint_parameter, f"{what} {attr}")
        mimic = None
        if (mim := elem.find("mimic")) is not None:
            what = f"joint {name!r} mimic"
            mimic = Mimic(mim.get("joint", ""), self.number(mim, "multiplier", what, 1.0),
                          self.number(mim, "offset", what, 0.0))
            pmax = self.limits.max_position
            self.bounded([mimic.multiplier, mimic.offset], -pmax, pmax, f"{what} multiplier/offset")
        return Joint(name, jtype, parent.get("link"), child.get("link"),
                     self.origin(elem.find("origin"), f"joint {name!r}"), axis, limit, dynamics, mimic)


def parse_urdf(root: ET.Element, source: str = "<string>", limits: DescriptionLimits | None = None) -> Robot:
    """Read a parsed ``<robot>`` element.

    Raises:
        DescriptionError: the root is not ``<robot>``, an element is malformed, a number is not
            finite or out of bounds, or there are more links, joints or geoms than ``limits`` allow.
    """
    limits = limits or DescriptionLimits()
    reader = _Reader(source, limits)
    if root.tag != "robot":
        raise reader.fail(f"root element is <{root.tag}>, expected <robot>")
    counts = {"links": (len(root.findall("link")), limits.max_bodies),
              "joints": (len(root.findall("joint")), limits.max_joints),
              "geoms": (len(root.findall("link/visual")) + len(root.findall("link/collision")), limits.max_geoms)}
    for what, (count, most) in counts.items():
        if count > most:
            raise DescriptionError(f"{source}: too many {what}: {count} > {most} (the node's description limits)",
                                   source=source)
    materials = [m for m in (reader.material(e) for e in root.findall("material")) if m is not None]
    links = [reader.link(e) for e in root.findall("link")]
    joints = [reader.joint(e) for e in root.findall("joint")]
    return Robot(name=root.get("name", ""), links=links, joints=joints, materials=materials, notes=reader.notes)
