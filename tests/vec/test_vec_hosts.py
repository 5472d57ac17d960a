"""A batched vector env over K running nodes reached by name through a Zenoh router network: the
multi-host set-up (a router per host, routers connected), here as two routers on loopback."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

import numpy as np
import pytest

from multiros import ros
from multiros.envs.vector import BatchedVectorEnv
from multiros.ros.processes import stop_process
from multiros.sim.launch import free_loopback_endpoint
from uniros.factory import make_batch

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

DOMAIN = "58"  # never domain 0's graph


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("ZENOH_", "UNIROS_ZENOH_")) and k not in ("ROS_DOMAIN_ID", "UNIROS_TRANSPORT")}
    env.update(ROS_DOMAIN_ID=DOMAIN, UNIROS_TRANSPORT="zenoh", **extra)
    return env


def _node(name: str, env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "multiros.sim.program", "--name", name, "--log-level", "WARNING",
                             "--owner-pid", str(os.getpid())], env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir())


def _stop(proc: subprocess.Popen) -> None:
    stop_process(proc)  # SIGINT, SIGTERM, SIGKILL: bounded waits


def test_vector_env_over_two_hosts_nodes_by_name() -> None:
    router_a, router_b = free_loopback_endpoint(), free_loopback_endpoint()
    # "host A": node sim_a, whose process starts router A; "host B": node sim_b behind router B,
    # which connects to A. The learner joins router A and reaches both by name.
    nodes = [_node("sim_a", _env(UNIROS_ZENOH_ROUTER=router_a)),
             _node("sim_b", _env(UNIROS_ZENOH_ROUTER=router_b, UNIROS_ZENOH_ROUTER_CONNECT=router_a))]
    try:
        with ros.Context(transport="zenoh", env={"ROS_DOMAIN_ID": DOMAIN},
                         router_endpoint=router_a) as ctx:
            batch = make_batch("RX200ReacherGoalSim-v0", 4,
                               {"node_name": ["sim_a", "sim_b"], "connect_kwargs": {"context": ctx}},
                               sim_mode="existing")
            vec = BatchedVectorEnv(batch)
            try:
                assert batch.num_nodes == 2 and batch.node_of == [0, 0, 1, 1]
                obs, _ = vec.reset(seed=0)
                for _ in range(5):
                    obs, *_ = vec.step(np.zeros((4, 5), np.float32))
                assert np.all(np.isfinite(obs["observation"]))
                assert [load["robots"] for load in vec.node_loads()] == [2, 2]
            finally:
                vec.close()
    finally:
        for proc in nodes:
            _stop(proc)
