"""``gymnasium.make_vec`` on the simulated IDs: their ``vector_entry_point`` is the batched vector env."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import rl_environments
import uniros
from multiros.envs.vector import BatchedVectorEnv

ENV = "RX200ReacherGoalSim-v0"


def _assert_same(a, b) -> None:
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_gymnasium_make_vec_equals_uniros_make_vec_step_for_step() -> None:
    n, horizon = 3, 6
    theirs = gym.make_vec(ENV, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=horizon)
    ours = uniros.make_vec(ENV, n, vectorization_mode="batched", max_episode_steps=horizon)
    try:
        assert isinstance(theirs, BatchedVectorEnv)
        assert theirs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        assert theirs.spec.kwargs["vectorization_mode"] == "vector_entry_point"
        assert theirs.action_space == ours.action_space
        _assert_same(theirs.reset(seed=11)[0], ours.reset(seed=11)[0])
        rng = np.random.default_rng(1)
        ended = 0
        for _ in range(2 * horizon + 2):  # crosses autoresets
            actions = rng.uniform(-1, 1, (n, 5)).astype(np.float32)
            a, b = theirs.step(actions), ours.step(actions)
            _assert_same(a[0], b[0])
            for x, y in zip(a[1:4], b[1:4]):
                np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(a[4]["is_success"], b[4]["is_success"])
            ended += int(np.sum(a[2] | a[3]))
        assert ended >= 2 * n
    finally:
        theirs.close()
        ours.close()


def test_vector_entry_point_is_the_default_and_takes_options() -> None:
    vec = gym.make_vec(ENV, num_envs=2, max_episode_steps=2,
                       vector_options={"autoreset_mode": AutoresetMode.SAME_STEP, "spacing": 3.0, "num_nodes": 1})
    try:
        assert isinstance(vec, BatchedVectorEnv)
        assert vec.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        vec.reset(seed=0)
        vec.step(np.zeros((2, 5), np.float32))
        _, _, _, trunc, info = vec.step(np.zeros((2, 5), np.float32))
        assert trunc.all() and info["_final_obs"].all()  # SAME_STEP: reset in the step that ended them
        world = vec.batch.connections[0].sim_node.world
        bases = [world.get_entity_state(name).position for name in vec.get_attr("robot_name")]
        assert np.linalg.norm(bases[0] - bases[1]) == pytest.approx(3.0)
    finally:
        vec.close()
    # uniros.make_vec follows Gymnasium's default; "sync" is still Gymnasium's own
    sync = uniros.make_vec(ENV, 2, vectorization_mode="sync")
    try:
        assert isinstance(sync, SyncVectorEnv)
    finally:
        sync.close()


def test_specs_stay_json_and_only_simulated_ids_have_it() -> None:
    for env_id in rl_environments.ENV_IDS:
        spec = gym.spec(env_id)
        assert spec.vector_entry_point == f"rl_environments.vector_entry:{env_id}"
        assert json.loads(spec.to_json())["vector_entry_point"] == spec.vector_entry_point
    for env_id in rl_environments.REAL_ENV_IDS:
        assert gym.spec(env_id).vector_entry_point is None
    with pytest.raises(gym.error.Error, match="vector_kwargs"):
        gym.make_vec(ENV, num_envs=2, vectorization_mode="vector_entry_point", vector_kwargs={"copy": False})
    import rl_environments.vector_entry as entry

    with pytest.raises(AttributeError, match="RX200ReacherSim-v0"):
        entry.NoSuchEnv  # noqa: B018
