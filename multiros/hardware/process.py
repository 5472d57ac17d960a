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
from collections.abc import Sequence

from multiros.hardware.robot_spec import PRESETS
from multiros.ros import Context, Node
from multiros.ros.controller_manager import ControllerManagerClient, ControllerManagerError
from multiros.ros.processes import (
    child_environment,
    private_environment,
    stop_process,
    track_child,
    untrack_child,
)

__all__ = ["FakeRobotProcess", "FakeRobotError"]



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
        module: the program's module (``uniros.fake_robot`` takes ``--arm PATH``, an arm file).

    Raises:
        FakeRobotError: the child exited or did not answer in time (it is stopped then).
    """

    def __init__(self, robot: str | None = "rx200", *, context: Context, args: Sequence[str] = (),
                 namespace: str | None = None, timeout_sec: float = 30.0, cwd: str | None = None,
                 module: str = "multiros.hardware.fake_robot") -> None:
        args = list(args)
        if namespace is None:
            if "--namespace" in args:
                namespace = args[args.index("--namespace") + 1]
            else:
                namespace = PRESETS[robot].namespace if robot in PRESETS else ""
        self.namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
        argv = [sys.executable, "-m", module, "--router", "none",
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
            ControllerManagerClient(node, self.namespace).wait_until_ready(timeout_sec, self.process)
        except ControllerManagerError as exc:
            raise FakeRobotError(f"uniros-fake-robot: {exc}") from None
        finally:
            node.destroy_node()

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the child by PID: SIGINT, then SIGTERM, then SIGKILL, each given ``timeout`` seconds
        (its clean shutdown takes well under a second on a quiet machine; a loaded one needs more)."""
        stop_process(self.process, timeout=timeout)
        untrack_child(self.process)

    def __enter__(self) -> FakeRobotProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
