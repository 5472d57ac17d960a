"""A ROS package index that works without ROS: ``package://`` URIs and ``$(find pkg)``.

Search order for ``find_package_share(name)``:

1. explicit ``extra_paths`` given to the index: directories that are a package root (named
   ``<pkg>`` or with a ``package.xml`` naming ``<pkg>``), or that contain ``<pkg>/``;
2. entry points of group ``uniros.description_packages`` (name = ROS package name, value = an
   importable Python package whose directory is the package root);
3. ``AMENT_PREFIX_PATH``: ``<prefix>/share/<pkg>``;
4. ``ROS_PACKAGE_PATH``: directories holding ``<pkg>/package.xml`` (searched recursively, ROS 1
   style) or named ``<pkg>``.

``ament_index_python`` is not used because it is not on PyPI and only knows (3).

Package names are checked (letters, digits, ``_``, ``-``, ``.``; not ``.`` or ``..``): a name comes
from a ``package://`` URI that may have arrived in a service request, and ``package://../x``
must not walk out of a search directory. :meth:`PackageIndex.package_roots` lists the directories
the index searches: the simulation node reads files of a request only from inside them.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import re
from collections.abc import Iterable, Mapping
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

from multiros.sim.errors import DescriptionError, PackageNotFoundError

__all__ = ["ENTRY_POINT_GROUP", "PackageIndex", "default_index"]

ENTRY_POINT_GROUP = "uniros.description_packages"
_MAX_WALK_DEPTH = 4  # ROS_PACKAGE_PATH dirs are crawled like rospack, but not forever
_VALID_PACKAGE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


class PackageIndex:
    """Finds ROS package share directories.

    Args:
        extra_paths: directories searched first (package roots or their parents).
        use_entry_points: search the ``uniros.description_packages`` entry points.
        environ: environment to read ``AMENT_PREFIX_PATH`` / ``ROS_PACKAGE_PATH`` from
            (default ``os.environ``, read at each lookup).
        packages: explicit ``{name: directory}`` mapping, searched before everything else.
    """

    def __init__(self, extra_paths: Iterable[str | Path] = (), *, use_entry_points: bool = True,
                 environ: Mapping[str, str] | None = None,
                 packages: Mapping[str, str | Path] | None = None) -> None:
        self._extra = tuple(Path(p).expanduser().absolute() for p in extra_paths)
        self._use_entry_points = use_entry_points
        self._environ = environ
        self._explicit = {k: Path(v).expanduser().absolute() for k, v in (packages or {}).items()}
        self._entry_points: tuple[Any, ...] | None = None

    def _description_entry_points(self) -> tuple[Any, ...]:
        """The ``uniros.description_packages`` entry points, read once per index: reading them
        scans every installed distribution's metadata (milliseconds, and importlib keeps a lookup
        per scan), and an env's ``make`` looks packages up several times. A package installed
        after the index's first lookup is found by a new index (a new process)."""
        if self._entry_points is None:
            self._entry_points = tuple(entry_points(group=ENTRY_POINT_GROUP)) if self._use_entry_points else ()
        return self._entry_points

    # ------------------------------------------------------------------ lookup
    def find_package_share(self, name: str) -> Path:
        """Return the share directory (package root) of ROS package ``name``.

        Raises:
            PackageNotFoundError: the package is in none of the searched places (all listed).
            DescriptionError: ``name`` is not a valid package name.
        """
        if not _VALID_PACKAGE.match(name) or name in (".", ".."):
            raise DescriptionError(f"{name[:100]!r} is not a valid ROS package name (letters, digits, '_', '-', '.')",
                                   source="package://")
        searched: list[str] = []
        for finder in (self._find_explicit, self._find_extra, self._find_entry_point, self._find_ament,
                       self._find_ros_package_path):
            found = finder(name, searched)
            if found is not None:
                return found
        where = "; ".join(searched) if searched else "nothing (no extra paths, entry points or ROS paths)"
        raise PackageNotFoundError(
            f"package '{name}' not found; searched: {where}. To make it found, any one of: source the ROS "
            f"workspace that installs it (AMENT_PREFIX_PATH), add the directory that holds it to ROS_PACKAGE_PATH, "
            f"or install a Python package registering it in the '{ENTRY_POINT_GROUP}' entry-point group "
            f"(from Python: PackageIndex(extra_paths=[that directory]))", package=name)

    def package_roots(self) -> tuple[Path, ...]:
        """Every directory this index finds packages in (absolute, not resolved; may not exist):
        the explicit packages, the extra paths, the entry points' package directories,
        ``<AMENT_PREFIX_PATH entry>/share`` and the ``ROS_PACKAGE_PATH`` entries."""
        roots: list[Path] = [*self._explicit.values(), *self._extra]
        if self._use_entry_points:
            for ep in self._description_entry_points():
                root = _python_package_dir(ep.value)
                if root is not None:
                    roots.append(root.absolute())
        ament = filter(None, self._env("AMENT_PREFIX_PATH").split(os.pathsep))
        ros = filter(None, self._env("ROS_PACKAGE_PATH").split(os.pathsep))
        roots += [Path(p).absolute() / "share" for p in ament]
        roots += [Path(p).expanduser().absolute() for p in ros]
        return tuple(dict.fromkeys(roots))

    def resolve_uri(self, uri: str | Path, base_dir: str | Path | None = None) -> Path:
        """Resolve ``package://pkg/rel``, ``file:///abs`` or a plain (possibly relative) path.

        Relative plain paths are taken relative to ``base_dir`` (default: the current directory).
        The returned path is not checked for existence (callers report missing files with context).
        """
        text = str(uri)
        if text.startswith("package://"):
            rest = text[len("package://"):]
            pkg, _, rel = rest.partition("/")
            if not pkg:
                raise PackageNotFoundError(f"URI '{text}' names no package", package="")
            return self.find_package_share(pkg) / unquote(rel)
        if text.startswith("file://"):
            parsed = urlparse(text)
            return Path(unquote(parsed.netloc + parsed.path))
        path = Path(text).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        return path

    # ------------------------------------------------------------------ sources
    def _env(self, key: str) -> str:
        env = os.environ if self._environ is None else self._environ
        return env.get(key, "")

    def _find_explicit(self, name: str, searched: list[str]) -> Path | None:
        if name in self._explicit:
            path = self._explicit[name]
            searched.append(f"explicit {path}")
            if path.is_dir():
                return path
        return None

    def _find_extra(self, name: str, searched: list[str]) -> Path | None:
        for base in self._extra:
            searched.append(f"extra path {base}")
            if _is_package_root(base, name):
                return base
            if (base / name).is_dir():
                return base / name
        return None

    def _find_entry_point(self, name: str, searched: list[str]) -> Path | None:
        if not self._use_entry_points:
            return None
        eps = [ep for ep in self._description_entry_points() if ep.name == name]
        if not eps:
            searched.append(f"entry points '{ENTRY_POINT_GROUP}'")
        for ep in eps:
            searched.append(f"entry point {ep.name} = {ep.value}")
            root = _python_package_dir(ep.value)
            if root is not None:
                return root
        return None

    def _find_ament(self, name: str, searched: list[str]) -> Path | None:
        for prefix in filter(None, self._env("AMENT_PREFIX_PATH").split(os.pathsep)):
            share = Path(prefix) / "share" / name
            searched.append(f"AMENT_PREFIX_PATH {share}")
            if share.is_dir():
                return share
        return None

    def _find_ros_package_path(self, name: str, searched: list[str]) -> Path | None:
        for entry in filter(None, self._env("ROS_PACKAGE_PATH").split(os.pathsep)):
            base = Path(entry)
            searched.append(f"ROS_PACKAGE_PATH {base}")
            found = _walk_for_package(base, name)
            if found is not None:
                return found
        return None


