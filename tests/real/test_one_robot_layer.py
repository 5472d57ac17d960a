"""One robot layer for both sides: the arms' simulated and Real envs share ``ArmRobot``, and what a side does
its own way is its connection's (the real scene: tracker, standing fixtures, gripper)."""

from __future__ import annotations

import functools
import importlib
import threading
from collections.abc import Callable, Iterator
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import uniros  # noqa: F401 - registers the IDs
from multiros.envs.connection import RobotConnection, SceneEntity
from multiros.envs.errors import EnvError
from multiros.envs.real.gripper import RealGripper
from multiros.envs.real.scene import RealScene, RealSceneOptions
from multiros.robot_state import RobotStates
from multiros.ros import Context, Node
from multiros.ros.executors import SingleThreadedExecutor
from rl_environments.arm_env import ArmEnv, ArmRealEnv, ArmRealGoalEnv, ArmSimEnv, ArmSimGoalEnv

from .conftest import Tracker

#: What the robot layer does that differs between the sides: each is ArmRobot's, asked of the connection.
#: The connection's methods those reach, abstract or with a default, each implemented on both sides.
SEAM = ("base_position", "add_scene", "place_entity", "use_gripper", "reset_gripper", "limit_joints",
        "command_arm", "observation_time", "open_camera", "read_camera")


def _entry(env_id: str) -> type:
    module, name = gym.spec(env_id).entry_point.split(":")
    return getattr(importlib.import_module(module), name)


@functools.cache
def _depth(cls: type) -> int:
    return 0 if cls is object else 1 + max(_depth(base) for base in cls.__bases__)


def _arm_ids() -> list[str]:
    return sorted(i for i in gym.registry if i.endswith(("Sim-v0", "Real-v0"))
                  and i.startswith(("RX200", "VX300S", "UR5e", "NED2", "IRB120")))


def test_every_arm_id_is_an_arm_env_of_its_side_at_most_8_classes_deep() -> None:
    """An arm, a task and a side make an env: each arm ID's entry point is one of the four arm env classes,
    whose method resolution order (counted as issue 50 counts it) is at most 8 classes; the step, reset and
    batch functions are the one ArmEnv's on both sides."""
    ids = _arm_ids()
    assert len(ids) >= 40
    for env_id in [*ids, "ABBIRB120ReacherEnv-v0", "ABBIRB120ReacherGoalRealEnv-v0"]:
        cls = _entry(env_id)
        assert cls in (ArmSimEnv, ArmSimGoalEnv, ArmRealEnv, ArmRealGoalEnv), env_id
        assert len(cls.__mro__) <= 8, f"{env_id}: {[k.__name__ for k in cls.__mro__]}"
        assert set(gym.spec(env_id).kwargs) == {"arm", "task"}, env_id
        for member in ("step", "reset", "batch_act", "batch_results"):
            owner = next(k for k in cls.__mro__ if member in k.__dict__)
            assert owner is ArmEnv, f"{env_id}: {member} is {owner.__name__}'s, not the shared ArmEnv's"


def test_both_connections_implement_the_seam_the_robot_layer_asks() -> None:
    from multiros.envs.real.connection import RealConnection
    from multiros.envs.sim_connection import SimConnection

    for name in SEAM:
        assert hasattr(RobotConnection, name), name
    for cls in (SimConnection, RealConnection):
        assert not getattr(cls, "__abstractmethods__", ()), (cls, cls.__abstractmethods__)
    # Where the sides differ, each has its own: a simulation spawns, teleports and sets fingers; a robot
    # serves a tracker, reaches a gripper's driver and passes the arm's command through its safety rules.
    for name in ("add_scene", "reset_gripper", "base_position", "open_camera", "read_camera"):
        assert name in SimConnection.__dict__ and name in RealConnection.__dict__, name
    for name in ("use_gripper", "limit_joints", "command_arm", "observation_time"):
        assert name in RealConnection.__dict__, name
    assert "place_entity" in SimConnection.__dict__


class _StubConnection:
    """What a RealScene uses of its connection: the node, topic resolution, timeouts, the base, frames."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.startup_timeout = 5.0
        self.base_position = np.array([0.0, 0.0, 0.5])
        self.fault: BaseException | None = None
        self.sources: dict[str, Callable[[RobotStates], tuple[np.ndarray, np.ndarray | None]]] = {}
        self.routes: dict[str, Callable[[np.ndarray], None]] = {}
        self.published: list[tuple[str, list[float]]] = []
        self.checks = 0
        self.link = self

    def ensure_commandable(self) -> None:
        self.checks += 1

    def publish_forward(self, controller: str, values: np.ndarray) -> None:
        self.published.append((controller, values.tolist()))

    def publish_trajectory(self, controller: str, joints: list[str], values: np.ndarray, cycle: Any) -> None:
        self.published.append((controller, [*joints, *values.tolist()]))

    def wait_for_subscriber(self, controller: str, interface: str, timeout: float) -> bool:
        return True

    def resolve(self, name: str) -> str:
        return name if name.startswith("/") else f"/toy/{name}"

    def add_frame_source(self, frame: str, poses: Callable[[RobotStates], Any]) -> None:
        self.sources[frame] = poses

    def route_controller(self, controller: str, send: Callable[[np.ndarray], None]) -> None:
        self.routes[controller] = send


@pytest.fixture
def graph() -> Iterator[Node]:
    """The env's node on an in-process graph, spun as a robot link spins it."""
    with Context(transport="inproc", env={}) as ctx:
        node = Node("scene_test", context=ctx)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        spin = threading.Thread(target=executor.spin, daemon=True)
        spin.start()
        try:
            yield node
        finally:
            executor.shutdown()
            spin.join(timeout=5.0)


