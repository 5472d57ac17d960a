"""Robot and object descriptions: xacro -> URDF -> ``mujoco.MjSpec``; MJCF accepted as is.

Why the URDF -> MjSpec conversion is written here instead of using MuJoCo's URDF importer: the
importer fuses fixed-joint links (end-effector frames vanish), discards visuals, knows nothing of
``package://`` and ``<ros2_control>``, and cannot fix degenerate inertias; we need all of those.
Parsing is done by :mod:`multiros.sim.urdf_model` (ElementTree; see there why not yourdfpy), and
the ``<ros2_control>`` and ``<gazebo>`` tags by :mod:`multiros.sim.urdf_tags` (joints, the controllers
file, camera sensors as MuJoCo cameras). A ``<mimic>`` joint becomes a MuJoCo joint
equality (``q = offset + multiplier * q_leader``), so a gripper's second finger follows the first.

xacro runs in :mod:`multiros.sim.xacro_runner` (``xacro_to_urdf`` is re-exported here).

Trust: a description that arrives in a service request is data, never a program. With a
:class:`SourcePolicy` (the simulation node passes one for every request), description *text* is
parsed as URDF or MJCF only (xacro evaluates Python in ``${...}``, so xacro text is refused unless
the policy allows it), and every file the text or URI names (the description itself, meshes,
MJCF includes and asset files, controller YAML) must resolve inside the package index's roots or
the policy's trusted paths. Files found there are trusted: xacro runs on them and their own
references are followed. Every description, trusted or not, is checked against
:class:`~multiros.sim.limits.DescriptionLimits` (sizes, counts, depth, finite and bounded numbers)
before it reaches a world. The checks live in :mod:`multiros.sim.trust`.
"""

from __future__ import annotations

import hashlib
import os
import re
import threading
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.errors import DescriptionError, PackageNotFoundError
from multiros.sim.limits import DescriptionLimits
from multiros.sim.packages import PackageIndex, default_index
from multiros.sim.trust import (
    SourcePolicy,
    UnsupportedFormatError,
    check_mesh_file,
    check_mjcf_files,
    check_model,
    screen_mjcf_text,
)
from multiros.sim.urdf_model import parse_urdf
from multiros.sim.urdf_tags import Ros2ControlJoint, add_gazebo_cameras, parse_controllers_file, parse_ros2_control
from multiros.sim.xacro_runner import xacro_to_urdf

__all__ = [
    "JointInfo",
    "Ros2ControlJoint",
    "RobotDescription",
    "MeshCache",
    "SourcePolicy",
    "UnsupportedFormatError",
    "xacro_to_urdf",
    "load_description",
    "urdf_to_description",
    "mjcf_to_description",
]

MIN_MASS = 1e-3  # kg, for links without (or with a degenerate) inertial
MIN_INERTIA = 1e-6  # kg m^2, smallest principal moment kept
_DIRECT_MESH_FORMATS = {".stl", ".obj"}
_XACRO_NAMESPACE = "http://www.ros.org/wiki/xacro"


@dataclass(frozen=True)
class JointInfo:
    """One actuatable (1-DoF) joint of a description.

    Attributes:
        name: joint name (unprefixed).
        type: ``"revolute"``, ``"continuous"`` or ``"prismatic"`` (URDF terms; MJCF hinge/slide map to them).
        lower, upper: position limits; ``limited`` False for continuous joints (then +-inf).
        effort: effort limit (N m or N); 0 = unlimited.
        velocity: velocity limit (metadata); 0 = unknown.
        damping, friction, armature: as written into the model.
    """

    name: str
    type: str
    lower: float
    upper: float
    limited: bool
    effort: float
    velocity: float
    damping: float
    friction: float
    armature: float


