"""Trust boundary of descriptions: where a request may read files, and what a description may hold.

A description that arrives in a service request is data, never a program, and may name files only
inside the package roots the node was configured with or its trusted paths (:class:`SourcePolicy`).
:func:`check_model` checks a compiled MJCF model against :class:`~multiros.sim.limits.DescriptionLimits`
(URDF numbers are checked while reading, in :mod:`multiros.sim.urdf_model`); :func:`screen_mjcf_text`
checks MJCF text before MuJoCo parses it, and :func:`check_mjcf_files` the asset files MuJoCo would
read when compiling it. :mod:`multiros.sim.description` applies all of them.
"""

from __future__ import annotations

import os
import posixpath
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

import mujoco
import numpy as np

from multiros.sim.errors import DescriptionError
from multiros.sim.limits import MAX_XACRO_ARG_CHARS, MAX_XACRO_ARGS, DescriptionLimits
from multiros.sim.packages import PackageIndex

__all__ = [
    "SourcePolicy",
    "UnsupportedFormatError",
    "check_mesh_file",
    "check_mjcf_files",
    "check_model",
    "screen_mjcf_text",
]

_XACRO_ARG_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.-]*$")


class UnsupportedFormatError(DescriptionError):
    """The description's format is not accepted from this source (xacro text in a request)."""


@dataclass(frozen=True)
class SourcePolicy:
    """What a description from an untrusted source (a service request) may use.

    Attributes:
        trusted_paths: directories, besides the package index's roots, whose files a plain path
            or ``file://`` URI may name (e.g. the directory of a user's own robot file).
        allow_xacro_text: run xacro on description text. xacro evaluates Python in ``${...}``:
            allow it only when every peer that can reach the node is trusted.
    """

    trusted_paths: tuple[Path, ...] = ()
    allow_xacro_text: bool = False

    @classmethod
    def create(cls, trusted_paths: Iterable[str | Path] = (), allow_xacro_text: bool = False) -> SourcePolicy:
        """A policy with ``trusted_paths`` made absolute (``~`` expanded)."""
        return cls(tuple(Path(p).expanduser().absolute() for p in trusted_paths), bool(allow_xacro_text))

    def resolve(self, uri: str | Path, index: PackageIndex, base_dir: str | Path | None = None, *,
                what: str = "file") -> Path:
        """Resolve ``uri`` like :meth:`PackageIndex.resolve_uri`, refusing anything outside the roots.

        ``package://pkg/rel`` must stay inside the package (no ``..`` out of it; links the package
        itself holds are followed). A plain path or ``file://`` URI must resolve (symlinks and
        ``..`` resolved) inside a package root of ``index`` or a trusted path. Existence is not
        checked, so a refusal tells nothing about the file.

        Raises:
            DescriptionError: the location is refused; PackageNotFoundError: unknown package.
        """
        text = str(uri)
        if "\x00" in text:
            raise DescriptionError(f"{what} location contains a NUL character", source="<request>")
        if text.startswith("package://"):
            pkg, _, rel = text[len("package://"):].partition("/")
            rel = unquote(rel)
            norm = posixpath.normpath(rel) if rel else "."
            if rel.startswith("/") or norm == ".." or norm.startswith("../"):
                raise DescriptionError(f"{what} '{text}' leaves its package; package:// paths must stay inside "
                                       f"the package", source="<request>")
            return index.find_package_share(pkg) / ("" if norm == "." else norm)
        path = index.resolve_uri(text, base_dir if base_dir is not None else Path.cwd())
        real = Path(os.path.realpath(path))
        for root in (*index.package_roots(), *self.trusted_paths):
            real_root = Path(os.path.realpath(root))
            if real == real_root or real_root in real.parents:
                return real
        raise DescriptionError(
            f"{what} '{text}' is outside the node's package roots and trusted paths; name it with a "
            f"package:// URI, or start the node with its directory in trusted_paths", source="<request>")

    def check_xacro_args(self, args: Mapping[str, str]) -> None:
        """Refuse xacro arguments that could inject substitutions, or too many / too long ones."""
        if len(args) > MAX_XACRO_ARGS:
            raise DescriptionError(f"{len(args)} xacro arguments; at most {MAX_XACRO_ARGS} are accepted",
                                   source="<request>")
        for key, value in args.items():
            key, value = str(key), str(value)
            if not _XACRO_ARG_NAME.match(key):
                raise DescriptionError(f"xacro argument name {key[:64]!r} is invalid (letters, digits, '_', '.', '-')",
                                       source="<request>")
            if len(value) > MAX_XACRO_ARG_CHARS:
                raise DescriptionError(f"xacro argument {key!r} is {len(value)} characters long; at most "
                                       f"{MAX_XACRO_ARG_CHARS} are accepted", source="<request>")
            if "$(" in value or "${" in value or any(ord(c) < 32 for c in value):
                raise DescriptionError(f"xacro argument {key!r} contains '$(', '${{' or a control character; "
                                       f"substitutions are not accepted in arguments", source="<request>")


