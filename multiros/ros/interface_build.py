"""``uniros-build-interfaces``: build ROS 2 interface packages for rclpy from the definitions uniros ships.

rclpy can only use a type whose generated package is installed. A ROS install gets the standard
ones from its distribution (``apt install ros-jazzy-simulation-interfaces``); uniros' own
``uniros_interfaces`` is in no distribution, and a venv with the PyPI ``ros-<distro>-*`` wheels has
no control_msgs, controller_manager_msgs, simulation_interfaces or tf2_msgs. This command builds
them with rosidl's own generators (CMake, ``rosidl_generate_interfaces``), so the result is what
colcon would build from the same definitions, and installs them into a prefix: by default this
venv (``sys.prefix``), where rclpy then finds them with nothing to set.

It needs CMake, a C/C++ compiler, Python headers, and the generator wheels (listed by
``--print-requirements``; a ROS install has them). A whole package takes minutes (control_msgs:
about 4.5 min on 2 cores); ``--only-used`` builds just the types uniros uses (the package is then
partial). ``--python-only`` leaves out rosidl's C++ generators (headers and type supports for rclcpp),
which are a third of the build and which rclpy never loads. Packages without dependencies on each other
build in parallel (``--jobs``).

Done by hand instead of with colcon: the released definition folders carry no ``CMakeLists.txt``
(an interface-only one is written here), and the PyPI wheels' exported CMake files name the
wheel builder's Python and numpy include folders, which are rewritten to this Python's first.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

__all__ = ["CPP_GENERATORS", "UNIROS_PACKAGES", "USED_TYPES", "build_packages", "generator_requirements", "main"]

#: The interface packages uniros' nodes and envs use that a plain rclpy install may lack, in build order.
UNIROS_PACKAGES: tuple[str, ...] = (
    "simulation_interfaces", "control_msgs", "controller_manager_msgs", "tf2_msgs", "uniros_interfaces",
)
#: ``--only-used``: the types of those packages uniros uses (their nested types come along).
#: tests/ros/test_interface_build.py checks this against the simulation node's and envs' services.
USED_TYPES: dict[str, tuple[str, ...]] = {
    "simulation_interfaces": (
        "srv/GetSimulatorFeatures", "srv/GetSpawnables", "srv/SpawnEntity", "srv/DeleteEntity", "srv/GetEntities",
        "srv/GetEntityState", "srv/SetEntityState", "srv/GetEntitiesStates", "srv/ResetSimulation",
        "srv/GetSimulationState", "srv/SetSimulationState", "srv/StepSimulation", "action/SimulateSteps",
        "msg/EntityState", "msg/Result", "msg/SimulationState", "msg/SimulatorFeatures", "msg/Spawnable",
    ),
    "control_msgs": ("action/FollowJointTrajectory",),
    "controller_manager_msgs": (
        "srv/ListControllers", "srv/SwitchController", "srv/LoadController", "srv/ConfigureController",
        "srv/UnloadController", "msg/ControllerState", "srv/ListHardwareInterfaces", "srv/ListHardwareComponents",
        "srv/ListControllerTypes", "srv/SetHardwareComponentState", "msg/HardwareComponentState",
        "msg/HardwareInterface",
    ),
}
#: ``--python-only``: the generators rclpy does not need. rosidl runs every generator registered for the
#: ``rosidl_generate_idl_interfaces`` extension point; finding any message package registers the C++ ones
#: too, so they are filtered out of that list just before ``rosidl_generate_interfaces``.
CPP_GENERATORS: tuple[str, ...] = (
    "rosidl_generator_cpp", "rosidl_typesupport_cpp", "rosidl_typesupport_fastrtps_cpp",
    "rosidl_typesupport_introspection_cpp",
)
_EXT = {"msg": ".msg", "srv": ".srv", "action": ".action"}
_PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64", "string", "wstring", "time", "duration",
})


def generator_requirements(distro: str) -> list[str]:
    """The pip requirements of rosidl's generators for ``distro`` (beyond ``ros-<distro>-rclpy``)."""
    names = ["ament-cmake", "ament-package", "ament-cmake-include-directories", "ament-cmake-ros",
             "rosidl-default-generators", "rosidl-core-generators", "ament-cmake-gmock", "ament-cmake-gtest",
             "ament-cmake-pytest"]
    names.append("python-cmake-module" if distro in ("humble", "jazzy") else "ament-cmake-ros-core")
    return [f"ros-{distro}-{n}" for n in names] + ["catkin_pkg"]


def _definition_dir(package: str, distro: str) -> Path:
    from multiros.ros.interfaces.registry import distro_roots

    for root in distro_roots(distro):
        if (root / package / "package.xml").is_file():
            return root / package
    raise SystemExit(f"uniros ships no definitions of '{package}' for {distro}")