@dataclass
class RobotDescription:
    """A loaded description, ready to be attached to a world.

    Attributes:
        name: robot/model name from the file.
        format: ``"urdf"`` or ``"mjcf"``.
        spec: the MjSpec; its worldbody has exactly one child, the root body (link).
        source: file path or ``"<string>"``.
        text: URDF text (after xacro) or MJCF text.
        root: root link/body name.
        joints: actuatable joints, in file order.
        links: all link (body) names, each also present as a site of the same name.
        link_bodies: body names that differ from their link name (a URDF link ``world`` clashes
            with MuJoCo's world body and becomes body ``world_urdf``).
        ros2_control: joints of the ``<ros2_control>`` tag (empty if absent).
        mimic_leaders: joints that a ``<mimic>`` joint follows (a gripper's driven joint), in file order.
        controllers_yaml: controller YAML referenced by a ``<gazebo><plugin><parameters>`` tag.
        free_root: the MJCF root body had a free joint: the entity is free-floating (the joint is
            taken out of ``spec``; the world adds its own when it spawns the entity).
        free_damping: that free joint's damping (N s/m and N m s/rad on its six degrees of freedom: a puck
            that glides and slows by drag), which the world's free joint keeps.
    """

    name: str
    format: str
    spec: mujoco.MjSpec
    source: str
    text: str
    root: str
    joints: tuple[JointInfo, ...]
    links: tuple[str, ...]
    ros2_control: tuple[Ros2ControlJoint, ...] = ()
    controllers_yaml: Path | None = None
    link_bodies: dict[str, str] = field(default_factory=dict)
    free_root: bool = False
    free_damping: float = 0.0
    mimic_leaders: tuple[str, ...] = ()

    def body_name(self, link: str) -> str:
        """MuJoCo body name of a link (differs only for a link called ``world``)."""
        return self.link_bodies.get(link, link)

    @property
    def actuated_joints(self) -> tuple[str, ...]:
        """Joints with a ros2_control command interface, else every 1-DoF joint.

        A joint that ``<mimic>`` joints follow is actuated too when the ``<ros2_control>`` tag leaves it
        out: it is a gripper's drive, which vendors leave out of the arm's hardware block when another
        driver runs the gripper (UFACTORY's xArm at its default plugin). Unactuated, the linkage could
        never move; the simulation drives it within its own URDF limits.
        """
        if self.ros2_control:
            known = {j.name for j in self.joints}
            listed = {j.name for j in self.ros2_control}
            named = [j.name for j in self.ros2_control if j.command_interfaces and j.name in known]
            return (*named, *(j for j in self.mimic_leaders if j in known and j not in listed))
        return tuple(j.name for j in self.joints)


# ---------------------------------------------------------------------------------------- meshes
class MeshCache:
    """Converts meshes MuJoCo cannot read (DAE, PLY, GLB, ...) to STL, cached by content hash.

    Args:
        directory: cache directory (default ``$XDG_CACHE_HOME/uniros/meshes`` or ``~/.cache/...``).
    """

    def __init__(self, directory: str | Path | None = None) -> None:
        if directory is None:
            base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
            directory = Path(base) / "uniros" / "meshes"
        self.directory = Path(directory)

    def usable_path(self, path: Path, *, source: str = "<string>") -> Path:
        """Return ``path`` if MuJoCo reads it, else the path of a cached STL conversion."""
        if path.suffix.lower() in _DIRECT_MESH_FORMATS:
            return path
        data = path.read_bytes()
        digest = hashlib.sha256(data).hexdigest()[:24]
        out = self.directory / f"{digest}.stl"
        if out.is_file():
            return out
        try:
            import trimesh

            mesh = trimesh.load(str(path), force="mesh", process=False)
            if mesh.is_empty:
                raise ValueError("no triangles")
            self.directory.mkdir(parents=True, exist_ok=True)
            tmp = out.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
            mesh.export(str(tmp), file_type="stl")
            os.replace(tmp, out)  # atomic: concurrent converters of the same mesh agree
        except Exception as exc:  # trimesh raises many types for unsupported/bad files
            raise DescriptionError(
                f"{source}: mesh '{path}' could not be converted to STL ({exc}); convert it to STL or OBJ",
                source=source) from exc
        return out


