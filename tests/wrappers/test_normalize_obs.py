import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env
from stable_baselines3.common.vec_env import DummyVecEnv

from multiros.wrappers import NormalizeObservationWrapper, NormalizeObservWrapper, TimeLimitWrapper
from multiros.wrappers import normalize_obs_wrapper as legacy_module

from .toy_envs import BoxEnv, ToyGoalEnv

pytestmark = pytest.mark.filterwarnings("ignore:.*different from the unwrapped")


def test_names():
    assert NormalizeObservationWrapper is NormalizeObservWrapper
    assert legacy_module.NormalizeObservWrapper is NormalizeObservWrapper


def test_box_observation_bounds_map_to_unit_box():
    env = NormalizeObservWrapper(BoxEnv())
    assert env.observation_space == spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float64)
    obs, info = env.reset(seed=0)
    assert np.array_equal(obs, [-1.0, -1.0, -1.0])
    assert info == {"reset_info": 1}  # FRobs_RL dropped it; we keep it
    obs, *_ = env.step(np.array([4.0, 0.5, 30.0]))
    assert np.array_equal(obs, [1.0, 1.0, 1.0])
    obs, *_ = env.step(np.array([1.0, 0.25, 20.0]))
    assert np.array_equal(obs, [0.0, 0.0, 0.0])


def test_box_round_trip_exact():
    env = NormalizeObservWrapper(BoxEnv())
    rng = np.random.default_rng(1)
    raw = rng.uniform(env.env.observation_space.low, env.env.observation_space.high, size=(500, 3))
    back = np.array([env.denormalize_observation(env.observation(x)) for x in raw])
    np.testing.assert_allclose(back, raw, rtol=0, atol=1e-13)


def test_out_of_bounds_values_are_not_clipped():
    env = NormalizeObservWrapper(BoxEnv(low=(0.0,), high=(1.0,)))
    assert env.observation(np.array([2.0]))[0] == pytest.approx(3.0)


def test_unbounded_observation_refused():
    with pytest.raises(ValueError, match="unbounded"):
        NormalizeObservWrapper(BoxEnv(low=(0.0, -np.inf), high=(1.0, 1.0)))


def test_goal_dict_normalises_observation_only_by_default():
    env = NormalizeObservWrapper(ToyGoalEnv())
    space = env.observation_space
    assert space["observation"] == spaces.Box(-1, 1, shape=(3,), dtype=np.float32)
    assert space["desired_goal"] == env.env.observation_space["desired_goal"]
    obs, _ = env.reset(seed=3)
    assert space.contains(obs)
    np.testing.assert_array_equal(obs["desired_goal"], env.unwrapped.goal)


def test_goal_dict_with_goal_normalisation_and_round_trip():
    env = NormalizeObservWrapper(ToyGoalEnv(), normalize_goal_spaces=True)
    for key in ("observation", "achieved_goal", "desired_goal"):
        assert env.observation_space[key] == spaces.Box(-1, 1, shape=(3,), dtype=np.float32)
    obs, _ = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    np.testing.assert_allclose(obs["desired_goal"], env.unwrapped.goal / env.unwrapped.bound, atol=1e-7)
    back = env.denormalize_observation(obs)
    np.testing.assert_allclose(back["desired_goal"], env.unwrapped.goal, atol=1e-7)


def test_compute_reward_through_wrapper_unnormalises_goals_batched():
    env = NormalizeObservWrapper(ToyGoalEnv(), normalize_goal_spaces=True)
    inner = env.unwrapped
    rng = np.random.default_rng(2)
    ag = rng.uniform(-inner.bound, inner.bound, size=(256, 3)).astype(np.float32)
    dg = rng.uniform(-inner.bound, inner.bound, size=(256, 3)).astype(np.float32)
    expected = inner.compute_reward(ag, dg, [{}] * 256)
    n_ag = env.observation({"observation": ag, "achieved_goal": ag, "desired_goal": dg})
    got = env.compute_reward(n_ag["achieved_goal"], n_ag["desired_goal"], [{}] * 256)
    assert got.shape == (256,)
    np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-6)
    term = env.compute_terminated(n_ag["achieved_goal"], n_ag["achieved_goal"], [{}] * 256)
    assert term.shape == (256,) and term.all()


def test_step_reward_equals_compute_reward_on_normalised_obs():
    env = TimeLimitWrapper(NormalizeObservWrapper(ToyGoalEnv(), normalize_goal_spaces=True), max_steps=10)
    env.reset(seed=0)
    for _ in range(5):
        obs, reward, _, _, info = env.step(env.action_space.sample())
        assert reward == pytest.approx(float(env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)),
                                       abs=1e-6)


def test_her_env_method_reaches_the_unnormalising_compute_reward():
    vec = DummyVecEnv([lambda: TimeLimitWrapper(NormalizeObservWrapper(ToyGoalEnv(), normalize_goal_spaces=True),
                                                max_steps=5)])
    ag = np.zeros((4, 3), dtype=np.float32)  # normalised 0 = centre of the goal box = (0, 0, 0)
    dg = np.ones((4, 3), dtype=np.float32)  # normalised 1 = the upper bound (1, 2, 0.5)
    rewards = vec.env_method("compute_reward", ag, dg, [{}] * 4, indices=[0])[0]
    np.testing.assert_allclose(rewards, -np.linalg.norm([1.0, 2.0, 0.5]) * np.ones(4), rtol=1e-6)
    vec.close()


def test_checkers_pass_on_wrapped_goal_env():
    env = TimeLimitWrapper(NormalizeObservWrapper(ToyGoalEnv(), normalize_goal_spaces=True), max_steps=20)
    check_env(env, skip_render_check=True)
    sb3_check_env(env, warn=False)


def test_non_dict_with_goal_flag_refused():
    with pytest.raises(TypeError, match="needs a Dict"):
        NormalizeObservWrapper(BoxEnv(), normalize_goal_spaces=True)
