"""The VX300S, UR5e, NED2 and IRB120 envs and the camera observations: the IDs and their twins, every new
simulated ID through gymnasium's checker, the scripted push and pick-and-place of each arm, camera
images that follow the arm, match a render of the same pose and equal the node's Image topics, and
clear errors for bad camera options and a camera that cannot render."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import rl_environments
import uniros
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_message
from multiros.sim.errors import RenderError
from rl_environments import ARM_TASKS, ARMS
from rl_environments.manipulation_scripted import run_episode, scripted_policy

# Push and pick-and-place only for an arm with a gripper (not the IRB120); the Zed2 variant apart.
NEW_SIM = [i for i in (f"{arm}{task}Sim-v0" for arm in ARMS if arm != "RX200Zed2" for task in ARM_TASKS)
           if i in rl_environments.ENV_IDS]
ZED2 = list(rl_environments.CAMERA_ENV_IDS)
Image = get_message("sensor_msgs/msg/Image")


def test_ids_and_twins_are_registered_as_rl_environments_names_them():
    """multiros_uniros.md §5.1's names: 4 arms x 6 tasks and the IRB120's 2, each with the slide's 2 (every arm,
    gripper or not), x (Sim, Real), the RX200's Zed2 variants (an arm file that extends the RX200's: their
    Real twins observe through the Zed2's topics)."""
    assert len(NEW_SIM) == 4 * 8 + 4
    assert {rl_environments.SIM_TO_REAL[i] for i in rl_environments.CAMERA_ENV_IDS} == {
        i.replace("Sim-v0", "Real-v0") for i in rl_environments.CAMERA_ENV_IDS}
    real = [i.replace("Sim-v0", "Real-v0") for i in NEW_SIM]
    assert set(NEW_SIM) | set(ZED2) <= set(rl_environments.ENV_IDS)
    assert set(real) <= set(rl_environments.REAL_ENV_IDS)
    assert [f"RX200Zed2{t}Sim-v0" for t in ARM_TASKS] == ZED2
    assert {"UR5ePnPGoalSim-v0", "NED2ReacherSim-v0", "VX300SPushReal-v0"} <= {*NEW_SIM, *real}
    for sim, twin in zip(NEW_SIM, real):
        assert rl_environments.SIM_TO_REAL[sim] == twin
        steps = 100 if "Reacher" in sim else 50
        assert gym.spec(sim).max_episode_steps == gym.spec(twin).max_episode_steps == steps
        assert ("Goal" in sim) == (sim in rl_environments.GOAL_ENV_IDS) == (twin in rl_environments.REAL_GOAL_ENV_IDS)


@pytest.mark.parametrize("env_id", [*NEW_SIM, *ZED2])
def test_make_reset_step_and_check_env(make, env_id):
    env = make(env_id)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.action_space.seed(0)
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs) and np.isfinite(reward) and "is_success" in info
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", [i for i in NEW_SIM if i.endswith(("PushGoalSim-v0", "PnPGoalSim-v0"))])
def test_scripted_policy_solves_each_arms_task(make, env_id):
    """>= 0.8 over fixed seeds through the registered ID (benchmarks/bench_scripted_envs.py runs 30)."""
    env = make(env_id)
    policy = scripted_policy(env)
    results = [run_episode(env, policy, seed=s) for s in range(10)]
    assert np.mean([r["is_success"] for r in results]) >= 0.8, results
    assert all(r["steps"] == 50 and r["truncated_reason"] is None for r in results)


# -- camera observations ---------------------------------------------------------------------------
def _changed(a: np.ndarray, b: np.ndarray) -> float:
    """The share of pixels whose colour differs noticeably."""
    return float((np.abs(a.astype(int) - b.astype(int)).sum(axis=-1) > 30).mean())


