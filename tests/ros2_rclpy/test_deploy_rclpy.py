"""``uniros deploy`` on rclpy (Fast DDS) against a plain-rclpy fake ros2_control RX200 in another process
(tests/ros2_rclpy/plain_robot.py, Interbotix layout): an exported policy runs its episode through the Real
twin with onnxruntime alone, and the robot receives its commands. The policy is a small ONNX graph built
here with onnx's helpers (this venv has no torch), holding the arm where it is, with a uniros record."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import time

import pytest

_NEEDED = ("rclpy", "control_msgs", "controller_manager_msgs", "onnx", "onnxruntime")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy, the interface packages .ci/rclpy builds, onnx and onnxruntime (run by .ci/rclpy)",
                allow_module_level=True)

import plain_robot  # noqa: E402

pytestmark = pytest.mark.slow
OBS = {"achieved_goal": 3, "desired_goal": 3, "observation": 18}  # RX200ReacherGoal (its Real twin checks it)
ACTIONS = 5


def _policy(path) -> None:
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    from uniros.policy_metadata import METADATA_KEY, PolicyInput, PolicyMetadata

    inputs = [helper.make_tensor_value_info(k, TensorProto.FLOAT, ["batch", n]) for k, n in OBS.items()]
    weights = numpy_helper.from_array(np.zeros((sum(OBS.values()), ACTIONS), dtype=np.float32), "w")
    nodes = [helper.make_node("Concat", list(OBS), ["x"], axis=1), helper.make_node("MatMul", ["x", "w"], ["action"])]
    graph = helper.make_graph(nodes, "hold", inputs, [helper.make_tensor_value_info("action", TensorProto.FLOAT,
                                                                                    ["batch", ACTIONS])], [weights])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    record = PolicyMetadata(env_id="RX200ReacherGoalSim-v0", algorithm="sac", layout="keys",
                            inputs=tuple(PolicyInput(k, (n,)) for k, n in OBS.items()),
                            action_low=(-1.0,) * ACTIONS, action_high=(1.0,) * ACTIONS, control_period=0.1,
                            exporter="tests/ros2_rclpy", opset=17)
    entry = model.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, record.to_json()
    onnx.save(model, path)


def test_deploy_runs_an_episode_on_rclpy(program, tmp_path) -> None:
    log = tmp_path / "commands.jsonl"
    robot = program([sys.executable, plain_robot.__file__, "--log", str(log)], "plain-robot")
    robot.wait_ready("ready", timeout=30)
    policy = tmp_path / "policy.onnx"
    _policy(policy)
    probe = ("import runpy, sys; sys.argv = ['uniros'] + sys.argv[1:]; from uniros.cli import main; code = main(); "
             "print('heavy modules:', sorted(m for m in ('torch', 'stable_baselines3') if m in sys.modules)); "
             "sys.exit(code)")
    proc = subprocess.Popen([sys.executable, "-c", probe, "deploy", str(policy), "--episodes", "1", "--transport",
                             "rclpy"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ), cwd=str(tmp_path))
    try:
        out, err = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    assert proc.returncode == 0, err[-2000:]
    assert "episode 1:" in err + out and "heavy modules: []" in out, (out, err[-2000:])
    deadline = time.monotonic() + 5
    while not log.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    commands = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    assert any(c["kind"] == "topic" for c in commands), "the robot received the policy's commands"
