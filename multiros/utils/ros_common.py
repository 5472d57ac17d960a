"""Package paths, YAML parameters, robot descriptions and child processes, without a ROS install.

The MultiROS ``ros_common`` / FRobs_RL ``ros_params``/``ros_urdf``/``ros_node`` verbs, reshaped:

* packages resolve through :mod:`multiros.sim.packages` (entry points, ``AMENT_PREFIX_PATH``,
  ``ROS_PACKAGE_PATH``), not ``rospack``;
* ROS 2 has no global parameter server: :func:`ros_load_yaml` returns the YAML and, given a node,
  declares the values as that node's parameters; :func:`get_param` reads by name from a node or
  from the returned mapping (``"task/reward/scale"`` and ``"task.reward.scale"`` both work);
* xacro runs in-process (:func:`multiros.sim.description.xacro_to_urdf`);
* child processes start from an argv list (never a shell or an xterm), are tracked by PID, and are
  stopped by PID on request and at interpreter exit. There is deliberately no host-wide kill:
  :func:`ros_kill_all_processes` stops only the processes this module started.
"""

from __future__ import annotations

import atexit
import logging
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from multiros.ros.processes import stop_process as _stop_child
from multiros.sim.errors import PackageNotFoundError
from multiros.sim.packages import PackageIndex, default_index

_logger = logging.getLogger(__name__)
_MISSING: Any = object()


# -- packages ------------------------------------------------------------------------------------
def get_package_path(pkg: str, *, index: PackageIndex | None = None) -> Path:
    """The share directory (package root) of ROS package ``pkg``.

    Raises:
        PackageNotFoundError: not found; the message lists every place searched.
    """
    return (index or default_index()).find_package_share(pkg)


def check_package_exists(pkg: str, *, index: PackageIndex | None = None) -> bool:
    """Whether ROS package ``pkg`` can be found."""
    try:
        get_package_path(pkg, index=index)
    except PackageNotFoundError:
        return False
    return True


def _package_file(pkg: str, file: str, folders: Sequence[str], index: PackageIndex | None) -> Path:
    root = get_package_path(pkg, index=index)
    candidates = [root / file] + [root / folder.strip("/") / file for folder in folders]
    for path in candidates:
        if path.is_file():
            return path
    raise FileNotFoundError(
        f"file {file!r} not found in package {pkg!r}; looked at: {', '.join(str(c) for c in candidates)}"
    )


# -- YAML parameters -------------------------------------------------------------------------------
def ros_load_yaml(
    pkg: str | None = None,
    file: str | None = None,
    *,
    path: str | Path | None = None,
    ns: str = "/",
    node: Any = None,
    index: PackageIndex | None = None,
    pkg_name: str | None = None,
    file_name: str | None = None,
    file_abs_path: str | Path | None = None,
) -> dict[str, Any]:
    """Load a YAML file from a package (``<pkg>/<file>``, else ``<pkg>/config/<file>``) or a path.

    Args:
        pkg, file: package and file inside it (MultiROS: ``pkg_name``, ``file_name``).
        path: an explicit file path instead (MultiROS: ``file_abs_path``).
        ns: namespace the values go under when declared on ``node`` (``"/"``: none; ``"task"``:
            parameter ``task.key``).
        node: a ``multiros.ros.Node``; when given, every leaf value is declared (or set) as a
            parameter of it. A ROS 2 parameter file (``<node>: {ros__parameters: ...}``) gives
            the node the section(s) matching its name.
        index: package index (default: the shared one).

    Returns:
        The YAML content as loaded (a mapping).

    Raises:
        PackageNotFoundError, FileNotFoundError: the package or file does not exist.
        ValueError: the file is not a YAML mapping, or a value has no ROS parameter type.
    """
    pkg = pkg or pkg_name
    file = file or file_name
    path = path or file_abs_path
    if path is None:
        if not (pkg and file):
            raise ValueError("ros_load_yaml needs pkg= and file=, or path=")
        path = _package_file(pkg, file, ("config",), index)
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"YAML file '{path}' not found")
    data = yaml.safe_load(path.read_text())
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ValueError(f"YAML file '{path}' must contain a mapping at the top level, got {type(data).__name__}")
    if node is not None:
        set_params(node, _node_values(data, node, ns, path))
    return data


