"""The registered task envs: IDs, checkers, goals, rewards and success, the smoke test, errors."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import rl_environments
import uniros
from rl_environments.reach import GoalSampler, goal_reward, is_success
from rl_environments.task_config import TaskConfigError, load_task_config, vector

# The RX200's IDs and FRobs_RL's IRB120 reacher; the other arms' (the IRB120's arm-file reach included) and the
# camera variants are tests/tasks/test_arm_envs.py's.
ALL_IDS = ("RX200ReacherSim-v0", "RX200ReacherGoalSim-v0", "ABBIRB120ReacherEnv-v0", "ABBIRB120ReacherGoalEnv-v0",
           "RX200PushSim-v0", "RX200PushGoalSim-v0", "RX200PnPSim-v0", "RX200PnPGoalSim-v0")
GOAL_IDS = tuple(i for i in rl_environments.GOAL_ENV_IDS if i in ALL_IDS)


def test_every_id_is_registered_on_import():
    arms = [f"{arm}{task}Sim-v0" for arm in ("VX300S", "UR5e", "NED2", "RX200Zed2")
            for task in ("Reacher", "ReacherGoal", "Push", "PushGoal", "PnP", "PnPGoal", "Slide", "SlideGoal")]
    arms += ["IRB120ReacherSim-v0", "IRB120ReacherGoalSim-v0", "IRB120SlideSim-v0", "IRB120SlideGoalSim-v0",
             "RX200SlideSim-v0", "RX200SlideGoalSim-v0"]  # the IRB120: no gripper, no push or pick-and-place
    assert set(rl_environments.ENV_IDS) == {*ALL_IDS, *arms}
    for env_id in rl_environments.ENV_IDS:
        spec = gym.spec(env_id)
        assert spec.max_episode_steps == (50 if env_id in rl_environments.MANIPULATION_ENV_IDS else 100)
    assert uniros.make is not gym.make and uniros.spaces is gym.spaces and uniros.register is gym.register


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gymnasium_check_env(make, env_id):
    check_env(make(env_id).unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_sb3_check_env(make, env_id):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    sb3_check_env(make(env_id).unwrapped, warn=True)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_smoke_loop_observations_stay_in_bounds(make, env_id):
    """The original documentation's smoke test: 100 random steps with resets."""
    env = make(env_id)
    obs, info = env.reset(seed=0)
    env.action_space.seed(0)
    episodes = 0
    for _ in range(100):
        assert env.observation_space.contains(obs), f"{env_id}: observation outside the declared space: {obs}"
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert np.isfinite(reward)
        assert "is_success" in info
        if terminated or truncated:
            obs, info = env.reset()
            episodes += 1
    assert env.observation_space.contains(obs)


def test_time_limit_truncates_after_100_steps(make):
    env = make("RX200ReacherGoalSim-v0")
    env.reset(seed=1)
    zero = np.zeros(env.action_space.shape, np.float32)
    steps = 0
    truncated = False
    while not truncated:
        _, _, terminated, truncated, _ = env.step(zero)
        steps += 1
        if terminated:
            pytest.skip("the goal happened to be reached with zero actions")
        assert steps <= 100
    assert steps == 100


def test_a_failed_first_reset_then_step_then_a_retry(make):
    """The step after a reset that raised raises the env's error (gymnasium's env checker used to
    fail first with a TypeError), gymnasium's ResetNeeded too; a reset that then succeeds steps."""
    from gymnasium.error import ResetNeeded

    from multiros.envs.errors import StepAfterFailedReset

    env = make("RX200ReacherGoalSim-v0")
    with pytest.raises(gym.error.Error, match="Seed must be"):
        env.reset(seed=-1)
    with pytest.raises(StepAfterFailedReset, match=r"after a reset that failed \(Error: Seed must be"):
        env.step(env.action_space.sample())
    with pytest.raises(ResetNeeded):
        env.step(env.action_space.sample())
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    assert env.observation_space.contains(obs)


