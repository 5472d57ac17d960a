"""Domain randomisation of the arm envs (rl_environments.randomization): a checked mapping, worlds drawn
per reset and seeded with the env (the same seed, the same worlds and trajectory), the node's command
timing visible in the arm's motion, the sensors' offsets and noise in the readings only, a batch whose envs
draw worlds of their own, and the arm file's ``dynamics:`` applied with no randomisation at all."""

from __future__ import annotations

import numpy as np
import pytest

import uniros
from rl_environments.randomization import Randomization, RandomizationError

REACH = "RX200ReacherGoalSim-v0"
PUSH = "RX200PushGoalSim-v0"
FULL = {"link_mass": [0.8, 1.2], "joint_damping": [0.5, 2.0], "joint_friction": [0.5, 2.0],
        "joint_armature": [0.8, 1.2], "actuator_gain": [0.8, 1.2], "action_latency": [0, 2], "control_jitter": 0.2,
        "lag": [0.0, 0.2], "joint_noise": 0.004, "joint_offset": 0.01, "object_mass": [0.7, 1.3],
        "object_friction": [0.7, 1.3], "object_size": [0.95, 1.05], "table_friction": [0.7, 1.3],
        "object_position_noise": 0.005}


@pytest.mark.parametrize(("data", "message"), [
    ({"link_mas": [0.8, 1.2]}, "did you mean 'link_mass'?"),
    ({"link_mass": [1.2, 0.8]}, "low is above high"),
    ({"link_mass": [0.0, 1.0]}, "each value must be in [0.05, 20] (scale)"),
    ({"action_latency": [0, 1.5]}, "whole control periods"),
    ({"joint_noise": [0.0, 0.1]}, "must be one number (rad)"),
    ({"lag": "slow"}, "must be [low, high] or one number (s)"),
    ({"joint_offset": float("nan")}, "must be in [0, 0.1]"),
    ({"droop": [0.0, 0.5]}, "each value must be in [0, 0.2] (rad)"),
    ([1, 2], "must be a mapping of keys to ranges"),
])
def test_a_bad_mapping_is_one_line_naming_the_key(data, message):
    with pytest.raises(RandomizationError) as err:
        Randomization.from_mapping(data)
    assert message in str(err.value) and "\n" not in str(err.value)


def _rollout(env, seed: int, steps: int = 15) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs["observation"]]
    for _ in range(steps):
        obs, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        out.append(obs["observation"])
    return np.array(out)


def test_the_same_seed_draws_the_same_worlds_and_another_seed_others():
    env = uniros.make(PUSH, randomization=FULL)
    try:
        a, b, c = _rollout(env, 5), _rollout(env, 5), _rollout(env, 6)
    finally:
        env.close()
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a[1:], c[1:])


def test_randomisation_leaves_the_tasks_own_random_stream_alone():
    """The goal a seed samples is the same with and without randomisation (the draws have their own stream)."""
    goals = []
    for kwargs in ({}, {"randomization": FULL}):
        env = uniros.make(REACH, **kwargs)
        try:
            goals.append(env.reset(seed=11)[0]["desired_goal"])
        finally:
            env.close()
    np.testing.assert_array_equal(goals[0], goals[1])


def test_action_latency_holds_the_arm_for_whole_control_periods():
    def ee_track(randomization):
        env = uniros.make(REACH, randomization=randomization)
        try:
            obs, _ = env.reset(seed=1)
            track = [obs["achieved_goal"].copy()]
            for _ in range(4):
                obs, *_ = env.step(np.full(env.action_space.shape, 0.5))
                track.append(obs["achieved_goal"].copy())
            return np.linalg.norm(np.diff(np.array(track), axis=0), axis=1)
        finally:
            env.close()

    prompt, late = ee_track(None), ee_track({"action_latency": 2})
    assert prompt[0] > 5e-3, "the exact arm moves in the first step"
    assert late[0] < 1e-3 and late[1] < 1e-3, "two control periods late: still for two steps"
    assert late[2] > 5e-3


