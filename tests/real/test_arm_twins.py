"""The VX300S, UR5e and NED2 Real twins against a stand-in of each vendor's driver (``uniros-fake-robot``
with the arm's description, namespace and controller names): the spaces equal the simulated twins',
the object's pose comes from a tracker's PoseStamped topic (stale and malformed poses refused), the
gripper command reaches the driver's interface, camera observations come from Image topics (stale
images refused), and the Ned2's gripper default says what to pass instead."""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

import uniros
from multiros.envs.real.sensor_link import StaleSensorError
from multiros.hardware.process import FakeRobotProcess
from multiros.ros import Context, Node
from multiros.ros.interfaces import get_message
from rl_environments import ARM_TASKS

from .conftest import TopicRecorder, Tracker, make_real

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

PoseStamped = get_message("geometry_msgs/msg/PoseStamped")
Image = get_message("sensor_msgs/msg/Image")
JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")

# The vendor drivers' names (the twins' defaults) and, where the stand-in has no such gripper
# driver, a gripper interface it does have.
ARMS: dict[str, dict[str, Any]] = {
    "VX300S": {"description": "package://vx300s_description/urdf/vx300s.urdf.xacro?robot_name=vx300s",
               "namespace": "/vx300s", "base": "vx300s/base_link",
               "activate": "joint_state_broadcaster,arm_controller,gripper_controller", "gripper": {}},
    "UR5e": {"description": "package://ur5e_description/urdf/ur5e.urdf.xacro", "namespace": "", "base": "base_link",
             "activate": "joint_state_broadcaster,scaled_joint_trajectory_controller,gripper_position_controller",
             "gripper": {"gripper_interface": "forward", "gripper_controller": "gripper_position_controller"}},
    "NED2": {"description": "package://ned2_description/urdf/ned2.urdf.xacro", "namespace": "", "base": "base_link",
             "activate": "joint_state_broadcaster,niryo_robot_follow_joint_trajectory_controller,"
                         "gripper_position_controller",
             "gripper": {"gripper_interface": "forward", "gripper_controller": "gripper_position_controller"}},
}


@functools.cache
def _sim_spaces(env_id: str, **kwargs: Any) -> tuple[Any, Any]:
    env = uniros.make(env_id, **kwargs)
    try:
        return env.observation_space, env.action_space
    finally:
        env.close()


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request: pytest.FixtureRequest, graph: Context) -> Iterator[tuple[str, FakeRobotProcess, Tracker]]:
    cfg = ARMS[request.param]
    robot = FakeRobotProcess(None, context=graph, args=["--description", cfg["description"], "--namespace",
                                                        cfg["namespace"] or "/", "--activate", cfg["activate"]],
                             namespace=cfg["namespace"], timeout_sec=60.0, cwd="/tmp")
    tracker = Tracker(graph, cfg["base"])
    try:
        yield request.param, robot, tracker
    finally:
        tracker.stop()
        robot.stop()


def _make(graph: Context, env_id: str, **kwargs: Any) -> Any:
    return make_real(graph, env_id, startup_timeout=15.0, **kwargs)


def test_every_twin_has_its_simulated_twins_spaces(graph, arm) -> None:
    name, _, _ = arm
    for task in ARM_TASKS:
        extra = ARMS[name]["gripper"] if task.startswith(("Push", "PnP", "Slide")) else {}
        env = _make(graph, f"{name}{task}Real-v0", **extra)
        try:
            obs_space, act_space = _sim_spaces(f"{name}{task}Sim-v0")
            assert env.observation_space == obs_space, f"{name}{task}"
            assert env.action_space == act_space, f"{name}{task}"
            assert env.unwrapped.robot_driver  # exactly one joint_states publisher: the stand-in
        finally:
            env.close()


