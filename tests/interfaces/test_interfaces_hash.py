"""RIHS01 type hashes: published known answers and rosbags' independent ``hash_rihs01``."""

from __future__ import annotations

import re

import pytest
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from test_interfaces_cdr import ORACLE

from multiros.ros.interfaces import list_types, type_description, type_hash

JAZZY = get_typestore(Stores.ROS2_JAZZY)
HASH = re.compile(r"^RIHS01_[0-9a-f]{64}$")


def test_known_answers() -> None:
    # ros2/rmw_zenoh docs/design.md, reproduced in reference/ros2_wire.md §1.7 and §2.1
    assert type_hash("std_msgs/msg/String") == (
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18")
    assert type_hash("example_interfaces/srv/AddTwoInts") == (
        "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a")
    assert type_hash("std_msgs/String") == type_hash("std_msgs/msg/String")


def _has_char(name: str, store, seen: set[str] | None = None) -> bool:
    seen = seen if seen is not None else set()
    if name in seen:
        return False
    seen.add(name)
    for _, desc in store.fielddefs[name][1]:
        text = repr(desc)
        if "'char'" in text:
            return True
        if any(_has_char(n, store, seen) for n in re.findall(r"'([a-z_0-9]+/\w+/\w+)'", text)):
            return True
    return False


_NO_CHAR = [n for n in list_types("msg") if n in JAZZY.fielddefs and not _has_char(n, JAZZY)]
_WITH_CHAR = [n for n in list_types("msg") if n in JAZZY.fielddefs and _has_char(n, JAZZY)]


@pytest.mark.parametrize("type_name", _NO_CHAR)
def test_message_hash_matches_rosbags(type_name: str) -> None:
    assert type_hash(type_name) == JAZZY.hash_rihs01(type_name)


def _char_fixed_store():
    """ORACLE with rosbags' char mapped to uint8, as rosidl does, plus service/event structs."""
    def fix(desc):
        if desc[0] == Nodetype.BASE and desc[1][0] == "char":
            return (Nodetype.BASE, ("uint8", desc[1][1]))
        if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            return (desc[0], (fix(desc[1][0]), desc[1][1]))
        return desc

    store = get_typestore(Stores.EMPTY)
    types = {name: (consts, [(f, fix(d)) for f, d in fields]) for name, (consts, fields) in ORACLE.fielddefs.items()}
    for srv in list_types("srv"):
        req, resp, event = f"{srv}_Request", f"{srv}_Response", f"{srv}_Event"
        types[event] = ([], [
            ("info", (Nodetype.NAME, "service_msgs/msg/ServiceEventInfo")),
            ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, req), 1))),
            ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, resp), 1))),
        ])
        types[srv] = ([], [("request_message", (Nodetype.NAME, req)), ("response_message", (Nodetype.NAME, resp)),
                           ("event_message", (Nodetype.NAME, event))])
    store.register(types)
    return store


FIXED = _char_fixed_store()


@pytest.mark.parametrize("type_name", _WITH_CHAR + [n for n in list_types("msg") if n not in JAZZY.fielddefs])
def test_message_hash_matches_char_fixed_rosbags(type_name: str) -> None:
    assert type_hash(type_name) == FIXED.hash_rihs01(type_name)


@pytest.mark.parametrize("type_name", list_types("srv"))
def test_service_hash_matches_char_fixed_rosbags(type_name: str) -> None:
    assert type_hash(type_name) == FIXED.hash_rihs01(type_name)


def test_stock_rosbags_char_pitfall_is_avoided() -> None:
    # stock rosbags maps char to FIELD_TYPE_CHAR (13); rosidl uses UINT8 (3)
    name = "service_msgs/msg/ServiceEventInfo"
    assert type_hash(name) != JAZZY.hash_rihs01(name)
    gid = type_description(name)["type_description"]["fields"][2]
    assert gid["name"] == "client_gid" and gid["type"]["type_id"] == 3 + 48 and gid["type"]["capacity"] == 16


@pytest.mark.parametrize("type_name", list_types())
def test_every_shipped_type_hashes(type_name: str) -> None:
    assert HASH.match(type_hash(type_name))


def test_bounded_fields_in_description() -> None:
    fields = {f["name"]: f["type"] for f in
              type_description("rcl_interfaces/msg/ParameterDescriptor")["type_description"]["fields"]}
    assert fields["floating_point_range"] == {
        "type_id": 1 + 96, "capacity": 1, "string_capacity": 0,
        "nested_type_name": "rcl_interfaces/msg/FloatingPointRange"}


def test_action_hash_is_stable_and_distinct() -> None:
    name = "simulation_interfaces/action/SimulateSteps"
    desc = type_description(name)
    assert [f["name"] for f in desc["type_description"]["fields"]] == [
        "goal", "result", "feedback", "send_goal_service", "get_result_service", "feedback_message"]
    refs = [r["type_name"] for r in desc["referenced_type_descriptions"]]
    assert refs == sorted(refs) and "unique_identifier_msgs/msg/UUID" in refs
    assert type_hash(name) != type_hash(f"{name}_Goal")
