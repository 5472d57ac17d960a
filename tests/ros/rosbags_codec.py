"""An independent CDR codec built on rosbags, for wire tests (and until the interface types land).

Message classes here are plain dataclasses with ``_type``; rosbags does the CDR.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

# rmw_zenoh's design document gives this service hash (ros2_wire.md §1.7); rosbags' own service
# hash is wrong (char -> uint8 pitfall), so the oracle uses the published value.
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"


@dataclass
class String:
    _type = "std_msgs/msg/String"
    data: str = ""


@dataclass
class Int64:
    _type = "std_msgs/msg/Int64"
    data: int = 0


class AddTwoInts:
    _type = "example_interfaces/srv/AddTwoInts"

    @dataclass
    class Request:
        _type = "example_interfaces/srv/AddTwoInts_Request"
        a: int = 0
        b: int = 0

    @dataclass
    class Response:
        _type = "example_interfaces/srv/AddTwoInts_Response"
        sum: int = 0


def make_typestore() -> Any:
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    types.update(get_types_from_msg("int64 a\nint64 b", "example_interfaces/msg/AddTwoInts_Request"))
    types.update(get_types_from_msg("int64 sum", "example_interfaces/msg/AddTwoInts_Response"))
    store.register(types)
    return store


def _store_name(type_name: str) -> str:
    # rosbags keeps service parts under "pkg/msg/" (it renames "pkg/srv/X" when parsing .msg text).
    return type_name.replace("/srv/", "/msg/")


class RosbagsCodec:
    """``multiros.ros.transport.zenoh.codec.Codec`` over rosbags, for the dataclasses above."""

    def __init__(self) -> None:
        self.store = make_typestore()

    def serialize(self, msg: Any) -> bytes:
        name = _store_name(msg._type)
        cls = self.store.types[name]
        return bytes(self.store.serialize_cdr(cls(**{f.name: getattr(msg, f.name) for f in fields(msg)}), name))

    def deserialize(self, data: bytes, msg_type: type) -> Any:
        obj = self.store.deserialize_cdr(bytes(data), _store_name(msg_type._type))
        return msg_type(**{f.name: getattr(obj, f.name) for f in fields(msg_type)})

    def type_hash(self, type_name: str) -> str:
        if type_name == AddTwoInts._type:
            return ADD_TWO_INTS_HASH
        return self.store.hash_rihs01(type_name)

    def dds_type_name(self, type_name: str) -> str:
        pkg, kind, name = type_name.split("/")
        return f"{pkg}::{kind}::dds_::{name}_"


__all__ = ["String", "Int64", "AddTwoInts", "RosbagsCodec", "ADD_TWO_INTS_HASH", "asdict"]