def _python_package_dir(module: str) -> Path | None:
    """Directory of an importable package, without importing it (importing may be slow or fail: a
    package's ``__init__`` may read user files). The top-level package is found by its spec, which
    does not run it; the rest of the dotted name is followed through the folders."""
    parts = module.split(":", 1)[0].strip().split(".")
    try:
        spec = importlib.util.find_spec(parts[0])
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return Path(spec.origin).parent if spec is not None and spec.origin and len(parts) == 1 else None
    for base in spec.submodule_search_locations:
        path = Path(base).joinpath(*parts[1:])
        if path.is_dir():
            return path
    return None


_PKG_NAME = re.compile(r"<name>\s*([^<\s]+)\s*</name>")


def _is_package_root(path: Path, name: str) -> bool:
    manifest = path / "package.xml"
    if manifest.is_file():
        match = _PKG_NAME.search(manifest.read_text(errors="replace"))
        if match:
            return match.group(1) == name
    return path.name == name and path.is_dir()


def _walk_for_package(base: Path, name: str, depth: int = 0) -> Path | None:
    if not base.is_dir():
        return None
    if _is_package_root(base, name):
        return base
    if depth >= _MAX_WALK_DEPTH or (base / "package.xml").is_file():
        return None  # do not descend into other packages (rospack does the same)
    try:
        children = sorted(p for p in base.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:
        return None
    for child in children:
        found = _walk_for_package(child, name, depth + 1)
        if found is not None:
            return found
    return None


@functools.lru_cache(maxsize=1)
def default_index() -> PackageIndex:
    """A shared index with no extra paths (it reads the environment at each lookup)."""
    return PackageIndex()
