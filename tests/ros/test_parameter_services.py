"""A node's parameters over its rcl_interfaces services (what `ros2 param` calls): list, get, describe,
set, read-only refused with the reason, hostile values refused, never an exception."""

from __future__ import annotations

import pytest

from multiros import ros
from multiros.ros.interfaces import get_message, get_service
from multiros.ros.parameter_services import ParameterServices, from_value_msg, list_names, to_value_msg
from multiros.ros.parameters import Parameter, ParameterDescriptor

Value = get_message("rcl_interfaces/msg/ParameterValue")
ParamMsg = get_message("rcl_interfaces/msg/Parameter")


@pytest.fixture
def served():
    ctx = ros.Context(transport="inproc").init()
    node = ros.Node("sim", context=ctx)
    node.declare_parameter("max_robots", 256, ParameterDescriptor(read_only=True, description="most robots"))
    node.declare_parameter("gains.kp", 10.0)
    node.declare_parameter("gains.inner.ki", [1, 2])
    services = ParameterServices(node)
    user = ros.Node("user", context=ctx)

    def call(name: str, /, **fields):
        srv = get_service(services_types[name])
        return user.create_client(srv, f"/sim/{name}").call(srv.Request(**fields), timeout_sec=5.0)

    services_types = {"list_parameters": "rcl_interfaces/srv/ListParameters",
                      "get_parameters": "rcl_interfaces/srv/GetParameters",
                      "get_parameter_types": "rcl_interfaces/srv/GetParameterTypes",
                      "describe_parameters": "rcl_interfaces/srv/DescribeParameters",
                      "set_parameters": "rcl_interfaces/srv/SetParameters",
                      "set_parameters_atomically": "rcl_interfaces/srv/SetParametersAtomically"}
    yield node, call
    services.destroy()
    ctx.try_shutdown()


def test_list_get_describe(served) -> None:
    node, call = served
    listed = call("list_parameters").result
    assert set(listed.names) == {"use_sim_time", "max_robots", "gains.kp", "gains.inner.ki"}
    assert set(listed.prefixes) == {"gains", "gains.inner"}
    assert call("list_parameters", prefixes=["gains"], depth=1).result.names == ["gains.kp"]
    values = call("get_parameters", names=["max_robots", "gains.kp", "missing"]).values
    assert [v.type for v in values] == [2, 3, 0]
    assert values[0].integer_value == 256 and values[1].double_value == 10.0
    assert list(call("get_parameter_types", names=["gains.inner.ki", "x"]).types) == [7, 0]
    (desc,) = call("describe_parameters", names=["max_robots"]).descriptors
    assert desc.read_only and desc.description == "most robots" and desc.type == 2


def test_set_refuses_read_only_and_wrong_types_with_the_reason(served) -> None:
    node, call = served
    results = call("set_parameters", parameters=[
        ParamMsg(name="max_robots", value=Value(type=2, integer_value=1)),
        ParamMsg(name="gains.kp", value=Value(type=3, double_value=2.5)),
        ParamMsg(name="gains.kp", value=Value(type=4, string_value="high")),
        ParamMsg(name="gains.kp", value=Value(type=42)),
        ParamMsg(name="gains.kp", value=Value(type=0)),
        ParamMsg(name="undeclared", value=Value(type=1, bool_value=True)),
    ]).results
    assert [r.successful for r in results] == [False, True, False, False, False, False]
    assert "read-only" in results[0].reason
    assert "DOUBLE" in results[2].reason and "unknown ParameterValue type 42" in results[3].reason
    assert "NOT_SET" in results[4].reason and "undeclared" in results[5].reason
    assert node.get_parameter("max_robots").value == 256 and node.get_parameter("gains.kp").value == 2.5
    atomic = call("set_parameters_atomically", parameters=[
        ParamMsg(name="gains.kp", value=Value(type=3, double_value=7.0)),
        ParamMsg(name="max_robots", value=Value(type=2, integer_value=1)),
    ]).result
    assert not atomic.successful and "read-only" in atomic.reason
    assert node.get_parameter("gains.kp").value == 2.5  # all or nothing


def test_values_round_trip_through_their_messages() -> None:
    for value in (True, 3, 2.5, "s", b"\x01\x02", [True, False], [1, 2], [0.5], ["a", "b"]):
        param = Parameter("p", value=value)
        back = from_value_msg("p", to_value_msg(param))
        assert back == param, value


def test_list_names_depth() -> None:
    names = ["a", "b.c", "b.d.e"]
    assert list_names(names, [], 1) == (["a"], [])
    assert list_names(names, [], 0) == (["a", "b.c", "b.d.e"], ["b", "b.d"])
    assert list_names(names, ["b"], 1) == (["b.c"], ["b"])


def test_nodes_serve_them_only_where_ros_tools_reach() -> None:
    ctx = ros.Context(transport="inproc").init()
    try:
        assert ros.Node("n", context=ctx).get_service_names_and_types() == []
    finally:
        ctx.try_shutdown()


