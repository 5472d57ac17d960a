"""The node API over the in-process transport: pub/sub, services, QoS, executors, faults."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import pytest

from multiros import ros


@dataclass
class Msg:
    data: int = 0


class Echo:
    _type = "test/srv/Echo"

    @dataclass
    class Request:
        value: int = 0

    @dataclass
    class Response:
        value: int = 0


def echo(req: Echo.Request, res: Echo.Response) -> Echo.Response:
    res.value = req.value
    return res


def spin_until(executor: ros.Executor, predicate, timeout: float = 2.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return predicate()


def test_pubsub_delivers_same_object_without_copy(ctx: ros.Context) -> None:
    talker, listener = ros.Node("talker", context=ctx), ros.Node("listener", context=ctx)
    got: list[Msg] = []
    listener.create_subscription(Msg, "chatter", got.append, 10)
    pub = talker.create_publisher(Msg, "/chatter", 10)
    msg = Msg(7)
    pub.publish(msg)
    assert got == []  # callbacks run in the executor, as in rclpy
    ex = ros.SingleThreadedExecutor(context=ctx)
    ex.add_node(listener)
    ex.spin_once(timeout_sec=1.0)
    assert got == [msg] and got[0] is msg
    assert pub.get_subscription_count() == 1
    with pytest.raises(TypeError, match="chatter"):
        pub.publish("not a Msg")


def test_has_subscribers_follows_the_graph(ctx: ros.Context) -> None:
    """The lazy publishers' check answers from a cache only while the graph stays as it was."""
    talker, listener = ros.Node("talker", context=ctx), ros.Node("listener", context=ctx)
    pub = talker.create_publisher(Msg, "/state", 10)
    assert not pub.has_subscribers() and not pub.has_subscribers()
    sub = listener.create_subscription(Msg, "state", lambda m: None, 10)
    assert pub.has_subscribers() and pub.has_subscribers()
    other = listener.create_subscription(Msg, "other", lambda m: None, 10)
    assert pub.has_subscribers()  # a change elsewhere in the graph: counted again, same answer
    listener.destroy_subscription(sub)
    assert not pub.has_subscribers()
    listener.destroy_subscription(other)
    assert not pub.has_subscribers() and pub.get_subscription_count() == 0


def test_keep_last_drops_oldest(ctx: ros.Context) -> None:
    node = ros.Node("n", context=ctx)
    got: list[int] = []
    node.create_subscription(Msg, "t", lambda m: got.append(m.data), 3)
    pub = node.create_publisher(Msg, "t", 10)
    for i in range(10):
        pub.publish(Msg(i))
    ex = ros.SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    spin_until(ex, lambda: len(got) == 3)
    assert got == [7, 8, 9]


def test_transient_local_late_joiner_gets_last_depth(ctx: ros.Context) -> None:
    node = ros.Node("n", context=ctx)
    tl = ros.QoSProfile(depth=2, durability=ros.DurabilityPolicy.TRANSIENT_LOCAL)
    pub = node.create_publisher(Msg, "latched", tl)
    for i in range(5):
        pub.publish(Msg(i))
    late, volatile = [], []
    node.create_subscription(Msg, "latched", lambda m: late.append(m.data), tl)
    node.create_subscription(Msg, "latched", lambda m: volatile.append(m.data), 10)
    ex = ros.SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    spin_until(ex, lambda: len(late) == 2)
    ex.spin_once(timeout_sec=0.05)
    assert late == [3, 4]
    assert volatile == []


def test_best_effort_and_incompatible_qos(ctx: ros.Context) -> None:
    node = ros.Node("n", context=ctx)
    be, rel = [], []
    node.create_subscription(Msg, "s", lambda m: be.append(m.data), ros.qos_profile_sensor_data)
    node.create_subscription(Msg, "s", lambda m: rel.append(m.data), 10)
    be_pub = node.create_publisher(Msg, "s", ros.qos_profile_sensor_data)
    be_pub.publish(Msg(1))  # best-effort publisher: only the best-effort subscription matches
    ex = ros.SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    spin_until(ex, lambda: be == [1])
    ex.spin_once(timeout_sec=0.05)
    assert be == [1] and rel == []
    node.create_publisher(Msg, "s", 10).publish(Msg(2))  # reliable publisher serves both
    spin_until(ex, lambda: be == [1, 2] and rel == [2])
    assert be == [1, 2] and rel == [2]


def test_service_call_is_synchronous_in_caller_thread(ctx: ros.Context) -> None:
    server, caller = ros.Node("server", context=ctx), ros.Node("caller", context=ctx)
    threads = []

    def cb(req, res):
        threads.append(threading.get_ident())
        return echo(req, res)

    server.create_service(Echo, "~/echo", cb)
    cli = caller.create_client(Echo, "/server/echo")
    assert cli.wait_for_service(timeout_sec=0.1)
    req = Echo.Request(5)
    assert cli.call(req).value == 5
    assert threads == [threading.get_ident()]
    fut = cli.call_async(Echo.Request(6))
    assert fut.done() and fut.result().value == 6
    assert caller.get_service_names_and_types() == [("/server/echo", ["test/srv/Echo"])]


