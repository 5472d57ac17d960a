import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from multiros.wrappers import NormalizeActionWrapper
from multiros.wrappers import normalize_action_wrapper as legacy_module

from .toy_envs import BoxEnv


def test_multiros_module_path_holds_the_class():
    assert legacy_module.NormalizeActionWrapper is NormalizeActionWrapper


def test_action_space_is_unit_box_and_inner_space_untouched():
    inner = BoxEnv()
    env = NormalizeActionWrapper(inner)
    assert env.action_space == spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float64)
    assert np.array_equal(inner.action_space.low, [-2.0, 0.0, 10.0])


def test_bounds_and_midpoint_map_exactly():
    env = NormalizeActionWrapper(BoxEnv())
    assert np.array_equal(env.action(np.array([-1.0, -1.0, -1.0])), [-2.0, 0.0, 10.0])
    assert np.array_equal(env.action(np.array([1.0, 1.0, 1.0])), [4.0, 0.5, 30.0])
    assert np.array_equal(env.action(np.zeros(3)), [1.0, 0.25, 20.0])


def test_round_trip_is_exact_in_float64():
    env = NormalizeActionWrapper(BoxEnv())
    rng = np.random.default_rng(0)
    a = rng.uniform(-1, 1, size=(1000, 3))
    back = np.array([env.reverse_action(env.action(x)) for x in a])
    np.testing.assert_allclose(back, a, rtol=0, atol=1e-14)
    raw = rng.uniform(env.env.action_space.low, env.env.action_space.high, size=(1000, 3))
    again = np.array([env.action(env.normalize_action(x)) for x in raw])
    np.testing.assert_allclose(again, raw, rtol=0, atol=1e-13)


def test_out_of_range_actions_are_clipped_to_env_bounds_and_keep_dtype():
    inner = BoxEnv(dtype=np.float32)
    env = NormalizeActionWrapper(inner)
    env.reset(seed=0)
    env.step(np.array([5.0, -5.0, 0.0], dtype=np.float32))
    sent = inner.received[-1]
    assert sent.dtype == np.float32
    assert inner.action_space.contains(sent)
    assert np.array_equal(sent, np.array([4.0, 0.0, 20.0], dtype=np.float32))


def test_step_passes_the_denormalised_action():
    inner = BoxEnv()
    env = NormalizeActionWrapper(inner)
    env.reset(seed=0)
    env.step(np.array([0.5, 0.0, -0.5]))
    np.testing.assert_allclose(inner.received[-1], [2.5, 0.25, 15.0])


def test_unbounded_dimension_is_refused_with_its_index():
    with pytest.raises(ValueError, match=r"unbounded dimensions at indices \[\[1\]\]"):
        NormalizeActionWrapper(BoxEnv(low=(-1.0, -np.inf, 0.0), high=(1.0, 1.0, 1.0)))


def test_non_box_space_is_refused():
    env = gym.make("CartPole-v1")
    with pytest.raises(TypeError, match="action space must be a gymnasium.spaces.Box"):
        NormalizeActionWrapper(env)
    env.close()


def test_degenerate_dimension_maps_to_its_value():
    env = NormalizeActionWrapper(BoxEnv(low=(0.0, 3.0), high=(1.0, 3.0)))
    assert np.array_equal(env.action(np.array([0.3, 0.9])), [0.65, 3.0])
    assert np.array_equal(env.reverse_action(np.array([0.5, 3.0])), [0.0, 0.0])


@pytest.mark.filterwarnings("ignore:.*different from the unwrapped")
def test_gymnasium_check_env_passes():
    check_env(NormalizeActionWrapper(BoxEnv(dtype=np.float32)), skip_render_check=True)