def _dependencies(package_dir: Path, known: Iterable[str]) -> list[str]:
    tree = ET.parse(package_dir / "package.xml")
    deps = [e.text.strip() for tag in ("depend", "build_depend") for e in tree.iter(tag) if e.text]
    known = set(known)
    return [d for d in dict.fromkeys(deps) if d in known]


def _referenced(path: Path, package: str) -> set[str]:
    """``kind/Name`` of the same-package types a definition file names (messages only)."""
    out = set()
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or line == "---" or "=" in line.split()[0]:
            continue
        base = re.split(r"[\[<]", line.split()[0], maxsplit=1)[0]
        if base in _PRIMITIVES:
            continue
        pkg, _, name = base.rpartition("/")
        if pkg in ("", package):
            out.add(f"msg/{name}")
    return out


def _selected_files(package_dir: Path, package: str, types: Sequence[str] | None) -> list[str]:
    every = sorted(str(p.relative_to(package_dir)) for kind in _EXT
                   for p in (package_dir / kind).glob(f"*{_EXT[kind]}"))
    if not types:
        return every
    todo, seen = list(types), set()
    while todo:
        item = todo.pop()
        if item in seen:
            continue
        seen.add(item)
        kind, name = item.split("/")
        path = package_dir / kind / f"{name}{_EXT[kind]}"
        if not path.is_file():
            raise SystemExit(f"{package} has no {item} in uniros' definitions")
        todo.extend(_referenced(path, package) - seen)
    return sorted(f"{item.split('/')[0]}/{item.split('/')[1]}{_EXT[item.split('/')[0]]}" for item in seen)


def _cmakelists(package: str, files: Sequence[str], deps: Sequence[str], *, python_only: bool = False) -> str:
    find = "".join(f"find_package({d} REQUIRED)\n" for d in deps)
    listed = "\n".join(f'  "{f}"' for f in files)
    dep_clause = f"\n  DEPENDENCIES {' '.join(deps)}" if deps else ""
    skip = ""
    if python_only:
        pattern = "|".join(CPP_GENERATORS)
        skip = (f'list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX "^({pattern}):")\n')
    return (f"cmake_minimum_required(VERSION 3.8)\nproject({package})\n"
            "find_package(ament_cmake REQUIRED)\nfind_package(rosidl_default_generators REQUIRED)\n"
            f"{find}{skip}rosidl_generate_interfaces(${{PROJECT_NAME}}\n{listed}{dep_clause}\n)\n"
            "ament_export_dependencies(rosidl_default_runtime)\nament_package()\n")


def fix_exported_paths(prefix: Path) -> int:
    """Point the wheels' exported CMake files at this Python's include folders; returns files changed."""
    include = sysconfig.get_paths()["include"]
    try:
        import numpy

        numpy_include = numpy.get_include()
    except ImportError:  # pragma: no cover - numpy comes with rclpy
        numpy_include = None
    changed = 0
    for path in (prefix / "share").glob("*/cmake/*.cmake"):
        text = path.read_text(errors="replace")
        if "/opt/python/" not in text:
            continue
        new = re.sub(r"/opt/python/cp3\d+-cp3\d+/include/python3\.\d+", include, text)
        if numpy_include:
            new = re.sub(r"/opt/python/cp3\d+-cp3\d+/lib/python3\.\d+/site-packages/numpy/(_core|core)/include",
                         numpy_include, new)
        if new != text:
            path.write_text(new)
            changed += 1
    return changed


def _build_one(package: str, distro: str, prefix: Path, work: Path, types: Sequence[str] | None,
               known: Iterable[str], log: Path, python_only: bool = False) -> float:
    start = time.monotonic()
    src_dir = _definition_dir(package, distro)
    stage = work / "src" / package
    if stage.exists():
        shutil.rmtree(stage)
    stage.mkdir(parents=True)
    files = _selected_files(src_dir, package, types)
    shutil.copy(src_dir / "package.xml", stage / "package.xml")
    for rel in files:
        (stage / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(src_dir / rel, stage / rel)
    deps = _dependencies(src_dir, known)
    (stage / "CMakeLists.txt").write_text(_cmakelists(package, files, deps, python_only=python_only))
    build = work / "build" / package
    if build.exists():
        shutil.rmtree(build)
    generator = ["-G", "Ninja"] if shutil.which("ninja") else []
    steps = [
        ["cmake", "-S", str(stage), "-B", str(build), *generator, f"-DCMAKE_INSTALL_PREFIX={prefix}",
         f"-DCMAKE_PREFIX_PATH={prefix}", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF",
         "-DCMAKE_BUILD_TYPE=Release"],
        ["cmake", "--build", str(build)],
        ["cmake", "--install", str(build)],
    ]
    env = dict(os.environ)
    env.setdefault("AMENT_PREFIX_PATH", str(prefix))
    with log.open("a") as out:
        for cmd in steps:
            out.write(f"$ {' '.join(cmd)}\n")
            out.flush()
            done = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, stdin=subprocess.DEVNULL)
            if done.returncode != 0:
                raise SystemExit(f"building {package} failed at `{' '.join(cmd[:3])} ...` (exit {done.returncode}); "
                                 f"see {log}")
    return time.monotonic() - start