def _states(n: int = 1) -> RobotStates:
    zeros = np.zeros((n, 1))
    return RobotStates(sim_time=0.0, names=("a",), position=zeros, velocity=zeros, effort=zeros,
                       frame_positions=np.zeros((n, 0, 3)), frame_orientations=np.zeros((n, 0, 4)))


def test_a_real_scene_serves_the_tracked_object_and_the_standing_fixture(graph: Node) -> None:
    conn = _StubConnection(graph)
    scene = RealScene(conn, RealSceneOptions(object_pose_frame="base_link", object_pose_timeout=5.0))  # type: ignore[arg-type]
    tracker = Tracker(graph.context, "base_link")
    tracker.position = [0.3, -0.1, 0.02]
    try:
        scene.add([SceneEntity("t", "package://x/mjcf/table.xml", (0.4, 0.0, 0.3), "t/table", movable=False),
                   SceneEntity("o", "package://x/mjcf/cube.xml", (0.3, 0.0, 0.5), "o/object", movable=True)])
        states = _states()
        table, table_q = conn.sources["t/table"](states)
        np.testing.assert_array_equal(table, [[0.4, 0.0, 0.3]])  # where the task says it stands
        assert table_q is None
        where, quat = conn.sources["o/object"](states)
        np.testing.assert_allclose(where, [[0.3, -0.1, 0.52]])  # the tracker's pose, in the task's world
        np.testing.assert_allclose(quat, [[1.0, 0.0, 0.0, 0.0]])
        # Added again (a task set up anew): one tracker subscription, not two.
        scene.add([SceneEntity("o", "package://x/mjcf/cube.xml", (0.3, 0.0, 0.5), "o/object", movable=True)])
        assert graph.context.wait_for(lambda: graph.count_subscribers("/object_pose") == 1, 5.0)
    finally:
        tracker.stop()
        scene.close()


def test_a_real_scene_tracks_one_object_and_a_gripper_must_be_in_use(graph: Node) -> None:
    scene = RealScene(_StubConnection(graph), RealSceneOptions())  # type: ignore[arg-type]
    two = [SceneEntity(n, "package://x/mjcf/cube.xml", (0.0, 0.0, 0.0), f"{n}/object", movable=True) for n in "ab"]
    with pytest.raises(EnvError, match="tracks one object"):
        scene.add(two)
    with pytest.raises(EnvError, match="not in use"):
        scene.reset_gripper("gripper_controller", [0.03])


def test_a_real_gripper_is_routed_and_commanded_at_reset(graph: Node) -> None:
    conn = _StubConnection(graph)
    scene = RealScene(conn, RealSceneOptions(gripper_interface="forward", gripper_controller="hand",  # type: ignore[arg-type]
                                             gripper_range=(0.0, 100.0)))
    scene.use_gripper("gripper_controller", (0.015, 0.037))
    assert scene.gripper is not None and list(conn.routes) == ["gripper_controller"]
    scene.reset_gripper("gripper_controller", [0.037, -0.037])  # the episode's start: open
    conn.routes["gripper_controller"](np.array([0.015]))  # a step's command: closed
    # The task's (closed, open) mapped onto the driver's range, on the driver's controller, each checked.
    assert conn.published == [("hand", [pytest.approx(100.0)]), ("hand", [pytest.approx(0.0)])]
    assert conn.checks == 2
    scene.close()
    assert scene.gripper is None


@pytest.mark.parametrize("interface", ["forward", "trajectory"])
def test_two_independently_driven_fingers_are_commanded_together(graph: Node, interface: str) -> None:
    """A gripper whose fingers are two driven joints: one finger target drives both, the second at its
    multiplier, on the driver's one controller; a GripperCommand action cannot take two."""
    conn = _StubConnection(graph)
    conn.loop = SimpleNamespace(cycle=0.04)  # type: ignore[attr-defined]
    scene = RealScene(conn, RealSceneOptions(gripper_interface=interface, gripper_controller="fingers",  # type: ignore[arg-type]
                                             gripper_joint="joint7", gripper_followers=(("joint8", -1.0),)))
    scene.use_gripper("gripper_controller", (0.0, 0.038))
    conn.routes["gripper_controller"](np.array([0.02, -0.02]))
    joints = ["joint7", "joint8"] if interface == "trajectory" else []
    assert conn.published == [("fingers", [*joints, pytest.approx(0.02), pytest.approx(-0.02)])]
    scene.close()
    with pytest.raises(ValueError, match="GripperCommand action takes one position"):
        RealGripper(conn, "gripper_action", "fingers", "joint7", (0.0, 0.038), followers=(("joint8", -1.0),))