def test_object_pose_from_the_tracker_and_the_gripper_through_its_driver(graph, arm) -> None:
    name, _, tracker = arm
    cfg = ARMS[name]
    kwargs = dict(cfg["gripper"], object_pose_timeout=0.5)
    env = _make(graph, f"{name}PushGoalReal-v0", **kwargs)
    ns = cfg["namespace"]
    gripper = cfg["gripper"].get("gripper_controller", "gripper_controller")
    kind = cfg["gripper"].get("gripper_interface", "trajectory")
    topic = f"{ns}/{gripper}/" + ("joint_trajectory" if kind == "trajectory" else "commands")
    recorder = TopicRecorder(graph, JointTrajectory if kind == "trajectory" else
                             get_message("std_msgs/msg/Float64MultiArray"), topic)
    try:
        u = env.unwrapped
        tracker.position = [0.31, -0.04, 0.02]
        tracked = u.connection.scene.object_pose
        where = [0.31, -0.04, 0.02] + u.task.base_position
        assert u.context.wait_for(lambda: np.allclose(u.task.object_position(), where, atol=1e-9)
                                  if tracked.received else False, 5.0)
        assert recorder.wait_matched()
        obs, _ = env.reset(seed=0)  # the arm moves to its start pose; the gripper opens
        np.testing.assert_allclose(obs["achieved_goal"], np.add([0.31, -0.04, 0.02], u.task.base_position), atol=1e-6)
        obs, _, _, _, info = env.step(np.array([0, 0, 0, -1.0], np.float32))  # close the gripper
        assert recorder.wait_count(2)
        last = recorder.messages[-1]
        sent = last.points[0].positions[0] if kind == "trajectory" else last.data[0]
        assert sent == pytest.approx(u.task.gripper_range[0]), "closed: the task's closed finger position"
        # A malformed pose is dropped (and named); when only those arrive the pose goes stale.
        tracker.quat = [0.0, 0.0, 0.0, 0.0]
        time.sleep(0.7)  # longer than object_pose_timeout: the specification of staleness
        with pytest.raises(StaleSensorError, match="not a unit quaternion"):
            env.step(np.zeros(4, np.float32))
        with pytest.raises(Exception, match="stopped after an error"):
            env.step(np.zeros(4, np.float32))  # the env stays stopped
    finally:
        tracker.quat = [1.0, 0.0, 0.0, 0.0]
        recorder.close()
        env.close()


def test_camera_observations_from_image_topics(graph, arm) -> None:
    name, _, _ = arm
    if name != "VX300S":
        pytest.skip("one arm is enough: the camera is the task's, not the arm's")
    kwargs = dict(rgb_plus_depth_plus_normal_obs=True, image_width=16, image_height=12)
    node = Node(f"camera_{time.monotonic_ns()}", context=graph)
    rgb_pub = node.create_publisher(Image, "/vx300s/camera/image_raw", 5)
    depth_pub = node.create_publisher(Image, "/vx300s/camera/depth/image_raw", 5)
    pattern = np.arange(24 * 32 * 3, dtype=np.uint8).reshape(24, 32, 3)
    stop = threading.Event()

    def publish() -> None:
        while not stop.wait(0.03):
            bgr = Image(height=24, width=32, encoding="bgr8", step=96, data=pattern[:, :, ::-1].tobytes())
            depth = Image(height=24, width=32, encoding="32FC1", step=128,
                          data=np.full((24, 32), 1.25, "<f4").tobytes())
            rgb_pub.publish(bgr)
            depth_pub.publish(depth)

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    try:
        # 2 s: the publisher thread shares the GIL with the env being made (0.5 s was once missed under load)
        env = _make(graph, "VX300SReacherGoalReal-v0", image_timeout=2.0, **kwargs)
        try:
            assert env.observation_space == _sim_spaces("VX300SReacherGoalSim-v0", **kwargs)[0]
            obs = env.unwrapped.observe()
            np.testing.assert_array_equal(obs["rgb"], pattern[1::2, 1::2])  # nearest pixel of the 2x smaller image
            np.testing.assert_array_equal(obs["depth"], np.full((12, 16), 1.25, np.float32))
            stop.set()
            thread.join(timeout=2.0)
            time.sleep(2.2)  # longer than image_timeout
            with pytest.raises(StaleSensorError, match="rgb image on /vx300s/camera/image_raw is stale"):
                env.unwrapped.observe()
        finally:
            env.close()
    finally:
        stop.set()
        node.destroy_node()


def test_the_ned2_gripper_default_names_what_to_pass() -> None:
    with pytest.raises(ValueError, match="gripper_interface='none'"):
        uniros.make("NED2PnPReal-v0")
