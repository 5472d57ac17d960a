"""The codec seam of the Zenoh transport.

The transport touches message encoding only through a ``Codec``; the default one delegates to
the six public functions of ``multiros.ros.interfaces``, so nothing here depends on that
package's internals. Tests may pass another codec (``Context(transport="zenoh", codec=...)``).
"""

from __future__ import annotations

from typing import Any, Protocol

from multiros.ros.exceptions import TransportError

__all__ = ["Codec", "InterfacesCodec"]


class Codec(Protocol):
    """Encodes messages as ROS 2 CDR (with the 4-byte encapsulation header) and names types."""

    def serialize(self, msg: Any) -> bytes: ...

    def deserialize(self, data: bytes, msg_type: type) -> Any: ...

    def type_hash(self, type_name: str) -> str: ...

    def dds_type_name(self, type_name: str) -> str: ...


class InterfacesCodec:
    """The codec of ``multiros.ros.interfaces`` (imported on first use)."""

    def __init__(self) -> None:
        try:
            from multiros.ros import interfaces
        except ImportError as exc:
            raise TransportError(
                f"the zenoh transport needs multiros.ros.interfaces for CDR and type hashes: {exc}"
            ) from exc
        self._itf = interfaces

    def serialize(self, msg: Any) -> bytes:
        return bytes(self._itf.serialize_message(msg))

    def deserialize(self, data: bytes, msg_type: type) -> Any:
        return self._itf.deserialize_message(data, msg_type)

    def type_hash(self, type_name: str) -> str:
        return self._itf.type_hash(type_name)

    def type_hash_of(self, ros_type: type) -> str:
        """Hash of a generated class, with the definitions (distribution) it was made from.

        Optional in a codec: the transport falls back to ``type_hash(type_name)`` without it.
        """
        if getattr(ros_type, "_registry", None) is None:
            return self._itf.type_hash(ros_type._type)
        return self._itf.type_hash(ros_type)

    def dds_type_name(self, type_name: str) -> str:
        return self._itf.dds_type_name(type_name)