def _node_values(data: dict[str, Any], node: Any, ns: str, source: Path) -> dict[str, Any]:
    if any(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
        from multiros.ros.parameters import parameters_from_yaml

        return parameters_from_yaml(data, node.get_fully_qualified_name())
    prefix = _param_name(ns)
    flat: dict[str, Any] = {}
    _flatten(prefix, data, flat, source)
    return flat


def _flatten(prefix: str, tree: Mapping[str, Any], out: dict[str, Any], source: Path) -> None:
    for key, value in tree.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            _flatten(name, value, out, source)
            continue
        if isinstance(value, list):
            if any(isinstance(v, (Mapping, list)) for v in value):
                raise ValueError(f"{source}: '{name}' is a list of mappings or lists, which ROS parameters cannot hold")
            numbers = value and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            if numbers and any(isinstance(v, float) for v in value):
                value = [float(v) for v in value]  # ROS arrays are homogeneous: [0, 1.5] is a double array
        out[name] = value


def _param_name(name: str) -> str:
    return name.strip("/").replace("/", ".")


def set_params(node: Any, values: Mapping[str, Any]) -> None:
    """Declare (or set, when already declared) parameters ``name -> value`` on ``node``.

    Raises:
        ValueError: a value has no ROS parameter type, or the node rejected it.
    """
    from multiros.ros.parameters import Parameter

    for raw_name, value in values.items():
        name = _param_name(raw_name)
        try:
            if node.has_parameter(name):
                result = node.set_parameters([Parameter(name, value=value)])[0]
                if not result.successful:
                    raise ValueError(result.reason)
            else:
                node.declare_parameter(name, value)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"parameter {name!r} = {value!r} rejected by node {node.get_name()!r}: {exc}") from exc


def set_param(node: Any, name: str, value: Any) -> None:
    """Declare or set one parameter of ``node`` (``/`` separators become ``.``)."""
    set_params(node, {name: value})


def get_param(source: Any, name: str, default: Any = _MISSING) -> Any:
    """A parameter by name from a node, or a value from a (nested) mapping such as the YAML.

    ``name`` may use ``/`` or ``.`` separators; a leading ``/`` is ignored.

    Raises:
        KeyError: not there and no ``default`` given.
    """
    key = _param_name(name)
    if isinstance(source, Mapping):
        if key in source:
            return source[key]
        current: Any = source
        for part in key.split("."):
            if isinstance(current, Mapping) and part in current:
                current = current[part]
            else:
                if default is _MISSING:
                    raise KeyError(f"no value {name!r} in the mapping (top-level keys: {sorted(source)[:10]})")
                return default
        return current
    if source.has_parameter(key):
        return source.get_parameter(key).value
    if default is _MISSING:
        raise KeyError(f"node {source.get_name()!r} has no parameter {key!r}; load it with ros_load_yaml(..., node=)")
    return default


def has_param(source: Any, name: str) -> bool:
    """Whether :func:`get_param` would find ``name``."""
    absent = object()
    return get_param(source, name, absent) is not absent


# -- robot descriptions ----------------------------------------------------------------------------
def _looks_like_location(text: str) -> bool:
    return text.lstrip().startswith("<") or "/" in text or text.endswith((".urdf", ".xacro", ".xml"))


