"""Run xacro on a file or string, with ``$(find pkg)`` answered from a :class:`PackageIndex`.

``$(find pkg)`` in xacro: xacro imports ``ament_index_python.packages.get_package_share_directory``
lazily inside its ``find`` handler. During our call we put a tiny shim module under that name in
``sys.modules`` that answers from our :class:`PackageIndex`, and remove it afterwards (a real
``ament_index_python`` is restored if one was loaded). A lock serialises xacro calls because xacro
keeps its substitution arguments and file stack in module globals.

Files are expanded once: the URDF of a file, its arguments and this process's environment is kept
(:data:`CACHE_ENTRIES` of them, per package index) with the modification times and sizes of every
file xacro read, and handed out again while none of those files changed. An env's ``make`` runs
xacro on the same robot file each time; besides the time (tens of milliseconds), every xacro run
keeps some of the documents it parsed alive for good (about 8-18 KB for the RX200 with xacro
2.1 on Python 3.11, measured with ``tracemalloc``), so a process that makes and closes envs in a
loop grew without end. xacro's own list of every file it ever included is trimmed after each run
for the same reason.

xacro evaluates Python in ``${...}``: run it only on trusted input (files in the package roots, the
user's own strings). :mod:`multiros.sim.description` refuses xacro text from requests.
"""

from __future__ import annotations

import os
import sys
import threading
import types
import weakref
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path

from multiros.sim.errors import DescriptionError, PackageNotFoundError
from multiros.sim.packages import PackageIndex, default_index

__all__ = ["CACHE_ENTRIES", "xacro_to_urdf"]

_xacro_lock = threading.Lock()
CACHE_ENTRIES = 16  # expanded files kept per package index
_CACHE_CHARS = 16_000_000  # most characters of URDF kept per package index
_FileStamp = tuple[str, int, int]  # path, st_mtime_ns, st_size
_cache: weakref.WeakKeyDictionary[PackageIndex, OrderedDict[tuple, tuple[str, tuple[_FileStamp, ...]]]] = (
    weakref.WeakKeyDictionary())


def _stamps(paths: list[str]) -> tuple[_FileStamp, ...] | None:
    try:
        return tuple((p, st.st_mtime_ns, st.st_size) for p in paths for st in (os.stat(p),))
    except OSError:
        return None


def _cached(index: PackageIndex, key: tuple) -> str | None:
    entries = _cache.get(index)
    entry = entries.get(key) if entries is not None else None
    if entry is None:
        return None
    text, stamps = entry
    if _stamps([p for p, _, _ in stamps]) != stamps:
        del entries[key]
        return None
    entries.move_to_end(key)
    return text


def _remember(index: PackageIndex, key: tuple, text: str, files: list[str]) -> None:
    stamps = _stamps(files)
    if stamps is None:
        return
    entries = _cache.setdefault(index, OrderedDict())
    entries[key] = (text, stamps)
    while len(entries) > CACHE_ENTRIES or sum(len(t) for t, _ in entries.values()) > _CACHE_CHARS:
        entries.popitem(last=False)


def _ament_shim(index: PackageIndex) -> tuple[types.ModuleType, types.ModuleType]:
    top = types.ModuleType("ament_index_python")
    pkgs = types.ModuleType("ament_index_python.packages")

    def get_package_share_directory(package_name: str, print_warning: bool = True) -> str:
        return str(index.find_package_share(package_name))

    pkgs.get_package_share_directory = get_package_share_directory
    pkgs.PackageNotFoundError = PackageNotFoundError
    top.packages = pkgs
    top.get_package_share_directory = get_package_share_directory
    return top, pkgs


def xacro_to_urdf(source: str | Path, args: Mapping[str, str] | None = None, *,
                  index: PackageIndex | None = None, base_dir: str | Path | None = None) -> str:
    """Run xacro on a file path or an XML string and return the URDF text.

    Args:
        source: a path to a ``.xacro``/``.urdf`` file, or the XML text itself (starts with ``<``).
        args: ``$(arg name)`` values.
        index: package index for ``$(find pkg)`` (default index otherwise).
        base_dir: directory for relative ``xacro:include`` in a string (default: current directory).

    Raises:
        DescriptionError: xacro failed (message names the file and xacro's reason).
    """
    import xacro

    index = index or default_index()
    mappings = {str(k): str(v) for k, v in (args or {}).items()}
    is_text = isinstance(source, str) and source.lstrip().startswith("<")
    name = "<string>" if is_text else str(source)
    if not is_text and not Path(source).is_file():
        raise DescriptionError(f"xacro file '{source}' not found", source=name)
    key = None if is_text else (str(Path(source).resolve()), tuple(sorted(mappings.items())),
                                 hash(frozenset(os.environ.items())))  # $(env ...) and $(optenv ...)
    top, pkgs = _ament_shim(index)
    with _xacro_lock:
        if key is not None and (text := _cached(index, key)) is not None:
            return text
        saved = {k: sys.modules.get(k) for k in ("ament_index_python", "ament_index_python.packages")}
        sys.modules["ament_index_python"], sys.modules["ament_index_python.packages"] = top, pkgs
        included = len(xacro.all_includes)
        try:
            if is_text:
                base = Path(base_dir) if base_dir is not None else Path.cwd()
                xacro.init_stacks(str(base / "__string__.xacro"))
                doc = xacro.parse(source)
                xacro.process_doc(doc, mappings=mappings)
                return doc.toprettyxml(indent="  ")
            doc = xacro.process_file(str(source), mappings=mappings)
            text = doc.toprettyxml(indent="  ")
            _remember(index, key, text, [key[0], *(str(f) for f in xacro.all_includes[included:])])
            return text
        except PackageNotFoundError as exc:
            raise DescriptionError(f"xacro {name}: {exc}", source=name, missing_assets=True) from exc
        except Exception as exc:  # xacro raises XacroException, ExpatError, NameError, KeyError, ...
            missing = _find_cause(exc, PackageNotFoundError)
            if missing is not None:
                raise DescriptionError(f"xacro {name}: {missing}", source=name, missing_assets=True) from exc
            detail = str(exc) or type(exc).__name__
            if isinstance(exc, KeyError):
                detail = f"undefined argument {exc}; pass it in xacro args"
            raise DescriptionError(f"xacro {name} failed: {detail}", source=name) from exc
        finally:
            for key, module in saved.items():
                if module is None:
                    sys.modules.pop(key, None)
                else:
                    sys.modules[key] = module
            xacro.init_stacks(None)
            del xacro.all_includes[included:]  # xacro appends every file it includes, for good


def _find_cause(exc: BaseException, kind: type) -> BaseException | None:
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, kind):
            return exc
        seen.add(id(exc))
        exc = getattr(exc, "exc", None) or exc.__cause__ or exc.__context__
    return None
