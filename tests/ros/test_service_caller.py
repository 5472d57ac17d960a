"""``current_caller()``: the client whose request a service callback serves, on every path (in-process,
Zenoh from a uniros client and from a foreign peer, rclpy's request header), and ``None`` outside a
callback or where the transport cannot tell."""

from __future__ import annotations

import struct
import time
from types import SimpleNamespace

from raw_zenoh import open_peer_session, query_until_answered

from multiros import ros
from multiros.ros.interfaces import dds_type_name, get_service, serialize_message, type_hash
from multiros.ros.service import current_caller

AddTwoInts = get_service("example_interfaces/srv/AddTwoInts")


def _recording_service(node: ros.Node, seen: list) -> ros.Service:
    def add(req, res):
        seen.append(current_caller())
        res.sum = req.a + req.b
        return res

    return node.create_service(AddTwoInts, "/add", add)


def test_in_process_callers_are_each_client(ctx: ros.Context) -> None:
    seen: list = []
    _recording_service(ros.Node("server", context=ctx), seen)
    one, two = (ros.Node(n, context=ctx, namespace="/ns").create_client(AddTwoInts, "/add") for n in ("a", "b"))
    one.call(AddTwoInts.Request(a=1, b=2))
    two.call(AddTwoInts.Request(a=1, b=2))
    assert one.call_async(AddTwoInts.Request(a=1, b=1)).result().sum == 2
    assert seen == [one.caller_id, two.caller_id, one.caller_id]
    assert one.caller_id.startswith("inproc:/ns/a#") and one.caller_id != two.caller_id
    assert current_caller() is None  # outside a callback


def test_zenoh_callers_are_their_gids(zenoh_ctx: ros.Context, zenoh_peer_ctx: ros.Context,
                                      router_endpoint: str) -> None:
    seen: list = []
    _recording_service(ros.Node("server", context=zenoh_ctx), seen)
    cli = ros.Node("client", context=zenoh_peer_ctx).create_client(AddTwoInts, "/add")
    assert cli.wait_for_service(timeout_sec=10.0)
    assert cli.call(AddTwoInts.Request(a=2, b=40), timeout_sec=10.0).sum == 42
    assert seen == ["zenoh:" + cli._wire.gid.hex()]

    # A foreign peer names itself: whatever GID it puts in the attachment is what the callback sees.
    session = open_peer_session(router_endpoint)
    try:
        domain = zenoh_ctx.domain_id
        key = f"{domain}/add/{dds_type_name('example_interfaces/srv/AddTwoInts')}/{type_hash(AddTwoInts)}"
        gid = bytes(range(100, 116))
        query_until_answered(session, key, payload=serialize_message(AddTwoInts.Request(a=1, b=1)), timeout=10.0,
                             attachment=lambda: struct.pack("<qqB", 1, time.time_ns(), 16) + gid)
        assert seen[1:] == ["zenoh:" + gid.hex()]
    finally:
        session.close()


def test_rclpy_callers_are_their_writer_guids(ctx: ros.Context) -> None:
    """The rclpy transport hands the lane's writer GUID to the callback; a request whose client it
    cannot read (a lane of its own) is anonymous. (No rclpy needed: the handle's serving step only.)"""
    from multiros.ros.transport.rclpy.transport import _ServiceHandle

    seen: list = []
    srv = _recording_service(ros.Node("server", context=ctx), seen)
    handle = object.__new__(_ServiceHandle)
    replies: list = []
    handle._srv_entity = srv
    handle._request_type = AddTwoInts.Request
    handle.transport = SimpleNamespace(from_rclpy=lambda request, _type: request)
    handle._reply = lambda response, header: replies.append(response.sum)
    guid = bytes(range(16))
    handle._take(AddTwoInts.Request(a=1, b=2), None, guid)
    handle._take(AddTwoInts.Request(a=2, b=2), None, ("request", 7))
    assert seen == ["dds:" + guid.hex(), None] and replies == [3, 4]