def test_missing_service_times_out_naming_it(ctx: ros.Context) -> None:
    cli = ros.Node("caller", context=ctx).create_client(Echo, "missing")
    assert not cli.wait_for_service(timeout_sec=0.05)
    start = time.monotonic()
    with pytest.raises(TimeoutError, match="'/missing'.*0.2"):
        cli.call(Echo.Request(), timeout_sec=0.2)
    assert time.monotonic() - start < 1.5
    fut = cli.call_async(Echo.Request())
    assert fut.done() and isinstance(fut.exception(), ros.ServiceCallError)


def test_service_appearing_during_wait_is_called(ctx: ros.Context) -> None:
    cli = ros.Node("caller", context=ctx).create_client(Echo, "late")
    server = ros.Node("server", context=ctx)
    timer = threading.Timer(0.05, lambda: server.create_service(Echo, "/late", echo))
    timer.start()
    try:
        assert cli.call(Echo.Request(3), timeout_sec=2.0).value == 3
    finally:
        timer.cancel()


def test_service_exception_names_service(ctx: ros.Context) -> None:
    node = ros.Node("n", context=ctx)
    node.create_service(Echo, "boom", lambda req, res: 1 / 0)
    node.create_service(Echo, "none", lambda req, res: None)
    cli = node.create_client(Echo, "boom")
    with pytest.raises(ros.ServiceCallError, match="'/boom'.*ZeroDivisionError"):
        cli.call(Echo.Request())
    with pytest.raises(ros.ServiceCallError, match="returned None"):
        node.create_client(Echo, "none").call(Echo.Request())


def test_node_callbacks_never_run_concurrently(ctx: ros.Context) -> None:
    node = ros.Node("n", context=ctx)
    active, overlaps = [0], [0]

    def slow(req, res):
        active[0] += 1
        overlaps[0] += active[0] > 1
        time.sleep(0.002)
        active[0] -= 1
        return echo(req, res)

    node.create_service(Echo, "slow", slow)
    cli = ros.Node("c", context=ctx).create_client(Echo, "/slow")
    workers = [threading.Thread(target=lambda: [cli.call(Echo.Request(1)) for _ in range(10)]) for _ in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(10)
    assert overlaps[0] == 0


def test_timers_and_spin_until_future_complete(ctx: ros.Context) -> None:
    node = ros.Node("n", context=ctx)
    ticks: list[float] = []
    timer = node.create_timer(0.01, lambda: ticks.append(time.monotonic()))
    fut = ros.Future(ctx.notify)
    threading.Timer(0.1, lambda: fut.set_result("done")).start()
    ros.spin_until_future_complete(node, fut, timeout_sec=2.0)
    assert fut.result() == "done"
    assert len(ticks) >= 3
    timer.cancel()
    n = len(ticks)
    ros.spin_once(node, timeout_sec=0.05)
    assert len(ticks) == n


def test_spin_stops_on_shutdown() -> None:
    context = ros.Context(env={}).init()
    node = ros.Node("n", context=context)
    ex = ros.MultiThreadedExecutor(context=context)
    ex.add_node(node)
    ticks = []
    node.create_timer(0.005, lambda: ticks.append(1))
    t = threading.Thread(target=ex.spin)
    t.start()
    deadline = time.monotonic() + 2
    while len(ticks) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    context.shutdown()
    t.join(5)
    assert not t.is_alive() and len(ticks) >= 3


def test_graph_queries_and_destroy(ctx: ros.Context) -> None:
    a = ros.Node("a", context=ctx, namespace="/r")
    pub = a.create_publisher(Msg, "x", 10)
    a.create_subscription(Msg, "x", lambda m: None, 10)
    assert ("a", "/r") in a.get_node_names_and_namespaces()
    assert a.count_publishers("x") == 1 and a.count_subscribers("/r/x") == 1
    a.destroy_publisher(pub)
    assert a.count_publishers("x") == 0
    a.destroy_node()
    assert ctx.graph().node_names_and_namespaces() == []


def test_init_shutdown_default_context_and_errors() -> None:
    context = ros.init(args=[], context=ros.Context(env={}))
    assert context.ok()
    with pytest.raises(RuntimeError):
        context.init()
    ros.shutdown(context=context)
    assert not context.ok()
    with pytest.raises(ros.NotInitializedException):
        ros.Node("n", context=context)


def test_domain_id_and_transport_from_env() -> None:
    context = ros.Context(env={"ROS_DOMAIN_ID": "7", "UNIROS_TRANSPORT": "inproc"})
    assert context.domain_id == 7 and context.transport_name == "inproc"
    with pytest.raises(ValueError, match="ROS_DOMAIN_ID"):
        ros.Context(env={"ROS_DOMAIN_ID": "x"})
    with pytest.raises(ros.TransportError, match="unknown transport"):
        ros.Context(transport="carrier-pigeon", env={}).init()
