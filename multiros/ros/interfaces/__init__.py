"""ROS 2 interface types without rclpy: message/service/action classes, CDR and RIHS01 type hashes.

rclpy-shaped helpers::

    from multiros.ros.interfaces import get_message, serialize_message, deserialize_message, type_hash
    JointState = get_message("sensor_msgs/msg/JointState")
    data = serialize_message(JointState(name=["a"], position=[0.5]))   # exact ROS 2 wire bytes
    msg = deserialize_message(data, JointState)
    type_hash("std_msgs/msg/String")                                    # 'RIHS01_df668c74...'

    from multiros.ros.interfaces import sensor_msgs, simulation_interfaces
    sensor_msgs.msg.JointState; simulation_interfaces.srv.StepSimulation.Request

Definitions ship as ``.msg``/``.srv``/``.action`` text per ROS 2 distribution (Jazzy, Kilted,
Rolling; Humble's too). The functions here use the distribution of ``ROS_DISTRO`` (Jazzy when unset);
``registry_for("rolling").service_class(...)`` gives another distribution's types. Classes and codecs
are generated on first use. Value representation: see :mod:`._classgen`.
"""

from __future__ import annotations

from typing import Any

from .errors import (
    DeserializationError,
    FieldError,
    FieldValueError,
    InterfaceDefinitionError,
    InterfaceError,
    UnknownTypeError,
    UnsupportedDistroError,
)
from .registry import (
    DEFAULT_DISTRO,
    SHIPPED_DISTROS,
    SUPPORTED_DISTROS,
    TypeRegistry,
    default_distro,
    default_registry,
    normalize_name,
    registry_for,
    require_peer_distro,
)
from .typehash import type_description, type_hash

__all__ = [
    "DEFAULT_DISTRO",
    "SHIPPED_DISTROS",
    "SUPPORTED_DISTROS",
    "DeserializationError",
    "first_sequence_length",
    "FieldError",
    "FieldValueError",
    "InterfaceDefinitionError",
    "InterfaceError",
    "TypeRegistry",
    "UnknownTypeError",
    "UnsupportedDistroError",
    "dds_type_name",
    "default_distro",
    "default_registry",
    "deserialize_message",
    "get_action",
    "get_message",
    "get_service",
    "is_message",
    "list_types",
    "normalize_name",
    "registry_for",
    "require_peer_distro",
    "serialize_message",
    "type_description",
    "type_hash",
]

_HEADER_ERROR = "bad encapsulation header {!r}: expected CDR 00 01 (little endian) or 00 00 (big endian)"


def get_message(name: str) -> Any:  # a class generated from the definition
    """The message class of ``name`` (``pkg/msg/Name`` or ``pkg/Name``; ``pkg/srv/X_Request`` too).

    Raises:
        UnknownTypeError: no such message; the error lists close matches or the known packages.
    """
    return default_registry().message_class(name)


def get_service(name: str) -> Any:  # a class generated from the definition
    """The service class of ``name`` (``pkg/srv/Name``), with ``Request``, ``Response`` and ``Event``."""
    return default_registry().service_class(name)


def get_action(name: str) -> Any:  # a class generated from the definition
    """The action class of ``name`` (``pkg/action/Name``), with ``Goal``, ``Result``, ``Feedback``, ``Impl``."""
    return default_registry().action_class(name)


def list_types(kind: str | None = None) -> list[str]:
    """All shipped interface names, e.g. ``sensor_msgs/msg/JointState``; ``kind`` = msg, srv or action."""
    return default_registry().list_types(kind)


def is_message(obj: object) -> bool:
    """True for an instance of a generated message class."""
    return hasattr(type(obj), "_spec") and hasattr(type(obj), "_fields")


def _registry_of(cls: type):
    return getattr(cls, "_registry", None) or default_registry()


def serialize_message(msg: object) -> bytes:
    """CDR bytes of ``msg`` as ROS 2 puts them on the wire (``00 01 00 00`` header included).

    Raises:
        FieldError: a field holds a value of the wrong type (``FieldValueError``: out of range, too
            long, wrong fixed length); the message names type and field.
        TypeError: ``msg`` is not a generated message.
    """
    cls = type(msg)
    try:
        fn = cls._cdr_ser
    except AttributeError:
        if not is_message(msg):
            raise TypeError(f"serialize_message needs a ROS message instance, got {cls.__name__}") from None
        fn = _registry_of(cls).serializer(cls._type)
        cls._cdr_ser = fn
    return fn(msg)


