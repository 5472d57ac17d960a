"""Node loggers leave nothing behind, and warnings about wire garbage are rate-limited."""

from __future__ import annotations

import logging
import time

import pytest
from raw_zenoh import open_peer_session

from multiros import ros
from multiros.ros.interfaces import get_message
from multiros.ros.logging import LogThrottle
from multiros.ros.transport.zenoh import wire

String = get_message("std_msgs/msg/String")
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_throttle_logs_a_burst_then_one_line_per_interval_with_the_count(caplog) -> None:
    clock = FakeClock()
    throttle = LogThrottle(burst=3, interval_sec=10.0, clock=clock)
    log = logging.getLogger("test.throttle")
    with caplog.at_level(logging.WARNING, logger="test.throttle"):
        logged = [throttle.log(log, logging.WARNING, "bad sample %d", i) for i in range(100)]
        assert logged[:3] == [True] * 3 and not any(logged[3:])
        clock.now = 10.5
        assert throttle.log(log, logging.WARNING, "bad sample %d", 100)
    lines = [r.getMessage() for r in caplog.records]
    assert lines[:2] == ["bad sample 0", "bad sample 1"]
    assert "at most one line per 10 s" in lines[2]
    assert lines[3] == "bad sample 100 (97 more like this since the last line were not logged)"
    assert throttle.seen == 101
    with pytest.raises(ValueError):
        LogThrottle(interval_sec=0)


def test_nodes_with_fresh_names_leave_no_logger_behind() -> None:
    manager = logging.Logger.manager
    with ros.Context(transport="inproc", env={}) as ctx:
        before = set(manager.loggerDict)
        for i in range(50):
            node = ros.Node(f"env_{i}", context=ctx, namespace="/ns" if i % 2 else "/")
            node.get_logger().info("hello")
            node.destroy_node()
        assert set(manager.loggerDict) - before == set()  # nor placeholders of namespaces (ros.ns)
        # A logger someone configured stays, with its configuration, for the next node of that name.
        configured = logging.getLogger("ros.configured")
        configured.setLevel(logging.ERROR)
        node = ros.Node("configured", context=ctx)
        node.destroy_node()
        assert manager.loggerDict.get("ros.configured") is configured
        # Two nodes of one name share the logger until both are gone.
        a, b = ros.Node("twin", context=ctx), ros.Node("twin", context=ctx)
        a.destroy_node()
        assert "ros.twin" in manager.loggerDict
        b.destroy_node()
        assert "ros.twin" not in manager.loggerDict


@pytest.mark.slow
def test_a_flood_of_malformed_samples_logs_a_few_lines(caplog, router_endpoint: str) -> None:
    """Hundreds of bad samples from a foreign peer: a handful of warning lines, not one per sample."""
    with ros.Context(transport="zenoh", env={}, router_endpoint=router_endpoint) as ctx:
        node = ros.Node("victim", context=ctx)
        got = []
        node.create_subscription(String, "/flood", got.append, 10)
        topic = f"0/flood/std_msgs::msg::dds_::String_/{STRING_HASH}"
        good_att = wire.encode_attachment(1, 0, bytes(16))
        valid = b"\x00\x01\x00\x00\x03\x00\x00\x00ok\x00"  # CDR of String(data="ok")
        peer = open_peer_session(router_endpoint)
        try:
            executor = ros.SingleThreadedExecutor(context=ctx)
            executor.add_node(node)
            deadline = time.monotonic() + 10.0
            while not got and time.monotonic() < deadline:  # the peer's samples reach the node
                peer.put(topic, valid, attachment=good_att)
                executor.spin_once(0.05)
            assert got, "the foreign peer's samples never arrived"
            with caplog.at_level(logging.WARNING, logger="multiros.ros.transport.zenoh.transport"):
                for i in range(300):
                    peer.put(topic, b"\xff" * (i % 7), attachment=good_att if i % 2 else None)
                got.clear()
                deadline = time.monotonic() + 10.0
                while not got and time.monotonic() < deadline:  # samples arrive in order: all 300 were handled
                    peer.put(topic, valid, attachment=good_att)
                    executor.spin_once(0.05)
            assert got
            dropped = [r for r in caplog.records if "dropped" in r.getMessage()]
            assert 1 <= len(dropped) <= 6, [r.getMessage() for r in dropped]
        finally:
            peer.close()