def build_packages(packages: Sequence[str], *, distro: str, prefix: Path, only_used: bool = False, jobs: int = 2,
                   work: Path | None = None, echo: bool = True, python_only: bool = False) -> dict[str, float]:
    """Build ``packages`` (dependencies first, independent ones in parallel) into ``prefix``.

    ``only_used``: only the types uniros uses; ``python_only``: only what rclpy loads (no C++ generators).

    Returns each package's build seconds. Raises ``SystemExit`` with a one-line reason on failure.
    """
    from multiros.ros.interfaces.registry import registry_for

    known = registry_for(distro).packages()
    for tool in ("cmake",):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} is not installed: it is needed to build interface packages (apt install cmake "
                             "g++ python3-dev ninja-build)")
    if not (prefix / "share" / "rosidl_default_generators").is_dir():
        raise SystemExit(f"rosidl's generators are not installed in {prefix}: pip install "
                         f"{' '.join(generator_requirements(distro))} (or use a sourced ROS install's prefix)")
    fix_exported_paths(prefix)
    work = work or Path(tempfile.mkdtemp(prefix="uniros-interfaces-"))
    work.mkdir(parents=True, exist_ok=True)
    wanted = list(dict.fromkeys(packages))
    deps = {p: [d for d in _dependencies(_definition_dir(p, distro), known) if d in wanted] for p in wanted}
    times: dict[str, float] = {}
    remaining = list(wanted)
    while remaining:
        ready = [p for p in remaining if all(d in times for d in deps[p])]
        if not ready:
            raise SystemExit(f"circular dependencies among {remaining}")
        if echo:
            print(f"building {', '.join(ready)} ({distro}) into {prefix} ...", flush=True)
        with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            futures = {p: pool.submit(_build_one, p, distro, prefix, work,
                                      USED_TYPES.get(p) if only_used else None, known, work / f"{p}.log", python_only)
                       for p in ready}
            for p, fut in futures.items():
                times[p] = fut.result()
                if echo:
                    print(f"  {p}: {times[p]:.0f} s", flush=True)
        remaining = [p for p in remaining if p not in times]
    return times


def _missing(packages: Sequence[str]) -> list[str]:
    import importlib.util

    return [p for p in packages if importlib.util.find_spec(p) is None]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="uniros-build-interfaces",
        description="Build ROS 2 interface packages for rclpy from the definitions uniros ships "
                    "(default: those uniros uses that this Python cannot import).")
    parser.add_argument("packages", nargs="*", help=f"packages to build (default: the missing ones of "
                                                     f"{', '.join(UNIROS_PACKAGES)})")
    parser.add_argument("--distro", default=(os.environ.get("ROS_DISTRO") or "jazzy"),
                        help="whose definitions (default: $ROS_DISTRO, else jazzy)")
    parser.add_argument("--prefix", default=sys.prefix, help="install prefix (default: this Python's, %(default)s)")
    parser.add_argument("--only-used", action="store_true", help="only the types uniros uses (a partial package)")
    parser.add_argument("--python-only", action="store_true",
                        help="only what rclpy loads: C type supports and Python bindings, no C++ (rclcpp cannot use "
                             "the result)")
    parser.add_argument("--jobs", type=int, default=2, help="packages built at once (default: %(default)s)")
    parser.add_argument("--work-dir", help="build folder (default: a new temporary one)")
    parser.add_argument("--print-requirements", action="store_true",
                        help="print the pip requirements of the generators and exit")
    opts = parser.parse_args(argv)
    if opts.print_requirements:
        print(" ".join(generator_requirements(opts.distro)))
        return 0
    packages = opts.packages or _missing(UNIROS_PACKAGES)
    unknown = [p for p in packages if p not in UNIROS_PACKAGES and not p.replace("_", "").isalnum()]
    if unknown:
        parser.error(f"not a package name: {unknown}")
    if not packages:
        print("every interface package uniros uses is importable already; nothing to build")
        return 0
    try:
        times = build_packages(packages, distro=opts.distro, prefix=Path(opts.prefix).resolve(),
                               only_used=opts.only_used, jobs=opts.jobs, python_only=opts.python_only,
                               work=Path(opts.work_dir) if opts.work_dir else None)
    except SystemExit as exc:
        if isinstance(exc.code, str):
            print(f"uniros-build-interfaces: {exc.code}", file=sys.stderr)
            return 2
        raise
    print(f"built {', '.join(times)} in {opts.prefix}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
