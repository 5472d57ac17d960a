"""Today's envs return what the recorded ones did (``golden_trajectories.py``): observations,
rewards, terminations, truncations and ``is_success`` to 1e-9, one env at a time and batched
(SAME_STEP autoreset, one and two composed nodes)."""

from __future__ import annotations

import numpy as np
import pytest
from golden_trajectories import CASES, SEEDS, load, record_batched, record_single

GOLDEN = load()
_IDS = [case for case, _, _ in CASES]


def _assert_matches(case: str, seed: int, got: dict[str, np.ndarray]) -> None:
    for key in ("terminated", "truncated", "success"):
        np.testing.assert_array_equal(got[key], GOLDEN[f"{case}/{seed}/{key}"], err_msg=f"{case} seed {seed} {key}")
    for key in ("obs", "reward"):
        want = GOLDEN[f"{case}/{seed}/{key}"]
        assert got[key].shape == want.shape, f"{case} seed {seed} {key}: shape {got[key].shape} != {want.shape}"
        np.testing.assert_allclose(got[key], want, rtol=0, atol=1e-9, err_msg=f"{case} seed {seed} {key}")


@pytest.mark.parametrize(("case", "env_id", "kwargs"), CASES, ids=_IDS)
def test_single_env_replays_the_recording(case: str, env_id: str, kwargs: dict) -> None:
    for seed in SEEDS:
        _assert_matches(case, seed, record_single(env_id, kwargs, case, seed))


@pytest.mark.parametrize(("case", "env_id", "kwargs"), CASES, ids=_IDS)
def test_batched_env_replays_the_recording(case: str, env_id: str, kwargs: dict) -> None:
    for seed, got in zip(SEEDS, record_batched(env_id, kwargs, case)):
        _assert_matches(case, seed, got)


@pytest.mark.parametrize("case", ["rx200_reach_goal", "rx200_pnp_goal"])
def test_batched_on_two_nodes_replays_the_recording(case: str) -> None:
    _, env_id, kwargs = next(c for c in CASES if c[0] == case)
    for seed, got in zip(SEEDS, record_batched(env_id, kwargs, case, num_nodes=2)):
        _assert_matches(case, seed, got)
