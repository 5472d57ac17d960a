"""Find interface definitions, parse them on first use and build classes and codecs lazily.

A :class:`TypeRegistry` reads ``<root>/<package>/{msg,srv,action}/<Name>.<ext>`` files.

Definitions ship per ROS 2 distribution: the packages whose release differs between distributions
(``simulation_interfaces``, ``controller_manager_msgs``, ``control_msgs``) in
``multiros/ros/distros/<distro>/``, the others in ``multiros/ros/definitions/``.
:func:`registry_for` gives one registry per distribution; :func:`default_registry` is the one of
``ROS_DISTRO`` (Jazzy when unset), chosen once per process. Registries never change after loading,
so sharing them between nodes and envs is safe. Shipped registries share one class per definition:
a type whose definition is the same in two distributions (``std_msgs/msg/Header``,
``simulation_interfaces/msg/Result``, ...) is the same Python class in both. Create your own
``TypeRegistry(roots=[...])`` to add packages.
"""

from __future__ import annotations

import difflib
import hashlib
import os
import threading
from collections.abc import Callable, Iterable
from pathlib import Path

from . import _cdrgen
from ._classgen import build_message_class
from .errors import UnknownTypeError, UnsupportedDistroError
from .idl import ActionSpec, MessageSpec, ServiceSpec, parse_action, parse_message, parse_service

__all__ = [
    "DEFAULT_DISTRO",
    "DEFINITIONS_ROOT",
    "DISTROS_ROOT",
    "SHIPPED_DISTROS",
    "SUPPORTED_DISTROS",
    "TypeRegistry",
    "default_distro",
    "default_registry",
    "distro_roots",
    "normalize_name",
    "registry_for",
    "require_peer_distro",
]

DEFINITIONS_ROOT = Path(__file__).resolve().parent.parent / "definitions"
DISTROS_ROOT = Path(__file__).resolve().parent.parent / "distros"
#: The distribution used when ``ROS_DISTRO`` is unset.
DEFAULT_DISTRO = "jazzy"
#: Distributions whose wire (rmw_zenoh keys with RIHS01 type hashes) uniros speaks.
SUPPORTED_DISTROS: tuple[str, ...] = ("jazzy", "kilted", "rolling")
#: Distributions whose definitions ship; Humble's rmw_zenoh has no type hashes, so its peers are
#: not reachable, but its definitions can still be loaded (``registry_for("humble")``).
SHIPPED_DISTROS: tuple[str, ...] = ("humble", *SUPPORTED_DISTROS)
_EXT = {"msg": ".msg", "srv": ".srv", "action": ".action"}
_SERVICE_PARTS = ("_Request", "_Response", "_Event")
_ACTION_PARTS = ("_Goal", "_Result", "_Feedback", "_FeedbackMessage")


def normalize_name(name: str, kind: str | None = None) -> tuple[str, str | None, str]:
    """Split ``pkg/msg/Name``, ``pkg/Name`` or ``pkg.msg.Name`` into (package, kind or None, name)."""
    parts = name.replace(".", "/").strip("/").split("/")
    if len(parts) == 3 and parts[1] in _EXT:
        if kind is not None and parts[1] != kind and not (kind == "msg" and parts[1] in ("srv", "action")):
            raise UnknownTypeError(f"{name!r} is a {parts[1]} name, expected a {kind} (pkg/{kind}/Name)")
        return parts[0], parts[1], parts[2]
    if len(parts) == 2 and all(parts):
        return parts[0], kind, parts[1]
    raise UnknownTypeError(f"malformed interface type name {name!r}; use 'pkg/msg/Name' (or 'pkg/Name')")