@pytest.mark.parametrize(("level", "shown", "hidden"), [
    ("INFO", ["[ros.sim]: ready", "[__main__]: own info", "[multiros.x]: own info"],
     ["[OpenGL.accel]: no module", "[ros.sim]: debug"]),
    ("DEBUG", ["[ros.sim]: debug", "[ros.sim]: ready", "[OpenGL.accel]: library warning"],
     ["[OpenGL.accel]: no module"]),
    ("WARNING", ["[OpenGL.accel]: library warning"], ["[ros.sim]: ready", "[__main__]: own info"]),
])
def test_a_child_programs_log_level_is_its_own_code_s_other_libraries_say_warnings(level, shown, hidden) -> None:
    """``--log-level`` sets uniros' own loggers (the node's, the program's); another library's INFO
    lines (PyOpenGL's 'No OpenGL_accelerate module') stay out whatever the level."""
    import subprocess
    import sys

    code = ("import argparse, logging; from multiros.ros.processes import add_child_options, start_child_program\n"
            "p = argparse.ArgumentParser(); add_child_options(p); start_child_program(p.parse_args())\n"
            "library = logging.getLogger('OpenGL.accel')\n"
            "library.info('no module'); library.warning('library warning')\n"
            "logging.getLogger('ros.sim').info('ready'); logging.getLogger('ros.sim').debug('debug')\n"
            "logging.getLogger('__main__').info('own info'); logging.getLogger('multiros.x').info('own info')\n")
    out = subprocess.run([sys.executable, "-c", code, "--log-level", level], capture_output=True, text=True,
                         timeout=60, check=True).stderr
    for line in shown:
        assert line in out, (line, out)
    for line in hidden:
        assert line not in out, (line, out)


def test_an_unknown_log_level_is_refused_by_name() -> None:
    import argparse

    from multiros.ros.processes import start_child_program

    with pytest.raises(ValueError, match="unknown --log-level 'LOUD'"):
        start_child_program(argparse.Namespace(log_level="LOUD", owner_pid=None))


def test_a_child_an_owner_starts_logs_what_the_owners_node_loggers_would() -> None:
    from multiros.ros.processes import owner_log_level

    ours = logging.getLogger("ros")
    before = ours.level
    try:
        ours.setLevel(logging.NOTSET)
        assert owner_log_level() == logging.getLevelName(logging.getLogger().getEffectiveLevel())
        ours.setLevel(logging.DEBUG)
        assert owner_log_level() == "DEBUG"
        ours.setLevel(logging.ERROR)
        assert owner_log_level() == "ERROR"
        ours.setLevel(15)  # a custom level: the standard one below it (a child knows no custom names)
        assert owner_log_level() == "DEBUG"
        ours.setLevel(25)
        assert owner_log_level() == "INFO"
    finally:
        ours.setLevel(before)


def test_only_private_graphs_are_the_owners_alone() -> None:
    """In-process, a private Zenoh graph and a child joined to it (the environment
    ``child_environment`` hands it) are the owner's alone; a plain Zenoh graph is not."""
    from multiros.ros.processes import child_environment, is_private_graph, private_context, private_environment

    inproc = ros.Context(transport="inproc")
    assert is_private_graph(inproc)
    owner = private_context()
    try:
        assert is_private_graph(owner)
        child = ros.Context(transport="zenoh", env={**private_environment(), **child_environment(owner)})
        assert is_private_graph(child)
    finally:
        owner.shutdown()
    assert not is_private_graph(ros.Context(transport="zenoh", env={"UNIROS_ZENOH_ROUTER": "tcp/127.0.0.1:1"}))
