"""`uniros deploy`: an exported policy drives the fake robot through the Real twin of its ID, with onnxruntime only
(no torch, no Stable-Baselines3 in the process), keeps the control period, and stops cleanly on Ctrl-C; bad input is
one line and exit code 2.

The deploying process is a child (``python -c`` running ``uniros.cli.main``) on the test's private graph; it reports
which heavy modules it had loaded when it ended. Every process started here is stopped by PID.
"""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from multiros.ros import Context
from multiros.ros.interfaces import get_message
from multiros.ros.processes import child_environment, stop_process

from .conftest import StandIn, TopicRecorder

SIM_ID, REAL_ID = "RX200ReacherGoalSim-v0", "RX200ReacherGoalReal-v0"
EPISODE_STEPS = 8  # the record's env_kwargs carry over to the Real twin: short episodes
HEAVY = ("torch", "stable_baselines3", "sb3_contrib")
# The runner takes Ctrl-C as a foreground program in a terminal does: a test suite started in the background
# (`cmd &` in a script) hands its children SIGINT ignored, and Python then keeps it ignored.
_RUNNER = ("import signal, sys\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
           "from uniros.cli import main\ncode = main(sys.argv[1:])\n"
           f"print('heavy modules:', sorted(m for m in {HEAVY!r} if m in sys.modules), flush=True)\n"
           "sys.exit(code)\n")
JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
JointState = get_message("sensor_msgs/msg/JointState")
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]


