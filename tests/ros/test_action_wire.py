"""Actions on the rmw_zenoh wire: a foreign peer (raw eclipse-zenoh + rosbags CDR) drives our
action server on the exact keys; fuzzed payloads on the action keys leave it answering; a result
wait longer than one request's timeout; plain Zenoh subscribers get our messages."""

from __future__ import annotations

import random
import struct
import threading
import time

import pytest
import zenoh
from raw_zenoh import open_peer_session
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from multiros import ros
from multiros.ros.action import STATUS_SUCCEEDED, ActionClient, ActionServer, CancelResponse
from multiros.ros.interfaces import get_action, get_message, type_hash
from multiros.ros.transport.zenoh import wire

SimulateSteps = get_action("simulation_interfaces/action/SimulateSteps")
String = get_message("std_msgs/msg/String")
PKG = "simulation_interfaces"
ACT = f"{PKG}/action/SimulateSteps_"

# Known answers: action_msgs/srv/CancelGoal from rosidl's generated code (Jazzy), the status
# array and the feedback message from rosbags' own hashing (messages have no char pitfall).
CANCEL_GOAL_HASH = "RIHS01_573d8b0a534451d7bc2ac8c5ffde8ac14b8593b7001175d0cd6516dcbeb8689a"
STATUS_ARRAY_HASH = "RIHS01_6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e"


