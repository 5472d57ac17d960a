"""Loading rclpy without letting it end the process.

``import rclpy`` loads librcl, whose start-up check calls ``exit(102)`` when ``RMW_IMPLEMENTATION``
names a middleware the install cannot load (measured with the PyPI wheels, whose librcl links
rmw_fastrtps_cpp directly: any other value ends the process at import, before Python can catch
anything). So when the variable is set, a child interpreter imports rclpy first, and a failure
becomes a :class:`~multiros.ros.exceptions.TransportError` that says what to do. Without the
variable nothing is probed: rcl then takes its default middleware, which always loads.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import threading
from typing import Any

from multiros.ros.exceptions import TransportError

__all__ = ["RMW_ENV", "rclpy_available", "check_rmw_implementation", "import_rclpy", "ros_distro_hint"]

RMW_ENV = "RMW_IMPLEMENTATION"
_PROBE_TIMEOUT_SEC = 60.0
_checked: dict[tuple[str, str], str | None] = {}  # (RMW_IMPLEMENTATION, LD_LIBRARY_PATH) -> error or None
_lock = threading.Lock()


def rclpy_available() -> bool:
    """Whether rclpy can be found (its spec; nothing is loaded, so this never ends the process)."""
    try:
        spec = importlib.util.find_spec("rclpy")
    except (ImportError, ValueError):
        return False
    return spec is not None and spec.origin is not None  # a folder named rclpy is no rclpy


def ros_distro_hint() -> str:
    """The distribution named by ``ROS_DISTRO``, else ``jazzy`` (for install hints)."""
    return (os.environ.get("ROS_DISTRO") or "jazzy").strip().lower() or "jazzy"


def check_rmw_implementation() -> None:
    """Refuse an ``RMW_IMPLEMENTATION`` that rclpy cannot load, before this process loads rclpy.

    Raises:
        TransportError: the middleware cannot be loaded; the message quotes rcl's reason.
    """
    rmw = os.environ.get(RMW_ENV, "").strip()
    if not rmw or "rclpy" in sys.modules:
        return  # rcl's default, or rclpy already loaded: this process passed the check
    key = (rmw, os.environ.get("LD_LIBRARY_PATH", ""))
    with _lock:
        if key not in _checked:
            _checked[key] = _probe(rmw)
        error = _checked[key]
    if error is not None:
        raise TransportError(error)


def _probe(rmw: str) -> str | None:
    try:
        proc = subprocess.run(
            [sys.executable, "-c", "import rclpy"], stdin=subprocess.DEVNULL, capture_output=True, text=True,
            timeout=_PROBE_TIMEOUT_SEC, env=dict(os.environ),
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"could not check {RMW_ENV}={rmw!r} (importing rclpy in a child process failed: {exc})"
    if proc.returncode == 0:
        return None
    lines = [ln.strip() for ln in (proc.stderr or "").splitlines() if ln.strip()]
    reason = next((ln for ln in lines if "RMW implementation" in ln or "rmw" in ln.lower()), lines[-1] if lines else "")
    package = "ros-" + ros_distro_hint() + "-" + rmw.replace("_", "-")
    return (
        f"{RMW_ENV}={rmw!r} names a ROS 2 middleware that rclpy cannot load here (rcl exits with code "
        f"{proc.returncode}: {reason[:300]}): unset {RMW_ENV} to use rclpy's default middleware, or install "
        f"{rmw} ({package} in a ROS install; the PyPI rclpy wheels carry rmw_fastrtps_cpp only)"
    )


def import_rclpy() -> Any:
    """``rclpy``, after :func:`check_rmw_implementation`.

    Raises:
        TransportError: rclpy is not importable, or the middleware cannot be loaded.
    """
    distro = ros_distro_hint()
    if not rclpy_available():
        raise TransportError(
            "transport 'rclpy' needs rclpy, which is not importable in this Python: source your ROS 2 "
            f"installation first (`source /opt/ros/{distro}/setup.bash`), or in a venv `pip install "
            f"ros-{distro}-rclpy ros-{distro}-rmw-fastrtps-cpp` (see docs/ros2_system.md); or use transport='zenoh'"
        )
    check_rmw_implementation()
    try:
        import rclpy
        import rclpy.executors  # noqa: F401 - the transport's executor
        import rclpy.serialization  # noqa: F401 - message conversion
    except ImportError as exc:
        raise TransportError(
            f"rclpy was found but does not import ({exc}): a ROS install must be sourced "
            f"(`source /opt/ros/{distro}/setup.bash`) in the same shell, and its Python version must be this "
            f"one ({sys.version_info.major}.{sys.version_info.minor})"
        ) from exc
    return rclpy