def test_camera_images_follow_the_arm_and_match_a_render_of_the_same_pose(make):
    kwargs = dict(rgb_plus_depth_plus_normal_obs=True, image_width=64, image_height=48)
    env = make("VX300SReacherSim-v0", **kwargs)
    obs, _ = env.reset(seed=2)
    assert obs["rgb"].shape == (48, 64, 3) and obs["rgb"].dtype == np.uint8
    assert obs["depth"].shape == (48, 64) and obs["depth"].dtype == np.float32
    first = obs["rgb"].copy()
    for _ in range(8):  # waist and shoulder swing round
        obs, *_ = env.step(np.array([1.0, 1.0, 0, 0, 0, 0], np.float32))
    assert _changed(first, obs["rgb"]) > 0.01, "the image must show the arm where it is now"
    assert np.all((obs["depth"] > 0.1) & (obs["depth"] <= 10.0))
    # Another env of the same ID and seed, its joints teleported to this one's: the same picture.
    u = env.unwrapped
    other = make("VX300SReacherSim-v0", **kwargs)
    other.reset(seed=2)
    names = list(u.robot_state.names)
    other.unwrapped.set_joint_positions(names, u.robot_state.position)
    other.unwrapped._refresh_state(0)
    again = other.unwrapped.cameras.read_images()
    assert _changed(obs["rgb"], again[0]) < 0.002
    np.testing.assert_allclose(obs["depth"], again[1], atol=1e-3)


def _receive(env, topics: list[str]) -> dict[str, object]:
    """Subscribe to ``topics`` on the env's node, step the env once, return the step's observation and one
    message per topic."""
    u = env.unwrapped
    got: dict[str, list] = {t: [] for t in topics}
    subs = [u.node.create_subscription(Image, t, got[t].append, 10) for t in topics]
    try:
        obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
        executor = SingleThreadedExecutor(context=u.sim_connection.context)
        executor.add_node(u.node)
        deadline = time.monotonic() + 10.0
        while not all(got.values()) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        executor.remove_node(u.node)
    finally:
        for sub in subs:
            u.node.destroy_subscription(sub)
    assert all(got.values()), {t: len(m) for t, m in got.items()}
    return {"obs": obs, **{t: m[-1] for t, m in got.items()}}


def test_zed2_ids_observe_the_pixels_its_driver_topics_carry(make):
    env = make("RX200Zed2PushGoalSim-v0")
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"observation", "achieved_goal", "desired_goal", "rgb", "depth"}
    assert obs["rgb"].shape == (360, 640, 3), "the Zed2's own size by default"
    zed = "/rx200/zed2/zed_node"
    got = _receive(env, [f"{zed}/rgb/image_rect_color", f"{zed}/depth/depth_registered"])
    rgb, depth = got[f"{zed}/rgb/image_rect_color"], got[f"{zed}/depth/depth_registered"]
    assert rgb.encoding == "rgb8" and depth.encoding == "32FC1"
    np.testing.assert_array_equal(np.frombuffer(bytes(rgb.data), np.uint8).reshape(360, 640, 3), got["obs"]["rgb"])
    sent = np.frombuffer(bytes(depth.data), "<f4").reshape(360, 640)
    np.testing.assert_array_equal(np.minimum(sent, 10.0), got["obs"]["depth"])


def test_the_spawned_camera_publishes_the_observation_under_gazebo_ros_camera_names(make):
    env = make("NED2PnPSim-v0", rgb_plus_normal_obs=True, image_width=40, image_height=30)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"observation", "rgb"} and obs["observation"].shape == (37,)
    got = _receive(env, ["/ned2/camera/image_raw"])
    msg = got["/ned2/camera/image_raw"]
    assert (msg.width, msg.height, msg.encoding) == (40, 30, "rgb8")
    np.testing.assert_array_equal(np.frombuffer(bytes(msg.data), np.uint8).reshape(30, 40, 3), got["obs"]["rgb"])