class TypeRegistry:
    """Interface definitions from one or more roots, with lazily built classes and codecs.

    Args:
        roots: Directories holding ``<package>/{msg,srv,action}/`` folders. Default: the shipped ones
            of :data:`DEFAULT_DISTRO` (``distro_roots("jazzy")``). A package found in several roots
            is taken from the first.

    Attributes:
        distro: The ROS 2 distribution of a registry from :func:`registry_for`, else ``None``.
    """

    def __init__(self, roots: Iterable[str | Path] | None = None, *, _distro: str | None = None,
                 _pool: dict | None = None) -> None:
        self._roots = distro_roots(DEFAULT_DISTRO) if roots is None else [Path(r) for r in roots]
        self.distro = _distro
        # Shared by the shipped registries: (name, definition signature) -> class.
        self._pool = _pool
        self._signatures: dict[str, str] = {}
        self._files: dict[str, Path] = {}
        for root in self._roots:
            for path in sorted(root.glob("*/*/*")):
                kind = path.parent.name
                if kind in _EXT and path.suffix == _EXT[kind]:
                    self._files.setdefault(f"{path.parent.parent.name}/{kind}/{path.stem}", path)
        self._lock = threading.RLock()
        self._messages: dict[str, MessageSpec] = {}
        self._services: dict[str, ServiceSpec] = {}
        self._actions: dict[str, ActionSpec] = {}
        self._classes: dict[str, type] = {}
        self._service_classes: dict[str, type] = {}
        self._action_classes: dict[str, type] = {}
        self._codecs: dict[tuple, Callable] = {}

    @property
    def roots(self) -> list[Path]:
        """The definition roots, in lookup order."""
        return list(self._roots)

    def definition_file(self, name: str) -> Path:
        """The ``.msg``/``.srv``/``.action`` file defining ``name`` (derived names: their source file)."""
        full = self.resolve(name)
        return self._files[full if full in self._files else self._derived_file(full)]

    # -- names ----------------------------------------------------------------------------------
    def packages(self) -> list[str]:
        """Names of the interface packages found."""
        return sorted({n.split("/", 1)[0] for n in self._files})

    def list_types(self, kind: str | None = None) -> list[str]:
        """Full names of all definition files (``pkg/msg/Name``, ``pkg/srv/Name``, ...), sorted."""
        return sorted(n for n in self._files if kind is None or n.split("/")[1] == kind)

    def _unknown(self, name: str, kind: str | None) -> UnknownTypeError:
        """The error for an unknown ``name``; its "did you mean" hint is searched when the message is read."""
        def message() -> str:
            candidates = self.list_types(kind)
            close = difflib.get_close_matches(name, candidates, n=5, cutoff=0.6)
            short = [c for c in candidates if c.rsplit("/", 1)[-1].lower() == name.rsplit("/", 1)[-1].lower()]
            close = list(dict.fromkeys(short + close))[:5]
            hint = f"did you mean {', '.join(close)}?" if close else f"known packages: {', '.join(self.packages())}"
            what = {"msg": "message", "srv": "service", "action": "action"}.get(kind or "", "interface")
            return f"unknown {what} type {name!r}; {hint}"

        return UnknownTypeError(message)

    def resolve(self, name: str, kind: str | None = None) -> str:
        """Full canonical name of a type; ``kind`` restricts the search (``msg``/``srv``/``action``).

        Raises:
            UnknownTypeError: no such type; the message lists close matches or the known packages.
        """
        if not isinstance(name, str):
            raise UnknownTypeError(f"interface type name must be a str like 'pkg/msg/Name', got {name!r}")
        pkg, found_kind, base = normalize_name(name, kind)
        kinds = [found_kind] if found_kind else (["msg", "srv", "action"] if kind is None else [kind])
        for k in kinds:
            full = f"{pkg}/{k}/{base}"
            if full in self._files or self._derived_file(full) is not None:
                return full
        raise self._unknown(name, kind)

    def _derived_file(self, full: str) -> str | None:
        """The service/action file that defines a derived name like ``pkg/srv/X_Request``."""
        pkg, kind, base = full.split("/")
        if kind == "msg":
            return None
        parts = base.split("_")
        for cut in range(len(parts) - 1, 0, -1):
            candidate = f"{pkg}/{kind}/{'_'.join(parts[:cut])}"
            if candidate in self._files:
                return candidate
        return None

    # -- specs ----------------------------------------------------------------------------------
    def _load(self, full: str) -> None:
        path = self._files[full]
        text = path.read_text(encoding="utf-8")
        kind = full.split("/")[1]
        if kind == "msg":
            self._messages[full] = parse_message(text, full, str(path))
        elif kind == "srv":
            self._add_service(parse_service(text, full, str(path)))
        else:
            spec = parse_action(text, full, str(path))
            self._actions[full] = spec
            for m in (spec.goal, spec.result, spec.feedback, spec.feedback_message):
                self._messages[m.name] = m
            self._add_service(spec.send_goal)
            self._add_service(spec.get_result)

    def _add_service(self, spec: ServiceSpec) -> None:
        self._services[spec.name] = spec
        for m in (spec.request, spec.response, spec.event):
            self._messages[m.name] = m

    def _ensure(self, full: str) -> None:
        if full in self._messages or full in self._services or full in self._actions:
            return
        with self._lock:
            source = full if full in self._files else self._derived_file(full)
            if source is not None and source not in self._messages and source not in self._services \
                    and source not in self._actions:
                self._load(source)

    def message_spec(self, name: str) -> MessageSpec:
        """Parsed spec of a message (including ``pkg/srv/X_Request`` and other derived messages)."""
        full = self.resolve(name, "msg")
        self._ensure(full)
        try:
            return self._messages[full]
        except KeyError:
            raise self._unknown(name, "msg") from None

    def service_spec(self, name: str) -> ServiceSpec:
        """Parsed spec of a service (also the ``X_SendGoal``/``X_GetResult`` services of actions)."""
        try:
            full = self.resolve(name, "srv")
        except UnknownTypeError:
            full = self.resolve(name, "action")
        self._ensure(full)
        try:
            return self._services[full]
        except KeyError:
            raise self._unknown(name, "srv") from None

    def action_spec(self, name: str) -> ActionSpec:
        """Parsed spec of an action."""
        full = self.resolve(name, "action")
        self._ensure(full)
        try:
            return self._actions[full]
        except KeyError:
            raise self._unknown(name, "action") from None

    # -- classes --------------------------------------------------------------------------------
    def message_class(self, name: str) -> type:
        """The generated class of a message type (built on first use)."""
        cls = self._classes.get(name)
        if cls is not None:
            return cls
        spec = self.message_spec(name)
        with self._lock:
            cls = self._classes.get(spec.name)
            if cls is None:
                key = None if self._pool is None else ("msg", spec.name, self._signature(spec.name))
                cls = None if key is None else self._pool.get(key)
                if cls is None:
                    cls = build_message_class(spec, self.message_class)
                    cls._registry = self
                    if key is not None:
                        cls = self._pool.setdefault(key, cls)
                self._classes[spec.name] = cls
            self._classes[name] = cls
        return cls

    def _signature(self, name: str) -> str:
        """Digest of a message's definition and of every type it references (comments excluded).

        Two registries giving a type the same signature define it identically, constants and
        defaults included, so they can share its class.
        """
        sig = self._signatures.get(name)
        if sig is None:
            spec = self.message_spec(name)
            parts = [repr(spec)]
            for f in spec.fields:
                if f.type.is_nested and f.type.base != name:
                    parts.append(self._signature(f.type.base))
            sig = hashlib.sha256("\n".join(parts).encode()).hexdigest()
            self._signatures[name] = sig
        return sig

    def service_class(self, name: str) -> type:
        """A class with ``Request``, ``Response``, ``Event`` and ``_type``, like rclpy's service types."""
        cls = self._service_classes.get(name)
        if cls is not None:
            return cls
        spec = self.service_spec(name)
        with self._lock:
            key = None
            if self._pool is not None:
                key = ("srv", spec.name, self._signature(spec.request.name), self._signature(spec.response.name))
                cls = self._pool.get(key)
                if cls is not None:
                    self._service_classes[name] = self._service_classes[spec.name] = cls
                    return cls
            pkg, kind, base = spec.name.split("/")
            cls = type(base, (), {
                "__slots__": (), "_type": spec.name, "_spec": spec, "_registry": self,
                "__module__": f"multiros.ros.interfaces.{pkg}.{kind}",
                "__doc__": f"ROS 2 service ``{spec.name}`` (generated).",
                "Request": self.message_class(spec.request.name),
                "Response": self.message_class(spec.response.name),
                "Event": self.message_class(spec.event.name),
            })
            if key is not None:
                cls = self._pool.setdefault(key, cls)
            self._service_classes[name] = self._service_classes[spec.name] = cls
        return cls

    def action_class(self, name: str) -> type:
        """A class with ``Goal``, ``Result``, ``Feedback`` and ``Impl`` (the derived services/messages)."""
        cls = self._action_classes.get(name)
        if cls is not None:
            return cls
        spec = self.action_spec(name)
        with self._lock:
            pkg, kind, base = spec.name.split("/")
            impl = type("Impl", (), {
                "__slots__": (),
                "SendGoalService": self.service_class(spec.send_goal.name),
                "GetResultService": self.service_class(spec.get_result.name),
                "FeedbackMessage": self.message_class(spec.feedback_message.name),
            })
            cls = type(base, (), {
                "__slots__": (), "_type": spec.name, "_spec": spec, "Impl": impl, "_registry": self,
                "__module__": f"multiros.ros.interfaces.{pkg}.{kind}",
                "__doc__": f"ROS 2 action ``{spec.name}`` (generated).",
                "Goal": self.message_class(spec.goal.name),
                "Result": self.message_class(spec.result.name),
                "Feedback": self.message_class(spec.feedback.name),
            })
            self._action_classes[name] = self._action_classes[spec.name] = cls
        return cls

    # -- codecs ---------------------------------------------------------------------------------
    def _lookup(self, type_name: str) -> tuple[MessageSpec, type]:
        return self.message_spec(type_name), self.message_class(type_name)

    def serializer(self, type_name: str, top: bool = True) -> Callable:
        """Compiled serializer (see :func:`._cdrgen.build_serializer`) for a message type."""
        key = ("ser", type_name, top)
        fn = self._codecs.get(key)
        if fn is None:
            with self._lock:
                fn = self._codecs.get(key)
                if fn is None:
                    spec, cls = self._lookup(type_name)
                    fn = _cdrgen.build_serializer(spec, cls, top, self._lookup,
                                                  lambda n: self.serializer(n, top=False))
                    self._codecs[key] = fn
        return fn

    def deserializer(self, type_name: str, endian: str = "<", top: bool = True) -> Callable:
        """Compiled deserializer ``f(buf, pos, len) -> (msg, pos)`` for a message type."""
        key = ("des", type_name, endian, top)
        fn = self._codecs.get(key)
        if fn is None:
            with self._lock:
                fn = self._codecs.get(key)
                if fn is None:
                    spec, cls = self._lookup(type_name)
                    fn = _cdrgen.build_deserializer(spec, cls, top, endian, self._lookup,
                                                    lambda n: self.deserializer(n, endian, top=False))
                    self._codecs[key] = fn
        return fn


