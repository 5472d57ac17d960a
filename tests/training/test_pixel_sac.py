"""uniros.pixel_sac: DrQ's random shift, the image encoder, and SAC whose encoder learns from the
critic loss (``algorithm: drq_sac``)."""

from __future__ import annotations

import numpy as np
import pytest
import torch as th
import torch.nn.functional as F
from gymnasium import spaces

import uniros
from uniros.errors import TrainingConfigError
from uniros.pixel_sac import DrQSAC, ImageEncoder, random_shift
from uniros.train_config import load_training_config, parse_training_config


def test_random_shift_crops_the_edge_padded_image_at_an_offset_per_image():
    th.manual_seed(0)
    images = th.randint(0, 256, (6, 3, 12, 10), dtype=th.uint8)
    shifted = random_shift(images, 2)
    assert shifted.shape == images.shape and shifted.dtype == th.float32
    padded = F.pad(images.float(), (2, 2, 2, 2), mode="replicate")
    offsets = []
    for k in range(len(images)):
        found = [(dy, dx) for dy in range(5) for dx in range(5)
                 if th.equal(shifted[k], padded[k, :, dy:dy + 12, dx:dx + 10])]
        assert found, f"image {k} is no crop of its padded self"
        offsets.append(found[0])
    assert len(set(offsets)) > 1  # drawn per image
    assert th.equal(random_shift(images, 0), images.float())
    with pytest.raises(ValueError, match="pad must be >= 0"):
        random_shift(images, -1)
    with pytest.raises(ValueError, match=r"\(N, C, H, W\)"):
        random_shift(images[0], 2)


def _goal_image_space() -> spaces.Dict:
    return spaces.Dict({"achieved_goal": spaces.Box(-1, 1, (3,)), "desired_goal": spaces.Box(-1, 1, (3,)),
                        "observation": spaces.Box(0, 255, (3, 48, 48), np.uint8)})


def test_image_encoder_reads_the_images_and_the_vectors_it_is_given():
    space = _goal_image_space()
    encoder = ImageEncoder(space, image_features=20, ignore_keys=["achieved_goal"])
    assert encoder.features_dim == 20 + 3 and encoder.image_keys == ["observation"]
    obs = {k: th.as_tensor(np.stack([s.sample() for _ in range(2)])).float() for k, s in space.spaces.items()}
    out = encoder(obs)
    assert out.shape == (2, 23) and th.all(out[:, :20].abs() <= 1)  # tanh
    moved = dict(obs, achieved_goal=obs["achieved_goal"] + 0.5)
    assert th.equal(encoder(moved), out)  # not read
    assert th.equal(encoder(dict(obs, desired_goal=obs["desired_goal"] + 0.5))[:, 20:], out[:, 20:] + 0.5)
    assert not th.equal(encoder(dict(obs, observation=255 - obs["observation"]))[:, :20], out[:, :20])
    with pytest.raises(ValueError, match="ignore_keys \\['goal'\\] are not keys"):
        ImageEncoder(space, ignore_keys=["goal"])
    with pytest.raises(ValueError, match="no image among"):
        ImageEncoder(space, ignore_keys=["observation"])


@pytest.fixture
def camera_env():
    env = uniros.make("RX200ReacherGoalSim-v0", rgb_obs_only=True, image_width=48, image_height=48,
                      ee_action_type=True, max_episode_steps=5)
    yield env
    env.close()


def _model(env, **kwargs):
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.vec_env import DummyVecEnv

    from uniros.image_spaces import images_channel_first

    venv = images_channel_first(DummyVecEnv([lambda: env]))
    return DrQSAC("MultiInputPolicy", venv, replay_buffer_class=HerReplayBuffer, learning_starts=10, batch_size=8,
                  buffer_size=200, seed=0, device="cpu",
                  policy_kwargs={"net_arch": [16, 16],
                                 "features_extractor_kwargs": {"ignore_keys": ["achieved_goal"]}}, **kwargs)


