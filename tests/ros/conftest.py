"""Fixtures for the ROS layer tests: contexts per test, free loopback ports, no port 7447."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from multiros import ros


def free_endpoint() -> str:
    """A Zenoh TCP endpoint on a free ephemeral loopback port."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


@pytest.fixture
def ctx() -> Iterator[ros.Context]:
    with ros.Context(transport="inproc", env={}) as context:
        yield context


@pytest.fixture
def router_endpoint() -> str:
    return free_endpoint()


@pytest.fixture
def zenoh_ctx(router_endpoint: str) -> Iterator[ros.Context]:
    """A Zenoh context that starts an embedded router on a free port."""
    with ros.Context(transport="zenoh", env={}, router_endpoint=router_endpoint) as context:
        yield context


@pytest.fixture
def zenoh_peer_ctx(zenoh_ctx: ros.Context, router_endpoint: str) -> Iterator[ros.Context]:
    """A second Zenoh context (its own session) using the first one's router."""
    with ros.Context(transport="zenoh", env={}, router="none", router_endpoint=router_endpoint) as context:
        yield context