def check_mesh_file(path: Path, limits: DescriptionLimits, source: str) -> int:
    """Refuse a mesh file over the byte or vertex limit; return its (estimated) vertex count.

    Counted without parsing: binary STL from its triangle count (3 vertices each), ASCII STL and
    OBJ by their ``vertex``/``v`` lines; other formats by size only (trimesh converts them).
    """
    size = path.stat().st_size
    if size > limits.max_mesh_bytes:
        raise DescriptionError(f"{source}: mesh '{path.name}' is {size} bytes; the limit is {limits.max_mesh_bytes}",
                               source=source)
    suffix = path.suffix.lower()
    vertices = 0
    if suffix == ".stl":
        with path.open("rb") as f:
            head = f.read(84)
            if head[:5].lower() == b"solid" and b"facet" in f.read(4096):
                vertices = path.read_bytes().count(b"vertex")
            elif len(head) == 84:
                vertices = 3 * int.from_bytes(head[80:84], "little")
    elif suffix == ".obj":
        with path.open("rb") as f:
            vertices = sum(1 for line in f if line.startswith(b"v "))
    if vertices > limits.max_mesh_vertices:
        raise DescriptionError(f"{source}: mesh '{path.name}' has {vertices} vertices; the limit is "
                               f"{limits.max_mesh_vertices}", source=source)
    return vertices


# ---------------------------------------------------------------------------------------- MJCF
# Elements a request's MJCF may not use: generators whose output is not bounded by the text
# (replicate, composite, flexcomp), plugins, other models (model, attach) and user data blocks
# (custom numeric/text/tuple, sized by an attribute). Files in the package roots may use them.
_MJCF_REFUSED_ELEMENTS = frozenset({"replicate", "composite", "flexcomp", "flex", "deformable", "extension", "plugin",
                                    "instance", "model", "attach", "custom", "numeric", "tuple"})
_MJCF_FILE_ELEMENTS = frozenset({"include", "mesh", "texture", "hfield", "skin"})
_MJCF_MAX_MEMORY = 1 << 30  # bytes of <size memory=...> in a request
_MEMORY_SUFFIX = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40, "P": 1 << 50, "E": 1 << 60}