def deserialize_message(data: bytes | bytearray | memoryview, msg_type: type | str, *,
                        trailing: str = "zero_padding") -> object:
    """Decode CDR bytes (header included) into a message of ``msg_type`` (a class or a type name).

    Accepts little- and big-endian CDR and up to 7 zero padding bytes at the end (ROS pads to 4).
    ``trailing``: what may follow the message: ``"zero_padding"`` (the default), ``"any_padding"``
    (up to 3 bytes of any value: Fast CDR leaves end padding uninitialised) or ``"ignore"`` (anything:
    only for bytes from a trusted local serializer; rclpy's ``serialize_message`` can report a
    buffer longer than the message).

    Raises:
        DeserializationError: truncated, corrupt or trailing bytes; names type and field.
    """
    cls = get_message(msg_type) if isinstance(msg_type, str) else msg_type
    if not isinstance(data, bytes):
        data = bytes(data)
    size = len(data)
    if size < 4 or data[0] != 0 or data[1] > 1:
        raise DeserializationError(cls._type, "", _HEADER_ERROR.format(data[:4].hex(" ")))
    try:
        fn = cls._cdr_des_le if data[1] else cls._cdr_des_be
    except AttributeError:
        fn = _registry_of(cls).deserializer(cls._type, "<" if data[1] else ">")
        setattr(cls, "_cdr_des_le" if data[1] else "_cdr_des_be", fn)
    msg, pos = fn(data, 4, size)
    if pos != size:
        rest = size - pos
        if trailing == "ignore" or (trailing == "any_padding" and rest <= 3):
            return msg
        if rest > 7 or (size - 4) % 4 or data[pos:].count(0) != rest:
            raise DeserializationError(cls._type, "", f"{rest} unexpected bytes after the message end")
    return msg


def first_sequence_length(data: bytes | bytearray | memoryview) -> int | None:
    """The element count of the first field of CDR bytes (header included) whose type starts with a
    sequence (``SetParameters``' parameters, ``GetParameters``' names): read without decoding anything
    else; ``None`` when the bytes are too short or not plain CDR. Only meaningful for such a type."""
    if len(data) < 8 or data[0] != 0 or data[1] > 1:
        return None
    return int.from_bytes(bytes(data[4:8]), "little" if data[1] else "big")


def dds_type_name(type_name: str) -> str:
    """DDS/rmw type name: ``sensor_msgs::msg::dds_::JointState_``.

    For a service name this is the service type used in rmw_zenoh keys
    (``example_interfaces::srv::dds_::AddTwoInts_``); ``pkg/srv/X_Request`` and ``pkg/srv/X_Response``
    give the request and response variants.
    """
    try:
        full = default_registry().resolve(type_name)
    except UnknownTypeError:
        pkg, kind, name = normalize_name(type_name)  # a full name of another distribution's type
        if kind is None:
            raise
        full = f"{pkg}/{kind}/{name}"
    pkg, kind, name = full.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


class _Namespace:
    """``sensor_msgs.msg`` / ``.srv`` / ``.action``: attribute access builds the class on demand."""

    def __init__(self, package: str, kind: str) -> None:
        self._package, self._kind = package, kind

    def __getattr__(self, name: str) -> type:
        if name.startswith("__"):
            raise AttributeError(name)
        full = f"{self._package}/{self._kind}/{name}"
        reg = default_registry()
        try:
            if self._kind == "msg":
                return reg.message_class(full)
            return reg.service_class(full) if self._kind == "srv" else reg.action_class(full)
        except UnknownTypeError as exc:
            raise AttributeError(str(exc)) from None

    def __dir__(self) -> list[str]:
        return [n.rsplit("/", 1)[1] for n in default_registry().list_types(self._kind)
                if n.startswith(self._package + "/")]

    def __repr__(self) -> str:
        return f"<ROS interfaces {self._package}.{self._kind}>"


class _Package:
    """An interface package with ``msg``, ``srv`` and ``action`` namespaces."""

    def __init__(self, name: str) -> None:
        self.__name__ = name
        self.msg = _Namespace(name, "msg")
        self.srv = _Namespace(name, "srv")
        self.action = _Namespace(name, "action")

    def __repr__(self) -> str:
        return f"<ROS interface package {self.__name__}>"


def __getattr__(name: str) -> _Package:
    if name in default_registry().packages():
        return _Package(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(__all__) | set(default_registry().packages()))
