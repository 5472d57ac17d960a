"""The pure parts of DDS privacy and of rcl's arguments: --ros-args split as rcl splits them, localhost
discovery by default for what uniros starts, a free private domain, one-line rcl errors, client ids."""

from __future__ import annotations

import socket

import pytest

from multiros.ros import Context
from multiros.ros.names import split_ros_arguments
from multiros.ros.processes import (
    DISCOVERY_RANGE_ENV,
    PRIVATE_DOMAINS,
    _domain_in_use,
    child_environment,
    discovery_environment,
    free_dds_domain,
)


def test_ros_args_sections_are_split_off() -> None:
    argv = ["--play", "--ros-args", "--enclave", "/uniros/sim", "-r", "a:=b", "--", "--gui", "--ros-args", "-p",
            "x:=1"]
    own, ros = split_ros_arguments(argv)
    assert own == ["--play", "--gui"]
    assert ros == ["--ros-args", "--enclave", "/uniros/sim", "-r", "a:=b", "--ros-args", "-p", "x:=1"]
    assert split_ros_arguments(["--name", "x"]) == (["--name", "x"], [])


def test_a_context_keeps_its_ros_args_for_rcl() -> None:
    ctx = Context(transport="inproc").init(["prog", "--ros-args", "--enclave", "/e", "--", "mine"])
    try:
        assert ctx.ros_argv == ["--ros-args", "--enclave", "/e"]
        assert ctx.arguments.enclave == "/e"
    finally:
        ctx.try_shutdown()


def test_what_uniros_starts_discovers_on_localhost_unless_told() -> None:
    assert discovery_environment({})[DISCOVERY_RANGE_ENV] == "LOCALHOST"
    assert discovery_environment({DISCOVERY_RANGE_ENV: "SUBNET"})[DISCOVERY_RANGE_ENV] == "SUBNET"
    ctx = Context(transport="inproc", env={"ROS_DOMAIN_ID": "7"})
    env = child_environment(ctx)
    assert env["ROS_DOMAIN_ID"] == "7" and env[DISCOVERY_RANGE_ENV] == "LOCALHOST"
    ctx = Context(transport="inproc", env={DISCOVERY_RANGE_ENV: "SUBNET"})
    assert child_environment(ctx)[DISCOVERY_RANGE_ENV] == "SUBNET"


def test_a_private_domain_is_one_nobody_here_uses() -> None:
    domain = free_dds_domain()
    assert domain in PRIVATE_DOMAINS
    # A participant of this machine on that domain holds its first discovery port: then it is taken.
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind(("127.0.0.1", 7410 + 250 * domain))
        except OSError:
            pytest.skip("someone took the port meanwhile")
        assert _domain_in_use(domain)
        others = {free_dds_domain(exclude=(domain,)) for _ in range(5)}
        assert domain not in others


def test_rcl_errors_become_one_line() -> None:
    from multiros.ros.transport.rclpy.transport import one_line

    exc = RuntimeError("Failed to create node: error not set, at ./src/rcl/node.c:271\n  more stack\n")
    assert one_line(exc) == "Failed to create node: error not set"
    assert one_line(RuntimeError("")) == "RuntimeError"


def test_client_ids_of_unknown_bindings_are_never_read_from_memory() -> None:
    from multiros.ros.transport.rclpy.transport import client_of

    class FakeRequestId:
        sequence_number = 1

    a, b = client_of(FakeRequestId()), client_of(FakeRequestId())
    assert a != b and a[0] == "request"


def test_uniros_train_names_the_graph_of_a_dds_run_without_a_router(monkeypatch) -> None:
    from uniros.cli import _shared_graph_note

    monkeypatch.setenv("ROS_DOMAIN_ID", "17")
    monkeypatch.setenv(DISCOVERY_RANGE_ENV, "LOCALHOST")
    text = _shared_graph_note("RX200ReacherGoalSim-v0", {"sim_mode": "existing", "transport": "rclpy"})
    assert text is not None and "through rclpy" in text and "LOCALHOST" in text and "Zenoh" not in text
    text = _shared_graph_note("RX200ReacherGoalSim-v0", {"sim_mode": "existing", "transport": "zenoh"})
    assert text is not None and "through the Zenoh router" in text