def screen_mjcf_text(text: str, name: str, limits: DescriptionLimits, policy: SourcePolicy | None,
                      index: PackageIndex) -> None:
    """Check MJCF text before MuJoCo parses it: element count and nesting depth (always); for a
    request (``policy``): refused elements, generated texture/height-field/memory sizes and the
    files named by ``<include>`` and the compiler's directories."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DescriptionError(f"{name}: malformed MJCF XML: {exc}", source=name) from exc
    count = 0
    stack: list[tuple[ET.Element, int]] = [(root, 1)]
    while stack:  # iterative: a deep nesting meets the limit, not Python's recursion limit
        elem, depth = stack.pop()
        count += 1
        if count > limits.max_xml_elements:
            raise DescriptionError(f"{name}: more than {limits.max_xml_elements} XML elements (the node's "
                                   f"description limits)", source=name)
        if depth > limits.max_depth + 8:  # body nesting plus <mujoco><worldbody> and a few wrappers
            raise DescriptionError(f"{name}: XML elements nested deeper than {limits.max_depth + 8} (the node's "
                                   f"description limits)", source=name)
        if policy is not None:
            _screen_mjcf_element(elem, name, limits, policy, index)
        stack.extend((child, depth + 1) for child in elem)


def _screen_mjcf_element(elem: ET.Element, name: str, limits: DescriptionLimits, policy: SourcePolicy,
                         index: PackageIndex) -> None:
    tag = elem.tag if isinstance(elem.tag, str) else ""
    label = f"{name}: <{tag}{' name=' + repr(elem.get('name')) if elem.get('name') else ''}>"
    if tag in _MJCF_REFUSED_ELEMENTS:
        raise DescriptionError(f"{label} is not accepted in a request's MJCF (generators, plugins, models and "
                               f"custom data are not); put the model in a package and spawn it by package:// URI",
                               source=name)
    for attr in elem.attrib:
        if attr.startswith("file") and tag not in _MJCF_FILE_ELEMENTS:
            raise DescriptionError(f"{label} attribute '{attr}' is not accepted in a request", source=name)
    if tag == "include" and elem.get("file") is not None:
        policy.resolve(elem.get("file", ""), index, what="MJCF include")
    if tag == "compiler":
        for attr in ("meshdir", "texturedir", "assetdir"):
            if elem.get(attr):
                policy.resolve(elem.get(attr, ""), index, what=f"MJCF compiler {attr}")
    if tag == "mesh" and elem.get("builtin") is not None:
        raise DescriptionError(f"{label}: builtin (generated) meshes are not accepted in a request", source=name)
    if tag == "texture":
        pixels = _int_attr(elem, "width", label) * _int_attr(elem, "height", label)
        if pixels > limits.max_texture_pixels:
            raise DescriptionError(f"{label}: {pixels} pixels; at most {limits.max_texture_pixels} are accepted",
                                   source=name)
    if tag == "hfield":
        cells = _int_attr(elem, "nrow", label) * _int_attr(elem, "ncol", label)
        if cells > limits.max_texture_pixels:
            raise DescriptionError(f"{label}: {cells} cells; at most {limits.max_texture_pixels} are accepted",
                                   source=name)
    if tag == "size":
        for attr in ("memory", "nstack"):
            if elem.get(attr) is not None and _memory_bytes(elem.get(attr, ""), label) > _MJCF_MAX_MEMORY:
                raise DescriptionError(f"{label} {attr}={elem.get(attr)!r} asks for more than {_MJCF_MAX_MEMORY} "
                                       f"bytes; not accepted in a request", source=name)


def _int_attr(elem: ET.Element, attr: str, label: str) -> int:
    text = elem.get(attr)
    if text is None:
        return 1
    try:
        value = int(text.strip())
    except ValueError:
        raise DescriptionError(f"{label} {attr}={text!r} is not an integer", source=label) from None
    return abs(value)


def _memory_bytes(text: str, label: str) -> int:
    match = re.fullmatch(r"\s*(-?\d+)\s*([KMGTPE]?)\s*", text, flags=re.I)
    if not match:
        raise DescriptionError(f"{label} memory size {text!r} is not a number with an optional K/M/G suffix",
                               source=label)
    return abs(int(match.group(1))) * _MEMORY_SUFFIX[match.group(2).upper()]


def _mjcf_asset_path(spec: mujoco.MjSpec, directory: str, file: str) -> str:
    """The path MuJoCo opens for an asset ``file`` with compiler directory ``directory``."""
    if os.path.isabs(file):
        return file
    if os.path.isabs(directory):
        return os.path.join(directory, file)
    return os.path.join(spec.modelfiledir or os.getcwd(), directory, file)


def check_mjcf_files(spec: mujoco.MjSpec, name: str, policy: SourcePolicy, index: PackageIndex,
                      limits: DescriptionLimits) -> None:
    """Every asset file of a parsed request MJCF (included parts too) must be inside the roots;
    mesh files within the size limits. Runs before compilation, which is when MuJoCo reads them."""
    files: list[tuple[str, str, str]] = []  # (kind, directory, file)
    files += [("mesh", spec.meshdir, m.file) for m in spec.meshes if m.file]
    files += [("skin", spec.meshdir, s.file) for s in spec.skins if s.file]
    files += [("hfield", spec.meshdir, h.file) for h in spec.hfields if h.file]
    for tex in spec.textures:
        files += [("texture", spec.texturedir, f) for f in (tex.file, *tex.cubefiles) if f]
    vertices = 0
    for kind, directory, file in files:
        path = policy.resolve(_mjcf_asset_path(spec, directory, file), index, what=f"MJCF {kind} file")
        if kind == "mesh" and path.is_file():
            vertices += check_mesh_file(path, limits, name)
    if vertices > limits.max_mesh_vertices:
        raise DescriptionError(f"{name}: the meshes have more than {limits.max_mesh_vertices} vertices in all",
                               source=name)


_OBJ_PREFIXES = (("body_", mujoco.mjtObj.mjOBJ_BODY, "nbody"), ("geom_", mujoco.mjtObj.mjOBJ_GEOM, "ngeom"),
                 ("jnt_", mujoco.mjtObj.mjOBJ_JOINT, "njnt"), ("site_", mujoco.mjtObj.mjOBJ_SITE, "nsite"),
                 ("cam_", mujoco.mjtObj.mjOBJ_CAMERA, "ncam"), ("light_", mujoco.mjtObj.mjOBJ_LIGHT, "nlight"),
                 ("mesh_", mujoco.mjtObj.mjOBJ_MESH, "nmesh"), ("mat_", mujoco.mjtObj.mjOBJ_MATERIAL, "nmat"),
                 ("tendon_", mujoco.mjtObj.mjOBJ_TENDON, "ntendon"), ("eq_", mujoco.mjtObj.mjOBJ_EQUALITY, "neq"),
                 ("sensor_", mujoco.mjtObj.mjOBJ_SENSOR, "nsensor"), ("pair_", mujoco.mjtObj.mjOBJ_PAIR, "npair"),
                 ("actuator_", mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"), ("key_", mujoco.mjtObj.mjOBJ_KEY, "nkey"))


def _element(model: mujoco.MjModel, field_name: str, row: int) -> str:
    """``"geom 'arm/box' (geom_size)"``-style label of a row of a model array."""
    if field_name.startswith("dof_") and row < model.nv:
        field_name, row = "jnt_" + field_name, int(model.dof_jntid[row])
    for prefix, obj, count in _OBJ_PREFIXES:
        if field_name.startswith(prefix) and row < getattr(model, count):
            label = mujoco.mj_id2name(model, int(obj), row) or f"#{row}"
            kind = prefix.rstrip("_").replace("jnt", "joint").replace("cam", "camera").replace("mat", "material")
            return f"{kind} '{label}'"
    return f"row {row}"


def check_model(model: mujoco.MjModel, name: str, limits: DescriptionLimits | None = None) -> None:
    """Check a compiled description model: counts, tree depth, every real number finite, and
    positions, sizes, masses, inertias, joint ranges and joint parameters within ``limits``.

    Raises:
        DescriptionError: naming the element (body/geom/joint name) and the model field.
    """
    limits = limits or DescriptionLimits()
    for what, count, most in (("bodies", model.nbody - 1, limits.max_bodies),
                              ("joints", model.njnt, limits.max_joints), ("geoms", model.ngeom, limits.max_geoms),
                              ("mesh vertices", model.nmeshvert, limits.max_mesh_vertices)):
        if count > most:
            raise DescriptionError(f"{name}: {count} {what}; the node's description limits allow {most}", source=name)
    depth = np.zeros(model.nbody, dtype=int)
    for b in range(1, model.nbody):  # a parent's id is always lower than its child's
        depth[b] = depth[model.body_parentid[b]] + 1
    if model.nbody > 1 and depth.max() > limits.max_depth:
        raise DescriptionError(f"{name}: the body tree is {depth.max()} bodies deep; the node's description limits "
                               f"allow {limits.max_depth}", source=name)
    for attr in dir(model):
        if attr.startswith("_"):
            continue
        try:
            value = getattr(model, attr)
        except Exception:  # some properties raise for models without the feature
            continue
        if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.size and not np.all(np.isfinite(value)):
            row = int(np.argwhere(~np.isfinite(value))[0][0])
            raise DescriptionError(f"{name}: {_element(model, attr, row)} has a value that is not finite ({attr})",
                                   source=name)
    pmax, jmax = limits.max_position, limits.max_joint_parameter
    bounds = (("body_pos", -pmax, pmax), ("body_ipos", -pmax, pmax), ("geom_pos", -pmax, pmax),
              ("site_pos", -pmax, pmax), ("geom_size", 0.0, limits.max_size), ("body_mass", 0.0, limits.max_mass),
              ("body_inertia", 0.0, limits.max_inertia), ("jnt_range", -pmax, pmax), ("jnt_stiffness", 0.0, jmax),
              ("dof_damping", 0.0, jmax), ("dof_frictionloss", 0.0, jmax), ("dof_armature", 0.0, jmax))
    for attr, low, high in bounds:
        value = np.asarray(getattr(model, attr))
        bad = np.argwhere((value < low) | (value > high))
        if bad.size:
            row = int(bad[0][0])
            shown = np.asarray(value[row]).tolist()
            raise DescriptionError(f"{name}: {_element(model, attr, row)} {attr.split('_', 1)[1]} {shown} is outside "
                                   f"[{low:g}, {high:g}] (the node's description limits)", source=name)
