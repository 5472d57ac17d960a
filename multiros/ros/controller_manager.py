"""Client of one robot's controller manager (the standard ros2_control services): the ROS layer's
ros2_control client, used alike by the simulation envs and by the Real envs.

Talks to ``<robot ns>/controller_manager/{list_controllers, load_controller, configure_controller,
switch_controller, unload_controller}`` (``controller_manager_msgs/srv/*``), which the MuJoCo
simulation node serves for every robot and a real ros2_control robot serves too; the node also
serves ``list_hardware_interfaces``, ``list_hardware_components``, ``list_controller_types`` and
``set_hardware_component_state`` (:data:`CONTROLLER_SERVICES`), so ``ros2 control`` works against it. A refused request
raises :class:`ControllerManagerError` naming the controllers and the namespace; a timeout is
retried at most ``max_retries`` times, then raises. :mod:`multiros.utils.ros_controllers` adds the
MultiROS and FRobs_RL function names on top.
"""

from __future__ import annotations

import logging
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from multiros.ros.exceptions import ServiceCallError, ServiceTimeoutError
from multiros.ros.interfaces import get_message, get_service

_logger = logging.getLogger(__name__)
__all__ = ["BEST_EFFORT", "STRICT", "CONTROLLER_SERVICES", "ControllerInfo", "ControllerManagerClient",
           "ControllerManagerError", "destroy_clients"]

BEST_EFFORT, STRICT = 1, 2

# Per robot, under ``<robot namespace>/controller_manager/<name>``.
CONTROLLER_SERVICES: dict[str, str] = {
    "list_controllers": "controller_manager_msgs/srv/ListControllers",
    "switch_controller": "controller_manager_msgs/srv/SwitchController",
    "load_controller": "controller_manager_msgs/srv/LoadController",
    "configure_controller": "controller_manager_msgs/srv/ConfigureController",
    "unload_controller": "controller_manager_msgs/srv/UnloadController",
    "list_hardware_interfaces": "controller_manager_msgs/srv/ListHardwareInterfaces",
    "list_hardware_components": "controller_manager_msgs/srv/ListHardwareComponents",
    "list_controller_types": "controller_manager_msgs/srv/ListControllerTypes",
    "set_hardware_component_state": "controller_manager_msgs/srv/SetHardwareComponentState",
}
Duration = get_message("builtin_interfaces/msg/Duration")


class ControllerManagerError(RuntimeError):
    """The controller manager refused a request or did not answer in time."""


def destroy_clients(node: Any, clients: dict[Any, Any]) -> None:
    """Destroy ``clients`` (a dict of service clients of ``node``) and empty it; a node already gone is fine."""
    for client in clients.values():
        try:
            node.destroy_client(client)
        except Exception:  # the node may already be gone
            _logger.debug("destroy_client failed", exc_info=True)
    clients.clear()


@dataclass(frozen=True)
class ControllerInfo:
    """One controller as ``list_controllers`` reports it (``state``: unconfigured, inactive, active)."""

    name: str
    state: str
    type: str
    claimed_interfaces: tuple[str, ...] = ()


def _node_of(node: Any) -> Any:
    if hasattr(node, "create_client"):
        return node
    inner = getattr(node, "node", None)
    if inner is not None and hasattr(inner, "create_client"):
        return inner
    raise TypeError(f"expected a multiros.ros Node (or an env/connection with .node), got {type(node).__name__}")


def _names(controllers: str | Sequence[str]) -> list[str]:
    return [controllers] if isinstance(controllers, str) else list(controllers)


