"""The simulation node in a child process over Zenoh: the smoke loop, the node's services end to end,
and a node that dies under an env. Every child is stopped by PID; the router listens on a free
loopback port (never 7447)."""

from __future__ import annotations

import os
import signal
import socket
import time

import numpy as np
import pytest

import uniros
from multiros.sim.client import SimulationNodeError, SimulationServiceError
from multiros.sim.launch import connect

pytestmark = [pytest.mark.slow, pytest.mark.multiprocess]


@pytest.fixture(autouse=True)
def _private_router(monkeypatch):
    """Each test gets its own Zenoh router on a free loopback port (children inherit it)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setenv("UNIROS_ZENOH_ROUTER", f"tcp/127.0.0.1:{port}")
    monkeypatch.delenv("UNIROS_TRANSPORT", raising=False)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie still answers kill(0); it is gone once reaped.
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split()[2] != "Z"


@pytest.mark.parametrize("env_id", ["RX200ReacherGoalSim-v0", "ABBIRB120ReacherEnv-v0"])
def test_smoke_loop_with_the_node_in_another_process(env_id):
    env = uniros.make(env_id, sim_mode="process")
    pid = env.unwrapped.sim_connection.pid
    try:
        assert pid is not None and pid != os.getpid() and _pid_alive(pid)
        obs, _ = env.reset(seed=0)
        env.action_space.seed(0)
        for _ in range(100):
            assert env.observation_space.contains(obs)
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert np.isfinite(reward) and "is_success" in info
            if terminated or truncated:
                obs, _ = env.reset()
    finally:
        env.close()
    deadline = time.monotonic() + 10
    while _pid_alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _pid_alive(pid), "close() did not stop the simulation node process"


def test_same_seed_same_trajectory_composed_and_across_processes():
    def run(**kwargs):
        env = uniros.make("RX200ReacherGoalSim-v0", **kwargs)
        try:
            obs, _ = env.reset(seed=9)
            env.action_space.seed(9)
            rows = [obs["observation"]]
            for _ in range(15):
                obs, *_ = env.step(env.action_space.sample())
                rows.append(obs["observation"])
            return np.array(rows)
        finally:
            env.close()

    assert run().tobytes() == run(sim_mode="process").tobytes()


def test_node_services_across_processes():
    conn = connect("process", timeout_sec=30.0)
    try:
        client = conn.client
        name = client.spawn_entity(
            "rx200",
            uri="package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
            "&__controllers=joint_state_broadcaster,arm_position_controller",
            namespace="/rx200",
        )
        assert name == "rx200" and client.get_entities() == ["rx200"]
        target = np.array([0.4, -0.2, 0.3, 0.1, 0.0])
        state = client.step_robot("rx200", {"arm_position_controller": target}, 500, ["rx200/ee_gripper_link"])
        arm = ("waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate")
        q = state.position[[state.names.index(j) for j in arm]]
        assert np.max(np.abs(q - target)) < 0.03
        assert state.frame_positions.shape == (1, 3)
        with pytest.raises(SimulationServiceError):
            client.step_robot("rx200", {"arm_position_controller": [np.nan] * 5}, 1)
        client.reset_simulation(255)
        assert client.get_entities() == []
    finally:
        conn.close()


def test_a_dead_node_gives_a_clear_error_and_the_env_can_be_recreated():
    # The node gets the default time to start (a loaded machine needs more than 2 s); only the calls
    # to the dead node are bounded by 2 s.
    env = uniros.make("RX200ReacherGoalSim-v0", sim_mode="process")
    try:
        env.reset(seed=0)
        env.unwrapped.sim.timeout_sec = 2.0  # calls to the dead node: 2 s each
        env.unwrapped.connection.stepper.timeout_sec = 2.0
        pid = env.unwrapped.sim_connection.pid
        os.kill(pid, signal.SIGKILL)
        start = time.monotonic()
        with pytest.raises(SimulationNodeError, match="did not answer|not available|failed"):
            for _ in range(3):
                env.step(env.action_space.sample())
        assert time.monotonic() - start < 15.0
    finally:
        env.close()
    env = uniros.make("RX200ReacherGoalSim-v0", sim_mode="process")
    try:
        env.reset(seed=0)
        env.step(env.action_space.sample())
    finally:
        env.close()


def test_existing_mode_without_a_node_fails_within_the_timeout():
    start = time.monotonic()
    with pytest.raises(SimulationNodeError, match="not ready within"):
        uniros.make("RX200ReacherGoalSim-v0", sim_mode="existing", sim_node_name="nobody_here", timeout_sec=1.5)
    assert time.monotonic() - start < 10.0
