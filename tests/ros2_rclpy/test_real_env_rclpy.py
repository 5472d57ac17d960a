"""``RX200ReacherGoalReal-v0`` on rclpy against a plain-rclpy fake ros2_control RX200 (tests/ros2_rclpy/plain_robot.py,
Interbotix layout, another process, Fast DDS): the env's commands keep the safety rules as the robot sees
them, and a robot killed mid-episode stops the env with an error that says so."""

from __future__ import annotations

import importlib.util
import json
import sys
import time

import pytest

_NEEDED = ("rclpy", "control_msgs", "controller_manager_msgs")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy and the interface packages .ci/rclpy builds (run by .ci/rclpy)", allow_module_level=True)

import numpy as np  # noqa: E402
import plain_robot  # noqa: E402
from plain_robot import ARM, LIMITS  # noqa: E402

import uniros  # noqa: E402
from multiros.envs.real.errors import StaleStateError, TrajectoryGoalError  # noqa: E402

pytestmark = pytest.mark.slow
MAX_DELTA = 0.15  # the env's max_joint_delta (its default)
#: The first reset moves for the furthest the arm can be (no state can shorten it): 6 s at the default
#: 0.5 rad/s. The plain robot moves at 2 rad/s, so the tests reset at that speed.
RESET_SPEED = 2.0


def _robot(program, tmp_path):
    log = tmp_path / "commands.jsonl"
    robot = program([sys.executable, plain_robot.__file__, "--log", str(log)], "plain-robot")
    robot.wait_ready("ready", timeout=30)
    return robot, log


def _commands(log) -> list[dict]:
    return [json.loads(line) for line in log.read_text().splitlines() if line.strip()]


def test_real_env_on_rclpy_keeps_the_safety_rules_on_the_robot(program, tmp_path) -> None:
    robot, log = _robot(program, tmp_path)
    env = uniros.make("RX200ReacherGoalReal-v0", startup_timeout=30.0, max_joint_delta=MAX_DELTA,
                      reset_joint_speed=RESET_SPEED)
    try:
        assert env.unwrapped.context.transport_name == "rclpy"  # the default where rclpy imports
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in range(15):  # full-scale actions: the rules must cut them down
            env.step(np.sign(rng.uniform(-1, 1, env.action_space.shape)).astype(np.float32))
        deadline = time.monotonic() + 5
        while len([c for c in _commands(log) if c["kind"] == "topic"]) < 15 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        env.close()
    commands = [c for c in _commands(log) if c["kind"] == "topic"]
    assert len(commands) >= 15
    speed_margin = 2.0 * 0.5 + 0.02  # the robot's speed x the env's joint_state_timeout: how old its state may be
    for c in commands:
        assert c["joints"] == ARM
        for j, target, measured in zip(ARM, c["target"], c["measured"]):
            lo, hi = LIMITS[j]
            assert lo - 1e-9 <= target <= hi + 1e-9, (j, target)
            assert abs(target - measured) <= MAX_DELTA + speed_margin, (j, target, measured)
    steps = [max(abs(t - m) for t, m in zip(c["target"], c["measured"])) for c in commands]
    assert max(steps) > 0.05  # the actions did move the arm


@pytest.mark.parametrize("command_interface", ["topic", "action"])
def test_robot_killed_mid_episode_stops_the_env_with_the_reason(program, tmp_path, command_interface) -> None:
    robot, _log = _robot(program, tmp_path)
    env = uniros.make("RX200ReacherGoalReal-v0", transport="rclpy", startup_timeout=30.0,
                      command_interface=command_interface, joint_state_timeout=0.3, timeout_sec=5.0,
                      reset_joint_speed=RESET_SPEED)
    try:
        env.reset(seed=0)
        env.step(env.action_space.sample())
        robot.kill()
        t0 = time.monotonic()
        with pytest.raises((StaleStateError, TrajectoryGoalError)) as caught:
            for _ in range(100):
                env.step(env.action_space.sample())
        elapsed = time.monotonic() - t0
        text = str(caught.value)
        # joint_state_timeout (0.3 s) after the kill, not the 5 s call timeout: DDS keeps a SIGKILLed
        # robot's action server in the graph for its lease time, joint_states stop at once.
        assert elapsed < 2.0, (elapsed, text)
        assert "within 10 s" not in text
        assert ("stale" in text if command_interface == "topic" else "looks lost" in text), text
        assert "/rx200/joint_states" in text
    finally:
        env.close()