# ---------------------------------------------------------------------------------------- entry point
def load_description(source: str | Path, *, args: Mapping[str, str] | None = None,
                     index: PackageIndex | None = None, mesh_cache: MeshCache | None = None,
                     default_armature: float = 0.01, base_dir: str | Path | None = None,
                     policy: SourcePolicy | None = None, limits: DescriptionLimits | None = None) -> RobotDescription:
    """Load a URDF, xacro or MJCF description from a path/URI or an XML string.

    The format is taken from the root element (``<robot>`` = URDF/xacro, ``<mujoco>`` = MJCF);
    files are run through xacro when their name ends in ``.xacro`` or they use the xacro namespace.

    Args:
        policy: the source is untrusted (a service request): see :class:`SourcePolicy`. ``None``
            trusts the caller (a local user's own files and strings).
        limits: size and value bounds (defaults: the module constants of :mod:`multiros.sim.limits`).

    Raises:
        DescriptionError: unreadable, malformed, refused or out-of-bounds input, or missing
            meshes/packages (``missing_assets``). UnsupportedFormatError: xacro text the policy refuses.
    """
    index = index or default_index()
    limits = limits or DescriptionLimits()
    text_input = isinstance(source, str) and source.lstrip().startswith("<")
    if policy is not None and args:
        policy.check_xacro_args(args)
    if text_input:
        text, name, directory = source, "<string>", Path(base_dir) if base_dir else Path.cwd()
    else:
        path = (policy.resolve(source, index, base_dir, what="description") if policy is not None
                else index.resolve_uri(source, base_dir))
        name, directory = str(path), path.parent
        if not path.is_file():
            raise DescriptionError(f"description file '{source}' not found (resolved to {path})",
                                   source=name, missing_assets=True)
        if path.stat().st_size > 4 * limits.max_chars:
            raise DescriptionError(f"{name}: {path.stat().st_size} bytes; descriptions are limited to "
                                   f"{limits.max_chars} characters", source=name)
        text = path.read_text(errors="replace")
    untrusted = text_input and policy is not None
    _check_text(text, name, limits, untrusted)
    root_tag = _root_tag(text, name)
    if root_tag == "mujoco":
        return mjcf_to_description(text if text_input else Path(name), source_name=name,
                                   policy=policy if untrusted else None, limits=limits, index=index)
    if root_tag != "robot":
        raise DescriptionError(f"{name}: unsupported root element <{root_tag}>; expected <robot> (URDF/xacro) "
                               f"or <mujoco> (MJCF)", source=name)
    if untrusted and _XACRO_NAMESPACE in text and not policy.allow_xacro_text:
        raise UnsupportedFormatError(
            f"{name}: xacro text is not evaluated when it arrives in a request (xacro runs Python); expand it "
            f"on your side (multiros.sim.launch.robot_resource does), send a package:// URI of the file, or "
            f"start the node with allow_xacro_strings=True if every peer is trusted", source=name)
    if name.endswith(".xacro") or "xacro" in text[:4000] and _XACRO_NAMESPACE in text:
        text = xacro_to_urdf(text if text_input else Path(name), args, index=index, base_dir=directory)
        _check_text(text, name, limits, False)
    return urdf_to_description(text, index=index, mesh_cache=mesh_cache, base_dir=directory,
                               source_name=name, default_armature=default_armature,
                               policy=policy if untrusted else None, limits=limits)


def _check_text(text: str, name: str, limits: DescriptionLimits, untrusted: bool) -> None:
    if len(text) > limits.max_chars:
        raise DescriptionError(f"{name}: the description is {len(text)} characters long; the limit is "
                               f"{limits.max_chars}", source=name)
    if untrusted and ("<!DOCTYPE" in text or "<!ENTITY" in text):
        raise DescriptionError(f"{name}: DOCTYPE and ENTITY declarations are not accepted in a request's "
                               f"description", source=name)


def _root_tag(text: str, name: str) -> str:
    match = re.search(r"<\s*([A-Za-z_][\w:.-]*)", re.sub(r"<\?.*?\?>|<!--.*?-->|<!DOCTYPE[^>]*>", "", text,
                                                      flags=re.S))
    if not match:
        raise DescriptionError(f"{name}: not an XML description (no root element)", source=name)
    return match.group(1).split(":")[-1]


