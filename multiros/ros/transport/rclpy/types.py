"""uniros interface classes and the rclpy classes installed for them.

rclpy can only publish, subscribe, call or serve a type whose generated package is installed
(its compiled type support). For each uniros class (``multiros.ros.interfaces``) this finds the
installed class of the same ROS type and checks that both come from the same definition: the
RIHS01 hash of the uniros class against the one rosidl recorded in the installed package
(``share/<pkg>/<kind>/<Name>.json``). Only then are their CDR bytes the same, which the transport
relies on to convert (see ``transport.py``).

Mismatches: a node *offers* some types in several distributions' variants at once (a service or
a publisher per variant, as over Zenoh, where each has its own key). rclpy serves one type per
name, so an offer whose variant differs from the installed one is skipped when another shipped
distribution's variant matches the installed package (that variant is offered too); a consumer
(subscription, client) must match. Anything else is a :class:`InterfaceMismatchError`.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import logging
import os
import threading
from pathlib import Path
from typing import Any

from multiros.ros.exceptions import TransportError
from multiros.ros.transport.rclpy.loader import ros_distro_hint

__all__ = ["MissingInterfacePackageError", "InterfaceMismatchError", "InstalledTypes", "PRIVATE_PACKAGES",
           "install_hint"]

_log = logging.getLogger(__name__)

#: Interface packages of uniros itself: never part of a ROS distribution.
PRIVATE_PACKAGES = frozenset({"uniros_interfaces"})
_ACTION_PARTS = {"_SendGoal": "SendGoalService", "_GetResult": "GetResultService",
                 "_FeedbackMessage": "FeedbackMessage", "_Goal": "Goal", "_Result": "Result", "_Feedback": "Feedback"}


class MissingInterfacePackageError(TransportError):
    """The interface package of a type is not installed for rclpy."""

    def __init__(self, package: str, type_name: str, what: str) -> None:
        self.package = package
        self.type_name = type_name
        super().__init__(f"{what}: {type_name} needs the ROS 2 interface package '{package}', which is not installed "
                         f"for rclpy: {install_hint(package)}")


class InterfaceMismatchError(TransportError):
    """The installed definition of a type differs from the one uniros uses."""


def install_hint(package: str) -> str:
    """How to get ``package`` for rclpy, in one sentence."""
    distro = ros_distro_hint()
    build = f"`uniros-build-interfaces {package}` builds it from the definitions uniros ships (docs/ros2_system.md)"
    if package in PRIVATE_PACKAGES:
        return f"it is uniros' own and in no ROS distribution: {build}"
    return f"install ros-{distro}-{package.replace('_', '-')} (apt in a ROS install), or {build}"


class InstalledTypes:
    """Finds and checks installed rclpy classes for uniros classes (one per transport; cached)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._classes: dict[str, Any] = {}
        self._hashes: dict[str, str | None] = {}

    # -- classes -------------------------------------------------------------------------------
    def rclpy_class(self, type_name: str, what: str) -> Any:
        """The installed class of ``pkg/kind/Name`` (action parts: ``pkg/action/X_SendGoal`` ...).

        Raises:
            MissingInterfacePackageError: its package is not installed.
        """
        with self._lock:
            cls = self._classes.get(type_name)
        if cls is not None:
            return cls
        pkg, kind, name = type_name.split("/")
        try:
            module = importlib.import_module(f"{pkg}.{kind}")
        except ImportError:
            raise MissingInterfacePackageError(pkg, type_name, what) from None
        cls = getattr(module, name, None)
        if cls is None and kind == "action":
            for suffix, attr in _ACTION_PARTS.items():
                if name.endswith(suffix):
                    action = getattr(module, name[: -len(suffix)], None)
                    holder = getattr(action, "Impl", None) if attr.endswith(("Service", "Message")) else action
                    cls = getattr(holder, attr, None)
                    break
        if cls is None:
            raise InterfaceMismatchError(
                f"{what}: the installed package '{pkg}' has no {kind} '{name}' (uniros uses {type_name}): the "
                f"installed release differs from the definitions uniros uses; {install_hint(pkg)}")
        with self._lock:
            self._classes[type_name] = cls
        return cls

    # -- hashes --------------------------------------------------------------------------------
    def installed_hash(self, type_name: str) -> str | None:
        """The RIHS01 hash rosidl recorded for ``type_name`` in its installed package (``None``: not found)."""
        with self._lock:
            if type_name in self._hashes:
                return self._hashes[type_name]
        pkg, kind, name = type_name.split("/")
        base = name
        if kind == "action":
            for suffix in _ACTION_PARTS:
                if name.endswith(suffix):
                    base = name[: -len(suffix)]
                    break
        found: str | None = None
        for share in _share_dirs(pkg):
            path = share / kind / f"{base}.json"
            try:
                data = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            for entry in data.get("type_hashes", ()):
                if entry.get("type_name") == type_name:
                    found = str(entry.get("hash_string"))
                    break
            if found:
                break
        with self._lock:
            self._hashes[type_name] = found
        return found

    def resolve(self, uniros_cls: Any, what: str, *, offer: bool) -> Any | None:
        """The installed class to use for ``uniros_cls``; ``None`` for an offer of another variant.

        Raises:
            MissingInterfacePackageError: the package is not installed.
            InterfaceMismatchError: the installed definition differs from uniros' (and, for an
                offer, from every shipped distribution's variant).
        """
        from multiros.ros.interfaces import SHIPPED_DISTROS, UnknownTypeError, registry_for, type_hash

        type_name = uniros_cls._type
        rcls = self.rclpy_class(type_name, what)
        installed = self.installed_hash(type_name)
        ours = type_hash(uniros_cls)
        if installed is None:
            _log.debug("%s: no type description of %s installed; its definition is not checked", what, type_name)
            return rcls
        if installed == ours:
            return rcls
        matches = []
        for distro in SHIPPED_DISTROS:
            try:
                reg = registry_for(distro)
                if type_hash(_same_type_in(reg, type_name)) == installed:
                    matches.append(distro)
            except (UnknownTypeError, LookupError, ValueError):
                continue
        if offer and matches:
            _log.debug("%s: variant %s of %s is not offered on rclpy: the installed package is %s's",
                       what, getattr(getattr(uniros_cls, "_registry", None), "distro", "?"), type_name, matches[0])
            return None
        ours_distro = getattr(getattr(uniros_cls, "_registry", None), "distro", None) or "custom definitions"
        fix = (f"set ROS_DISTRO={matches[0]} (the definitions of the sourced distribution)" if matches else
               "the installed package is a release uniros does not ship; "
               + install_hint(type_name.split("/")[0]))
        raise InterfaceMismatchError(
            f"{what}: the installed {type_name} (hash {installed[:20]}...) differs from the one uniros uses "
            f"({ours_distro}: {ours[:20]}...): {fix}")


def _same_type_in(registry: Any, type_name: str) -> Any:
    _pkg, kind, name = type_name.split("/")
    if kind == "srv":
        return registry.service_class(type_name)
    if kind == "action":
        for suffix in ("_SendGoal", "_GetResult"):
            if name.endswith(suffix):
                return getattr(registry.action_class(type_name[: -len(suffix)]).Impl,
                               "SendGoalService" if suffix == "_SendGoal" else "GetResultService")
    return registry.message_class(type_name)


def _share_dirs(package: str) -> list[Path]:
    """Where ``share/<package>`` may be: beside the installed Python package's prefix, then
    ``AMENT_PREFIX_PATH``'s prefixes."""
    out: list[Path] = []
    spec = importlib.util.find_spec(package)
    for loc in (spec.submodule_search_locations or []) if spec is not None else []:
        parents = Path(loc).resolve().parents
        for depth in (3, 2, 4):  # <prefix>/lib/pythonX.Y/site-packages/<pkg>, .../local/lib/...
            if depth < len(parents):
                out.append(parents[depth] / "share" / package)
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            out.append(Path(prefix) / "share" / package)
    return [p for p in dict.fromkeys(out) if p.is_dir()]
