"""ROS 2 actions (``multiros.ros.action``): goals, feedback, results, cancel, bounds, on both transports."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from multiros import ros
from multiros.ros.action import (
    STATUS_ABORTED,
    STATUS_CANCELED,
    STATUS_EXECUTING,
    STATUS_SUCCEEDED,
    STATUS_UNKNOWN,
    ActionClient,
    ActionServer,
    CancelResponse,
    GoalResponse,
    get_action_names_and_types,
)
from multiros.ros.action.server import MAX_RESULT_WAITERS
from multiros.ros.interfaces import get_action, get_service

SimulateSteps = get_action("simulation_interfaces/action/SimulateSteps")
CancelGoal = get_service("action_msgs/srv/CancelGoal")
Result = SimulateSteps.Result


class Behaviour:
    """A configurable execute callback: feedback per step, then succeed / abort / wait for cancel."""

    def __init__(self) -> None:
        self.release = threading.Event()
        self.started = threading.Event()
        self.mode = "succeed"

    def __call__(self, handle):
        self.started.set()
        steps = int(handle.request.steps)
        for i in range(steps):
            handle.publish_feedback(SimulateSteps.Feedback(completed_steps=i + 1, remaining_steps=steps - i - 1))
        if self.mode == "raise":
            raise ValueError("boom")
        if self.mode == "abort":
            handle.abort()
            return Result()
        if self.mode == "wait":
            deadline = time.monotonic() + 10.0
            while not handle.is_cancel_requested and not self.release.is_set() and time.monotonic() < deadline:
                time.sleep(0.005)
            if handle.is_cancel_requested:
                handle.canceled()
                res = Result()
                res.result.error_message = "stopped"
                return res
        handle.succeed()
        res = Result()
        res.result.error_message = f"done {steps}"
        return res


def _contexts(kind: str, endpoint: str) -> Iterator[tuple[ros.Context, ros.Context]]:
    if kind == "inproc":
        with ros.Context(transport="inproc", env={}) as ctx:
            yield ctx, ctx
        return
    with ros.Context(transport="zenoh", env={}, router_endpoint=endpoint, default_timeout_sec=5.0) as a, \
            ros.Context(transport="zenoh", env={}, router="none", router_endpoint=endpoint,
                        default_timeout_sec=5.0) as b:
        yield a, b


@pytest.fixture(params=["inproc", pytest.param("zenoh", marks=pytest.mark.slow)])
def pair(request, router_endpoint: str):
    """(server context, client context): one inproc context, or two Zenoh sessions."""
    yield from _contexts(request.param, router_endpoint)


@pytest.fixture
def setup(pair):
    server_ctx, client_ctx = pair
    behaviour = Behaviour()
    server_node = ros.Node("server", context=server_ctx)
    server = ActionServer(server_node, SimulateSteps, "steps", behaviour,
                          goal_callback=lambda g: GoalResponse.REJECT if g.steps == 13 else GoalResponse.ACCEPT,
                          cancel_callback=lambda h: CancelResponse.ACCEPT)
    client_node = ros.Node("client", context=client_ctx, namespace="/elsewhere")
    client = ActionClient(client_node, SimulateSteps, "/steps")
    assert client.wait_for_server(timeout_sec=5.0)
    # The server's services can be seen before the server sees the client's feedback subscription;
    # feedback published before that is not delivered (as with any ROS 2 topic): wait for it.
    assert _wait(lambda: server._feedback_pub.get_subscription_count() > 0)
    return behaviour, server, client


def _wait(predicate, timeout: float = 30.0) -> bool:  # a bound, not a sleep: returns when true
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.005)
    return predicate()


def test_goal_feedback_and_result(setup) -> None:
    _, server, client = setup
    feedback = []
    handle_future = client.send_goal_async(SimulateSteps.Goal(steps=3), feedback_callback=feedback.append)
    assert handle_future.wait(5.0)
    handle = handle_future.result()
    assert handle.accepted
    response = handle.get_result(timeout_sec=5.0)
    assert response.status == STATUS_SUCCEEDED and response.result.result.error_message == "done 3"
    assert _wait(lambda: len(feedback) == 3)
    assert [f.feedback.completed_steps for f in feedback] == [1, 2, 3]
    assert bytes(feedback[0].goal_id.uuid) == bytes(handle.goal_id.uuid)
    assert handle.status == STATUS_SUCCEEDED
    # The result stays available after the goal finished.
    assert handle.get_result_async() is handle.get_result_async()
    again = client._get_result_async(handle)
    assert again.wait(5.0) and again.result().status == STATUS_SUCCEEDED
    # The synchronous form.
    assert client.send_goal(SimulateSteps.Goal(steps=1), timeout_sec=5.0).status == STATUS_SUCCEEDED
    assert ("/steps", ["simulation_interfaces/action/SimulateSteps"]) in get_action_names_and_types(client._node)


def test_a_result_completes_after_the_feedback_sent_before_it(setup) -> None:
    """A slow feedback callback (a user writing each message to disk) must not lose feedback:
    the result waits for the feedback that arrived before it, which is delivered in order."""
    _, server, client = setup
    feedback, at_result = [], []

    def slow_consumer(msg) -> None:
        threading.Event().wait(0.1)  # the consumer's own work, not a wait for anything
        feedback.append(msg.feedback.completed_steps)

    handle = client.send_goal_async(SimulateSteps.Goal(steps=4), feedback_callback=slow_consumer)
    assert handle.wait(5.0) and handle.result().accepted
    result = handle.result().get_result_async()
    result.add_done_callback(lambda _: at_result.append(list(feedback)))
    assert result.wait(10.0) and result.result().status == STATUS_SUCCEEDED
    assert _wait(lambda: at_result)
    assert at_result == [[1, 2, 3, 4]]  # all of it, in order, before the result
    assert feedback == [1, 2, 3, 4]  # and nothing after it


def test_a_failing_feedback_callback_is_logged_and_delivery_goes_on(setup, caplog) -> None:
    _, server, client = setup
    seen = []

    def flaky(msg) -> None:
        seen.append(msg.feedback.completed_steps)
        if msg.feedback.completed_steps == 1:
            raise ValueError("consumer bug")

    with caplog.at_level("ERROR", logger="multiros.ros.action.client"):
        response = client.send_goal(SimulateSteps.Goal(steps=2), feedback_callback=flaky, timeout_sec=10.0)
    assert response.status == STATUS_SUCCEEDED and seen == [1, 2]
    assert "feedback callback of action '/steps' raised" in caplog.text and "consumer bug" in caplog.text


def test_a_feedback_callback_that_waits_for_a_result_times_out_instead_of_hanging(setup) -> None:
    _, server, client = setup
    waited = []
    handles = []
    have_handle = threading.Event()

    def impatient(msg) -> None:
        if not waited and have_handle.wait(5.0):
            try:
                handles[0].get_result(timeout_sec=0.2)
            except ros.ServiceTimeoutError as exc:  # its result is queued behind this very callback
                waited.append(exc)

    future = client.send_goal_async(SimulateSteps.Goal(steps=2), feedback_callback=impatient)
    assert future.wait(5.0)
    handles.append(future.result())
    have_handle.set()
    assert handles[0].get_result(timeout_sec=10.0).status == STATUS_SUCCEEDED
    assert len(waited) == 1


def test_rejected_goal(setup) -> None:
    _, server, client = setup
    assert client.send_goal(SimulateSteps.Goal(steps=13), timeout_sec=5.0) is None
    handle = client.send_goal_async(SimulateSteps.Goal(steps=13))
    assert handle.wait(5.0) and not handle.result().accepted
    with pytest.raises(RuntimeError, match="rejected"):
        handle.result().get_result_async()
    with pytest.raises(TypeError, match="SimulateSteps_Goal"):
        client.send_goal_async(SimulateSteps.Feedback())


def test_abort_and_failing_execute(setup) -> None:
    behaviour, _, client = setup
    behaviour.mode = "abort"
    assert client.send_goal(SimulateSteps.Goal(steps=1), timeout_sec=5.0).status == STATUS_ABORTED
    behaviour.mode = "raise"
    response = client.send_goal(SimulateSteps.Goal(steps=1), timeout_sec=5.0)
    assert response.status == STATUS_ABORTED and response.result == Result()


def test_cancel_and_cancel_answers(setup) -> None:
    behaviour, server, client = setup
    behaviour.mode = "wait"
    fut = client.send_goal_async(SimulateSteps.Goal(steps=0))
    assert fut.wait(5.0)
    handle = fut.result()
    assert behaviour.started.wait(5.0)
    assert _wait(lambda: handle.status == STATUS_EXECUTING)  # from the status topic
    cancel = handle.cancel_goal(timeout_sec=5.0)
    assert cancel.return_code == CancelGoal.Response.ERROR_NONE
    assert [bytes(g.goal_id.uuid) for g in cancel.goals_canceling] == [bytes(handle.goal_id.uuid)]
    result = handle.get_result(timeout_sec=5.0)
    assert result.status == STATUS_CANCELED and result.result.result.error_message == "stopped"
    # Canceling a finished goal, an unknown goal; a result for an unknown goal.
    assert handle.cancel_goal(timeout_sec=5.0).return_code == CancelGoal.Response.ERROR_GOAL_TERMINATED
    t = SimulateSteps.Impl
    unknown = client._types.uuid(uuid=b"\x01" * 16)
    res = client._cancel_client.call(CancelGoal.Request(goal_info=client._types.goal_info(goal_id=unknown)),
                                     timeout_sec=5.0)
    assert res.return_code == CancelGoal.Response.ERROR_UNKNOWN_GOAL_ID
    res = client._result_client.call(t.GetResultService.Request(goal_id=unknown), timeout_sec=5.0)
    assert res.status == STATUS_UNKNOWN


def test_cancel_rejected_by_default_and_client_timeout(pair) -> None:
    server_ctx, client_ctx = pair
    behaviour = Behaviour()
    behaviour.mode = "wait"
    ActionServer(ros.Node("s", context=server_ctx), SimulateSteps, "/slow", behaviour)
    client = ActionClient(ros.Node("c", context=client_ctx), SimulateSteps, "/slow")
    assert client.wait_for_server(5.0)
    start = time.monotonic()
    with pytest.raises(TimeoutError, match="/slow/_action/get_result"):
        client.send_goal(SimulateSteps.Goal(steps=0), timeout_sec=0.3)
    assert time.monotonic() - start < 3.0
    handle = client.send_goal_async(SimulateSteps.Goal(steps=0))
    assert handle.wait(5.0)
    assert handle.result().cancel_goal(timeout_sec=5.0).return_code == CancelGoal.Response.ERROR_REJECTED
    behaviour.release.set()
    assert handle.result().get_result(timeout_sec=5.0).status == STATUS_SUCCEEDED
    nobody = ActionClient(ros.Node("lonely", context=client_ctx), SimulateSteps, "/missing")
    assert not nobody.wait_for_server(timeout_sec=0.1)


def test_bad_goal_ids_and_bounds(ctx: ros.Context) -> None:
    behaviour = Behaviour()
    behaviour.mode = "wait"
    node = ros.Node("s", context=ctx)
    server = ActionServer(node, SimulateSteps, "/bounded", behaviour, max_goals=2, max_results=3, result_timeout=60)
    client = ActionClient(ros.Node("c", context=ctx), SimulateSteps, "/bounded")
    send = client._goal_client
    Req = SimulateSteps.Impl.SendGoalService.Request
    # All-zero goal id: rejected with a clear answer.
    assert not send.call(Req(goal_id=client._types.uuid(uuid=bytes(16)))).accepted
    first = client.send_goal_async(SimulateSteps.Goal(), goal_uuid=b"\x07" * 16).result()
    assert first.accepted
    # Duplicate goal id: rejected.
    assert not client.send_goal_async(SimulateSteps.Goal(), goal_uuid=b"\x07" * 16).result().accepted
    assert client.send_goal_async(SimulateSteps.Goal()).result().accepted
    # max_goals=2 active: the third is rejected before goal_callback runs.
    assert not client.send_goal_async(SimulateSteps.Goal()).result().accepted
    assert len(server.goal_handles()) == 2
    # A flood of get_result requests for a running goal stays bounded.
    futures = [client._result_client.call_async(
        SimulateSteps.Impl.GetResultService.Request(goal_id=first.goal_id)) for _ in range(MAX_RESULT_WAITERS + 5)]
    assert sum(f.done() for f in futures) == 5  # the 5 oldest were answered with an error
    assert all(isinstance(f.exception(), ros.ServiceCallError) for f in futures[:5])
    behaviour.release.set()
    assert _wait(lambda: all(f.done() for f in futures))
    assert futures[-1].result().status == STATUS_SUCCEEDED
    # Results kept: at most max_results finished goals.
    for _ in range(4):
        assert client.send_goal(SimulateSteps.Goal(), timeout_sec=5.0).status == STATUS_SUCCEEDED
    assert len(server._goals) <= 3 and len(server._finished) <= 3
    res = client._result_client.call(SimulateSteps.Impl.GetResultService.Request(goal_id=first.goal_id))
    assert res.status == STATUS_UNKNOWN  # forgotten: the oldest result went first


def test_results_expire_after_result_timeout(ctx: ros.Context) -> None:
    server = ActionServer(ros.Node("s", context=ctx), SimulateSteps, "/expire", Behaviour(), result_timeout=0.05)
    client = ActionClient(ros.Node("c", context=ctx), SimulateSteps, "/expire")
    handle = client.send_goal_async(SimulateSteps.Goal()).result()
    assert handle.get_result(5.0).status == STATUS_SUCCEEDED
    request = SimulateSteps.Impl.GetResultService.Request(goal_id=handle.goal_id)
    assert _wait(lambda: client._result_client.call(request).status == STATUS_UNKNOWN, 2.0)
    assert not server._goals


def test_destroying_the_node_stops_running_goals(ctx: ros.Context) -> None:
    behaviour = Behaviour()
    behaviour.mode = "wait"
    node = ros.Node("s", context=ctx)
    ActionServer(node, SimulateSteps, "/dying", behaviour)
    client = ActionClient(ros.Node("c", context=ctx), SimulateSteps, "/dying")
    handle = client.send_goal_async(SimulateSteps.Goal()).result()
    assert behaviour.started.wait(5.0)
    result = handle.get_result_async()
    node.destroy_node()  # the goal sees is_cancel_requested and ends
    assert result.wait(5.0)
    assert not client.server_is_ready()
    assert not node.waitables


def test_goal_handle_state_machine(ctx: ros.Context) -> None:
    handles = []
    server = ActionServer(ros.Node("s", context=ctx), SimulateSteps, "/sm", Behaviour(),
                          handle_accepted_callback=handles.append)  # never executed on its own
    client = ActionClient(ros.Node("c", context=ctx), SimulateSteps, "/sm")
    handle = client.send_goal_async(SimulateSteps.Goal()).result()
    (goal,) = handles
    with pytest.raises(RuntimeError, match="cannot go from ACCEPTED with event SUCCEED"):
        goal.succeed()
    with pytest.raises(TypeError, match="SimulateSteps_Feedback"):
        goal.publish_feedback(SimulateSteps.Goal())
    goal.execute()
    assert handle.get_result(5.0).status == STATUS_SUCCEEDED
    with pytest.raises(RuntimeError, match="cannot execute"):
        goal.execute()
    assert server.goal_handles() == []


def test_a_feedback_variant_must_share_goal_and_result(ctx: ros.Context) -> None:
    """``feedback_variants`` is for another distribution's definition differing in feedback only."""
    node = ros.Node("variants", context=ctx)
    other = get_action("control_msgs/action/FollowJointTrajectory")
    with pytest.raises(ValueError, match="in more than its feedback"):
        ActionServer(node, SimulateSteps, "/variant", Behaviour(), feedback_variants=[(other, lambda fb: fb)])
    assert not [name for name, _ in node.get_topic_names_and_types() if name.startswith("/variant")]


def test_a_feedback_flood_cannot_hold_a_result_back() -> None:
    """At most MAX_QUEUED_FEEDBACK feedback messages wait (the oldest dropped); a result is never dropped,
    so a flood of feedback for a live goal delays its result by at most that many callbacks."""
    import threading as _threading

    from multiros.ros.action.client import MAX_QUEUED_FEEDBACK, _FeedbackDelivery

    delivery = _FeedbackDelivery("/flood")
    gate, seen, done = _threading.Event(), [], _threading.Event()
    # The thread is busy while the flood arrives (a callback still running: not a queued feedback to drop).
    delivery.put(lambda: gate.wait(60.0))
    for i in range(20_000):
        delivery.put(lambda i=i: seen.append(i), feedback=True)
    delivery.put(done.set)  # the goal's result, behind the flood
    gate.set()
    assert done.wait(60.0)
    delivery.close()
    assert delivery.dropped == 20_000 - MAX_QUEUED_FEEDBACK
    assert seen == list(range(20_000 - MAX_QUEUED_FEEDBACK, 20_000))  # the newest kept, in order