class ControllerManagerClient:
    """Client of one controller manager.

    Args:
        node: the ``multiros.ros.Node`` that owns the service clients (or an env/connection
            exposing one as ``.node``).
        ns: the robot's namespace (``"/rx200"``); ``None`` or ``"/"`` for the root namespace.
        timeout_sec: bound on each service call.
        max_retries: how many times a call that timed out is tried in all.
    """

    def __init__(self, node: Any, ns: str | None = None, *, timeout_sec: float = 5.0, max_retries: int = 1) -> None:
        self._node = _node_of(node)
        self.ns = "/" + (ns or "").strip("/") if (ns or "").strip("/") else ""
        self.timeout_sec = float(timeout_sec)
        self.max_retries = max(1, int(max_retries))
        self._types = {k: get_service(v) for k, v in CONTROLLER_SERVICES.items()}
        self._clients: dict[str, Any] = {}

    def service_name(self, name: str) -> str:
        """Fully qualified name of one of the controller manager's services."""
        return f"{self.ns}/controller_manager/{name}"

    def _call(self, service: str, /, **fields: Any) -> Any:
        name = service
        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = self._node.create_client(self._types[name], self.service_name(name))
        request = self._types[name].Request(**fields)
        for attempt in range(1, self.max_retries + 1):
            try:
                return client.call(request, timeout_sec=self.timeout_sec)
            except ServiceTimeoutError as exc:
                if attempt == self.max_retries:
                    raise ControllerManagerError(
                        f"controller manager {self.ns or '/'} did not answer {self.service_name(name)} within "
                        f"{self.timeout_sec:g} s ({attempt} attempt(s)); is the robot spawned in namespace "
                        f"{self.ns or '/'!r}?"
                    ) from exc
                _logger.debug("%s timed out, retrying (%d/%d)", self.service_name(name), attempt, self.max_retries)
        raise AssertionError("unreachable")

    def _expect_ok(self, response: Any, what: str) -> bool:
        if not response.ok:
            raise ControllerManagerError(
                f"controller manager {self.ns or '/'} refused to {what}; list_controllers() shows the states, "
                "and the simulation node's log says why"
            )
        return True

    def wait_until_ready(self, timeout_sec: float, process: subprocess.Popen | None = None) -> None:
        """Block until ``list_controllers`` answers (the robot is up), at most ``timeout_sec``.

        Args:
            process: the robot's process, if this program started it: its exit ends the wait at once.

        Raises:
            ControllerManagerError: no answer in time, or ``process`` exited first (its code is named).
        """
        deadline = time.monotonic() + timeout_sec
        client = self._node.create_client(self._types["list_controllers"], self.service_name("list_controllers"))
        try:
            while True:
                if process is not None and process.poll() is not None:
                    raise ControllerManagerError(
                        f"the robot's process (pid {process.pid}) exited with code {process.returncode} before "
                        f"{self.service_name('list_controllers')} answered")
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise ControllerManagerError(
                        f"controller manager {self.ns or '/'} did not answer {self.service_name('list_controllers')} "
                        f"within {timeout_sec:g} s")
                if client.wait_for_service(timeout_sec=min(0.5, remaining)):
                    try:
                        client.call(self._types["list_controllers"].Request(),
                                    timeout_sec=min(2.0, max(remaining, 0.1)))
                        return
                    except (ServiceCallError, ServiceTimeoutError):  # not answering yet: retry until the deadline
                        continue
        finally:
            self._node.destroy_client(client)

    # -- queries ----------------------------------------------------------------------------
    def list_controllers(self) -> list[ControllerInfo]:
        """Every loaded controller with its state and type."""
        res = self._call("list_controllers")
        return [ControllerInfo(c.name, c.state, c.type, tuple(c.claimed_interfaces)) for c in res.controller]

    def states(self) -> dict[str, str]:
        """``{controller name: state}``."""
        return {c.name: c.state for c in self.list_controllers()}

    # -- lifecycle --------------------------------------------------------------------------
    def load(self, controllers: str | Sequence[str]) -> bool:
        """Load controllers (they are then ``unconfigured``)."""
        for name in _names(controllers):
            self._expect_ok(self._call("load_controller", name=name), f"load controller {name!r}")
        return True

    def configure(self, controllers: str | Sequence[str]) -> bool:
        """Configure loaded controllers (``unconfigured`` -> ``inactive``)."""
        for name in _names(controllers):
            self._expect_ok(self._call("configure_controller", name=name), f"configure controller {name!r}")
        return True

    def unload(self, controllers: str | Sequence[str]) -> bool:
        """Unload inactive controllers."""
        for name in _names(controllers):
            self._expect_ok(self._call("unload_controller", name=name), f"unload controller {name!r}")
        return True

    def switch(
        self,
        activate: Sequence[str] = (),
        deactivate: Sequence[str] = (),
        *,
        strictness: int = STRICT,
        activate_asap: bool = False,
        timeout: float = 0.0,
    ) -> bool:
        """Deactivate, then activate, controllers in one control cycle.

        Args:
            strictness: ``STRICT`` (2, fail on any problem) or ``BEST_EFFORT`` (1).
            timeout: seconds before pending controllers are aborted (0 = no limit).
        """
        fields: dict[str, Any] = {
            "activate_controllers": _names(activate),
            "deactivate_controllers": _names(deactivate),
            "strictness": int(strictness),
            "activate_asap": bool(activate_asap),
        }
        if timeout:
            sec = int(timeout)
            fields["timeout"] = Duration(sec=sec, nanosec=int(round((timeout - sec) * 1e9)))
        res = self._call("switch_controller", **fields)
        return self._expect_ok(res, f"activate {_names(activate)} / deactivate {_names(deactivate)}")

    def activate(self, controllers: str | Sequence[str], **kwargs: Any) -> bool:
        """Activate (start) controllers, configuring any that are still unconfigured."""
        names = _names(controllers)
        states = self.states()
        unconfigured = [n for n in names if states.get(n) == "unconfigured"]
        if unconfigured:
            self.configure(unconfigured)
        return self.switch(activate=names, **kwargs)

    def deactivate(self, controllers: str | Sequence[str], **kwargs: Any) -> bool:
        """Deactivate (stop) controllers."""
        return self.switch(deactivate=_names(controllers), **kwargs)

    def reset(self, controllers: str | Sequence[str] | None = None, **kwargs: Any) -> bool:
        """Stop then start controllers (default: all active ones), clearing their internal state."""
        names = _names(controllers) if controllers is not None else [
            c.name for c in self.list_controllers() if c.state == "active"
        ]
        if not names:
            return True
        self.deactivate(names, **kwargs)
        return self.activate(names, **kwargs)

    def spawn(self, controllers: str | Sequence[str], **kwargs: Any) -> bool:
        """Load (when not loaded), configure and activate controllers."""
        names = _names(controllers)
        loaded = self.states()
        missing = [n for n in names if n not in loaded]
        if missing:
            self.load(missing)
        return self.activate(names, **kwargs)

    def unspawn(self, controllers: str | Sequence[str], **kwargs: Any) -> bool:
        """Deactivate (when active) and unload controllers."""
        names = _names(controllers)
        active = [n for n, s in self.states().items() if s == "active" and n in names]
        if active:
            self.deactivate(active, **kwargs)
        return self.unload(names)

    def close(self) -> None:
        """Destroy the service clients."""
        destroy_clients(self._node, self._clients)


