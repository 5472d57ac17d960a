"""Bad input: unknown names, bad field values, truncated and random bytes."""

from __future__ import annotations

import random

import numpy as np
import pytest
from interfaces_factory import random_message

from multiros.ros.interfaces import (
    DeserializationError,
    FieldError,
    FieldValueError,
    InterfaceError,
    UnknownTypeError,
    deserialize_message,
    get_action,
    get_message,
    get_service,
    serialize_message,
    type_hash,
)

JointState = get_message("sensor_msgs/msg/JointState")
UInt8 = get_message("std_msgs/msg/UInt8")


@pytest.mark.parametrize("call, name", [
    (get_message, "sensor_msgs/msg/JointStat"),
    (get_message, "nonexistent_msgs/msg/Foo"),
    (get_message, "not a name"),
    (get_service, "std_srvs/srv/Trigge"),
    (get_service, "sensor_msgs/msg/JointState"),
    (get_action, "simulation_interfaces/action/Nope"),
    (type_hash, "std_msgs/msg/Strin"),
])
def test_unknown_names(call, name: str) -> None:
    with pytest.raises(UnknownTypeError) as info:
        call(name)
    assert isinstance(info.value, LookupError) and isinstance(info.value, InterfaceError)


def test_unknown_name_suggests_close_matches() -> None:
    with pytest.raises(UnknownTypeError, match="sensor_msgs/msg/JointState"):
        get_message("sensor_msgs/msg/JointStat")
    with pytest.raises(UnknownTypeError, match="known packages: .*std_msgs"):
        get_message("nonexistent_msgs/msg/Zzzzzz")


def test_the_hint_is_searched_only_when_the_message_is_read(monkeypatch) -> None:
    """A miss that is caught (another distribution without the type, a name tried as each kind) costs
    no search of every known name; the message, read or pickled to another process, has the hint."""
    import difflib
    import pickle

    searches: list[str] = []
    real = difflib.get_close_matches
    monkeypatch.setattr(difflib, "get_close_matches",
                        lambda word, *a, **k: searches.append(word) or real(word, *a, **k))
    with pytest.raises(UnknownTypeError) as info:
        get_message("sensor_msgs/msg/JointStat")
    assert searches == []
    copy = pickle.loads(pickle.dumps(info.value))
    assert "did you mean sensor_msgs/msg/JointState" in str(copy) and searches == ["sensor_msgs/msg/JointStat"]
    assert str(info.value) == str(copy) and info.value.args == (str(copy),)
    assert type_hash(get_message("sensor_msgs/msg/JointState")) and len(searches) == 1  # hits search nothing


@pytest.mark.parametrize("kwargs, exc, field", [
    ({"data": 300}, FieldValueError, "data"),
    ({"data": -1}, FieldValueError, "data"),
    ({"data": 1.5}, FieldError, "data"),
    ({"data": "1"}, FieldError, "data"),
    ({"bogus": 1}, FieldError, "bogus"),
])
def test_construction_validates_scalars(kwargs: dict, exc: type, field: str) -> None:
    with pytest.raises(exc) as info:
        UInt8(**kwargs)
    assert info.value.type_name == "std_msgs/msg/UInt8" and field in str(info.value)


@pytest.mark.parametrize("kwargs, exc, field", [
    ({"name": "abc"}, FieldError, "name"),
    ({"name": ["a", 3]}, FieldError, "name[1]"),
    ({"position": ["x"]}, FieldError, "position"),
    ({"position": [[1.0, 2.0]]}, FieldValueError, "position"),
    ({"header": 5}, FieldError, "header"),
    ({"header": {"frame_id": 7}}, FieldError, "header.frame_id"),
])
def test_construction_validates_containers(kwargs: dict, exc: type, field: str) -> None:
    with pytest.raises(exc) as info:
        JointState(**kwargs)
    assert "sensor_msgs/msg/JointState" in str(info.value) and field in str(info.value)


def test_bounds_and_fixed_lengths() -> None:
    uuid = get_message("unique_identifier_msgs/msg/UUID")
    with pytest.raises(FieldValueError, match="uuid.*16"):
        uuid(uuid=b"\x01" * 15)
    with pytest.raises(FieldValueError, match=r"k.*exactly 9"):
        get_message("sensor_msgs/msg/CameraInfo")(k=[1.0] * 8)
    with pytest.raises(FieldValueError, match="floating_point_range.*bound 1"):
        get_message("rcl_interfaces/msg/ParameterDescriptor")(floating_point_range=[{}, {}])
    with pytest.raises(FieldValueError, match=r"data.*\[-128, 127\]"):
        get_message("std_msgs/msg/Int8MultiArray")(data=[1, 200])
    with pytest.raises(FieldValueError):
        get_message("std_msgs/msg/UInt8MultiArray")(data=[1, 256])


