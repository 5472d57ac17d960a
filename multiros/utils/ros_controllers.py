"""Load, configure, switch, reset and unload a robot's controllers through its controller manager.

Talks to the standard ros2_control services under ``<robot ns>/controller_manager/``
(``list_controllers``, ``load_controller``, ``configure_controller``, ``switch_controller``,
``unload_controller``; ``controller_manager_msgs/srv/*``), which the MuJoCo simulation node serves
for every robot (and a real ros2_control robot serves too).

:class:`ControllerManagerClient` is the typed interface; the module functions keep the MultiROS
(``load_ros_controller``, ``switch_controllers``, ``reset_controllers``, ...) and FRobs_RL
(``load_controller_srv``, ...) names, with the node as an explicit first argument. A refused
request raises :class:`ControllerManagerError` (naming the controllers and the namespace) instead
of returning ``False``; a timeout is retried at most ``max_retries`` times, then raises.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from multiros.ros.controller_manager import (
    BEST_EFFORT,
    STRICT,
    ControllerInfo,
    ControllerManagerClient,
    ControllerManagerError,
)


# -- MultiROS / FRobs_RL function names -------------------------------------------------------------
def _run(node: Any, ns: str | None, max_retries: int, timeout_sec: float, fn: str, *args: Any, **kw: Any) -> Any:
    cm = ControllerManagerClient(node, ns, timeout_sec=timeout_sec, max_retries=max_retries)
    try:
        return getattr(cm, fn)(*args, **kw)
    finally:
        cm.close()


def list_controllers(node: Any, ns: str | None = None, *, timeout_sec: float = 5.0) -> list[ControllerInfo]:
    """Every controller of the robot in ``ns`` with its state."""
    return _run(node, ns, 1, timeout_sec, "list_controllers")


def list_loaded_controllers(node: Any, ns: str | None = None, max_retries: int = 5, *,
                            timeout_sec: float = 5.0) -> list[str]:
    """MultiROS: names of the loaded controllers."""
    return [c.name for c in _run(node, ns, max_retries, timeout_sec, "list_controllers")]


def load_ros_controller(node: Any, controller_name: str, ns: str | None = None, max_retries: int = 5, *,
                        timeout_sec: float = 5.0) -> bool:
    """Load one controller."""
    return _run(node, ns, max_retries, timeout_sec, "load", controller_name)


def load_controller_list(node: Any, controller_list: Sequence[str], ns: str | None = None, max_retries: int = 5,
                         *, timeout_sec: float = 5.0) -> bool:
    """Load several controllers."""
    return _run(node, ns, max_retries, timeout_sec, "load", controller_list)


def unload_ros_controller(node: Any, controller_name: str, ns: str | None = None, max_retries: int = 5, *,
                          timeout_sec: float = 5.0) -> bool:
    """Unload one (inactive) controller."""
    return _run(node, ns, max_retries, timeout_sec, "unload", controller_name)


def unload_controller_list(node: Any, controller_list: Sequence[str], ns: str | None = None, max_retries: int = 5,
                           *, timeout_sec: float = 5.0) -> bool:
    """Unload several (inactive) controllers."""
    return _run(node, ns, max_retries, timeout_sec, "unload", controller_list)


def switch_controllers(node: Any, controllers_on: Sequence[str], controllers_off: Sequence[str],
                       ns: str | None = None, strictness: int = BEST_EFFORT, start_asap: bool = False,
                       timeout: float = 0.0, max_retries: int = 5, *, timeout_sec: float = 5.0) -> bool:
    """Activate ``controllers_on`` and deactivate ``controllers_off`` (MultiROS argument order)."""
    return _run(node, ns, max_retries, timeout_sec, "switch", controllers_on, controllers_off,
                strictness=strictness, activate_asap=start_asap, timeout=timeout)


def start_controllers(node: Any, controllers_on: Sequence[str], ns: str | None = None, max_retries: int = 5, *,
                      timeout_sec: float = 5.0) -> bool:
    """Activate controllers (configuring unconfigured ones first)."""
    return _run(node, ns, max_retries, timeout_sec, "activate", controllers_on)


def stop_controllers(node: Any, controllers_off: Sequence[str], ns: str | None = None, max_retries: int = 5, *,
                     timeout_sec: float = 5.0) -> bool:
    """Deactivate controllers."""
    return _run(node, ns, max_retries, timeout_sec, "deactivate", controllers_off)


def reset_controllers(node: Any, controllers_reset: Sequence[str] | None = None, ns: str | None = None,
                      max_retries: int = 5, *, timeout_sec: float = 5.0) -> bool:
    """Stop then start controllers (default: all active ones)."""
    return _run(node, ns, max_retries, timeout_sec, "reset", controllers_reset)


def spawn_controllers(node: Any, controller_list: Sequence[str], ns: str | None = None, max_retries: int = 5, *,
                      timeout_sec: float = 5.0) -> bool:
    """Load, configure and activate controllers."""
    return _run(node, ns, max_retries, timeout_sec, "spawn", controller_list)


def unspawn_controllers(node: Any, controller_list: Sequence[str], ns: str | None = None, max_retries: int = 5, *,
                        timeout_sec: float = 5.0) -> bool:
    """Deactivate and unload controllers."""
    return _run(node, ns, max_retries, timeout_sec, "unspawn", controller_list)


# FRobs_RL names
load_controller_srv = load_ros_controller
load_controller_list_srv = load_controller_list
unload_controller_srv = unload_ros_controller
unload_controller_list_srv = unload_controller_list
switch_controllers_srv = switch_controllers
start_controllers_srv = start_controllers
stop_controllers_srv = stop_controllers
reset_controllers_srv = reset_controllers
spawn_controllers_srv = spawn_controllers
kill_controllers_srv = unspawn_controllers

__all__ = [
    "BEST_EFFORT", "STRICT", "ControllerInfo", "ControllerManagerClient", "ControllerManagerError",
    "list_controllers", "list_loaded_controllers", "load_ros_controller", "load_controller_list",
    "unload_ros_controller", "unload_controller_list", "switch_controllers", "start_controllers",
    "stop_controllers", "reset_controllers", "spawn_controllers", "unspawn_controllers",
    "load_controller_srv", "load_controller_list_srv", "unload_controller_srv", "unload_controller_list_srv",
    "switch_controllers_srv", "start_controllers_srv", "stop_controllers_srv", "reset_controllers_srv",
    "spawn_controllers_srv", "kill_controllers_srv",
]
