import numpy as np
import pytest

from multiros.wrappers import TimeLimitWrapper
from multiros.wrappers import time_limit_wrapper as legacy_module

from .toy_envs import BoxEnv

ACTION = np.array([0.0, 0.0, 10.0])


def run(env, n):
    env.reset(seed=0)
    return [env.step(ACTION) for _ in range(n)]


def test_module_path():
    assert legacy_module.TimeLimitWrapper is TimeLimitWrapper


def test_truncates_after_max_steps_with_flags():
    out = run(TimeLimitWrapper(BoxEnv(), max_steps=3), 3)
    for _, _, terminated, truncated, info in out[:2]:
        assert not truncated and not terminated
        assert "time_limit_reached" not in info
    _, _, terminated, truncated, info = out[2]
    assert truncated is True
    assert terminated is False  # FRobs_RL set terminated too; gymnasium semantics say no
    assert info["is_success"] is False
    assert info["TimeLimit.truncated"] is True
    assert info["time_limit_reached"] is True


def test_success_flag_of_env_is_kept():
    _, _, _, truncated, info = run(TimeLimitWrapper(BoxEnv(success=True), max_steps=2), 2)[-1]
    assert truncated and info["is_success"] is True


def test_terminated_on_last_step_is_not_a_timelimit_truncation():
    _, _, terminated, truncated, info = run(TimeLimitWrapper(BoxEnv(terminate_at=2), max_steps=2), 2)[-1]
    assert terminated and truncated
    assert info["TimeLimit.truncated"] is False


def test_reset_restarts_the_count():
    env = TimeLimitWrapper(BoxEnv(), max_steps=2)
    run(env, 2)
    env.reset()
    assert env.elapsed_steps == 0
    assert env.step(ACTION)[3] is False


def test_multiros_keyword_and_default():
    assert TimeLimitWrapper(BoxEnv(), max_episode_steps=7).max_steps == 7
    assert TimeLimitWrapper(BoxEnv()).max_episode_steps == 100


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_bad_limits_refused(bad):
    with pytest.raises(ValueError, match="max_steps"):
        TimeLimitWrapper(BoxEnv(), max_steps=bad)


def test_frobs_stacking_order_runs():
    from multiros.wrappers import NormalizeActionWrapper, NormalizeObservWrapper

    env = TimeLimitWrapper(NormalizeObservWrapper(NormalizeActionWrapper(BoxEnv())), max_steps=4)
    env.reset(seed=0)
    steps = 0
    while True:
        *_, terminated, truncated, info = env.step(env.action_space.sample())
        steps += 1
        if terminated or truncated:
            break
    assert steps == 4 and "is_success" in info