def test_goal_env_keeps_its_keys_and_her_still_relabels(make):
    env = make("UR5eReacherGoalSim-v0", rgb_obs_only=True, image_width=32, image_height=32)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"observation", "achieved_goal", "desired_goal"}
    assert obs["observation"].shape == (32, 32, 3) and obs["observation"].dtype == np.uint8
    rewards = env.unwrapped.compute_reward(np.zeros((4, 3)), np.zeros((4, 3)), [{}] * 4)
    assert rewards.shape == (4,) and np.all(rewards == 0)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"rgb_obs_only": True, "rgb_plus_normal_obs": True}, "conflict"),
    ({"rgb_obs_only": True, "normal_obs_only": True}, "normal_obs_only=True conflicts"),
    ({"normal_obs_only": False}, "needs a camera mode"),
    ({"image_width": 64}, "without a camera observation"),
    ({"rgb_obs_only": True, "image_width": 4}, "image_width must be an integer from 8 to 1920"),
    ({"rgb_obs_only": True, "image_height": 2000}, "image_height must be an integer from 8 to 1080"),
    ({"rgb_obs_only": True, "image_width": 64.0}, "image_width must be an integer"),
    ({"rgb_obs_only": True, "camera_name": "render_camera", "camera_position": (1, 0, 1)}, "one or the other"),
    ({"rgb_obs_only": True, "camera_position": (1, 0, float("nan"))}, "camera_position must be 3 finite"),
    ({"rgb_obs_only": True, "camera_fovy": 200}, "camera_fovy"),
    ({"rgb_obs_only": True, "camera_name": "render_camera", "image_width": 64},
     "give both image_width and image_height"),
])
def test_bad_camera_options_are_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        uniros.make("VX300SReacherSim-v0", **kwargs)


def test_a_camera_request_has_both_sides_of_its_size_or_neither():
    """The seam's own check, for code that opens a connection's camera without the env's options."""
    from multiros.envs.connection import CameraRequest

    with pytest.raises(ValueError, match="give both image_width and image_height"):
        CameraRequest("render_camera", None, None, 45.0, 64, None, "render_camera/image_raw", None)
    assert CameraRequest("render_camera", None, None, 45.0, None, None, "render_camera/image_raw", None).width is None


def test_a_camera_that_sees_almost_one_colour_is_named(make, caplog):
    """A 1-degree view of a patch of floor (levels 204-209): a warning at make; the default view: none."""
    with caplog.at_level("WARNING", logger="multiros.envs.sim_connection"):
        make("RX200ReacherSim-v0", rgb_obs_only=True, image_width=16, image_height=16)
        assert "sees almost one colour" not in caplog.text
        make("RX200ReacherSim-v0", rgb_obs_only=True, image_width=16, image_height=16,
             camera_position=(0.9, 0.9, 0.05), camera_lookat=(0.9, 0.9, -1.0), camera_fovy=1.0)
    assert "the observation camera 'rx200_camera/camera' sees almost one colour" in caplog.text


def test_a_camera_that_does_not_exist_or_cannot_render_says_so(monkeypatch):
    with pytest.raises(RenderError, match="camera 'vx300s/nope' not found"):
        uniros.make("VX300SReacherSim-v0", rgb_obs_only=True, camera_name="nope")
    import mujoco

    def no_gl(*args, **kwargs):
        raise RuntimeError("gladLoadGL error")

    monkeypatch.setattr(mujoco, "Renderer", no_gl)
    with pytest.raises(RenderError, match="MUJOCO_GL=egl"):
        uniros.make("VX300SReacherSim-v0", rgb_obs_only=True)


def test_batched_envs_observe_each_through_its_own_camera():
    vec = uniros.make_vec("VX300SReacherGoalSim-v0", 2, rgb_plus_normal_obs=True, image_width=32, image_height=32)
    try:
        vec.reset(seed=0)
        obs, *_ = vec.step(vec.action_space.sample())
        assert obs["rgb"].shape == (2, 32, 32, 3) and obs["observation"].shape == (2, 21)
        for j, now in enumerate(vec.call("observe")):  # each env's camera sees its own world slot
            np.testing.assert_array_equal(now["rgb"], obs["rgb"][j])
    finally:
        vec.close()
