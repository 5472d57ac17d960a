"""The slide (rl_environments.slide_task), the task written on the arm env design: a puck struck to a goal
beyond the end effector's box, on every arm, the gripperless IRB120 included."""

from __future__ import annotations

import numpy as np
import pytest

import rl_environments
import uniros
from rl_environments.arm_env import ArmSimGoalEnv
from rl_environments.manipulation_scripted import run_episode, scripted_policy
from rl_environments.slide_task import PUCK, SlideTask


def test_every_arm_has_its_slide_ids_made_of_the_task_table_row():
    for arm in rl_environments.ARMS:
        for infix in ("Slide", "SlideGoal"):
            sim, real = f"{arm}{infix}Sim-v0", f"{arm}{infix}Real-v0"
            assert sim in rl_environments.ENV_IDS and rl_environments.SIM_TO_REAL[sim] == real
            assert sim in rl_environments.MANIPULATION_ENV_IDS  # scripted demonstrations fill replay buffers
            assert rl_environments.EPISODE_STEPS[sim] == 50


@pytest.mark.parametrize("arm", ["RX200", "IRB120"])
def test_the_goal_lies_beyond_the_end_effectors_box_and_the_puck_glides_there(arm):
    env = uniros.make(f"{arm}SlideGoalSim-v0")
    task = env.unwrapped.task
    try:
        assert isinstance(task, SlideTask) and env.action_space.shape == (3,)
        far = task.ee_high[0] + task.base_position[0]
        policy = scripted_policy(env)
        speeds: list[float] = []

        def record(obs, next_obs, *_):
            if policy.released:
                speeds.append(float(np.linalg.norm(next_obs["observation"][12:14])))

        for seed in range(3):
            obs, _ = env.reset(seed=seed)
            assert obs["desired_goal"][0] > far + 0.05, "the goal lies out of the tool's reach"
            assert env.observation_space.contains(obs)
            speeds.clear()
            run_episode(env, policy, seed=seed, on_step=record)
            # let go, it slows by drag alone: each 40 ms step keeps exp(-0.04 damping / mass) of its speed
            ratios = [b / a for a, b in zip(speeds[3:], speeds[4:]) if a > 0.05]
            assert ratios and np.allclose(ratios, np.exp(-0.04 * PUCK["damping"] / PUCK["mass"]), atol=0.02)
    finally:
        env.close()


@pytest.mark.parametrize("arm", ["RX200", "VX300S", "UR5e", "NED2", "IRB120"])
def test_the_scripted_slide_reaches_its_goals(arm):
    env = uniros.make(f"{arm}SlideGoalSim-v0")
    try:
        policy = scripted_policy(env)
        results = [run_episode(env, policy, seed=seed) for seed in range(6)]
        # 1.00 on every arm over 20 seeds, 0.94 to 1.00 over 50 (benchmarks/bench_scripted_envs.py)
        assert sum(r["is_success"] for r in results) >= 5, results
        assert all(r["truncated_reason"] is None for r in results), results  # the puck stays on the table
    finally:
        env.close()


def test_composed_from_values_and_options_checked():
    env = ArmSimGoalEnv(arm="IRB120", task="slide", reward_type="dense")
    try:
        assert len(type(env).__mro__) <= 8 and env.task.reward_type == "dense"
        obs, _ = env.reset(seed=0)
        reward = env.compute_reward(obs["achieved_goal"], obs["desired_goal"], {})
        assert reward == pytest.approx(-np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]), abs=1e-6)
    finally:
        env.close()
    with pytest.raises(ValueError, match="end-effector actions"):
        ArmSimGoalEnv(arm="RX200", task="slide", ee_action_type=False)
    with pytest.raises(ValueError, match="no task 'slid'"):
        ArmSimGoalEnv(arm="RX200", task="slid")


def test_the_scripted_slide_reads_a_plain_camera_envs_state_and_refuses_an_image_only_one():
    env = uniros.make("RX200SlideSim-v0", rgb_plus_normal_obs=True, image_width=16, image_height=16)
    try:  # the Zed2 slide's shipped config fills its replay buffer from such an env
        assert run_episode(env, scripted_policy(env), seed=0)["steps"] == 50
    finally:
        env.close()
    env = uniros.make("RX200SlideSim-v0", rgb_obs_only=True, image_width=16, image_height=16)
    try:
        obs, _ = env.reset(seed=0)
        with pytest.raises(ValueError, match="reads the state observation"):
            scripted_policy(env)(obs)
    finally:
        env.close()


def test_frobs_reacher_is_the_irb120s_only():
    from rl_environments.task_config import TaskConfigError

    with pytest.raises(TaskConfigError, match="FRobs_RL's reacher is the IRB120's"):
        ArmSimGoalEnv(arm="UR5e", task="frobs_reach")
