"""``uniros teleop``: Joy and Twist messages (and keys) become an arm env's end-effector actions and gripper;
a silent input stops the arm; bad messages and options are refused; a script publishing Joy messages on a
private Zenoh graph drives a push episode through the command in another process."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from types import SimpleNamespace

import numpy as np
import pytest

from uniros.teleop import STALE_AFTER, JoyMapping, TeleopError, TeleopInput, TeleopPolicy, main, parse_joy_map


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _joy(axes, buttons=()):
    return SimpleNamespace(axes=list(axes), buttons=list(buttons))


def test_joy_axes_and_buttons_become_motion_and_gripper() -> None:
    clock = Clock()
    source = TeleopInput(clock)
    policy = TeleopPolicy(source, SimpleNamespace(shape=(4,)))
    source.on_joy(_joy([0.5, 1.0, 0.0, 0.0, -0.8], [1, 0]), JoyMapping())
    np.testing.assert_allclose(policy(), [1.0, 0.5, -0.8, -1.0])  # x: left stick up, y: left, z: right stick; A
    source.on_joy(_joy([0.05, 0.0, 0.0, 0.0, 0.0], [0, 0]), JoyMapping())
    np.testing.assert_allclose(policy(), [0.0, 0.0, 0.0, -1.0]), "dead zone; the gripper holds"
    source.on_joy(_joy([0.0, 0.0, 0.0, 0.0, 0.0], [0, 1]), JoyMapping())
    assert policy()[3] == 1.0
    source.on_joy(_joy([0.0, 1.0, 0, 0, 0]), JoyMapping())
    clock.now += STALE_AFTER + 0.01
    np.testing.assert_allclose(policy()[:3], 0.0), "a silent pad stops the arm"


def test_hostile_joy_messages_are_ignored() -> None:
    source = TeleopInput(Clock())
    source.on_joy(_joy([float("nan")] * 5), JoyMapping())
    source.on_joy(_joy([0.0, 1.0]), JoyMapping())  # too few axes for z=4
    source.on_joy(_joy([0.0] * 1000), JoyMapping())
    assert source.ignored == 3 and source.messages == 0


def test_twist_and_keys() -> None:
    source = TeleopInput(Clock())
    twist = SimpleNamespace(linear=SimpleNamespace(x=0.5, y=-0.25, z=2.0), angular=SimpleNamespace(z=-1.0))
    source.on_twist(twist, 0.5)
    motion, gripper = source.command()
    np.testing.assert_allclose(motion, [1.0, -0.5, 1.0]) and gripper == -1.0
    source.on_key(" ")
    assert source.command()[1] == 1.0
    source.on_key("d")
    np.testing.assert_allclose(source.command()[0], [0, -1, 0])
    source.on_key("q")
    assert source.quit


def test_joy_map_and_action_space_errors() -> None:
    assert parse_joy_map("x=3,y=-2,close=5") == JoyMapping(x=(3, 1.0), y=(2, -1.0), close=5)
    for bad in ("x", "w=1", "x=abc", "x=99"):
        with pytest.raises(TeleopError):
            parse_joy_map(bad)
    with pytest.raises(TeleopError, match="ee_action_type=True"):
        TeleopPolicy(TeleopInput(), SimpleNamespace(shape=(5,)))


def test_keyboard_needs_a_terminal(capsys) -> None:
    assert main(["RX200PushGoalSim-v0", "--keyboard", "--episodes", "1"]) == 2
    assert "stdin is not a terminal" in capsys.readouterr().err


@pytest.mark.multiprocess
def test_a_script_publishing_joy_drives_a_push_episode_through_the_command() -> None:
    from multiros.ros import Node
    from multiros.ros.interfaces import get_message
    from multiros.ros.processes import child_environment, private_context, stop_process

    ctx = private_context()
    proc = None
    try:
        env = {**os.environ, **child_environment(ctx)}
        proc = subprocess.Popen([sys.executable, "-m", "uniros.cli", "teleop", "RX200PushGoalSim-v0", "--joy", "/joy",
                                 "--episodes", "1", "--transport", "zenoh"], env=env, cwd=tempfile.gettempdir(),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        node = Node("joy_script", context=ctx)
        Joy = get_message("sensor_msgs/msg/Joy")
        pub = node.create_publisher(Joy, "/joy", 10)
        deadline = time.monotonic() + 120
        k = 0
        while proc.poll() is None and time.monotonic() < deadline:
            msg = Joy()
            msg.axes = [0.0, 1.0 if (k // 20) % 2 == 0 else -1.0, 0.0, 0.0, 0.0]  # forward, back, ...
            msg.buttons = [1, 0]  # A: close
            pub.publish(msg)
            k += 1
            time.sleep(0.02)
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err[-2000:]
        line = [s for s in out.splitlines() if s.startswith("episode 1:")]
        assert line, out
        messages = int(line[0].split("(")[1].split()[0])
        assert messages > 10, line[0]
    finally:
        if proc is not None and proc.poll() is None:
            stop_process(proc)
        ctx.try_shutdown()


@pytest.mark.multiprocess
@pytest.mark.slow
def test_record_policy_teleop_writes_the_episodes_a_script_drives(tmp_path) -> None:
    """``uniros record ID --policy teleop --joy /joy``: the episodes a Joy-publishing script drives are written as
    a dataset whose actions are the pad's (x forward, the gripper closed)."""
    from multiros.ros import Node
    from multiros.ros.interfaces import get_message
    from multiros.ros.processes import child_environment, private_context, stop_process
    from uniros.lerobot_dataset_reader import read_dataset

    ctx = private_context()
    proc = None
    out = tmp_path / "teleop"
    try:
        env = {**os.environ, **child_environment(ctx)}
        proc = subprocess.Popen([sys.executable, "-m", "uniros.cli", "record", "RX200PushGoalSim-v0", "--policy",
                                 "teleop", "--joy", "/joy", "--episodes", "1", "--output", str(out), "--no-progress",
                                 "--transport", "zenoh"], env=env, cwd=tempfile.gettempdir(),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        node = Node("joy_script", context=ctx)
        Joy = get_message("sensor_msgs/msg/Joy")
        pub = node.create_publisher(Joy, "/joy", 10)
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline:
            msg = Joy()
            msg.axes, msg.buttons = [0.0, 1.0, 0.0, 0.0, 0.0], [1, 0]
            pub.publish(msg)
            time.sleep(0.02)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err[-2000:]
    finally:
        if proc is not None and proc.poll() is None:
            stop_process(proc)
        ctx.try_shutdown()
    (episode,) = read_dataset(out).episodes
    actions = episode.frames["action"]
    driven = actions[np.abs(actions[:, 0]) > 0]
    assert len(driven) > len(actions) // 2, "most steps carry the pad's command"
    np.testing.assert_allclose(driven[:, [0, 3]], np.tile([1.0, -1.0], (len(driven), 1)))
