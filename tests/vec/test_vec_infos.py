"""The batched vector env's info merging equals Gymnasium's ``VectorEnv._add_info``, env by env."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from gymnasium.vector import VectorEnv

from multiros.envs.vector import _merge_plain_infos


class _Infos(VectorEnv):
    def __init__(self, num_envs: int) -> None:
        self.num_envs = num_envs


def _gymnasium(per_env: list[dict[str, Any] | None]) -> dict[str, Any]:
    vec, infos = _Infos(len(per_env)), {}
    for i, info in enumerate(per_env):
        infos = vec._add_info(infos, info or {}, i)
    return infos


@pytest.mark.parametrize("per_env", [
    [{"is_success": True}, {"is_success": False}, {"is_success": True}],
    [{}, None, {}],
    [{"is_success": False}, {}, {"is_success": True, "sim_status": 104, "sim_diverged": True}],
    [{"a": 1}, {"a": 2.5}, {"a": True}],  # the first env's type makes the array's dtype
    [{"a": 1.5}, {"a": 2}, {"b": np.float32(0.25)}],
    [{"n": np.int64(3), "x": 0.5}, {"x": -1.0, "n": np.int64(-4)}, {}],
    [{"d": np.float32(0.5)}, {"d": np.float32(-2.0)}, {"d": np.float32(1e-8)}],
    [{"d": 7}, {"d": -3}, {"d": 2**40}],
])
def test_plain_infos_merge_as_gymnasium_does(per_env: list[dict[str, Any] | None]) -> None:
    merged = _merge_plain_infos(per_env, len(per_env))
    expected = _gymnasium(per_env)
    assert merged is not None
    assert list(merged) == list(expected)  # same keys, masks after their keys, same order
    for key, value in expected.items():
        assert merged[key].dtype == value.dtype, key
        np.testing.assert_array_equal(merged[key], value, err_msg=key)


@pytest.mark.parametrize("per_env", [
    [{"is_success": np.True_}, {}],  # numpy bools: gymnasium makes an object array
    [{"sim_error": "diverged"}, {}],
    [{"nested": {"a": 1}}, {}],
    [{"v": np.zeros(3)}, {}],
    [{"final_obs": 1.0}, {}],
    [{"a": 1}, {"a": None}],
])
def test_other_infos_are_left_to_gymnasium(per_env: list[dict[str, Any] | None]) -> None:
    assert _merge_plain_infos(per_env, len(per_env)) is None


def test_a_value_its_array_cannot_hold_fails_as_in_gymnasium() -> None:
    per_env = [{"steps": 1}, {"steps": float("nan")}]
    with pytest.raises(ValueError, match="NaN"):
        _gymnasium(per_env)
    with pytest.raises(ValueError, match="NaN"):
        _merge_plain_infos(per_env, 2)
