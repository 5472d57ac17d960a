"""An arm file's YAML: read within bounds and merged with the file it ``extends``.

:func:`read_arm_yaml` gives the plain data :func:`rl_environments.arm_file.parse_arm_file` checks: the
file read through :mod:`multiros.bounded_yaml` (size, depth and aliases bounded: a file a user names may be
hostile), and, where it says ``extends: <arm file>``, laid over that file (mappings key by key, anything
else replaced; at most four files deep, no file extending itself), the extended file's relative paths
made absolute against it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from multiros.excerpt import excerpt

__all__ = ["ArmFileError", "read_arm_yaml", "resolve_uri"]


class ArmFileError(ValueError):
    """An arm file that cannot be used: the message names the file, the key and the fix."""


def read_arm_yaml(source: Path) -> Any:
    """The YAML data of the arm file at ``source``, with the files it extends merged under it."""
    return _read_extended(source, ())


def resolve_uri(uri: str, base: Path) -> str:
    """A URI as the simulation node takes it: ``package://`` as is, a path made absolute against the file."""
    if "://" in uri and not uri.startswith("file://"):
        return uri
    text = uri[len("file://"):] if uri.startswith("file://") else uri
    path = Path(text).expanduser()
    return str(path if path.is_absolute() else (base / path).resolve())


_MAX_EXTENDS = 4  # files an arm file may extend, one through another
_PATH_KEYS = (("description", "uri"), ("description", "controllers"), ("scene", "table"), ("scene", "object"))


def _read_yaml(source: Path) -> Any:
    """The file's YAML within bounds (:mod:`multiros.bounded_yaml`: size, depth, aliases expanded)."""
    from multiros.bounded_yaml import YamlBoundsError, read_yaml_bounded

    if not source.is_file():
        raise ArmFileError(f"{source}: arm file not found")
    try:
        return read_yaml_bounded(source)
    except YamlBoundsError as exc:
        raise ArmFileError(f"{source}: {exc}") from None
    except OSError as exc:
        raise ArmFileError(f"{source}: cannot be read: {exc.strerror or type(exc).__name__}") from None


def _read_extended(source: Path, chain: tuple[Path, ...]) -> Any:
    """An arm file's YAML with the file it ``extends`` merged under it: its mappings key by key, anything
    else replaced (a variant of an arm: another name, a camera, xacro arguments). The extended file's
    relative paths stay relative to it."""
    data = _read_yaml(source)
    if not isinstance(data, dict) or "extends" not in data:
        return data
    ref = data.pop("extends")
    if not isinstance(ref, str) or not ref.strip():
        raise ArmFileError(excerpt(f"{source}: key 'extends' must name an arm file (a path relative to this one), "
                                   f"got {ref!r}"))
    base_path = (source.resolve().parent / Path(ref).expanduser()).resolve()
    if base_path in chain or base_path == source.resolve():
        raise ArmFileError(excerpt(f"{source}: key 'extends' {ref!r} extends itself (through "
                                   f"{[str(p) for p in chain]})"))
    if len(chain) >= _MAX_EXTENDS:
        raise ArmFileError(f"{source}: key 'extends': more than {_MAX_EXTENDS} arm files extend one another")
    base = _read_extended(base_path, (*chain, source.resolve()))
    if not isinstance(base, dict):
        raise ArmFileError(excerpt(f"{source}: key 'extends' {ref!r}: {base_path} is not an arm file (a YAML mapping)"))
    for section, key in _PATH_KEYS:  # the extended file's paths, made absolute against it
        part = base.get(section)
        if isinstance(part, dict) and isinstance(part.get(key), str):
            part[key] = resolve_uri(part[key], base_path.parent)
    return _merged(base, data)


def _merged(base: Any, over: Any) -> Any:
    """``over`` on ``base``: mappings merged key by key (recursively), anything else from ``over``."""
    if not isinstance(base, dict) or not isinstance(over, dict):
        return over
    out = dict(base)
    for key, value in over.items():
        out[key] = _merged(base.get(key), value)
    return out