@pytest.fixture(scope="module")
def policy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained SAC + HER policy of the simulated reach with VecNormalize statistics, exported (a run folder)."""
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("onnxruntime")
    from stable_baselines3 import SAC, HerReplayBuffer
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import uniros
    from uniros.policy_export import export_run

    run = tmp_path_factory.mktemp("run")
    env = uniros.make(SIM_ID)
    venv = VecNormalize(DummyVecEnv([lambda: env]))
    try:
        venv.reset()
        for _ in range(20):
            venv.step(np.array([venv.action_space.sample()]))
        model = SAC("MultiInputPolicy", venv, replay_buffer_class=HerReplayBuffer, buffer_size=1000, device="cpu")
        model.save(run / "best_model.zip")
        venv.save(str(run / "best_model.vecnormalize.pkl"))
    finally:
        venv.close()
    (run / "run.json").write_text(json.dumps({"env_id": SIM_ID, "env_kwargs": {
        "max_episode_steps": EPISODE_STEPS, "sim_mode": "composed", "transport": "inproc"}}))
    export_run(run, check_samples=100)
    return run


@pytest.fixture(scope="module")
def fake_robot(graph: Context) -> Iterator[StandIn]:
    robot = StandIn("fake", graph)
    try:
        yield robot
    finally:
        robot.stop()


def _start(args: list[str], graph: Context) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH_", "UNIROS_ZENOH_"))}
    env.update(child_environment(graph))
    return subprocess.Popen([sys.executable, "-c", _RUNNER, "deploy", *args], env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=os.path.dirname(__file__))


def _finish(proc: subprocess.Popen, timeout: float) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        stop_process(proc)
        out, err = proc.communicate()
        pytest.fail(f"uniros deploy did not end within {timeout} s:\n{out}\n{err}")
    return proc.returncode, out, err


@pytest.mark.slow
@pytest.mark.multiprocess
def test_deploy_runs_episodes_with_onnxruntime_only(policy: Path, fake_robot: StandIn, graph: Context) -> None:
    proc = _start([str(policy), "--episodes", "2", "--transport", "zenoh"], graph)
    code, out, err = _finish(proc, 120)
    print(out)  # the figures, with pytest -s
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith(f"deploying {policy / 'best_model.onnx'} (SAC, trained on {SIM_ID}) on {REAL_ID}: "
                               "control period 100.0 ms"), out
    assert [line.split(":")[0] for line in lines[1:3]] == ["episode 1", "episode 2"]
    assert f"{EPISODE_STEPS} steps" in lines[1]
    summary = lines[3]
    assert summary.startswith("2 episodes, success ") and "inference p50 " in summary and "(target 100.0 ms)" in summary
    periods = [float(summary.split("control period p50 ")[1].split(" ms")[0])]
    assert 90.0 <= periods[0] <= 130.0, summary  # the Real env's loop kept its 100 ms period
    assert lines[-1] == "heavy modules: []"


@pytest.mark.slow
@pytest.mark.multiprocess
def test_ctrl_c_holds_the_arm_closes_and_exits_0(policy: Path, fake_robot: StandIn, graph: Context) -> None:
    commands = TopicRecorder(graph, JointTrajectory, "/rx200/arm_controller/joint_trajectory")
    states = TopicRecorder(graph, JointState, "/rx200/joint_states")
    proc = _start([str(policy), "--transport", "zenoh"], graph)  # until Ctrl-C
    try:
        assert commands.wait_count(2 * EPISODE_STEPS, timeout=90), "the policy never commanded the arm"
        sent_before = len(commands.messages)
        proc.send_signal(signal.SIGINT)
        code, out, err = _finish(proc, 60)
    finally:
        stop_process(proc)
        commands.close()
        states.close()
    assert code == 0, err
    after_start = [line for line in out.splitlines()[1:] if not line.startswith(("episode ", "heavy modules:"))]
    assert len(after_start) == 1, out
    assert after_start[0].startswith("stopped on Ctrl-C: the arm holds its measured position; "), out
    assert out.splitlines()[-1] == "heavy modules: []"
    # The last command holds where the arm was measured: its target is the joint states' position then.
    hold = commands.messages[-1]
    assert len(commands.messages) > sent_before
    assert list(hold.joint_names) == ARM
    target = np.asarray(hold.points[-1].positions)
    index = {n: i for i, n in enumerate(states.messages[-1].name)}
    measured = np.asarray([states.messages[-1].position[index[j]] for j in ARM])
    assert np.max(np.abs(target - measured)) < 0.05, (target, measured)


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.skipif(any(importlib.util.find_spec(p) is None for p in ("rclpy", "control_msgs")),
                    reason="needs rclpy and the interface packages .ci/rclpy builds")
def test_deploy_on_rclpy(policy: Path, tmp_path: Path) -> None:
    ctx = Context(transport="rclpy").init()  # the suite's own domain (tests/conftest.py), discovery on this machine
    robot = None
    try:
        robot = StandIn("fake", ctx)
        proc = _start([str(policy), "--episodes", "1", "--transport", "rclpy"], ctx)
        code, out, err = _finish(proc, 120)
        assert code == 0, err
        assert "episode 1:" in out and out.splitlines()[-1] == "heavy modules: []"
    finally:
        if robot is not None:
            robot.stop()
        ctx.try_shutdown()


# -- bad input: one line, exit code 2 (nothing reaches a robot) ------------------------------------------------------
def _deploy_error(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    from uniros.cli import main

    assert main(["deploy", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("uniros deploy: error: ")
    return err


def test_a_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "no such file or run directory" in _deploy_error([str(tmp_path / "nothing.onnx")], capsys)


def test_a_run_without_an_exported_policy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "uniros export" in _deploy_error([str(tmp_path)], capsys)


def test_a_file_that_is_not_onnx(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("onnxruntime")
    bad = tmp_path / "policy.onnx"
    bad.write_bytes(b"PK\x03\x04 not a protobuf" * 10)
    assert "is not an ONNX model" in _deploy_error([str(bad)], capsys)


def _onnx_without_metadata(path: Path) -> Path:
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    graph = helper.make_graph([helper.make_node("Identity", ["obs"], ["action"])], "g",
                              [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5])],
                              [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", 5])])
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)]), path)
    return path


def test_an_onnx_without_uniros_metadata(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("onnxruntime")
    path = _onnx_without_metadata(tmp_path / "plain.onnx")
    assert "without uniros metadata" in _deploy_error([str(path)], capsys)


def _with_record(path: Path, **record: object) -> Path:
    import onnx

    from uniros.policy_metadata import METADATA_KEY, PolicyInput, PolicyMetadata

    model = onnx.load(path)
    meta = PolicyMetadata(env_id="RX200ReacherSim-v0", algorithm="sac", layout="single",
                          inputs=(PolicyInput("obs", (5,)),), action_low=(-1.0,) * 5, action_high=(1.0,) * 5)
    text = json.loads(meta.to_json())
    text.update(record)
    entry = model.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, json.dumps(text)
    onnx.save(model, path)
    return path


def test_an_id_mismatch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("onnxruntime")
    path = _with_record(_onnx_without_metadata(tmp_path / "p.onnx"))
    err = _deploy_error([str(path), "--env", "ABBIRB120ReacherRealEnv-v0"], capsys)
    assert "trained on RX200ReacherSim-v0, not for ABBIRB120ReacherRealEnv-v0" in err and "RX200ReacherReal-v0" in err


def test_a_sim_id_without_a_real_twin(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("onnxruntime")
    path = _with_record(_onnx_without_metadata(tmp_path / "p.onnx"), env_id="Pendulum-v1")
    assert "has no Real twin" in _deploy_error([str(path)], capsys)


def test_a_record_that_lies(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("onnxruntime")
    path = _with_record(_onnx_without_metadata(tmp_path / "p.onnx"),
                        inputs=[{"name": "obs", "shape": [10 ** 9], "dtype": "float32"}])
    assert "metadata input 'obs' has the shape" in _deploy_error([str(path)], capsys)
    path = _with_record(_onnx_without_metadata(tmp_path / "q.onnx"), action_low=[float("nan")] * 5)
    assert "action_low" in _deploy_error([str(path)], capsys)


def test_episodes_must_be_positive(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "--episodes must be at least 1" in _deploy_error([str(tmp_path), "--episodes", "0"], capsys)


