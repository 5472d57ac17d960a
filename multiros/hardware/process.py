"""Start ``uniros-fake-robot`` in a child process joined to a context's graph, and stop it by PID.

::

    from multiros.ros.processes import private_context
    from multiros.hardware.process import FakeRobotProcess

    ctx = private_context()                       # a router of its own on a free loopback port
    with FakeRobotProcess("rx200", context=ctx) as robot:
        ...                                       # /rx200/joint_states, controller manager, actions
    ctx.try_shutdown()

The child watches its owner (this process) and exits within about a second of its death.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence

from multiros.hardware.robot_spec import PRESETS
from multiros.ros import Context, Node
from multiros.ros.processes import (
    child_environment,
    private_environment,
    stop_process,
    track_child,
    untrack_child,
)
from multiros.sim.distro_adapters import get_service

__all__ = ["FakeRobotProcess", "FakeRobotError"]

ListControllers = get_service("controller_manager_msgs/srv/ListControllers")


class FakeRobotError(RuntimeError):
    """The fake robot process did not start or did not become ready."""


class FakeRobotProcess:
    """``uniros-fake-robot`` in a child process on ``context``'s Zenoh graph.

    Args:
        robot: a preset name (``"rx200"``, ``"irb120"``) or ``None`` with ``--description`` in ``args``.
        context: the graph to join (its router endpoint and domain are handed to the child).
        args: more ``uniros-fake-robot`` options (``["--rate", "50", "--stall-after", "2"]``).
        namespace: the robot's namespace, to probe readiness (default: the preset's, or the
            ``--namespace`` in ``args``).
        timeout_sec: how long to wait until its controller manager answers.
        cwd: working directory of the child.

    Raises:
        FakeRobotError: the child exited or did not answer in time (it is stopped then).
    """

    def __init__(self, robot: str | None = "rx200", *, context: Context, args: Sequence[str] = (),
                 namespace: str | None = None, timeout_sec: float = 30.0, cwd: str | None = None) -> None:
        args = list(args)
        if namespace is None:
            if "--namespace" in args:
                namespace = args[args.index("--namespace") + 1]
            else:
                namespace = PRESETS[robot].namespace if robot in PRESETS else ""
        self.namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
        argv = [sys.executable, "-m", "multiros.hardware.fake_robot", "--router", "none",
                "--owner-pid", str(os.getpid()), *(["--robot", robot] if robot else []), *args]
        env = private_environment()
        env.update(child_environment(context))
        self.process = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL, cwd=cwd)
        track_child(self.process)
        try:
            self._wait_ready(context, timeout_sec)
        except BaseException:
            self.stop()
            raise

    @property
    def pid(self) -> int:
        return self.process.pid

    def _wait_ready(self, context: Context, timeout_sec: float) -> None:
        node = Node(f"fake_robot_probe_{os.getpid()}_{id(self):x}", context=context)
        try:
            client = node.create_client(ListControllers, f"{self.namespace}/controller_manager/list_controllers")
            deadline = time.monotonic() + timeout_sec
            while True:
                if self.process.poll() is not None:
                    raise FakeRobotError(f"uniros-fake-robot (pid {self.process.pid}) exited with code "
                                         f"{self.process.returncode} before it was ready")
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise FakeRobotError(f"uniros-fake-robot (pid {self.process.pid}) did not answer "
                                         f"{self.namespace}/controller_manager/list_controllers within "
                                         f"{timeout_sec:g} s")
                if client.wait_for_service(timeout_sec=min(0.5, remaining)):
                    try:
                        client.call(ListControllers.Request(), timeout_sec=min(2.0, max(remaining, 0.1)))
                        return
                    except Exception:  # noqa: BLE001 - not answering yet: retry until the deadline
                        continue
        finally:
            node.destroy_node()

    def stop(self) -> None:
        """Stop the child by PID (SIGINT, then SIGTERM, then SIGKILL, bounded waits)."""
        stop_process(self.process)
        untrack_child(self.process)

    def __enter__(self) -> FakeRobotProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