def test_bounded_string_defined_inline() -> None:
    from multiros.ros.interfaces._classgen import build_message_class
    from multiros.ros.interfaces.idl import parse_message

    cls = build_message_class(parse_message("string<=4 s\nstring<=3[<=2] names", "t_msgs/msg/B"), None)
    assert cls(s="abcd").s == "abcd"
    with pytest.raises(FieldValueError, match="t_msgs/msg/B.s"):
        cls(s="abcde")
    with pytest.raises(FieldValueError, match=r"names\[0\]"):
        cls(names=["abcd"])
    with pytest.raises(FieldValueError, match="names"):
        cls(names=["a", "b", "c"])


@pytest.mark.parametrize("field, value, exc", [
    ("position", "oops", FieldError),
    ("name", [1], FieldError),
    ("header", None, FieldError),
])
def test_serialization_validates_assigned_fields(field: str, value: object, exc: type) -> None:
    msg = JointState()
    setattr(msg, field, value)
    with pytest.raises(exc, match=f"sensor_msgs/msg/JointState.{field}"):
        serialize_message(msg)


def test_serialization_names_out_of_range_field_in_packed_run() -> None:
    pose = get_message("geometry_msgs/msg/Pose")()
    pose.orientation.z = "x"
    with pytest.raises(FieldError, match="orientation.z"):
        serialize_message(pose)
    stamp = get_message("builtin_interfaces/msg/Time")()
    stamp.nanosec = 2**32
    with pytest.raises(FieldValueError, match="nanosec"):
        serialize_message(stamp)


def _samples() -> list[tuple[str, bytes]]:
    names = ["sensor_msgs/msg/JointState", "std_msgs/msg/String", "visualization_msgs/msg/Marker",
             "simulation_interfaces/srv/GetEntitiesStates_Response", "uniros_interfaces/srv/StepRobot_Response",
             "rcl_interfaces/msg/ParameterDescriptor", "sensor_msgs/msg/CameraInfo", "std_msgs/msg/Empty"]
    return [(n, serialize_message(random_message(n, random.Random(3)))) for n in names]


@pytest.mark.parametrize("type_name, data", _samples())
def test_every_prefix_is_rejected(type_name: str, data: bytes) -> None:
    for cut in range(len(data)):
        prefix = data[:cut]
        try:
            deserialize_message(prefix, type_name)
        except DeserializationError as exc:
            assert type_name in str(exc)
        else:  # only legal if what was cut is the zero end padding a sender may add
            assert cut >= len(data) - 3 and not any(data[cut:]) and (cut - 4) % 4 == 0


@pytest.mark.parametrize("type_name, data", _samples())
def test_random_bytes_and_bit_flips(type_name: str, data: bytes) -> None:
    rng = random.Random(11)
    for i in range(400):
        if i % 2:
            blob = bytes(rng.randrange(256) for _ in range(rng.randrange(4, 200)))
            blob = b"\x00\x01\x00\x00" + blob[4:]
        else:
            corrupt = bytearray(data)
            for _ in range(rng.randint(1, 4)):
                corrupt[rng.randrange(len(corrupt))] = rng.randrange(256)
            blob = bytes(corrupt)
        try:
            msg = deserialize_message(blob, type_name)
        except DeserializationError as exc:
            assert type_name in str(exc)
        else:  # decoded: a valid message that survives a round trip (padding/bool bytes may differ)
            again = serialize_message(msg)
            assert serialize_message(deserialize_message(again, type_name)) == again


def test_absurd_sequence_length_is_rejected_quickly() -> None:
    data = bytearray(serialize_message(get_message("std_msgs/msg/Float64MultiArray")(data=[1.0])))
    data[4:8] = (0xFFFFFFF0).to_bytes(4, "little")  # layout.dim count
    with pytest.raises(DeserializationError, match=r"layout\.dim"):
        deserialize_message(bytes(data), "std_msgs/msg/Float64MultiArray")


def test_bad_header() -> None:
    with pytest.raises(DeserializationError, match="encapsulation"):
        deserialize_message(b"\x00\x02\x00\x00\x00", "std_msgs/msg/Empty")
    with pytest.raises(DeserializationError):
        deserialize_message(b"", "std_msgs/msg/Empty")


def test_non_utf8_string() -> None:
    data = bytearray(serialize_message(get_message("std_msgs/msg/String")(data="ab")))
    data[8] = 0xFF
    with pytest.raises(DeserializationError, match="std_msgs/msg/String.data.*UTF-8"):
        deserialize_message(bytes(data), "std_msgs/msg/String")


def test_numpy_values_accepted() -> None:
    msg = JointState(position=np.array([1, 2], dtype=np.int32))
    assert msg.position.dtype == np.float64
    assert UInt8(data=np.uint8(7)).data == 7