# ---------------------------------------------------------------------------------------- URDF
def urdf_to_description(urdf: str, *, index: PackageIndex | None = None, mesh_cache: MeshCache | None = None,
                        base_dir: str | Path | None = None, source_name: str = "<string>",
                        default_armature: float = 0.01, policy: SourcePolicy | None = None,
                        limits: DescriptionLimits | None = None) -> RobotDescription:
    """Build an MjSpec from URDF text (see the module docstring for what is kept).

    ``policy`` (untrusted text) restricts the mesh and controller files the text may name;
    ``limits`` bounds sizes, counts, depth and numbers.
    """
    index = index or default_index()
    mesh_cache = mesh_cache or MeshCache()
    limits = limits or DescriptionLimits()
    try:
        xml_root = ET.fromstring(urdf)
    except ET.ParseError as exc:
        raise DescriptionError(f"{source_name}: malformed URDF XML: {exc}", source=source_name) from exc
    robot = parse_urdf(xml_root, source_name, limits)
    if not robot.links:
        raise DescriptionError(f"{source_name}: URDF has no <link>", source=source_name)
    links = {link.name: link for link in robot.links}
    if len(links) != len(robot.links):
        raise DescriptionError(f"{source_name}: two links have the same name", source=source_name)
    children: dict[str, list] = {}
    parent_joint: dict[str, str] = {}
    for joint in robot.joints:
        for end in (joint.parent, joint.child):
            if end not in links:
                raise DescriptionError(f"{source_name}: joint '{joint.name}' names unknown link '{end}'",
                                       source=source_name)
        if joint.type in ("floating", "planar"):
            raise DescriptionError(f"{source_name}: joint '{joint.name}' of type '{joint.type}' is not supported",
                                   source=source_name)
        if joint.child in parent_joint:
            raise DescriptionError(f"{source_name}: link '{joint.child}' is the child of joints "
                                   f"'{parent_joint[joint.child]}' and '{joint.name}'; a URDF must form a tree",
                                   source=source_name)
        parent_joint[joint.child] = joint.name
        children.setdefault(joint.parent, []).append(joint)
    roots = [n for n in links if n not in parent_joint]
    if len(roots) != 1:
        raise DescriptionError(f"{source_name}: URDF must form one tree, found roots {roots[:10]}", source=source_name)
    colors = {m.name: m.color.rgba for m in robot.materials if m.color is not None}

    spec = mujoco.MjSpec()
    spec.modelname = robot.name or "robot"
    spec.compiler.degree = False
    spec.compiler.inertiafromgeom = int(mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE)
    ctx = _UrdfBuild(spec, index, mesh_cache, Path(base_dir) if base_dir else Path.cwd(), source_name, colors,
                     policy, limits)
    joint_infos: list[JointInfo] = []

    link_bodies = {"world": "world_urdf"} if "world" in links else {}

    # Depth-first, parents before children, siblings in file order; iterative, so a long chain
    # meets the depth limit instead of Python's recursion limit.
    stack: list[tuple[str, object, object, int]] = [(roots[0], spec.worldbody, None, 1)]
    built = 0
    while stack:
        link_name, parent_body, joint, depth = stack.pop()
        if depth > limits.max_depth:
            raise DescriptionError(f"{source_name}: the link tree is deeper than {limits.max_depth} links (at link "
                                   f"'{link_name}'); the node's description limits refuse it", source=source_name)
        body_name = link_bodies.get(link_name, link_name)
        if joint is None:
            body = parent_body.add_body(name=body_name)
        else:
            pos, quat = _mat_to_pos_quat(joint.origin)
            body = parent_body.add_body(name=body_name, pos=pos, quat=quat)
            if joint.type in ("revolute", "continuous", "prismatic"):
                joint_infos.append(ctx.add_joint(body, joint, default_armature))
        ctx.fill_link(body, links[link_name])
        built += 1
        for child in reversed(children.get(link_name, [])):
            stack.append((child.child, body, child, depth + 1))
    if built != len(links):
        raise DescriptionError(f"{source_name}: {len(links) - built} link(s) are not connected to the root "
                               f"'{roots[0]}' (a cycle of joints?)", source=source_name)
    _add_mimics(spec, robot.joints, {j.name for j in joint_infos})
    add_gazebo_cameras(spec, xml_root, {name: link_bodies.get(name, name) for name in links}, source_name, limits)
    rc_joints = parse_ros2_control(xml_root, source_name)
    return RobotDescription(name=spec.modelname, format="urdf", spec=spec, source=source_name, text=urdf,
                            root=roots[0], joints=tuple(joint_infos), links=tuple(links),
                            ros2_control=rc_joints, link_bodies=link_bodies,
                            controllers_yaml=parse_controllers_file(xml_root, index, source_name, policy),
                            mimic_leaders=robot.mimic_leaders())