def test_droop_is_a_dead_band_each_joint_stops_short_by():
    """``droop``: a command within the band of where a joint stands does not move it; a larger one moves
    it to the band's edge short of the target (absolute joint targets, so the commands are exact)."""
    env = uniros.make(REACH, delta_action=False, randomization={"droop": [0.05, 0.05]})
    try:
        env.reset(seed=3)
        u = env.unwrapped
        start = u.arm_positions().copy()
        small = start.copy()
        small[1] += 0.03
        for _ in range(5):
            env.step(small.astype(np.float32))
        np.testing.assert_allclose(u.arm_positions(), start, atol=5e-3)  # within the band: still
        large = start.copy()
        large[1] += 0.2
        for _ in range(10):
            env.step(large.astype(np.float32))
        assert u.arm_positions()[1] - start[1] == pytest.approx(0.15, abs=5e-3)  # 0.05 short of 0.2
    finally:
        env.close()


def test_calibration_offsets_and_noise_are_in_the_readings_not_the_arm():
    env = uniros.make(REACH, randomization={"joint_offset": 0.05})
    try:
        env.reset(seed=2)
        u = env.unwrapped
        sensors = u.connection.sensors
        assert sensors is not None and np.max(np.abs(sensors.offsets)) > 0.01
        read = u.arm_positions()
        np.testing.assert_allclose(read, u.task.init_joint_pos, atol=1e-6), "the reset pose as the encoders read"
        # the arm stands where the model puts the pose minus the offsets: its end effector is elsewhere
        chain = u.arm.chain
        truth = chain.fk_position(np.asarray(u.task.init_joint_pos) - sensors.offsets)
        believed = chain.fk_position(np.asarray(u.task.init_joint_pos))
        ee = u.ee_position() - u.connection.base_position
        assert np.linalg.norm(ee - truth) < 2e-3 < np.linalg.norm(ee - believed)
    finally:
        env.close()


def test_the_trackers_latency_reports_the_object_where_it_was_that_long_ago():
    """Actions that push the cube, replayed with and without 0.18 s of tracker latency (4.5 control periods):
    the late tracker reports at each step what the prompt one reported five steps before, and the cube
    where it was placed at the reset, not where the last episode left it."""
    from rl_environments.manipulation_scripted import scripted_policy

    prompt, late = uniros.make(PUSH), uniros.make(PUSH, randomization={"object_position_latency": [0.18, 0.18]})
    try:
        seen = {}
        for name, env in (("prompt", prompt), ("late", late)):
            for episode in (0, 1):  # the second episode starts after a pushed cube
                obs, _ = env.reset(seed=10 + episode)
                goals = [obs["achieved_goal"].copy()]
                if name == "prompt":
                    policy, actions = scripted_policy(env), []
                    for _ in range(25):
                        actions.append(policy(obs))
                        obs, *_ = env.step(actions[-1])
                        goals.append(obs["achieved_goal"].copy())
                    seen[("actions", episode)] = actions
                else:
                    for action in seen[("actions", episode)]:
                        obs, *_ = env.step(action)
                        goals.append(obs["achieved_goal"].copy())
                seen[(name, episode)] = np.array(goals)
        for episode in (0, 1):
            truth, reported = seen[("prompt", episode)], seen[("late", episode)]
            assert np.ptp(truth[:, 0]) + np.ptp(truth[:, 1]) > 0.02, "the actions move the cube"
            np.testing.assert_allclose(reported[5:], truth[:-5], atol=1e-6)
            np.testing.assert_allclose(reported[:5], np.repeat(truth[:1], 5, axis=0), atol=1e-6)
        assert late.unwrapped.connection.sensors.frame_latency == pytest.approx(0.18)
    finally:
        prompt.close()
        late.close()


def test_a_batch_draws_a_world_per_env():
    vec = uniros.make_vec(PUSH, 2, vectorization_mode="batched", randomization={"object_mass": [0.5, 2.0],
                                                                               "joint_offset": 0.02})
    try:
        vec.reset(seed=4)
        offsets = [vec.envs[i].unwrapped.connection.sensors.offsets for i in range(2)]
        assert not np.allclose(offsets[0], offsets[1])
    finally:
        vec.close()


