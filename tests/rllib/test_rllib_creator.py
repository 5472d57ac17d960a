"""uniros.rllib without Ray: the env creator each env runner calls, its seeds, and the install hint."""

from __future__ import annotations

import pickle
import sys

import numpy as np
import pytest

from multiros.envs.sim_env import MujocoEnvCore
from multiros.envs.vector import BatchedVectorEnv
from uniros.rllib import EnvCreator, RunnerSeeds, register_envs


def test_creator_makes_one_env_or_a_batched_vector_env() -> None:
    creator = pickle.loads(pickle.dumps(EnvCreator("RX200ReacherSim-v0")))  # Ray ships it to each runner
    env = creator({"reward_type": "dense", "max_episode_steps": 5})
    try:
        assert isinstance(env.unwrapped, MujocoEnvCore)
        assert env.spec.max_episode_steps == 5
    finally:
        env.close()
    vec = creator({"num_envs": 3, "max_episode_steps": 5, "vector_kwargs": {"spacing": 2.5}})
    try:
        assert isinstance(vec, RunnerSeeds) and isinstance(vec.unwrapped, BatchedVectorEnv)
        assert vec.num_envs == 3
        vec.reset(seed=4)  # RLlib's seed for runner w is base + w: env i gets (base + w) * num_envs + i
        assert [e.np_random_seed for e in vec.unwrapped.envs] == [12, 13, 14]
        obs, reward, term, trunc, _ = vec.step(np.zeros((3, 5), np.float32))
        assert obs.shape[0] == 3 and np.all(np.isfinite(reward))
    finally:
        vec.close()
    with pytest.raises(ValueError, match="vector_entry_point"):
        creator({"vector_kwargs": {"spacing": 3.0}})


def test_runner_seeds_never_repeat_across_runners() -> None:
    n, runners, base = 4, 3, 7
    seeds = [(base + w) * n + i for w in range(1, runners + 1) for i in range(n)]
    assert len(set(seeds)) == len(seeds)  # Gymnasium's (base + w) + i would repeat 6 of the 12


def test_unknown_id_and_missing_ray(monkeypatch) -> None:
    with pytest.raises(LookupError, match="RX200ReacherSim-v0"):
        EnvCreator("NoSuchEnv-v0")
    monkeypatch.setitem(sys.modules, "ray.tune.registry", None)  # as if Ray were not installed
    with pytest.raises(ImportError, match=r"uniros\[rllib\]"):
        register_envs()
