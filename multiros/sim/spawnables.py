"""What ``GetSpawnables`` lists: the robot and object descriptions of the installed description packages.

A description package registers itself in the ``uniros.description_packages`` entry-point group
(see :mod:`multiros.sim.packages`); its ``urdf/*.urdf``, ``urdf/*.urdf.xacro`` and ``mjcf/*.xml``
files are spawnable as ``package://<package>/<relative path>``. Include-only files (``*.xacro``
that are not ``*.urdf.xacro``) are not listed.
"""

from __future__ import annotations

from importlib.metadata import entry_points

from multiros.sim.packages import ENTRY_POINT_GROUP, PackageIndex

__all__ = ["list_spawnables"]

_PATTERNS = ("urdf/*.urdf", "urdf/*.urdf.xacro", "mjcf/*.xml")
_MAX = 1000


def list_spawnables(index: PackageIndex) -> list[tuple[str, str]]:
    """``(uri, description)`` of every spawnable file of the registered description packages."""
    out: list[tuple[str, str]] = []
    for name in sorted({ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)}):
        try:
            root = index.find_package_share(name)
        except LookupError:
            continue
        for pattern in _PATTERNS:
            for path in sorted(root.glob(pattern)):
                if path.is_file():
                    rel = path.relative_to(root).as_posix()
                    out.append((f"package://{name}/{rel}", f"{path.name} from {name}"))
                if len(out) >= _MAX:
                    return out
    return out
