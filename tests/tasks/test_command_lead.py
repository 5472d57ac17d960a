"""The object tasks' ``command_lead`` option: actions move on from the last command (within the lead of the
measured arm) instead of from the measured arm, so a lagging, late or sticking servo still gets the whole
of each action; 0 keeps Fetch's (and the golden trajectories') measured reference."""

from __future__ import annotations

import numpy as np
import pytest

PUSH = "RX200PushGoalSim-v0"


def _ee_x_after_a_pulse(env, steps: int = 14) -> list[float]:
    """The end effector's x, from the reset, over five full +x actions and then zero actions."""
    obs, _ = env.reset(seed=7)
    x0 = float(obs["observation"][0])
    xs = []
    for t in range(steps):
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        action[0] = 1.0 if t < 5 else 0.0
        obs, *_ = env.step(action)
        xs.append(float(obs["observation"][0]) - x0)
    return xs


def test_with_a_control_period_of_latency_a_lead_ends_the_chase_of_old_readings(make):
    """From the measured arm, a command one period late chases a reading one period old: the arm swings
    on after the actions stop. From the last command it moves the five actions' 10 cm and stays."""
    late = {"action_latency": [1, 1]}
    measured = _ee_x_after_a_pulse(make(PUSH, randomization=late))
    led = _ee_x_after_a_pulse(make(PUSH, randomization=late, command_lead=0.03))
    assert np.ptp(measured[8:]) > 0.02, measured  # still swinging well after the last action
    assert np.ptp(led[8:]) < 2e-3, led
    assert led[-1] == pytest.approx(5 * 0.02, abs=5e-3)


def test_with_a_lagging_servo_the_actions_add_up_to_their_distance(make):
    lag = {"lag": [0.1, 0.1]}
    measured = _ee_x_after_a_pulse(make(PUSH, randomization=lag))
    led = _ee_x_after_a_pulse(make(PUSH, randomization=lag, command_lead=0.05))
    assert measured[-1] < 0.05, measured  # each action moves the arm a fraction of itself
    assert led[-1] == pytest.approx(5 * 0.02, abs=8e-3), led


def test_the_command_stays_within_the_lead_of_the_measured_arm_and_resets_forget_it(make):
    env = make(PUSH, randomization={"lag": [0.25, 0.25]}, command_lead=0.03)
    task = env.unwrapped.task
    obs, _ = env.reset(seed=1)
    assert np.isnan(task.ee_goal).all()
    base = task.base_position
    for _ in range(6):
        before = obs["observation"][:3].astype(np.float64) - base
        obs, *_ = env.step(np.array([1.0, -1.0, 0.0, 1.0], dtype=np.float32))
        lead = task.ee_goal - before
        assert np.all(np.abs(lead) <= 0.03 + 0.02 + 1e-4), lead  # the lead plus one action
    assert abs(task.ee_goal[0] - (obs["observation"][0] - base[0])) > 0.02  # it ran ahead of the arm
    env.reset(seed=2)
    assert np.isnan(task.ee_goal).all()


def test_a_zero_lead_commands_what_the_default_commands(make):
    default, zero = make(PUSH), make(PUSH, command_lead=0.0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (10, 4)).astype(np.float32)
    runs = []
    for env in (default, zero):
        obs, _ = env.reset(seed=3)
        seen = [obs["observation"]]
        for a in actions:
            seen.append(env.step(a)[0]["observation"])
        runs.append(np.array(seen))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_joint_actions_move_on_from_the_last_joint_targets(make):
    env = make(PUSH, ee_action_type=False, command_lead=0.1, randomization={"lag": [0.25, 0.25]})
    task = env.unwrapped.task
    env.reset(seed=0)
    start = task.joint_targets.copy()
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    action[0], action[-1] = 1.0, 1.0
    for _ in range(2):
        env.step(action)
    # two steps of delta_coeff (0.05 rad) on the first joint, though the lagging joint moved less
    assert task.joint_targets[0] - start[0] == pytest.approx(2 * task.delta_coeff, abs=1e-9)


def test_the_slide_task_takes_the_lead_too(make):
    env = make("RX200SlideGoalSim-v0", command_lead=0.05, randomization={"lag": [0.1, 0.1]})
    obs, _ = env.reset(seed=0)
    x0 = float(obs["observation"][0])
    for _ in range(3):
        obs, *_ = env.step(np.array([1.0, 0.0, 0.0], dtype=np.float32))
    assert env.unwrapped.task.ee_goal[0] + env.unwrapped.task.base_position[0] - x0 == pytest.approx(
        3 * env.unwrapped.task.ee_delta_coeff, abs=1e-3)


@pytest.mark.parametrize("bad", [-0.01, 2.0, "0.03", True, float("nan")])
def test_a_bad_lead_is_refused_with_its_name(make, bad):
    with pytest.raises(ValueError, match="command_lead"):
        make(PUSH, command_lead=bad)