def distro_roots(distro: str) -> list[Path]:
    """Definition roots of a shipped distribution: its own packages first, then the common ones."""
    return [DISTROS_ROOT / _check_distro(distro, SHIPPED_DISTROS), DEFINITIONS_ROOT]


def _check_distro(distro: object, allowed: tuple[str, ...], source: str = "distribution") -> str:
    name = distro.strip().lower() if isinstance(distro, str) else distro
    if name not in allowed:
        hint = ""
        if name == "humble":
            hint = (" Humble's rmw_zenoh puts no type hashes in its keys, so uniros cannot reach Humble "
                    "peers;")
        raise UnsupportedDistroError(
            f"{source} {distro!r} is not supported;{hint} supported: {', '.join(allowed)} "
            f"(default {DEFAULT_DISTRO} when ROS_DISTRO is unset)"
        )
    return name  # type: ignore[return-value]


_REGISTRIES: dict[str, TypeRegistry] = {}
_REGISTRIES_LOCK = threading.Lock()
_POOL: dict[tuple, type] = {}
_DEFAULT: list[TypeRegistry] = []
_DEFAULT_LOCK = threading.Lock()


def registry_for(distro: str) -> TypeRegistry:
    """The registry of one distribution's definitions (created on first call, then shared).

    Args:
        distro: ``jazzy``, ``kilted``, ``rolling`` (:data:`SUPPORTED_DISTROS`) or ``humble``.

    Raises:
        UnsupportedDistroError: no definitions ship for ``distro``; the message names the shipped ones.
    """
    name = _check_distro(distro, SHIPPED_DISTROS)
    reg = _REGISTRIES.get(name)
    if reg is None:
        with _REGISTRIES_LOCK:
            reg = _REGISTRIES.get(name)
            if reg is None:
                reg = _REGISTRIES[name] = TypeRegistry(distro_roots(name), _distro=name, _pool=_POOL)
    return reg


