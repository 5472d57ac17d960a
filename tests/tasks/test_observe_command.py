"""The object tasks' ``observe_command`` option: three observation values after the arm joints, the last
commanded end effector minus the measured one, so a policy sees what a lagging or late servo has still to
move; off by default (the observation, and the golden trajectories, as before)."""

from __future__ import annotations

import numpy as np
import pytest

from rl_environments.manipulation_task import COMMAND_OFFSET_BOUND

PUSH = "RX200PushGoalSim-v0"


def test_the_offset_is_the_last_command_minus_the_measured_end_effector(make):
    env = make(PUSH, observe_command=True, command_lead=0.03, randomization={"lag": [0.25, 0.25]})
    default = make(PUSH)
    task = env.unwrapped.task
    space = env.observation_space["observation"]
    assert space.shape[0] == default.observation_space["observation"].shape[0] + 3
    np.testing.assert_array_equal(space.low[-3:], -COMMAND_OFFSET_BOUND)
    np.testing.assert_array_equal(space.high[-3:], COMMAND_OFFSET_BOUND)
    obs, _ = env.reset(seed=1)
    np.testing.assert_array_equal(obs["observation"][-3:], 0.0)  # no command yet this episode
    seen = []
    for _ in range(4):
        obs, *_ = env.step(np.array([1.0, 0.0, 0.0, 1.0], dtype=np.float32))
        measured = obs["observation"][:3].astype(np.float64) - task.base_position
        np.testing.assert_allclose(obs["observation"][-3:], task.ee_goal - measured, atol=1e-5)
        seen.append(float(obs["observation"][-3]))
    assert max(seen) > 0.01, seen  # a lagging arm trails its +x commands
    obs, _ = env.reset(seed=2)
    np.testing.assert_array_equal(obs["observation"][-3:], 0.0)  # a reset forgets the last command


def test_the_offset_leaves_the_other_values_as_they_were(make):
    plain, observed = make(PUSH), make(PUSH, observe_command=True)
    actions = np.random.default_rng(0).uniform(-1, 1, (6, 4)).astype(np.float32)
    runs = []
    for env in (plain, observed):
        obs, _ = env.reset(seed=3)
        seen = [obs["observation"][:plain.observation_space["observation"].shape[0]]]
        for a in actions:
            seen.append(env.step(a)[0]["observation"][:plain.observation_space["observation"].shape[0]])
        runs.append(np.array(seen))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_a_plain_env_has_the_offset_before_its_goal(make):
    plain, observed = make("RX200PushSim-v0"), make("RX200PushSim-v0", observe_command=True)
    n = plain.observation_space.shape[0]
    assert observed.observation_space.shape == (n + 3,)
    obs, _ = observed.reset(seed=0)
    obs, *_ = observed.step(np.array([0.0, 1.0, 0.0, 1.0], dtype=np.float32))
    task = observed.unwrapped.task
    np.testing.assert_allclose(obs[-6:-3], task.goal, atol=1e-5)  # the goal, then goal minus object, last
    measured = obs[:3].astype(np.float64) - task.base_position
    np.testing.assert_allclose(obs[n - 6:n - 3], task.ee_goal - measured, atol=1e-5)


def test_the_slide_task_takes_it_too(make):
    env = make("RX200SlideGoalSim-v0", observe_command=True)
    default = make("RX200SlideGoalSim-v0")
    assert env.observation_space["observation"].shape[0] == default.observation_space["observation"].shape[0] + 3
    env.reset(seed=0)
    obs, *_ = env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
    task = env.unwrapped.task
    measured = obs["observation"][:3].astype(np.float64) - task.base_position
    np.testing.assert_allclose(obs["observation"][-3:], task.ee_goal - measured, atol=1e-5)


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_a_value_that_is_not_a_bool_is_refused_with_its_name(make, bad):
    with pytest.raises(ValueError, match="observe_command"):
        make(PUSH, observe_command=bad)


def test_joint_actions_are_refused_they_command_no_end_effector(make):
    with pytest.raises(ValueError, match="observe_command needs end-effector actions"):
        make(PUSH, ee_action_type=False, observe_command=True)