@pytest.mark.parametrize("env_id", GOAL_IDS)
def test_goals_are_reachable_and_in_the_goal_box(make, env_id):
    env = make(env_id).unwrapped
    rng = np.random.default_rng(0)
    chain = env.task.chain
    low, high = env.observation_space["desired_goal"].low, env.observation_space["desired_goal"].high
    for _ in range(30):
        goal = env.task.goal_sampler.sample(rng)
        assert np.all(goal >= low - 1e-6) and np.all(goal <= high + 1e-6)
        result = chain.ik(goal - env.task.base_position, restarts=8, rng=rng)
        assert result.converged, f"{env_id}: sampled goal {goal} is not reachable (IK error {result.error:.4f})"


def test_goal_sampler_refuses_a_box_outside_the_workspace(make):
    env = make("RX200ReacherGoalSim-v0").unwrapped
    sampler = GoalSampler(env.task.chain, [5, 5, 5], [6, 6, 6], max_tries=256)
    with pytest.raises(RuntimeError, match="does not overlap"):
        sampler.sample(np.random.default_rng(0))


def test_reward_success_and_termination_semantics_goal_env(make):
    env = make("RX200ReacherGoalSim-v0").unwrapped
    obs, _ = env.reset(seed=3)
    tol = env.task.tolerance
    dg = obs["desired_goal"]
    near = dg + np.array([tol * 0.5, 0, 0], np.float32)
    far = dg + np.array([tol * 2.0, 0, 0], np.float32)
    assert env.compute_reward(near, dg, {}) == 0.0
    assert env.compute_reward(far, dg, {}) == -1.0
    assert env.compute_terminated(near, dg, {}) and not env.compute_terminated(far, dg, {})
    batch_ag = np.stack([near, far, near])
    batch_dg = np.stack([dg, dg, dg])
    np.testing.assert_array_equal(env.compute_reward(batch_ag, batch_dg, [{}] * 3), [0.0, -1.0, 0.0])
    np.testing.assert_array_equal(env.compute_terminated(batch_ag, batch_dg, [{}] * 3), [True, False, True])


def test_reaching_the_goal_ends_the_episode_with_success(make):
    """Drive the arm to the goal with IK through absolute joint actions: success and termination."""
    env = make("RX200ReacherGoalSim-v0", delta_action=False).unwrapped
    obs, _ = env.reset(seed=5)
    q = env.task.chain.ik(obs["desired_goal"] - env.task.base_position, restarts=8).q
    for _ in range(40):
        obs, reward, terminated, truncated, info = env.step(q.astype(np.float32))
        if terminated:
            break
    assert terminated and info["is_success"] and reward == 0.0
    assert np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]) <= env.task.tolerance


def test_plain_rx200_rewards(make):
    env = make("RX200ReacherSim-v0").unwrapped
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.zeros(5, np.float32))
    assert reward == pytest.approx(-info["distance"])
    shaped = make("RX200ReacherSim-v0", simple_dense_reward=False).unwrapped
    shaped.reset(seed=0)
    _, reward, _, _, info = shaped.step(np.zeros(5, np.float32))
    assert reward == pytest.approx(-2.0 * info["distance"] - 0.5)
    sparse = make("RX200ReacherSim-v0", reward_type="sparse").unwrapped
    sparse.reset(seed=0)
    assert sparse.step(np.zeros(5, np.float32))[1] == -1.0


