"""Ray RLlib trains on uniros envs: PPO with 2 env runners on a local Ray instance (loopback only).

Needs the ``rllib`` extra (``.ci/rllib`` runs it in a venv of its own); skipped without Ray. Ray 2.x
has no "local mode" any more (``ray.init(local_mode=True)`` is refused): the test starts a local
instance of 2 CPUs in a temporary folder, and after ``ray.shutdown()`` checks that every process
Ray started (GCS, raylet, agents, the env runner workers) is gone, killing leftovers by PID.
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
import time
from collections.abc import Iterator

import numpy as np
import pytest

ray = pytest.importorskip("ray", reason="needs the 'rllib' extra (run .ci/rllib)")
pytest.importorskip("ray.rllib")

import uniros.rllib  # noqa: E402

ENV = "RX200ReacherSim-v0"


def _children() -> dict[int, set[int]]:
    tree: dict[int, set[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            tree.setdefault(ppid, set()).add(int(entry))
    return tree


def _descendants(pid: int) -> set[int]:
    tree, out, todo = _children(), set(), [pid]
    while todo:
        for child in tree.get(todo.pop(), ()):
            if child not in out:
                out.add(child)
                todo.append(child)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.fixture
def local_ray() -> Iterator[set[int]]:
    """A local Ray instance; yields the set to which the test adds PIDs it learns (env runners)."""
    before = _descendants(os.getpid())
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths must fit 107 bytes
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False, _temp_dir=temp)
    started: set[int] = set()
    try:
        node = ray._private.worker._global_node
        assert node.node_ip_address == "127.0.0.1"  # tests/rllib/conftest.py
        started |= {p.process.pid for procs in node.all_processes.values() for p in procs}
        yield started
    finally:
        started |= _descendants(os.getpid()) - before
        ray.shutdown()
        deadline = time.monotonic() + 30.0
        while any(_alive(p) for p in started) and time.monotonic() < deadline:
            time.sleep(0.1)
        stray = sorted(p for p in started if _alive(p))
        for pid in stray:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        shutil.rmtree(temp, ignore_errors=True)
        assert not stray, f"Ray processes still running 30 s after ray.shutdown(): {stray} (killed)"


@pytest.mark.slow
@pytest.mark.multiprocess
def test_ppo_trains_on_two_env_runners(local_ray: set[int]) -> None:
    from ray.rllib.algorithms.ppo import PPOConfig

    assert uniros.rllib.register_envs([ENV]) == [ENV]
    config = (
        PPOConfig()
        .environment(ENV, env_config={"max_episode_steps": 20, "reward_type": "dense"})
        .env_runners(num_env_runners=2, num_envs_per_env_runner=2, gym_env_vectorize_mode="vector_entry_point",
                     rollout_fragment_length=40, sample_timeout_s=120.0)
        .training(train_batch_size_per_learner=160, minibatch_size=80, num_epochs=1)
        .rl_module(model_config={"fcnet_hiddens": [32]})
        .debugging(seed=3)
    )
    algo = config.build_algo()
    try:
        runners = algo.env_runner_group.foreach_env_runner(
            lambda r: (r.worker_index, os.getpid(), r.env.unwrapped.get_attr("robot_name")), local_env_runner=False)
        local_ray.update(pid for _, pid, _ in runners)
        assert sorted(w for w, _, _ in runners) == [1, 2]
        pids = {pid for _, pid, _ in runners}
        assert len(pids) == 2 and os.getpid() not in pids
        for _, pid, names in runners:  # each runner's robots live on a composed node in the runner's own process
            assert all(name.startswith(f"rx200_{pid}x") for name in names)
        results = [algo.train() for _ in range(2)]
        for result in results:
            sampled = result["env_runners"]["num_env_steps_sampled"]
            assert sampled >= 160
            assert np.isfinite(result["env_runners"]["episode_return_mean"])
            losses = result["learners"]["default_policy"]
            for key in ("total_loss", "policy_loss", "vf_loss", "entropy"):
                assert np.isfinite(losses[key]), (key, losses)
        # Each runner's node counts its physics steps: num_sim_steps per vector step of its num_envs envs.
        per_runner = algo.env_runner_group.foreach_env_runner(
            lambda r: (r.worker_index, r.env.unwrapped.node_loads()[0]["physics_steps"]
                       // r.env.unwrapped.batch.num_sim_steps * r.env.num_envs,
                       [e.np_random_seed for e in r.env.unwrapped.envs],
                       [float(x) for x in r.env.unwrapped.envs[0].goal]),
            local_env_runner=False)
        steps = {w: n for w, n, _, _ in per_runner}
        total = results[-1]["env_runners"]["num_env_steps_sampled_lifetime"]
        assert all(n >= total / 2 for n in steps.values()), (steps, total)  # both runners sampled their share
        seeds = [s for _, _, ss, _ in per_runner for s in ss]
        assert sorted(seeds) == [8, 9, 10, 11]  # runner w: (3 + w) * 2 + i, no seed twice
        goals = [g for _, _, _, g in per_runner]
        assert goals[0] != goals[1]
    finally:
        algo.stop()