def _store():
    """rosbags with the action's derived types, parsed from plain text (an independent codec)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    defs = {
        f"{PKG}/msg/Result": "uint8 result\nstring error_message",
        f"{PKG}/action/SimulateSteps_Goal": "uint64 steps",
        f"{PKG}/action/SimulateSteps_Result": f"{PKG}/Result result",
        f"{PKG}/action/SimulateSteps_Feedback": "uint64 completed_steps\nuint64 remaining_steps",
        f"{PKG}/action/SimulateSteps_FeedbackMessage":
            f"unique_identifier_msgs/UUID goal_id\n{PKG}/action/SimulateSteps_Feedback feedback",
        f"{PKG}/action/SimulateSteps_SendGoal_Request":
            f"unique_identifier_msgs/UUID goal_id\n{PKG}/action/SimulateSteps_Goal goal",
        f"{PKG}/action/SimulateSteps_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp",
        f"{PKG}/action/SimulateSteps_GetResult_Request": "unique_identifier_msgs/UUID goal_id",
        f"{PKG}/action/SimulateSteps_GetResult_Response": f"int8 status\n{PKG}/action/SimulateSteps_Result result",
        "action_msgs/msg/CancelGoal_Request": "action_msgs/GoalInfo goal_info",
        "action_msgs/msg/CancelGoal_Response": "int8 return_code\naction_msgs/GoalInfo[] goals_canceling",
    }
    for name, text in defs.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def _session(endpoint: str) -> zenoh.Session:
    return open_peer_session(endpoint)


def _wait(predicate, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.005)
    return predicate()


def _execute(handle):
    steps = int(handle.request.steps)
    for i in range(steps):
        if handle.is_cancel_requested:
            handle.canceled()
            return SimulateSteps.Result()
        handle.publish_feedback(SimulateSteps.Feedback(completed_steps=i + 1, remaining_steps=steps - i - 1))
        time.sleep(0.02)
    handle.succeed()
    result = SimulateSteps.Result()
    result.result.result = 1
    result.result.error_message = f"{steps} steps"
    return result


def _keys(prefix: str) -> dict[str, str]:
    def key(suffix: str, type_name: str, dds: str) -> str:
        return f"0/{prefix}/_action/{suffix}/{dds}/{type_hash(type_name)}"

    keys = {
        "send_goal": key("send_goal", f"{PKG}/action/SimulateSteps_SendGoal",
                         f"{PKG}::action::dds_::SimulateSteps_SendGoal_"),
        "get_result": key("get_result", f"{PKG}/action/SimulateSteps_GetResult",
                          f"{PKG}::action::dds_::SimulateSteps_GetResult_"),
        "feedback": key("feedback", f"{PKG}/action/SimulateSteps_FeedbackMessage",
                        f"{PKG}::action::dds_::SimulateSteps_FeedbackMessage_"),
        "cancel_goal": f"0/{prefix}/_action/cancel_goal/action_msgs::srv::dds_::CancelGoal_/{CANCEL_GOAL_HASH}",
        "status": f"0/{prefix}/_action/status/action_msgs::msg::dds_::GoalStatusArray_/{STATUS_ARRAY_HASH}",
    }
    return keys


def _query(peer: zenoh.Session, key: str, payload: bytes, seq: int, timeout: float = 5.0) -> list:
    att = struct.pack("<qqB", seq, time.time_ns(), 16) + bytes(range(16))
    return list(peer.get(key, payload=payload, attachment=att, target=zenoh.QueryTarget.ALL_COMPLETE,
                         consolidation=zenoh.ConsolidationMode.NONE, timeout=timeout))


@pytest.mark.slow
def test_foreign_peer_drives_our_action_server(zenoh_ctx: ros.Context, router_endpoint: str) -> None:
    node = ros.Node("sim", context=zenoh_ctx, namespace="/robot1")
    server = ActionServer(node, SimulateSteps, "~/simulate_steps", _execute,
                          cancel_callback=lambda h: CancelResponse.ACCEPT)
    store = _store()
    keys = _keys("robot1/sim/simulate_steps")
    # The hashes we put in the keys: independent where an oracle exists.
    assert keys["feedback"].endswith(store.hash_rihs01(f"{PKG}/action/SimulateSteps_FeedbackMessage"))
    assert store.hash_rihs01("action_msgs/msg/GoalStatusArray") == STATUS_ARRAY_HASH
    peer = _session(router_endpoint)
    try:
        tokens = []
        lv = peer.liveliness().declare_subscriber("@ros2_lv/0/**", lambda s: tokens.append(str(s.key_expr)),
                                                  history=True)
        for kind, name in (("SS", "send_goal"), ("SS", "cancel_goal"), ("SS", "get_result"),
                           ("MP", "feedback"), ("MP", "status")):
            frag = f"/{kind}/%/%robot1/sim/%robot1%sim%simulate_steps%_action%{name}/"
            assert _wait(lambda f=frag: any(f in t for t in tokens)), (frag, tokens)
        assert any("%_action%status/action_msgs::msg::dds_::GoalStatusArray_/" in t and t.endswith(":1:,1:,:,:,,")
                   for t in tokens)  # status is transient local, depth 1
        # Plain Zenoh subscribers, no ROS liveliness token: they still get feedback and status.
        feedback, status = [], []
        subs = [peer.declare_subscriber(keys["feedback"], feedback.append),
                peer.declare_subscriber(keys["status"], status.append)]
        goal_id = bytes(range(100, 116))
        UUID = store.types["unique_identifier_msgs/msg/UUID"]
        Req = store.types[f"{PKG}/action/SimulateSteps_SendGoal_Request"]
        Goal = store.types[f"{PKG}/action/SimulateSteps_Goal"]
        payload = bytes(store.serialize_cdr(Req(goal_id=UUID(uuid=_u8(goal_id)), goal=Goal(steps=5)),
                                            f"{PKG}/action/SimulateSteps_SendGoal_Request"))
        assert _wait(lambda: server._feedback_pub._wire._matching)  # Zenoh saw the plain subscriber
        replies = _query(peer, keys["send_goal"], payload, 1)
        assert len(replies) == 1 and replies[0].ok is not None
        rseq, _, rgid = wire.decode_attachment(replies[0].ok.attachment.to_bytes())
        assert (rseq, rgid) == (1, bytes(range(16)))
        accepted = store.deserialize_cdr(replies[0].ok.payload.to_bytes(), f"{ACT}SendGoal_Response")
        assert accepted.accepted and accepted.stamp.sec > 0
        # get_result waits on the server until the goal ends.
        GR = store.types[f"{PKG}/action/SimulateSteps_GetResult_Request"]
        payload = bytes(store.serialize_cdr(GR(goal_id=UUID(uuid=_u8(goal_id))),
                                            f"{PKG}/action/SimulateSteps_GetResult_Request"))
        replies = _query(peer, keys["get_result"], payload, 2, timeout=10.0)
        assert len(replies) == 1 and replies[0].ok is not None
        result = store.deserialize_cdr(replies[0].ok.payload.to_bytes(), f"{ACT}GetResult_Response")
        assert result.status == STATUS_SUCCEEDED and result.result.result.error_message == "5 steps"
        assert _wait(lambda: len(feedback) == 5)
        fb = [store.deserialize_cdr(s.payload.to_bytes(), f"{ACT}FeedbackMessage") for s in feedback]
        assert [f.feedback.completed_steps for f in fb] == [1, 2, 3, 4, 5]
        assert bytes(fb[0].goal_id.uuid) == goal_id
        assert all(len(s.attachment.to_bytes()) == 33 for s in feedback)
        assert _wait(lambda: any(_status_of(store, s, goal_id) == STATUS_SUCCEEDED for s in status))
        seen = {_status_of(store, s, goal_id) for s in status}
        assert {1, 2, 4} <= seen  # accepted, executing, succeeded
        # Cancel: an unknown goal, then a running one.
        GI = store.types["action_msgs/msg/GoalInfo"]
        Time = store.types["builtin_interfaces/msg/Time"]
        CReq = store.types["action_msgs/msg/CancelGoal_Request"]

        def cancel(gid: bytes, seq: int):
            info = GI(goal_id=UUID(uuid=_u8(gid)), stamp=Time(sec=0, nanosec=0))
            data = bytes(store.serialize_cdr(CReq(goal_info=info), "action_msgs/msg/CancelGoal_Request"))
            (reply,) = _query(peer, keys["cancel_goal"], data, seq)
            return store.deserialize_cdr(reply.ok.payload.to_bytes(), "action_msgs/msg/CancelGoal_Response")

        assert cancel(b"\x09" * 16, 3).return_code == 2  # ERROR_UNKNOWN_GOAL_ID
        long_id = bytes(range(50, 66))
        payload = bytes(store.serialize_cdr(Req(goal_id=UUID(uuid=_u8(long_id)), goal=Goal(steps=500)),
                                            f"{PKG}/action/SimulateSteps_SendGoal_Request"))
        assert _query(peer, keys["send_goal"], payload, 4)[0].ok is not None
        answer = cancel(long_id, 5)
        assert answer.return_code == 0 and bytes(answer.goals_canceling[0].goal_id.uuid) == long_id
        payload = bytes(store.serialize_cdr(GR(goal_id=UUID(uuid=_u8(long_id))),
                                            f"{PKG}/action/SimulateSteps_GetResult_Request"))
        (reply,) = _query(peer, keys["get_result"], payload, 6)
        assert store.deserialize_cdr(reply.ok.payload.to_bytes(),
                                     f"{PKG}/action/SimulateSteps_GetResult_Response").status == 5  # CANCELED
        for sub in subs:
            sub.undeclare()
        lv.undeclare()
    finally:
        peer.close()


def _u8(data: bytes):
    import numpy as np

    return np.frombuffer(data, dtype=np.uint8).copy()


def _status_of(store, sample, goal_id: bytes) -> int | None:
    msg = store.deserialize_cdr(sample.payload.to_bytes(), "action_msgs/msg/GoalStatusArray")
    for st in msg.status_list:
        if bytes(st.goal_info.goal_id.uuid) == goal_id:
            return int(st.status)
    return None


@pytest.mark.slow
def test_fuzzed_action_requests_leave_the_server_answering(zenoh_ctx: ros.Context, router_endpoint: str) -> None:
    node = ros.Node("victim", context=zenoh_ctx)
    ActionServer(node, SimulateSteps, "/fuzzed", _execute, max_goals=4)
    keys = _keys("fuzzed")
    rng = random.Random(4321)
    good_att = wire.encode_attachment(1, 0, bytes(16))
    peer = _session(router_endpoint)
    try:
        assert _wait(lambda: bool(_query(peer, keys["send_goal"], b"", 1, timeout=0.5)), 10.0)
        for i in range(90):
            size = rng.choice([0, 3, 4, 20, 28, 36, 200])
            payload = b"\x00\x01\x00\x00" + rng.randbytes(size) if i % 2 else rng.randbytes(size)
            att = [None, rng.randbytes(rng.randint(0, 40)), good_att][i % 3]
            key = keys[("send_goal", "cancel_goal", "get_result")[i % 3]]
            replies = list(peer.get(key, payload=payload, attachment=att, timeout=3.0,
                                    target=zenoh.QueryTarget.ALL_COMPLETE))
            assert len(replies) == 1  # an answer every time: an error, or a well-formed reply
            peer.put(keys["feedback"], payload, attachment=att)
            peer.put(keys["status"], payload, attachment=att)
        # Floods of well-formed goals: at most max_goals active, the rest rejected, the server alive.
        other = ros.Context(transport="zenoh", env={}, router="none", router_endpoint=router_endpoint).init()
        try:
            client = ActionClient(ros.Node("c", context=other), SimulateSteps, "/fuzzed")
            assert client.wait_for_server(5.0)
            handles = [client.send_goal_async(SimulateSteps.Goal(steps=50)) for _ in range(12)]
            assert all(h.wait(5.0) for h in handles)
            assert 1 <= sum(h.result().accepted for h in handles) <= 4
            for h in handles:
                if h.result().accepted:
                    assert h.result().get_result(timeout_sec=10.0).status == STATUS_SUCCEEDED
            assert client.send_goal(SimulateSteps.Goal(steps=1), timeout_sec=5.0).status == STATUS_SUCCEEDED
        finally:
            other.shutdown()
    finally:
        peer.close()


@pytest.mark.slow
def test_result_wait_longer_than_one_request_timeout(router_endpoint: str) -> None:
    release = threading.Event()

    def slow(handle):
        release.wait(3.0)
        handle.succeed()
        return SimulateSteps.Result()

    with ros.Context(transport="zenoh", env={}, router_endpoint=router_endpoint, default_timeout_sec=0.3) as a, \
            ros.Context(transport="zenoh", env={}, router="none", router_endpoint=router_endpoint,
                        default_timeout_sec=0.3) as b:
        ActionServer(ros.Node("s", context=a), SimulateSteps, "/slow", slow)
        client = ActionClient(ros.Node("c", context=b), SimulateSteps, "/slow")
        assert client.wait_for_server(5.0)
        fut = client.send_goal_async(SimulateSteps.Goal())
        assert fut.wait(5.0) and fut.result().accepted
        result = fut.result().get_result_async()
        assert not result.wait(1.0)  # several 0.3 s requests went by, still waiting
        release.set()
        assert result.wait(5.0) and result.result().status == STATUS_SUCCEEDED


@pytest.mark.slow
def test_plain_zenoh_subscriber_gets_messages_without_a_ros_token(zenoh_ctx: ros.Context,
                                                                  router_endpoint: str) -> None:
    pub = ros.Node("talker", context=zenoh_ctx).create_publisher(String, "/plain", 10)
    handle = pub._wire
    assert not handle._matching  # nobody listens: nothing is serialized or put
    peer = _session(router_endpoint)
    try:
        got = []
        sub = peer.declare_subscriber("0/plain/**", got.append)  # a recorder/bridge: no liveliness token
        assert _wait(lambda: handle._matching)
        pub.publish(String(data="to anyone"))
        assert _wait(lambda: got)
        assert get_type_store_string(got[0].payload.to_bytes()) == "to anyone"
        sub.undeclare()
        assert _wait(lambda: not handle._matching)
    finally:
        peer.close()


def get_type_store_string(data: bytes) -> str:
    return get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(data, "std_msgs/msg/String").data
