"""Service round-trip latency and pub/sub throughput of the ROS layer's transports, in one run.

    PYTHONPATH=. python benchmarks/bench_transport.py [--n 2000]

Prints median and p99 (µs) of an AddTwoInts round trip: in-process (inproc), one Zenoh context
(intra-process), two Zenoh contexts in one process, across processes over Zenoh, and a raw
eclipse-zenoh query across processes (baseline); then pub/sub throughput (msgs/s) in-process
and across processes (ping -> child -> pong). Every child process is killed by PID at the end.
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from multiros import ros  # noqa: E402
from multiros.ros.interfaces import get_message, get_service  # noqa: E402

AddTwoInts = get_service("example_interfaces/srv/AddTwoInts")
Int64 = get_message("std_msgs/msg/Int64")


def free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def add(req, res):
    res.sum = req.a + req.b
    return res


def stats(samples_ns: list[int]) -> tuple[float, float]:
    s = sorted(samples_ns)
    return statistics.median(s) / 1e3, s[min(len(s) - 1, int(0.99 * len(s)))] / 1e3


def time_calls(call, n: int, warmup: int) -> tuple[float, float]:
    for _ in range(warmup):
        call()
    out = []
    for _ in range(n):
        t = time.perf_counter_ns()
        call()
        out.append(time.perf_counter_ns() - t)
    return stats(out)


def raw_echo_child(endpoint: str) -> None:
    """Child mode: a raw Zenoh queryable echoing payload and attachment."""
    import zenoh

    c = zenoh.Config()
    c.insert_json5("mode", '"peer"')
    c.insert_json5("connect/endpoints", json.dumps([endpoint]))
    c.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    c.insert_json5("scouting/multicast/enabled", "false")
    with zenoh.open(c) as s:
        s.declare_queryable("bench/echo", lambda q: q.reply(q.key_expr, q.payload, attachment=q.attachment),
                            complete=True)
        sys.stdin.read()  # until the parent closes stdin or kills us


def spawn(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, *args], cwd=ROOT, stdin=subprocess.PIPE,
                            env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=2000)
    parser.add_argument("--raw-echo", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.raw_echo:
        raw_echo_child(args.raw_echo)
        return
    n, rows = args.n, []
    req = AddTwoInts.Request(a=1, b=2)

    with ros.Context(transport="inproc", env={}) as ctx:
        ros.Node("srv", context=ctx).create_service(AddTwoInts, "/add", add)
        cli = ros.Node("cli", context=ctx).create_client(AddTwoInts, "/add")
        rows.append(("inproc, same context", *time_calls(lambda: cli.call(req), n * 10, 1000)))
        base = time_calls(lambda: add(req, AddTwoInts.Response()), n * 10, 1000)
        rows.append(("  (the callback alone)", *base))

    endpoint = free_endpoint()
    procs: list[subprocess.Popen] = []
    try:
        with ros.Context(transport="zenoh", env={}, router_endpoint=endpoint) as zctx:
            ros.Node("srv", context=zctx).create_service(AddTwoInts, "/add_local", add)
            node = ros.Node("cli", context=zctx)
            cli = node.create_client(AddTwoInts, "/add_local")
            rows.append(("zenoh, same context (intra-process)", *time_calls(lambda: cli.call(req), n * 10, 1000)))
            with ros.Context(transport="zenoh", env={}, router="none", router_endpoint=endpoint) as other:
                ros.Node("srv2", context=other).create_service(AddTwoInts, "/add_other", add)
                c2 = node.create_client(AddTwoInts, "/add_other")
                assert c2.wait_for_service(10)
                rows.append(("zenoh, two contexts in one process", *time_calls(lambda: c2.call(req), n, 200)))
            procs.append(spawn(["-m", "tests.ros.zenoh_child", endpoint]))
            c3 = node.create_client(AddTwoInts, "/add")
            if not c3.wait_for_service(30):
                raise RuntimeError("child node did not start")
            rows.append(("zenoh, across processes", *time_calls(lambda: c3.call(req), n, 200)))

            procs.append(spawn([str(Path(__file__)), "--raw-echo", endpoint]))
            sess = zctx.transport.session
            import zenoh

            querier = sess.declare_querier("bench/echo", target=zenoh.QueryTarget.ALL_COMPLETE,
                                           consolidation=zenoh.ConsolidationMode.NONE)
            payload, att = b"\x00\x01\x00\x00" + bytes(16), bytes(33)
            deadline = time.monotonic() + 30
            while not list(querier.get(payload=payload, attachment=att)):
                if time.monotonic() > deadline:
                    raise RuntimeError("raw echo child did not start")
            rows.append(("raw eclipse-zenoh query, across processes",
                         *time_calls(lambda: list(querier.get(payload=payload, attachment=att)), n, 200)))

            # pub/sub throughput across processes: ping -> child -> pong.
            got = [0]
            node.create_subscription(Int64, "/pong", lambda m: got.__setitem__(0, got[0] + 1), 1000)
            ping = node.create_publisher(Int64, "/ping", 1000)
            zctx.wait_for(lambda: ping.get_subscription_count() > 0 and node.count_publishers("/pong") > 0, 10)
            ex = ros.SingleThreadedExecutor(context=zctx)
            ex.add_node(node)
            count = n * 5
            msg = Int64(data=1)
            t0 = time.perf_counter()
            for i in range(count):
                ping.publish(msg)
                if i % 100 == 99:
                    while node.subscriptions[0]._queue:
                        ex.spin_once(0)
            end = time.monotonic() + 5
            while got[0] < count * 0.99 and time.monotonic() < end:
                ex.spin_once(0.05)
            cross_rate = got[0] / (time.perf_counter() - t0)
            cross_loss = 1 - got[0] / count
    finally:
        for p in procs:
            p.kill()
            p.wait(10)

    with ros.Context(transport="inproc", env={}) as ctx:
        a, b = ros.Node("a", context=ctx), ros.Node("b", context=ctx)
        got = [0]
        b.create_subscription(Int64, "/t", lambda m: got.__setitem__(0, got[0] + 1), 1000)
        pub = a.create_publisher(Int64, "/t", 1000)
        ex = ros.SingleThreadedExecutor(context=ctx)
        ex.add_node(b)
        count, msg = n * 50, Int64(data=1)
        t0 = time.perf_counter()
        for i in range(count):
            pub.publish(msg)
            if i % 500 == 499:
                while b.subscriptions[0]._queue:
                    ex.spin_once(0)
        while b.subscriptions[0]._queue:
            ex.spin_once(0)
        inproc_rate = got[0] / (time.perf_counter() - t0)

    print(f"\nservice round trip, AddTwoInts (n={n}; x10 for in-process rows)")
    print(f"{'path':45s} {'median µs':>10s} {'p99 µs':>10s}")
    for name, med, p99 in rows:
        print(f"{name:45s} {med:10.1f} {p99:10.1f}")
    inproc_med = rows[0][1]
    cross = dict((r[0], r[1]) for r in rows)
    print(f"\ninproc overhead beyond the callback: {inproc_med - rows[1][1]:.2f} µs")
    print(f"across processes / raw zenoh query: "
          f"{cross['zenoh, across processes'] / cross['raw eclipse-zenoh query, across processes']:.2f}x")
    print(f"across processes / inproc: {cross['zenoh, across processes'] / inproc_med:.0f}x")
    print("\npub/sub throughput, std_msgs/Int64")
    print(f"{'inproc, one process':45s} {inproc_rate:12,.0f} msgs/s")
    print(f"{'zenoh, ping->child->pong across processes':45s} {cross_rate:12,.0f} msgs/s "
          f"(lost {cross_loss:.1%})")


if __name__ == "__main__":
    main()