def default_distro() -> str:
    """The distribution ROS would use: ``ROS_DISTRO`` if set (and supported), else Jazzy.

    Raises:
        UnsupportedDistroError: ``ROS_DISTRO`` names a distribution uniros does not speak; the message
            names the supported ones.
    """
    value = os.environ.get("ROS_DISTRO", "").strip()
    if not value:
        return DEFAULT_DISTRO
    return _check_distro(value, SUPPORTED_DISTROS, "ROS_DISTRO")


def _in_process_distro() -> str:
    """:func:`default_distro`, or :data:`DEFAULT_DISTRO` when ``ROS_DISTRO`` names one uniros does not
    speak (a sourced Humble): messages that never leave the process (a simulated env on the inproc
    transport) need no peer's definitions, and the transports that reach peers refuse it when opened
    (:func:`require_peer_distro`)."""
    try:
        return default_distro()
    except UnsupportedDistroError:
        return DEFAULT_DISTRO


def require_peer_distro(what: str) -> str:
    """:func:`default_distro`, for ``what`` (a transport that reaches other ROS 2 programs).

    Raises:
        UnsupportedDistroError: ``ROS_DISTRO`` names a distribution whose peers uniros cannot reach;
            the message says that simulated envs on the inproc transport still work.
    """
    try:
        return default_distro()
    except UnsupportedDistroError as exc:
        raise UnsupportedDistroError(f"{what}: {exc}. Simulated envs on the default inproc transport need no ROS "
                                     "and work with any ROS_DISTRO") from None


def default_registry() -> TypeRegistry:
    """The registry of :func:`default_distro`, chosen on the first call and kept for the process
    (Jazzy's when ``ROS_DISTRO`` names a distribution uniros does not speak: see
    :func:`require_peer_distro`)."""
    if not _DEFAULT:
        reg = registry_for(_in_process_distro())
        with _DEFAULT_LOCK:
            if not _DEFAULT:
                _DEFAULT.append(reg)
    return _DEFAULT[0]