def load_urdf(
    source: str | Path | None = None,
    file_name: str | None = None,
    *,
    pkg_name: str | None = None,
    model_path: str | Path | None = None,
    folder: str = "urdf",
    xacro_args: Mapping[str, Any] | Sequence[str] | None = None,
    args_xacro: Mapping[str, Any] | Sequence[str] | None = None,
    node: Any = None,
    param_name: str = "robot_description",
    index: PackageIndex | None = None,
) -> str:
    """Run xacro on a robot description and return the URDF text.

    ``source`` is a package name (``load_urdf("rx200_description")``: its one ``*.urdf.xacro`` or
    ``*.urdf`` in ``urdf/``; name it with ``file_name`` when there are several), a path, a
    ``package://`` URI, or the XML text itself.

    Args:
        source: see above (MultiROS: ``model_path`` or ``pkg_name``).
        file_name: file inside the package's ``folder``.
        folder: folder of the package holding the description.
        xacro_args: ``{"name": "value"}`` or ``["name:=value"]`` (MultiROS: ``args_xacro``).
        node: when given, the URDF is also stored as its parameter ``param_name``.
        index: package index for ``package://`` and ``$(find ...)``.

    Raises:
        PackageNotFoundError, FileNotFoundError: the package or file is missing.
        ValueError: several candidate files and no ``file_name``; a malformed xacro argument.
        multiros.sim.errors.DescriptionError: xacro failed (the message says why).
    """
    from multiros.sim.description import xacro_to_urdf

    index = index or default_index()
    args = _xacro_args(xacro_args if xacro_args is not None else args_xacro)
    by_package = source is None and model_path is None and pkg_name is not None
    if source is None:
        source = model_path if model_path is not None else pkg_name
    if source is None:
        raise ValueError("load_urdf needs a package name, a path, a package:// URI or URDF text")
    text_source = str(source)
    if by_package or not _looks_like_location(text_source):
        location: str | Path = _description_file(text_source, file_name, folder, index)
    elif text_source.lstrip().startswith("<"):
        location = text_source
    else:
        location = index.resolve_uri(text_source)
        if not Path(location).is_file():
            raise FileNotFoundError(f"robot description '{source}' not found (resolved to {location})")
    if isinstance(location, Path) and not (location.suffix == ".xacro" or "xmlns:xacro" in location.read_text()):
        urdf = location.read_text()
    elif isinstance(location, str) and "xmlns:xacro" not in location:
        urdf = location
    else:
        urdf = xacro_to_urdf(location, args, index=index)
    if node is not None:
        set_param(node, param_name, urdf)
    return urdf


def _description_file(pkg: str, file_name: str | None, folder: str, index: PackageIndex) -> Path:
    if file_name is not None:
        return _package_file(pkg, file_name, (folder,), index)
    directory = get_package_path(pkg, index=index) / folder.strip("/")
    found = sorted(p for p in directory.glob("*") if p.name.endswith((".urdf.xacro", ".urdf")))
    if len(found) != 1:
        names = [p.name for p in found] or "none"
        raise ValueError(
            f"package {pkg!r} has {len(found)} descriptions in {directory} ({names}); pass file_name= to choose"
        )
    return found[0]


def _xacro_args(args: Mapping[str, Any] | Sequence[str] | None) -> dict[str, str]:
    if not args:
        return {}
    if isinstance(args, Mapping):
        return {str(k): str(v) for k, v in args.items()}
    out = {}
    for item in args:
        key, sep, value = str(item).partition(":=")
        if not sep:
            raise ValueError(f"xacro argument {item!r} must look like 'name:=value'")
        out[key] = value
    return out