def test_irb120_frobs_rewards(make):
    env = make("ABBIRB120ReacherEnv-v0").unwrapped
    obs, _ = env.reset(seed=0)
    assert obs.shape == (12,)
    np.testing.assert_allclose(np.linalg.norm(obs[:3]), 1.0, rtol=1e-5)
    _, reward, _, _, info = env.step(np.zeros(6, np.float32))
    assert reward == pytest.approx(-1.0 * info["distance"] - 0.01)
    # Driving a joint target into its limit costs joint_limits_reward (-5).
    action = np.zeros(6, np.float32)
    action[0] = 1.0  # the base joint: nothing blocks it on the way to +2.88 rad
    for _ in range(40):
        _, reward, *_ = env.step(action)
    assert env.task.at_joint_limits()
    assert reward == pytest.approx(-1.0 * np.linalg.norm(env.task.goal - env.ee_position()) - 0.01 - 5.0, abs=1e-6)


def test_ee_action_option(make):
    env = make("RX200ReacherGoalSim-v0", ee_action_type=True).unwrapped
    obs, _ = env.reset(seed=0)
    assert env.action_space.shape == (3,)
    start = obs["achieved_goal"].copy()
    for _ in range(15):
        obs, *_ = env.step(np.array([0.0, 0.0, 1.0], np.float32))
    assert obs["achieved_goal"][2] > start[2] + 0.05  # moved up


def test_vectorised_rewards_are_pure():
    ag = np.zeros((4, 3))
    dg = np.array([[0, 0, 0.01], [0, 0, 0.03], [0, 0, 0.0], [1, 0, 0]])
    np.testing.assert_array_equal(goal_reward(ag, dg, 0.02, "sparse"), [0, -1, 0, -1])
    np.testing.assert_allclose(goal_reward(ag, dg, 0.02, "dense"), [-0.01, -0.03, 0.0, -1.0], rtol=1e-6)
    assert goal_reward(ag[0], dg[0], 0.02, "sparse") == 0.0
    np.testing.assert_array_equal(is_success(ag, dg, 0.02), [True, False, True, False])


def test_unknown_id_lists_what_exists():
    with pytest.raises(uniros.factory.UnknownEnvError) as err:
        uniros.make("RX200ReacherGoalSimm-v0")
    message = str(err.value)
    assert "RX200ReacherGoalSim-v0" in message and "ABBIRB120ReacherEnv-v0" in message


def test_unknown_kwarg_lists_accepted_ones():
    with pytest.raises(TypeError) as err:
        uniros.make("RX200ReacherGoalSim-v0", rewrd_type="sparse")
    message = str(err.value)
    assert "rewrd_type" in message and "reward_type" in message and "sim_mode" in message
    assert "(did you mean 'reward_type'?)" in message


@pytest.mark.parametrize(("typo", "meant"), [("image_widht", "image_width"), ("max_episode_step", "max_episode_steps"),
                                             ("rgb_plus_normal_ob", "rgb_plus_normal_obs")])
def test_a_kwarg_typo_names_the_nearest_of_every_accepted_one(typo, meant):
    """The accepted list holds the camera options and gymnasium.make's own keywords too."""
    with pytest.raises(uniros.factory.EnvKeywordError) as err:
        uniros.make("RX200ReacherGoalSim-v0", **{typo: 1})
    assert err.value.unknown == [typo] and err.value.suggestions == {typo: meant}
    assert f"unexpected keyword argument(s) ['{typo}'] (did you mean '{meant}'?)" in str(err.value)
    for name in ("image_width", "rgb_obs_only", "camera_position", "max_episode_steps", "render_mode"):
        assert name in err.value.accepted
    assert "args" not in err.value.accepted  # *args is no keyword


def test_a_bad_kwarg_beside_good_ones_is_the_only_one_named():
    """Gymnasium's message repeats every keyword given; only the one the env does not take is named."""
    with pytest.raises(uniros.factory.EnvKeywordError) as err:
        uniros.make("RX200ReacherGoalSim-v0", ee_action_type=True, reward_type="dense", rewrd_scale=2.0)
    assert err.value.unknown == ["rewrd_scale"]
    assert "unexpected keyword argument(s) ['rewrd_scale']" in str(err.value)
    assert "ee_action_type" not in err.value.suggestions


