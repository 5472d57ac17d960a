"""Stand-ins for a real robot, in other processes, on a private Zenoh graph.

* ``sim``: the simulation node (``python -m multiros.sim.program --play --robot rx200=...``) in
  real-time mode: its ros2_control-style topics, controller manager and FollowJointTrajectory;
* ``fake``: ``uniros-fake-robot`` (multiros.hardware), a fake ros2_control robot.

Each test graph is a context with its own router on a free loopback port (never 7447) and the
suite's non-zero ``ROS_DOMAIN_ID``; every child is stopped by PID.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from multiros.ros import Context, Node
from multiros.ros.interfaces import get_message
from multiros.ros.processes import child_environment, private_context, stop_process

PoseStamped = get_message("geometry_msgs/msg/PoseStamped")

RX200_URI = "package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
STANDINS = ("sim", "fake")
_CWD = tempfile.gettempdir()  # children import the installed package, as a user's scripts do
#: ``joint_state_timeout`` for tests that are not about the staleness watchdog. The default (0.5 s) is a
#: robot's; on a loaded shared machine a stand-in in another process can pause longer than that, and a
#: test of names or spaces must not then fail on the watchdog. Watchdog tests set their own limit.
STATE_TIMEOUT = 5.0
#: ``reset_joint_speed`` for tests that are not about the reset's pacing. An env's first reset moves for
#: the furthest the arm can be from its initial pose (a state that claims the arm is there cannot shorten
#: it): about 6 s at the default 0.5 rad/s, spent by every test that makes an env. The pacing tests
#: (tests/real/test_spoofing.py) set their own speed.
RESET_SPEED = 4.0


def make_real(context: Context, env_id: str, *, startup_timeout: float, **kwargs: Any) -> Any:
    """``uniros.make`` of a Real env on ``context``, with ``STATE_TIMEOUT`` and ``RESET_SPEED`` unless the
    test sets its own."""
    import uniros

    kwargs.setdefault("joint_state_timeout", STATE_TIMEOUT)
    kwargs.setdefault("reset_joint_speed", RESET_SPEED)
    return uniros.make(env_id, context=context, startup_timeout=startup_timeout, **kwargs)


def _fake_available() -> bool:
    try:
        import multiros.hardware.process  # noqa: F401
    except ImportError:
        return False
    return True


class StandIn:
    """A robot stand-in process: ``kind`` ``"sim"`` or ``"fake"``, stopped by PID."""

    def __init__(self, kind: str, ctx: Context, args: tuple[str, ...] = ()) -> None:
        self.kind = kind
        self.ctx = ctx
        self._fake: Any = None
        self.proc: subprocess.Popen | None = None
        if kind == "fake":
            if not _fake_available():
                pytest.skip("uniros-fake-robot (multiros.hardware) is not installed")
            from multiros.hardware.process import FakeRobotProcess

            self._fake = FakeRobotProcess("rx200", context=ctx, args=list(args), timeout_sec=30.0, cwd=_CWD)
            self.proc = self._fake.process
        else:
            env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH_", "UNIROS_ZENOH_"))}
            env.update(child_environment(ctx))
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "multiros.sim.program", "--log-level", "WARNING", "--play",
                 "--owner-pid", str(os.getpid()), "--robot", f"rx200={RX200_URI}", *args],
                env=env, stdin=subprocess.DEVNULL, cwd=_CWD)
            try:
                wait_controller_manager(ctx, "/rx200", self.proc, 30.0)
            except BaseException:
                self.stop()
                raise

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def kill(self) -> None:
        """SIGKILL, as a robot whose driver dies."""
        assert self.proc is not None
        self.proc.kill()
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self._fake is not None:
            self._fake.stop()
        elif self.proc is not None:
            stop_process(self.proc)


def wait_controller_manager(ctx: Context, ns: str, proc: subprocess.Popen, timeout: float) -> None:
    """Wait until ``<ns>/controller_manager/list_controllers`` answers (the robot is up)."""
    from multiros.ros.controller_manager import ControllerManagerClient

    node = Node(f"standin_probe_{os.getpid()}_{time.monotonic_ns()}", context=ctx)
    try:
        ControllerManagerClient(node, ns).wait_until_ready(timeout, proc)
    finally:
        node.destroy_node()


@pytest.fixture(scope="module")
def graph() -> Iterator[Context]:
    """A private Zenoh graph (router on a free loopback port) for this module's stand-ins and envs."""
    ctx = private_context()
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


@pytest.fixture(scope="module", params=STANDINS)
def standin(request: pytest.FixtureRequest, graph: Context) -> Iterator[StandIn]:
    """One stand-in per kind, shared by the module's tests (which leave its controllers as they found them)."""
    robot = StandIn(request.param, graph)
    try:
        yield robot
    finally:
        robot.stop()


class TopicRecorder:
    """Records every message on a topic (the robot side's view of what the env sent)."""

    def __init__(self, ctx: Context, msg_type: Any, topic: str) -> None:
        from multiros.ros.executors import SingleThreadedExecutor

        self.messages: list[Any] = []
        self._lock = threading.Lock()
        self.node = Node(f"recorder_{os.getpid()}_{time.monotonic_ns()}", context=ctx)
        self.sub = self.node.create_subscription(msg_type, topic, self._on, 100)
        self._executor = SingleThreadedExecutor(context=ctx)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._executor.spin, daemon=True)
        self._thread.start()

    def _on(self, msg: Any) -> None:
        with self._lock:
            self.messages.append(msg)

    def wait_count(self, n: int, timeout: float = 5.0) -> bool:
        return self.node.context.wait_for(lambda: len(self.messages) >= n, timeout)

    def wait_matched(self, timeout: float = 5.0) -> bool:
        return self.node.context.wait_for(lambda: self.sub.get_publisher_count() > 0, timeout)

    def close(self) -> None:
        self._executor.shutdown()
        self._thread.join(timeout=2.0)
        self.node.destroy_node()


class Tracker:
    """A stand-in object tracker: publishes a PoseStamped at 20 Hz until stopped."""

    def __init__(self, ctx: Context, frame: str, topic: str = "/object_pose") -> None:
        self.node = Node(f"tracker_{time.monotonic_ns()}", context=ctx)
        self.pub = self.node.create_publisher(PoseStamped, topic, 10)
        self.frame, self.position, self.quat = frame, [0.3, 0.02, 0.02], [1.0, 0.0, 0.0, 0.0]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(0.05):
            msg = PoseStamped()
            msg.header.frame_id = self.frame
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = self.position
            (msg.pose.orientation.w, msg.pose.orientation.x, msg.pose.orientation.y,
             msg.pose.orientation.z) = self.quat
            self.pub.publish(msg)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.node.destroy_node()
