"""Batched vector envs over nodes in other processes: make_vec's process mode (a worker process per
node), one node behind a private router, K nodes, a node that dies, and two clients sharing one node."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

import uniros
from multiros.envs.vector import BatchedVectorEnv
from multiros.envs.worker_vector import WorkerVectorEnv
from multiros.sim.client import SimulationNodeError
from uniros.vec_env import WorkerVecEnv, make_batched_vec_env

ENV = "RX200ReacherGoalSim-v0"

pytestmark = pytest.mark.multiprocess


def _rollout(vec, steps: int = 8) -> list:
    obs, _ = vec.reset(seed=11)
    out = [obs]
    rng = np.random.default_rng(5)
    for _ in range(steps):
        out.append(vec.step(rng.uniform(-1, 1, (vec.num_envs, 5)).astype(np.float32))[0])
    return out


@pytest.mark.slow
def test_process_and_k_process_forms_equal_composed() -> None:
    """Node in another process, and K=2 nodes in 2 processes (2 robots each): same observations."""
    composed = uniros.make_vec(ENV, 4, vectorization_mode="batched")
    try:
        expected = _rollout(composed)
    finally:
        composed.close()
    for k in (1, 2):
        vec = uniros.make_vec(ENV, 4, vectorization_mode="batched", sim_mode="process",
                              vector_kwargs={"num_nodes": k})
        try:
            procs = [c.process for c in vec.batch.connections]
            pids = [p.pid for p in procs]
            assert len(set(pids)) == k and os.getpid() not in pids
            assert vec.batch.node_of == ([0, 0, 0, 0] if k == 1 else [0, 0, 1, 1])
            for a, b in zip(_rollout(vec), expected):
                for key in a:
                    np.testing.assert_array_equal(a[key], b[key])
            loads = vec.node_loads()
            assert [load["robots"] for load in loads] == ([4] if k == 1 else [2, 2])
        finally:
            vec.close()
        assert all(p.poll() is not None for p in procs)  # stopped (and reaped) by close()


def test_process_mode_nodes_step_their_envs_in_their_own_processes() -> None:
    """make_vec's ``sim_mode="process"``: each of K nodes is a child process stepping its envs beside
    it, actions and observations through shared memory, none in this process; the observations are
    the composed node's; close stops the processes by PID. The SB3 form does the same."""
    composed = uniros.make_vec(ENV, 4, vectorization_mode="batched", vector_kwargs={"num_nodes": 1})
    try:
        expected = _rollout(composed)
    finally:
        composed.close()
    vec = uniros.make_vec(ENV, 4, sim_mode="process", vector_kwargs={"num_nodes": 2})
    try:
        assert isinstance(vec, WorkerVectorEnv) and vec.num_workers == 2 and vec.local_rows is None
        procs = list(vec._workers.procs)
        assert len({p.pid for p in procs}) == 2 and all(p.poll() is None for p in procs)
        for a, b in zip(_rollout(vec), expected):
            for key in a:
                np.testing.assert_array_equal(a[key], b[key])
        assert [load["robots"] for load in vec.node_loads()] == [2, 2]
    finally:
        vec.close()
    assert all(p.poll() is not None for p in procs)  # stopped (and reaped) by close()
    venv = make_batched_vec_env(ENV, 2, sim_mode="process", num_nodes=2)
    try:
        assert isinstance(venv, WorkerVecEnv) and venv.venv.num_workers == 2 and venv.venv.local_rows is None
        assert venv.reset()["observation"].shape == (2, *venv.observation_space["observation"].shape)
    finally:
        venv.close()


def test_process_mode_with_a_transport_calls_its_node_from_this_process() -> None:
    """A node on a wire of the caller's (``transport``) stays a process of its own, reached over that
    wire: the envs stay here (the form of ``workers=0``)."""
    vec = uniros.make_vec(ENV, 2, sim_mode="process", transport="zenoh")
    try:
        assert isinstance(vec, BatchedVectorEnv)
        child = vec.batch.connections[0].process
        assert child.pid != os.getpid()
        vec.reset(seed=0)
        vec.step(np.zeros((2, 5), np.float32))
    finally:
        vec.close()
    assert child.poll() is not None


@pytest.mark.slow
def test_dead_node_is_named_within_bounded_time() -> None:
    vec = uniros.make_vec(ENV, 2, vectorization_mode="batched", sim_mode="process",
                          vector_kwargs={"num_nodes": 2, "timeout_sec": 5.0})
    try:
        vec.reset(seed=0)
        vec.step(np.zeros((2, 5), np.float32))
        victim = vec.batch.connections[1].process
        os.kill(victim.pid, signal.SIGKILL)
        victim.wait(timeout=5)
        start = time.monotonic()
        with pytest.raises(SimulationNodeError, match=rf"node 1 of 2 \(/mujoco_sim, pid {victim.pid}\)"):
            vec.step(np.zeros((2, 5), np.float32))
        assert time.monotonic() - start < 5.5
    finally:
        vec.close()


def test_two_clients_share_one_node_isolated() -> None:
    """Robots of two clients on one node (in another process): own names and namespaces; one
    client's resets and commands leave the other's robots alone; the node reports both loads."""
    from multiros.sim.client import RobotStepSpec
    from uniros.factory import make_batch

    first = make_batch(ENV, 2, sim_mode="process")
    second = None
    try:
        conn = first.connections[0]
        second = make_batch(ENV, 2, {"connect_kwargs": {"context": conn.context}}, sim_mode="existing")
        assert second.connections[0].client.sim_node == conn.client.sim_node
        names = [e.robot_name for e in first.envs + second.envs]
        assert len(set(names)) == 4 and len({e.namespace for e in first.envs + second.envs}) == 4
        for batch in (first, second):
            for i in range(2):
                batch.reset_env(i, seed=i)
        first.step_envs([0, 1], [np.ones(5, np.float32)] * 2)
        ee = first.envs[0].frames

        def mine() -> list:
            out = conn.client.step_robots([RobotStepSpec(e.robot_name, frames=ee) for e in first.envs], steps=0)
            return [o.state.position for o in out]

        before = mine()
        for i in range(2):
            second.reset_env(i, seed=5)
        second.step_envs([0, 1], [np.zeros(5, np.float32)] * 2)  # advances the shared world's time
        after = mine()
        for a, b in zip(before, after):  # commands held: the robots stay close to where they were
            np.testing.assert_allclose(a[:5], b[:5], atol=0.05)
        load = conn.client.get_node_load()
        assert load["robots"] == 4 and load["physics_steps"] > 0
    finally:
        if second is not None:
            second.close()
        first.close()