# -- child processes -------------------------------------------------------------------------------
class _ProcessTable:
    """The processes this module started, by PID (atexit stops the survivors)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.procs: dict[int, subprocess.Popen] = {}

    def add(self, proc: subprocess.Popen) -> None:
        with self.lock:
            self.procs[proc.pid] = proc

    def pop(self, pid: int) -> subprocess.Popen | None:
        with self.lock:
            return self.procs.pop(pid, None)

    def pids(self) -> list[int]:
        with self.lock:
            return list(self.procs)


_table = _ProcessTable()


def start_node_process(
    argv: Sequence[str],
    *,
    env: Mapping[str, str] | None = None,
    cwd: str | Path | None = None,
    ready: Callable[[], bool] | None = None,
    timeout_sec: float = 10.0,
    stdout: Any = None,
    stderr: Any = None,
) -> subprocess.Popen:
    """Start a child process from ``argv`` (no shell) and track it by PID.

    Args:
        argv: program and arguments, e.g. ``[sys.executable, "-m", "multiros.sim.program"]``.
        env: full environment of the child (default: this process's).
        cwd: working directory.
        ready: optional readiness check, polled until it returns ``True`` (e.g. a service answers).
        timeout_sec: bound on the readiness wait.
        stdout, stderr: passed to ``subprocess.Popen``.

    Raises:
        TypeError: ``argv`` is a string (a shell command line); pass a list.
        RuntimeError: the child exited before it was ready.
        TimeoutError: not ready within ``timeout_sec`` (the child is stopped first).
    """
    if isinstance(argv, (str, bytes)):
        raise TypeError(f"argv must be a list of arguments, not a shell command line: {argv!r}")
    proc = subprocess.Popen(list(argv), env=dict(env) if env is not None else None, cwd=cwd,
                            stdin=subprocess.DEVNULL, stdout=stdout, stderr=stderr)
    _table.add(proc)
    if ready is None:
        return proc
    deadline = time.monotonic() + timeout_sec
    try:
        while not ready():
            if proc.poll() is not None:
                raise RuntimeError(f"process {argv[0]!r} (pid {proc.pid}) exited with code {proc.returncode} "
                                   "before it was ready")
            if time.monotonic() >= deadline:
                raise TimeoutError(f"process {argv[0]!r} (pid {proc.pid}) not ready within {timeout_sec:g} s")
            time.sleep(0.02)  # polling interval of the readiness check, not a settle delay
    except BaseException:
        stop_process(proc.pid)
        raise
    return proc


def start_python_node(module: str, *args: str, **kwargs: Any) -> subprocess.Popen:
    """``start_node_process([python, "-m", module, *args])`` (FRobs_RL: ``ros_node_from_pkg``)."""
    return start_node_process([sys.executable, "-m", module, *args], **kwargs)


def stop_process(pid: int | subprocess.Popen, timeout: float = 5.0) -> bool:
    """Stop a process started by :func:`start_node_process`: SIGINT, SIGTERM, then SIGKILL, by PID.

    Returns:
        ``True`` if it was running and is now stopped, ``False`` if it had already exited.

    Raises:
        ValueError: ``pid`` was not started by this module (it is never signalled).
    """
    pid = pid.pid if isinstance(pid, subprocess.Popen) else int(pid)
    proc = _table.pop(pid)
    if proc is None:
        raise ValueError(f"pid {pid} was not started by multiros.utils.ros_common; refusing to signal it")
    was_running = proc.poll() is None
    _stop_child(proc, timeout=timeout)
    return was_running


def running_processes() -> list[int]:
    """PIDs of the processes this module started and has not stopped yet."""
    return _table.pids()


def ros_kill_all_processes(timeout: float = 5.0) -> list[int]:
    """Stop every process this module started (and nothing else on the host).

    FRobs_RL's and MultiROS' functions of this name ran ``killall -9`` on ROS and Gazebo processes
    of every user; this one keeps the name so ported scripts run, but only touches its own children.

    Returns:
        The PIDs that were stopped.
    """
    stopped = []
    for pid in _table.pids():
        try:
            stop_process(pid, timeout=timeout)
            stopped.append(pid)
        except ValueError:  # stopped concurrently
            continue
    return stopped


kill_all_ros_and_gazebo = ros_kill_all_processes
ros_kill_all_nodes = ros_kill_all_processes


@atexit.register
def _stop_all_at_exit() -> None:
    ros_kill_all_processes(timeout=2.0)


__all__ = [
    "get_package_path", "check_package_exists", "ros_load_yaml", "set_params", "set_param", "get_param",
    "has_param", "load_urdf", "start_node_process", "start_python_node", "stop_process", "running_processes",
    "ros_kill_all_processes", "kill_all_ros_and_gazebo", "ros_kill_all_nodes",
]
