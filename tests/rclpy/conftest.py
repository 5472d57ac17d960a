"""The rclpy-transport tests: real rclpy over its default middleware (Fast DDS), two OS processes.

They run in the venv ``.ci/rclpy`` makes (PyPI's ros-jazzy-rclpy, rmw_fastrtps_cpp, standard message
wheels, and the interface packages built from uniros' definitions). Elsewhere every test here is
skipped, with the reason. rclpy is never imported to find out (``find_spec`` only): importing it with
an unloadable ``RMW_IMPLEMENTATION`` ends the process.

Discovery stays on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) on the suite's own
domain (tests/conftest.py: never 0). Every process a test starts is stopped by PID.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_STATIC_PEERS", None)

RCLPY = importlib.util.find_spec("rclpy") is not None
NEEDED = ("simulation_interfaces", "control_msgs", "controller_manager_msgs", "uniros_interfaces")
MISSING = [p for p in NEEDED if importlib.util.find_spec(p) is None] if RCLPY else list(NEEDED)


SKIP_REASON = ("" if RCLPY and not MISSING else
               "rclpy is not installed in this Python (.ci/rclpy runs these tests in a venv with it)" if not RCLPY
               else f"interface packages {MISSING} are not installed (.ci/rclpy builds them)")


class Program:
    """A uniros program in a child process, stopped by PID; ``wait_ready`` reads its log for a line."""

    def __init__(self, argv: Sequence[str], log_path: str) -> None:
        self.log_path = log_path
        self._log = open(log_path, "w")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen([*argv, "--owner-pid", str(os.getpid())], stdout=self._log,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)

    def log(self) -> str:
        with open(self.log_path) as f:
            return f.read()

    def wait_ready(self, marker: str = "ready", timeout: float = 90.0) -> None:
        deadline = time.monotonic() + timeout
        while marker not in self.log():
            if self.proc.poll() is not None:
                raise AssertionError(f"{self.proc.args[0]} exited with {self.proc.returncode}:\n{self.log()[-3000:]}")
            if time.monotonic() > deadline:
                raise AssertionError(f"not ready within {timeout:g} s:\n{self.log()[-3000:]}")
            time.sleep(0.05)

    def kill(self) -> None:
        """SIGKILL: the program dies without saying goodbye to the graph."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self._log.close()


def uniros_script(name: str) -> str:
    return os.path.join(os.path.dirname(sys.executable), name)


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