def _add_mimics(spec: mujoco.MjSpec, joints: Sequence[object], movable: set[str]) -> None:
    """URDF ``<mimic>``: a joint equality ``q = offset + multiplier * q_leader`` (e.g. the second
    finger of a parallel gripper follows the commanded one). A mimic of an unknown or fixed joint is
    ignored, as robot_state_publisher does."""
    for joint in joints:
        mimic = getattr(joint, "mimic", None)
        if mimic is None or joint.name not in movable or mimic.joint not in movable or mimic.joint == joint.name:
            continue
        spec.add_equality(name=f"mimic_{joint.name}", type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                          name1=joint.name, name2=mimic.joint,
                          data=[float(mimic.offset), float(mimic.multiplier)] + [0.0] * 10)


class _UrdfBuild:
    """Per-conversion state: mesh assets, materials, naming."""

    def __init__(self, spec, index, mesh_cache, base_dir, source, colors, policy, limits) -> None:
        self.spec, self.index, self.cache, self.base_dir = spec, index, mesh_cache, base_dir
        self.source, self.colors = source, colors
        self.policy, self.limits = policy, limits
        self.meshes: dict[tuple[str, tuple], str] = {}
        self.vertices = 0

    def add_joint(self, body, joint, default_armature: float) -> JointInfo:
        axis = joint.direction
        if not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-9:
            raise DescriptionError(f"{self.source}: joint '{joint.name}' has a zero axis", source=self.source)
        limit, dyn = joint.limit, joint.dynamics
        continuous = joint.type == "continuous"
        lower = float(limit.lower) if limit is not None and limit.lower is not None else 0.0
        upper = float(limit.upper) if limit is not None and limit.upper is not None else 0.0
        limited = not continuous and upper > lower
        effort = float(limit.effort or 0.0) if limit is not None else 0.0
        velocity = float(limit.velocity or 0.0) if limit is not None else 0.0
        damping = float(dyn.damping or 0.0) if dyn is not None else 0.0
        friction = float(dyn.friction or 0.0) if dyn is not None else 0.0
        jtype = mujoco.mjtJoint.mjJNT_SLIDE if joint.type == "prismatic" else mujoco.mjtJoint.mjJNT_HINGE
        mj = body.add_joint(name=joint.name, type=jtype, axis=axis / np.linalg.norm(axis), damping=damping,
                            frictionloss=friction, armature=default_armature)
        if limited:
            mj.range = [lower, upper]
            mj.limited = int(mujoco.mjtLimited.mjLIMITED_TRUE)
        else:
            mj.limited = int(mujoco.mjtLimited.mjLIMITED_FALSE)
        if effort > 0:
            mj.actfrcrange = [-effort, effort]
            mj.actfrclimited = int(mujoco.mjtLimited.mjLIMITED_TRUE)
        return JointInfo(joint.name, joint.type, lower if limited else -np.inf, upper if limited else np.inf,
                         limited, effort, velocity, damping, friction, default_armature)

    def fill_link(self, body, link) -> None:
        body.add_site(name=link.name, size=[0.005, 0.005, 0.005], group=4)
        body.explicitinertial = True
        inertial = link.inertial
        mass = float(inertial.mass) if inertial is not None and inertial.mass is not None else 0.0
        tensor = (np.asarray(inertial.inertia, dtype=float) if inertial is not None and inertial.inertia is not None
                  else np.zeros((3, 3)))
        origin = inertial.origin if inertial is not None and inertial.origin is not None else np.eye(4)
        pos, rot = origin[:3, 3], origin[:3, :3]
        principal, axes = _fix_inertia(mass, tensor)
        body.mass = max(mass, MIN_MASS) if np.isfinite(mass) else MIN_MASS
        body.ipos = pos
        body.iquat = _mat_to_quat(rot @ axes)
        body.inertia = principal
        for i, visual in enumerate(link.visuals):
            geom = self._add_geom(body, visual.geometry, visual.origin, f"{link.name}_visual_{i}")
            if geom is not None:
                geom.contype, geom.conaffinity, geom.group = 0, 0, 2
                geom.rgba = self._rgba(visual.material)
        has_visual = bool(link.visuals)
        for i, collision in enumerate(link.collisions):
            geom = self._add_geom(body, collision.geometry, collision.origin, f"{link.name}_collision_{i}")
            if geom is not None:
                geom.group = 3 if has_visual else 0
                geom.rgba = [0.5, 0.5, 0.5, 1.0]

    def _rgba(self, material) -> list[float]:
        if material is not None:
            if material.color is not None:
                return list(material.color.rgba)
            if material.name in self.colors:
                return list(self.colors[material.name])
        return [0.7, 0.7, 0.7, 1.0]

    def _add_geom(self, body, geometry, origin, name: str):
        if geometry is None:
            return None
        pos, quat = _mat_to_pos_quat(origin)
        geom = body.add_geom(pos=pos, quat=quat)
        if geometry.box is not None:
            geom.type = mujoco.mjtGeom.mjGEOM_BOX
            geom.size = np.asarray(geometry.box.size, dtype=float) / 2.0
        elif geometry.cylinder is not None:
            geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
            geom.size = [geometry.cylinder.radius, geometry.cylinder.length / 2.0, 0.0]
        elif geometry.sphere is not None:
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.size = [geometry.sphere.radius, 0.0, 0.0]
        elif geometry.mesh is not None:
            geom.type = mujoco.mjtGeom.mjGEOM_MESH
            geom.meshname = self._mesh(geometry.mesh)
        else:
            self.spec.delete(geom)
            return None
        return geom

    def _mesh(self, mesh) -> str:
        scale = mesh.scale if mesh.scale is not None else 1.0
        scale = tuple(float(s) for s in np.broadcast_to(np.asarray(scale, dtype=float), (3,)))
        key = (mesh.filename, scale)
        if key in self.meshes:
            return self.meshes[key]
        try:
            if self.policy is not None:
                path = self.policy.resolve(mesh.filename, self.index, self.base_dir, what="mesh")
            else:
                path = self.index.resolve_uri(mesh.filename, self.base_dir)
        except PackageNotFoundError as exc:
            raise DescriptionError(f"{self.source}: mesh '{mesh.filename}' not found: {exc}",
                                   source=self.source, missing_assets=True) from exc
        except DescriptionError as exc:
            raise DescriptionError(f"{self.source}: {exc}", source=self.source) from exc
        if not path.is_file():
            raise DescriptionError(f"{self.source}: mesh '{mesh.filename}' not found; searched: {path}",
                                   source=self.source, missing_assets=True)
        self.vertices += check_mesh_file(path, self.limits, self.source)
        if self.vertices > self.limits.max_mesh_vertices:
            raise DescriptionError(f"{self.source}: the meshes have more than {self.limits.max_mesh_vertices} "
                                   f"vertices in all (the node's description limits)", source=self.source)
        usable = self.cache.usable_path(path, source=self.source)
        name = f"mesh{len(self.meshes)}_{re.sub(r'[^A-Za-z0-9_]', '_', path.stem)}"
        self.spec.add_mesh(name=name, file=str(usable.resolve()), scale=list(scale))
        self.meshes[key] = name
        return name