def test_bad_task_config_names_key_and_file(tmp_path):
    good = load_task_config("irb120_reacher_task_config.yaml", {"tolerance_goal_pos": float}, section="irb120")
    assert good["tolerance_goal_pos"] == 0.05
    bad = tmp_path / "cfg.yaml"
    bad.write_text("rx200:\n  reach_tolerance: close\n")
    with pytest.raises(TaskConfigError, match=r"cfg\.yaml.*'reach_tolerance'.*number"):
        load_task_config(bad, {"reach_tolerance": float}, section="rx200")
    bad.write_text("rx200:\n  position_goal_min: [0, 1]\n")
    with pytest.raises(TaskConfigError, match="'position_goal_min'.*3 finite numbers"):
        load_task_config(bad, {"position_goal_min": vector(3)}, section="rx200")
    with pytest.raises(TaskConfigError, match="missing key 'reach_tolerance'"):
        load_task_config(bad, {"reach_tolerance": float}, section="rx200")
    with pytest.raises(TaskConfigError, match="not found"):
        load_task_config(tmp_path / "nope.yaml", {})


def test_env_with_bad_config_file_fails_clearly(tmp_path):
    bad = tmp_path / "rx200.yaml"
    bad.write_text("rx200:\n  arm_joints: [a]\n")
    with pytest.raises(TaskConfigError, match="missing key"):
        uniros.make("RX200ReacherGoalSim-v0", config_file=str(bad))


def test_two_envs_in_one_process_are_independent(make):
    a, b = make("RX200ReacherGoalSim-v0"), make("RX200ReacherGoalSim-v0")
    oa, _ = a.reset(seed=11)
    ob, _ = b.reset(seed=11)
    np.testing.assert_array_equal(oa["desired_goal"], ob["desired_goal"])
    for _ in range(5):
        oa, *_ = a.step(np.ones(5, np.float32))
    ob2, *_ = b.step(np.zeros(5, np.float32))
    assert not np.allclose(oa["achieved_goal"], ob2["achieved_goal"])


def test_same_seed_same_trajectory(make):
    def run():
        env = make("ABBIRB120ReacherGoalEnv-v0")
        obs, _ = env.reset(seed=4)
        env.action_space.seed(4)
        rows = [obs["observation"]]
        for _ in range(20):
            obs, *_ = env.step(env.action_space.sample())
            rows.append(obs["observation"])
        return np.array(rows)

    assert run().tobytes() == run().tobytes()


def _wait_for_goal_marker(env, timeout: float = 5.0) -> None:
    """The node holds the current goal's marker (it applies markers as they arrive: at once here;
    tests/tasks/test_render_goal.py checks the first frame after reset without waiting)."""
    node = env.sim_connection.sim_node
    deadline = time.monotonic() + timeout
    while True:
        renderer = node._renderer
        marker = None if renderer is None else renderer.markers.get("goal/0")
        if marker is not None and np.allclose(marker.position, env.task.goal):
            return
        assert time.monotonic() < deadline, "the goal marker never reached the node"
        time.sleep(0.01)


@pytest.mark.slow
def test_rgb_array_rendering_shows_the_goal_marker(make):
    env = make("RX200ReacherGoalSim-v0", render_mode="rgb_array", render_width=160, render_height=120).unwrapped
    env.reset(seed=0)
    _wait_for_goal_marker(env)
    first = env.render()
    assert first.shape == (120, 160, 3) and first.dtype == np.uint8 and first.std() > 0
    env.reset(seed=1)  # a new goal moves the green marker
    _wait_for_goal_marker(env)
    moved = env.render()
    assert np.abs(moved.astype(int) - first.astype(int)).sum() > 0


def test_human_rendering_without_a_display_is_refused_clearly(make, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    env = make("RX200ReacherGoalSim-v0", render_mode="human")
    env.reset(seed=0)
    with pytest.raises(Exception, match="display"):
        env.render()
