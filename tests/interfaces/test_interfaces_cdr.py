"""CDR bytes against rosbags (independent implementation) and round trips for every shipped type."""

from __future__ import annotations

import random
import re

import numpy as np
import pytest
from interfaces_factory import random_message, to_rosbags
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from multiros.ros.interfaces import (
    DeserializationError,
    default_registry,
    deserialize_message,
    get_message,
    get_service,
    list_types,
    serialize_message,
)

JAZZY = get_typestore(Stores.ROS2_JAZZY)
COMMON = [n for n in list_types("msg") if n in JAZZY.fielddefs]
OWN_ONLY = [n for n in list_types("msg") if n not in JAZZY.fielddefs]


def _service_messages() -> list[str]:
    reg = default_registry()
    names = []
    for srv in list_types("srv"):
        spec = reg.service_spec(srv)
        names += [spec.request.name, spec.response.name, spec.event.name]
    for action in list_types("action"):
        a = reg.action_spec(action)
        names += [a.goal.name, a.result.name, a.feedback.name, a.feedback_message.name,
                  a.send_goal.request.name, a.send_goal.response.name,
                  a.get_result.request.name, a.get_result.response.name]
    return names


SERVICE_MESSAGES = _service_messages()


def _oracle_store(registry=None, store=None):
    """rosbags typestore holding Jazzy plus every type of ``registry`` (default: the default one),
    parsed by rosbags' own parser from the same definition files."""
    registry = registry or default_registry()
    store = store or get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for full in registry.list_types():
        path = registry.definition_file(full)
        pkg, kind, text = path.parent.parent.name, path.parent.name, path.read_text()
        name = f"{pkg}/{kind}/{path.stem}"
        if kind == "msg" and name not in store.fielddefs:
            types.update(get_types_from_msg(text, name))
        elif kind in ("srv", "action"):
            parts = re.split(r"^---[ \t]*$", text, flags=re.M)
            suffixes = ("_Request", "_Response") if kind == "srv" else ("_Goal", "_Result", "_Feedback")
            for part, suffix in zip(parts, suffixes):
                # rosbags resolves relative names only for pkg/msg/ names: parse as msg, then rename
                parsed = get_types_from_msg(part, f"{pkg}/msg/{path.stem}{suffix}")
                types.update({k.replace(f"{pkg}/msg/{path.stem}{suffix}", f"{name}{suffix}"): v
                              for k, v in parsed.items()})
    store.register(types)
    return store


ORACLE = _oracle_store()


@pytest.mark.parametrize("type_name", COMMON)
def test_bytes_identical_to_rosbags(type_name: str) -> None:
    for seed in range(4):
        msg = random_message(type_name, random.Random(seed))
        ours = serialize_message(msg)
        theirs = bytes(JAZZY.serialize_cdr(to_rosbags(msg, JAZZY), type_name))
        assert ours == theirs, f"{type_name} seed {seed}"
        assert deserialize_message(theirs, type_name) == msg
        big = bytes(JAZZY.serialize_cdr(to_rosbags(msg, JAZZY), type_name, little_endian=False))
        assert deserialize_message(big, type_name) == msg


@pytest.mark.parametrize("type_name", COMMON)
def test_default_message_identical_to_rosbags(type_name: str) -> None:
    msg = get_message(type_name)()
    theirs = bytes(JAZZY.serialize_cdr(to_rosbags(msg, JAZZY), type_name))
    assert serialize_message(msg) == theirs
    assert deserialize_message(theirs, type_name) == msg


@pytest.mark.parametrize("type_name", OWN_ONLY + [n for n in SERVICE_MESSAGES if "_Event" not in n])
def test_round_trip_and_oracle(type_name: str) -> None:
    """simulation_interfaces, uniros_interfaces, services: round trip; rosbags checks what it can parse."""
    for seed in range(4):
        msg = random_message(type_name, random.Random(seed))
        data = serialize_message(msg)
        assert deserialize_message(data, type(msg)) == msg
        assert deserialize_message(data + b"\x00" * (-len(data) % 4), type(msg)) == msg  # ROS end padding
        if type_name in ORACLE.fielddefs:
            assert bytes(ORACLE.serialize_cdr(to_rosbags(msg, ORACLE), type_name)) == data


@pytest.mark.parametrize("type_name", [n for n in SERVICE_MESSAGES if n.endswith("_Event")])
def test_service_event_round_trip(type_name: str) -> None:
    msg = random_message(type_name, random.Random(7))
    assert deserialize_message(serialize_message(msg), type_name) == msg


def test_empty_message_is_one_byte() -> None:
    assert serialize_message(get_message("std_msgs/msg/Empty")()) == b"\x00\x01\x00\x00\x00"
    assert serialize_message(get_service("std_srvs/srv/Empty").Request()) == b"\x00\x01\x00\x00\x00"


def test_known_joint_state_bytes() -> None:
    js = get_message("sensor_msgs/msg/JointState")(name=["a"], position=[1.0])
    data = serialize_message(js)
    assert data[:4] == b"\x00\x01\x00\x00"
    assert data.hex() == ("00010000" "00000000" "00000000" "01000000" "00" "000000"
                          "01000000" "02000000" "6100" "0000" "01000000" "000000000000f03f"
                          "00000000" "00000000")


def test_trailing_garbage_rejected() -> None:
    data = serialize_message(get_message("std_msgs/msg/String")(data="abc"))
    with pytest.raises(DeserializationError, match="unexpected bytes"):
        deserialize_message(data + b"\x01", "std_msgs/msg/String")
    with pytest.raises(DeserializationError, match="unexpected bytes"):
        deserialize_message(data + b"\x00" * 8, "std_msgs/msg/String")


def test_numpy_arrays_are_writable_copies() -> None:
    js = get_message("sensor_msgs/msg/JointState")(position=[1.0, 2.0])
    back = deserialize_message(serialize_message(js), type(js))
    back.position[0] = 5.0
    assert back.position.dtype == np.float64 and back.position[0] == 5.0