def test_the_arm_files_dynamics_apply_without_randomisation(tmp_path, monkeypatch):
    """An arm file with ``dynamics:`` (as uniros sysid writes it): its envs' joints settle at gain * command
    + offset, no ``randomization`` given."""
    import yaml

    from rl_environments.arm_registry import arm_of, register_arm, unregister_arm

    monkeypatch.setenv("UNIROS_ARMS", "")
    shipped = arm_of("RX200").path
    data = yaml.safe_load(shipped.read_text())
    data["name"] = "DroopRX200"
    assert data["description"]["uri"].startswith("package://"), "the copy must find the description"
    data["dynamics"] = {"time_constant": 0.05, "offset": [0.0, 0.03, -0.03, 0.0, 0.0]}
    path = tmp_path / "droop.yaml"
    path.write_text(yaml.safe_dump(data))
    register_arm(path)
    try:
        env = uniros.make("DroopRX200ReacherGoalSim-v0", delta_action=False)  # actions: absolute joint targets
        try:
            env.reset(seed=0)
            u = env.unwrapped
            target = np.asarray(u.task.init_joint_pos, dtype=np.float64)
            for _ in range(10):
                env.step(target.astype(np.float32))
            np.testing.assert_allclose(u.arm_positions() - target, [0.0, 0.03, -0.03, 0.0, 0.0], atol=5e-3)
        finally:
            env.close()
    finally:
        unregister_arm("DroopRX200")


def _sim2real_configs() -> list:
    from importlib import resources
    from pathlib import Path

    root = Path(str(resources.files("rl_environments.config").joinpath("training", "sim2real")))
    return sorted(root.glob("*.yaml"))


@pytest.mark.parametrize("path", _sim2real_configs(), ids=lambda p: p.stem)
def test_each_shipped_sim2real_config_loads_and_its_env_steps(path):
    from uniros.train_config import load_training_config

    config = load_training_config(path)
    assert config.env_kwargs.get("randomization"), "a sim2real config randomises"
    env = uniros.make(path.stem, **config.env_kwargs)
    try:
        env.reset(seed=0)
        for _ in range(3):
            env.step(env.action_space.sample())
    finally:
        env.close()


def test_the_sim2real_configs_cover_reach_on_every_shipped_arm_and_push_on_the_rx200():
    names = {p.stem for p in _sim2real_configs()}
    assert {"RX200ReacherGoalSim-v0", "VX300SReacherGoalSim-v0", "UR5eReacherGoalSim-v0", "NED2ReacherGoalSim-v0",
            "IRB120ReacherGoalSim-v0", "RX200PushGoalSim-v0"} <= names


def test_a_pixel_envs_camera_and_colours_change_its_images():
    def first_image(randomization, seed):
        env = uniros.make("RX200PushGoalSim-v0", rgb_plus_normal_obs=True, image_width=32, image_height=24,
                          **({"randomization": randomization} if randomization else {}))
        try:
            obs, _ = env.reset(seed=seed)
            return obs["rgb"].astype(int)
        finally:
            env.close()

    pytest.importorskip("mujoco")
    r = {"camera_position": 0.05, "camera_fovy": [0.9, 1.1], "colour": 0.3}
    plain, a, b = first_image(None, 0), first_image(r, 0), first_image(r, 0)
    np.testing.assert_array_equal(a, b)
    assert np.abs(plain - a).mean() > 1.0


def test_every_key_has_its_row_in_the_docs_table():
    from pathlib import Path

    from rl_environments.randomization import RANDOMIZATION_KEYS

    text = (Path(__file__).resolve().parents[2] / "docs" / "sim_to_real.md").read_text()
    missing = [key for key in RANDOMIZATION_KEYS if f"| `{key}` |" not in text]
    assert not missing, f"docs/sim_to_real.md has no row for {missing}"