@pytest.mark.slow
def test_the_encoder_learns_from_the_critic_and_the_actor_reads_it_detached(camera_env, tmp_path):
    model = _model(camera_env, image_shift=2)
    encoder = model.critic.features_extractor
    assert model.actor.features_extractor is encoder and isinstance(encoder, ImageEncoder)
    in_critic = {id(p) for group in model.critic.optimizer.param_groups for p in group["params"]}
    in_actor = {id(p) for group in model.actor.optimizer.param_groups for p in group["params"]}
    enc = {id(p) for p in encoder.parameters()}
    assert enc <= in_critic and not enc & in_actor
    assert {id(p) for p in model.actor.mu.parameters()} <= in_actor
    before = [p.detach().clone() for p in encoder.parameters()]
    target_before = [p.detach().clone() for p in model.critic_target.features_extractor.parameters()]
    model.learn(20)
    assert model._n_updates > 0
    assert any(not th.equal(a, b) for a, b in zip(before, encoder.parameters()))
    assert any(not th.equal(a, b) for a, b in zip(target_before, model.critic_target.features_extractor.parameters()))

    # Saved and loaded: the same actions, the same shift.
    obs = model.env.reset()
    action, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "drq.zip")
    loaded = DrQSAC.load(tmp_path / "drq.zip", env=model.get_env(), device="cpu")  # HER needs the env
    assert loaded.image_shift == 2
    np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0], action, atol=1e-6)


def test_drq_sac_refuses_what_it_cannot_do(camera_env):
    with pytest.raises(ValueError, match="image_shift must be"):
        _model(camera_env, image_shift=-1)
    with pytest.raises(ValueError, match="gSDE"):
        _model(camera_env, use_sde=True)


def test_a_training_yaml_names_drq_sac_and_its_keywords():
    config = parse_training_config({"algorithm": "drq_sac", "use_HER": True, "training_steps": 1000,
                                    "drq_sac_params": {"image_shift": 4, "learning_rate": 1e-3, "tau": 0.01}})
    assert config.algorithm == "drq_sac" and config.algo_params["image_shift"] == 4
    with pytest.raises(TrainingConfigError, match="image_shfit"):
        parse_training_config({"algorithm": "drq_sac", "training_steps": 1000, "drq_sac_params": {"image_shfit": 4}})


def test_the_shipped_pixel_config_is_the_documented_recipe():
    """config/training/pixels/RX200ReacherGoalSim-v0.yaml (installed with the package): drq_sac on the image
    and the goal only, the settings of docs/training.md's my_drq.yaml (bench_pixel_learning's pixels_strict)."""
    from importlib import resources

    import yaml

    shipped = resources.files("rl_environments.config").joinpath("training", "pixels", "RX200ReacherGoalSim-v0.yaml")
    config = load_training_config(str(shipped))
    documented = parse_training_config(yaml.safe_load(_doc_block(":caption: my_drq.yaml\n", "```")), "docs")
    assert config.algorithm == documented.algorithm == "drq_sac" and config.use_her
    assert config.policy_params == documented.policy_params
    assert config.policy_params["features_extractor_kwargs"] == {"ignore_keys": ["achieved_goal"]}
    for key in ("learning_rate", "batch_size", "tau", "image_shift", "learning_starts", "buffer_size", "device"):
        assert config.algo_params[key] == documented.algo_params[key], key
    assert config.env_kwargs == documented.env_kwargs and config.training_steps == documented.training_steps


