"""The rclpy-transport tests: real rclpy over its default middleware (Fast DDS), two OS processes.

They run in the venv ``.ci/rclpy`` makes (PyPI's ros-jazzy-rclpy, rmw_fastrtps_cpp, standard message
wheels, and the interface packages built from uniros' definitions). Elsewhere each module skips itself,
with the reason, before importing anything of ROS: it asks ``find_spec`` (importing rclpy with an
unloadable ``RMW_IMPLEMENTATION`` would end the process).

Discovery stays on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) on the suite's own
domain (tests/conftest.py: never 0). Every process a test starts is stopped by PID.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence

import pytest
from rclpy_harness import Program

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_STATIC_PEERS", None)


@pytest.fixture
def program(tmp_path) -> Iterator:
    started: list[Program] = []

    def start(argv: Sequence[str], name: str = "program") -> Program:
        prog = Program(argv, str(tmp_path / f"{name}-{len(started)}.log"))
        started.append(prog)
        return prog

    yield start
    for prog in started:
        prog.stop()