def test_what_one_request_may_cost_is_bounded(served) -> None:
    """A flood takes its turn: more than MAX_NAMES names or parameters is refused at once, huge values are
    refused before they are decoded, and no reason is longer than MAX_REASON characters."""
    import time

    from multiros.ros.parameter_services import MAX_ARRAY, MAX_NAMES, MAX_REASON

    node, call = served
    many = [ParamMsg(name=f"flood.p{i}", value=Value(type=2, integer_value=i)) for i in range(10_000)]
    start = time.monotonic()
    results = call("set_parameters", parameters=many).results
    assert len(results) == 1 and not results[0].successful  # one refusal, not 10,000
    assert f"at most {MAX_NAMES} parameters" in results[0].reason
    assert not call("set_parameters_atomically", parameters=many).result.successful
    assert list(call("get_parameters", names=[f"p{i}" for i in range(MAX_NAMES + 1)]).values) == []
    assert list(call("describe_parameters", names=[f"p{i}" for i in range(MAX_NAMES + 1)]).descriptors) == []
    assert list(call("list_parameters", prefixes=[f"p{i}" for i in range(MAX_NAMES + 1)]).result.names) == []
    assert list(call("list_parameters", prefixes=["gains"]).result.names) == ["gains.inner.ki", "gains.kp"]
    assert time.monotonic() - start < 5.0
    huge = ParamMsg(name="gains.kp", value=Value(type=7, integer_array_value=list(range(MAX_ARRAY + 1))))
    (result,) = call("set_parameters", parameters=[huge]).results
    assert not result.successful and f"at most {MAX_ARRAY:,}" in result.reason
    long_name = ParamMsg(name="x" * 100_000, value=Value(type=1, bool_value=True))
    (result,) = call("set_parameters", parameters=[long_name]).results
    assert not result.successful and len(result.reason) <= MAX_REASON
    assert node.get_parameter("gains.kp").value == 10.0 and "flood.p0" not in node._parameters.values


def test_every_parameter_service_is_bounded_in_bytes_and_items_and_refuses_what_is_over() -> None:
    """A transport that sees a request's CDR bytes (rclpy's) asks the service whether they are over its bounds
    (more bytes than MAX_REQUEST_BYTES, or more names than MAX_NAMES read from the first sequence's length)
    and for its refusal instead of decoding them: a set gets one refused result saying why, an atomic set a
    refused result, the others empty answers; a request within both is not over."""
    from multiros.ros.interfaces import first_sequence_length, serialize_message
    from multiros.ros.parameter_services import MAX_NAMES, MAX_REQUEST_BYTES

    ctx = ros.Context(transport="inproc").init()
    try:
        services = ParameterServices(ros.Node("sim", context=ctx))
        by_name = {srv.srv_name.rsplit("/", 1)[1]: srv for srv in services.services}
        assert all(srv.max_request_bytes == MAX_REQUEST_BYTES and srv.max_request_items == MAX_NAMES
                   for srv in services.services)
        Get, Set = get_service("rcl_interfaces/srv/GetParameters"), get_service("rcl_interfaces/srv/SetParameters")
        many = serialize_message(Get.Request(names=[f"p{i}" for i in range(MAX_NAMES + 1)]))  # 3 KB
        assert len(many) < MAX_REQUEST_BYTES and first_sequence_length(many) == MAX_NAMES + 1
        assert by_name["get_parameters"].over_bound(many) == f"a request of {MAX_NAMES + 1} items; at most {MAX_NAMES}"
        assert by_name["get_parameters"].over_bound(serialize_message(Get.Request(names=["a"] * MAX_NAMES))) is None
        huge = ParamMsg(name="s", value=to_value_msg(Parameter("s", value="x" * 300_000)))
        big = serialize_message(Set.Request(parameters=[huge]))
        why = by_name["set_parameters"].over_bound(big)
        assert why == f"a request of {len(big):,} bytes; at most 262,144"
        (result,) = by_name["set_parameters"]._refused(why).results
        assert not result.successful and result.reason == f"refused: {why}"
        atomic = by_name["set_parameters_atomically"]._refused("a request of 300 items; at most 256").result
        assert not atomic.successful and "300 items" in atomic.reason
        assert list(by_name["get_parameters"]._refused("x").values) == []
        assert list(by_name["list_parameters"]._refused("x").result.names) == []
        assert first_sequence_length(b"\x00\x01\x00\x00") is None  # too short
        assert first_sequence_length(b"\x00\x07\x00\x00\x05\x00\x00\x00") is None  # not plain CDR
        assert first_sequence_length(b"\x00\x00\x00\x00\x00\x00\x01\x00") == 256  # big endian
        with pytest.raises(ValueError, match="max_bytes"):
            services.services[0].bound_requests(0)
        with pytest.raises(ValueError, match="max_items"):
            services.services[0].bound_requests(10, max_items=-1)
    finally:
        ctx.try_shutdown()
