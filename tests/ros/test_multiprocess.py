"""Pub/sub and services across two OS processes over Zenoh, and a child killed mid-call."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from multiros import ros
from multiros.ros.interfaces import get_message, get_service

pytestmark = [pytest.mark.slow, pytest.mark.multiprocess]

ROOT = Path(__file__).resolve().parents[2]
CHILD = Path(__file__).resolve().with_name("zenoh_child.py")
AddTwoInts = get_service("example_interfaces/srv/AddTwoInts")
Int64 = get_message("std_msgs/msg/Int64")


@pytest.fixture
def child(zenoh_ctx: ros.Context, router_endpoint: str) -> Iterator[subprocess.Popen]:
    proc = subprocess.Popen([sys.executable, str(CHILD), router_endpoint], cwd=ROOT,
                            env={"PATH": "/usr/bin:/bin"},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        yield proc
    finally:
        proc.kill()
        proc.wait(timeout=10)


def _ready_client(ctx: ros.Context, proc: subprocess.Popen, name: str):
    cli = ros.Node("parent", context=ctx).create_client(AddTwoInts, name)
    if not cli.wait_for_service(timeout_sec=20.0):
        proc.kill()
        pytest.fail(f"child never offered {name}: {proc.stderr.read().decode()[-2000:]}")
    return cli


def test_service_and_pubsub_across_processes(zenoh_ctx: ros.Context, child: subprocess.Popen) -> None:
    cli = _ready_client(zenoh_ctx, child, "/add")
    assert cli.call(AddTwoInts.Request(a=20, b=22), timeout_sec=5.0).sum == 42
    node = cli.node
    assert "child" in node.get_node_names()
    got = []
    node.create_subscription(Int64, "/pong", lambda m: got.append(m.data), 100)
    ping = node.create_publisher(Int64, "/ping", 100)
    assert zenoh_ctx.wait_for(lambda: ping.get_subscription_count() == 1 and node.count_publishers("/pong") == 1,
                              10.0)
    ex = ros.SingleThreadedExecutor(context=zenoh_ctx)
    ex.add_node(node)
    deadline = time.monotonic() + 10
    while 7 not in got and time.monotonic() < deadline:
        ping.publish(Int64(data=7))
        ex.spin_once(timeout_sec=0.1)
    assert 7 in got


def test_child_killed_mid_call_gives_clear_error(zenoh_ctx: ros.Context, child: subprocess.Popen) -> None:
    cli = _ready_client(zenoh_ctx, child, "/hang")
    killer = threading.Timer(0.3, child.kill)
    killer.start()
    start = time.monotonic()
    try:
        with pytest.raises((ros.ServiceTimeoutError, ros.ServiceCallError), match="'/hang'"):
            cli.call(AddTwoInts.Request(), timeout_sec=3.0)
    finally:
        killer.cancel()
    assert time.monotonic() - start < 5.0
    assert zenoh_ctx.wait_for(lambda: not cli.service_is_ready(), 10.0)  # the graph forgets the dead child
    with pytest.raises(TimeoutError, match="'/hang'"):
        cli.call(AddTwoInts.Request(), timeout_sec=0.2)