@pytest.mark.parametrize("env_id", ["VX300SReacherGoalSim-v0", "NED2ReacherGoalSim-v0"])
def test_the_other_pixel_configs_are_the_rx200_recipe_at_64_pixels(env_id):
    """config/training/pixels/<ID>.yaml of the VX300S and the NED2: the RX200's file but a 64 x 64 image
    and 60,000 steps (docs/tasks.md: what the runs that reached 0.95 used)."""
    from importlib import resources

    pixels = resources.files("rl_environments.config").joinpath("training", "pixels")
    rx200 = load_training_config(str(pixels.joinpath("RX200ReacherGoalSim-v0.yaml")))
    other = load_training_config(str(pixels.joinpath(f"{env_id}.yaml")))
    assert other.env_kwargs == {**rx200.env_kwargs, "image_width": 64, "image_height": 64}
    assert other.training_steps == 60_000 and rx200.training_steps == 40_000
    assert other.algo_params == rx200.algo_params  # buffer_size 40,000 in both
    assert (other.algorithm, other.use_her, other.her_params, other.policy_params, other.normalize,
            other.eval_freq, other.eval_episodes, other.stop_at_success, other.seed) == \
           (rx200.algorithm, rx200.use_her, rx200.her_params, rx200.policy_params, rx200.normalize,
            rx200.eval_freq, rx200.eval_episodes, rx200.stop_at_success, rx200.seed)


def test_the_irb120_pixel_config_is_the_recipe_with_its_camera_and_a_dark_floor():
    """config/training/pixels/IRB120ReacherGoalSim-v0.yaml: the VX300S's file (the RX200's recipe at 64 x 64)
    with a camera framing the goal box and ``floor_color: dark``, what the run that reached 0.95 used."""
    from importlib import resources

    pixels = resources.files("rl_environments.config").joinpath("training", "pixels")
    vx300s = load_training_config(str(pixels.joinpath("VX300SReacherGoalSim-v0.yaml")))
    irb120 = load_training_config(str(pixels.joinpath("IRB120ReacherGoalSim-v0.yaml")))
    assert irb120.env_kwargs == {**vx300s.env_kwargs, "camera_position": [0.938, -0.368, 0.675],
                                 "camera_lookat": [0.3, 0.0, 0.25], "floor_color": "dark"}
    assert irb120.training_steps == vx300s.training_steps and irb120.algo_params == vx300s.algo_params
    assert (irb120.algorithm, irb120.use_her, irb120.policy_params, irb120.stop_at_success, irb120.seed) == \
           (vx300s.algorithm, vx300s.use_her, vx300s.policy_params, vx300s.stop_at_success, vx300s.seed)


def test_the_ur5e_pixel_config_is_the_irb120_recipe_with_its_camera_and_100000_steps():
    """config/training/pixels/UR5eReacherGoalSim-v0.yaml: the IRB120's file (dark floor) with the camera 1.1 m
    from the UR5e's goal box and 100,000 steps, what the run that reached 0.95 at 96,000 steps used."""
    from importlib import resources

    pixels = resources.files("rl_environments.config").joinpath("training", "pixels")
    irb120 = load_training_config(str(pixels.joinpath("IRB120ReacherGoalSim-v0.yaml")))
    ur5e = load_training_config(str(pixels.joinpath("UR5eReacherGoalSim-v0.yaml")))
    assert ur5e.env_kwargs == {**irb120.env_kwargs, "camera_position": [1.238, -0.64, 0.765],
                               "camera_lookat": [0.475, 0.0, 0.3]}
    assert ur5e.env_kwargs["floor_color"] == "dark" and ur5e.training_steps == 100_000
    assert ur5e.algo_params == irb120.algo_params
    assert (ur5e.algorithm, ur5e.use_her, ur5e.policy_params, ur5e.stop_at_success, ur5e.seed) == \
           (irb120.algorithm, irb120.use_her, irb120.policy_params, irb120.stop_at_success, irb120.seed)