def _fix_inertia(mass: float, tensor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and axes (right-handed) of an inertia tensor, made physically valid.

    Zero/tiny/negative moments become ``MIN_INERTIA``; moments breaking the triangle inequality
    (A + B >= C) are raised; a non-finite tensor is replaced by a small sphere's.
    """
    if not np.all(np.isfinite(tensor)):
        tensor = np.zeros((3, 3))
    sym = (tensor + tensor.T) / 2.0
    moments, axes = np.linalg.eigh(sym)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    floor = max(MIN_INERTIA, 1e-4 * max(mass, MIN_MASS) * 1e-2)
    moments = np.maximum(moments, floor)
    for _ in range(3):  # each pass fixes the largest violation; converges in <= 2 passes
        big = int(np.argmax(moments))
        others = moments.sum() - moments[big]
        if others < moments[big]:
            moments[np.arange(3) != big] += (moments[big] - others) / 2.0 + 1e-12
    return moments, axes


def _mat_to_quat(rot: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot, dtype=float).ravel())
    return quat


def _mat_to_pos_quat(matrix: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    matrix = np.eye(4) if matrix is None else np.asarray(matrix, dtype=float)
    return matrix[:3, 3].copy(), _mat_to_quat(matrix[:3, :3])


# ---------------------------------------------------------------------------------------- MJCF
def mjcf_to_description(source: str | Path, *, source_name: str | None = None, policy: SourcePolicy | None = None,
                        limits: DescriptionLimits | None = None, index: PackageIndex | None = None) -> RobotDescription:
    """Load an MJCF file or string. Its ``<actuator>`` elements are removed (the controllers add
    their own) and each body gets a site of the same name. The worldbody must have exactly one
    child body (the root); wrap several bodies in one if needed. A free joint on the root
    (``<freejoint/>``) makes the description free-floating (``free_root``); an unnamed root body is
    called ``base_link``. ``policy`` (untrusted text) and ``limits``: see :func:`load_description`."""
    is_text = isinstance(source, str) and source.lstrip().startswith("<")
    name = source_name or ("<string>" if is_text else str(source))
    limits = limits or DescriptionLimits()
    if is_text:
        screen_mjcf_text(source, name, limits, policy, index or default_index())
    try:
        spec = mujoco.MjSpec.from_string(source) if is_text else mujoco.MjSpec.from_file(str(source))
        if policy is not None:
            check_mjcf_files(spec, name, policy, index or default_index(), limits)
        model = spec.compile()  # validate now, to report the file's own errors with its name
    except DescriptionError:
        raise
    except Exception as exc:
        raise DescriptionError(f"{name}: invalid MJCF: {exc}", source=name,
                               missing_assets="resource not found" in str(exc).lower()) from exc
    check_model(model, name, limits)
    text = source if is_text else Path(source).read_text(errors="replace")
    roots = list(spec.worldbody.bodies)
    if len(roots) != 1:
        raise DescriptionError(f"{name}: MJCF worldbody must have exactly one body (found {len(roots)}); "
                               f"put the model under one root body", source=name)
    for act in list(spec.actuators):
        spec.delete(act)
    root = roots[0]
    if not root.name:
        taken = {b.name for b in spec.bodies}
        root.name = next((n for n in ("base_link", "root_body") if n not in taken), "uniros_root_body")
    # MuJoCo allows a free joint only on a top-level body, i.e. the root here: record it and take it
    # out, so the world's own free joint (with the spawn pose) is the only one.
    free = [j for j in root.joints if int(j.type) == int(mujoco.mjtJoint.mjJNT_FREE)]
    free_damping = max((float(np.atleast_1d(j.damping)[0]) for j in free), default=0.0)
    for j in free:
        spec.delete(j)
    joints: list[JointInfo] = []
    for j in spec.joints:
        jtype = int(j.type)
        if jtype not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            continue
        if not j.name:  # a joint is known by name: joint_states, commands and the controllers' actuators
            body = j.parent.name or "an unnamed body"
            raise DescriptionError(f"{name}: a {'slide' if jtype == int(mujoco.mjtJoint.mjJNT_SLIDE) else 'hinge'} "
                                   f"joint of body '{body}' has no name: give every hinge and slide joint a name "
                                   "(<joint name=\"...\">); ROS addresses joints by name", source=name)
        lim = int(j.limited)
        limited = lim == int(mujoco.mjtLimited.mjLIMITED_TRUE) or (
            lim == int(mujoco.mjtLimited.mjLIMITED_AUTO) and j.range[1] > j.range[0])
        scale = np.pi / 180.0 if (spec.compiler.degree and jtype == int(mujoco.mjtJoint.mjJNT_HINGE)) else 1.0
        lower, upper = (float(j.range[0]) * scale, float(j.range[1]) * scale) if limited else (-np.inf, np.inf)
        effort = float(max(abs(j.actfrcrange[0]), abs(j.actfrcrange[1]))) if int(j.actfrclimited) == 1 else 0.0
        joints.append(JointInfo(j.name, "prismatic" if jtype == int(mujoco.mjtJoint.mjJNT_SLIDE) else
                                ("revolute" if limited else "continuous"), lower, upper, limited, effort, 0.0,
                                float(j.damping[0] if np.ndim(j.damping) else j.damping),
                                float(j.frictionloss), float(j.armature[0] if np.ndim(j.armature) else j.armature)))
    links = []
    for body in spec.bodies:
        if body.name and body is not spec.worldbody:
            links.append(body.name)
            if spec.site(body.name) is None:
                body.add_site(name=body.name, size=[0.005, 0.005, 0.005], group=4)
    return RobotDescription(name=spec.modelname or "mjcf", format="mjcf", spec=spec, source=name, text=text,
                            root=root.name, joints=tuple(joints), links=tuple(links), free_root=bool(free),
                            free_damping=free_damping)