@pytest.mark.slow
def test_uniros_train_and_eval_a_drq_sac_model_on_a_camera_env(tmp_path, capsys):
    from uniros.cli import main as cli_main

    config = tmp_path / "drq.yaml"
    config.write_text("""
algorithm: drq_sac
training_steps: 60
eval_freq: 60
eval_episodes: 1
normalize: True
use_HER: True
use_custom_policy: True
policy_params:
  net_arch: [16, 16]
  features_extractor_kwargs: {ignore_keys: [achieved_goal], image_features: 16}
save_freq: 30
drq_sac_params: {learning_starts: 30, batch_size: 8, buffer_size: 100, image_shift: 2}
env_kwargs: {rgb_obs_only: True, image_width: 48, image_height: 48, ee_action_type: True, max_episode_steps: 10}
""")
    out = tmp_path / "runs"
    assert cli_main(["train", "RX200ReacherGoalSim-v0", "--config", str(config), "--output", str(out), "--name", "r",
                     "--eval-episodes", "1", "--no-video", "--no-progress"]) == 0
    assert "Traceback" not in capsys.readouterr().err
    from stable_baselines3.common.save_util import load_from_zip_file

    from uniros.trainer import algorithm_of

    saved = out / "r" / "final_model.zip"
    assert algorithm_of(saved) == "drq_sac"  # told from SAC by its saved image_shift
    data, _, _ = load_from_zip_file(str(saved), device="cpu")
    assert data["image_shift"] == 2 and data["_n_updates"] > 0
    assert data["observation_space"]["observation"].shape == (3, 48, 48)  # channel-first below the normaliser
    assert cli_main(["eval", str(out / "r"), "--episodes", "1"]) == 0
    assert "RX200ReacherGoalSim-v0: success rate " in capsys.readouterr().out
    # A resume goes on from the checkpoint: the model and its statistics hold the image channel-first,
    # the env gives it channel-last (a resume once found every checkpoint unusable and began at step 0).
    assert cli_main(["train", "--resume", str(out / "r"), "--steps", "90", "--eval-episodes", "0", "--no-video",
                     "--no-progress"]) == 0
    captured = capsys.readouterr()
    text = captured.out + captured.err
    assert "resuming from checkpoint model_60_steps.zip (60 steps, with its replay buffer and normalisation " \
           "statistics)" in text, text
    assert "skipped checkpoint" not in text and "starting the run again from step 0" not in text


def _doc_block(start: str, end: str) -> str:
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "training.md").read_text()
    head = text.index(start) + len(start)
    return text[head:text.index(end, head)]


def test_the_documented_drq_sac_yaml_loads_and_builds(monkeypatch):
    """docs/training.md's drq_sac YAML is complete (training_steps, the policy options in use) and
    builds a DrQSAC model on a goal env with a camera image (on the CPU here: auto without CUDA)."""
    import gymnasium as gym
    import yaml
    from gymnasium_robotics.core import GoalEnv
    from stable_baselines3.common.vec_env import DummyVecEnv

    import uniros.devices as devices
    from uniros.trainer import build_model

    data = yaml.safe_load(_doc_block(":caption: my_drq.yaml\n", "```"))
    config = parse_training_config(data, "docs/training.md")
    assert config.algorithm == "drq_sac" and config.training_steps == 40000 and config.device == "auto"
    assert config.policy_params["features_extractor_kwargs"] == {"ignore_keys": ["achieved_goal"]}
    del data["training_steps"]
    assert parse_training_config(data, "docs/training.md", steps=1234).training_steps == 1234  # --steps

    space = _goal_image_space()

    class CameraGoal(GoalEnv):
        observation_space, action_space = space, spaces.Box(-1, 1, (3,), np.float32)

        def compute_reward(self, achieved_goal, desired_goal, info):
            return -np.ones(np.shape(achieved_goal)[:-1], np.float32)

        def reset(self, *, seed=None, options=None):
            gym.Env.reset(self, seed=seed)
            return space.sample(), {}

        def step(self, action):
            return space.sample(), -1.0, False, False, {"is_success": False}

    config.algo_params["buffer_size"] = 50
    monkeypatch.setattr(devices, "_cuda_count", lambda: 0)
    model = build_model(config, DummyVecEnv([CameraGoal]))
    assert type(model) is DrQSAC and str(model.device) == "cpu"
    assert model.policy.actor.features_extractor.image_keys == ["observation"]


def test_the_documented_rl_zoo3_record_video_command_is_valid_python():
    code = _doc_block("python - <<'EOF'\n", "EOF\n")
    compile(code, "docs/training.md (record_video)", "exec")
    assert "rl_zoo3.record_video" in code and "import uniros" in code
