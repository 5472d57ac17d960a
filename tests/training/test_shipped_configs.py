"""The config shipped for every simulated ID: each loads and its env takes its env kwargs; `uniros
train ID` from the command line, a short run (200 steps) of the real thing, demonstrations, HER and
camera images included, then `uniros eval` on it, for one ID of each kind of config (the other
arms' configs are the RX200's settings on the same tasks). The runs put 2 scripted episodes into
the replay buffer where the shipped config puts 50 (the config as shipped otherwise): 50 took most
of a run's time, and the demonstrations' own tests are in tests/tasks.
Whether the configs learn is benchmarks/bench_shipped_configs.py's job (hours for push)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

import rl_environments
import uniros
from uniros.cli import main as cli_main
from uniros.train_config import default_config_for

# One run per kind of config (the main suite's time): HER with normalisation, plain SAC with the shaped
# reward, FRobs_RL's IRB120, demonstrations without HER, demonstrations with HER on another arm, a camera.
CLI_RUNS = ["RX200ReacherGoalSim-v0", "RX200ReacherSim-v0", "ABBIRB120ReacherEnv-v0", "RX200PushSim-v0",
            "VX300SPnPGoalSim-v0", "RX200Zed2ReacherGoalSim-v0"]


@pytest.mark.slow
@pytest.mark.parametrize("env_id", rl_environments.ENV_IDS)
def test_every_simulated_id_ships_a_config_its_env_takes(env_id):
    config = default_config_for(env_id)
    env = uniros.make(env_id, **config.env_kwargs)
    try:
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("env_id", CLI_RUNS)
def test_uniros_train_runs_shipped_configs_from_the_cli(env_id, tmp_path, capsys):
    out = tmp_path / "runs"
    shipped = default_config_for(env_id).to_dict()  # the ID's file, or its task's for an arm file's ID
    params = shipped["model_params"]
    params["demonstrations"] = min(2, params.get("demonstrations", 0))  # as shipped, but 2 demonstrations
    config = tmp_path / f"{env_id}.yaml"
    config.write_text(yaml.safe_dump(shipped))
    assert cli_main(["train", env_id, "--config", str(config), "--steps", "200", "--output", str(out), "--name", "r",
                     "--eval-episodes", "1", "--no-video", "--no-progress"]) == 0
    text = capsys.readouterr()
    assert f"on {env_id} for 200 steps (config: " in text.out and "Traceback" not in text.err
    run = out / "r"
    meta = json.loads((run / "run.json").read_text())
    assert meta["status"] == "finished" and meta["steps"] == 200
    assert (run / "final_model.zip").is_file()
    assert cli_main(["eval", str(run), "--episodes", "1"]) == 0
    assert f"{env_id}: success rate " in capsys.readouterr().out


def test_demonstrations_of_a_camera_env_go_into_the_buffer_channel_first():
    """Scripted episodes of a camera variant (images next to the state) fill the replay buffer of a
    CNN policy, whose observation space holds the images channel-first."""
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rl_environments.manipulation_scripted import fill_replay_buffer
    from uniros.image_spaces import images_channel_first

    make = lambda: uniros.make("RX200Zed2PushSim-v0", rgb_plus_normal_obs=True, image_width=48,  # noqa: E731
                               image_height=36, max_episode_steps=10)
    train, demo = make(), make()
    try:
        venv = images_channel_first(DummyVecEnv([lambda: train]))
        assert venv.observation_space["rgb"].shape == (3, 36, 48)
        model = SAC("MultiInputPolicy", venv, buffer_size=100, learning_starts=0, device="cpu")
        stats = fill_replay_buffer(model, demo, 2, seed=0)
        buffer = model.replay_buffer
        assert stats["transitions"] == 20 and buffer.pos == 20
        stored = buffer.observations["rgb"][:20, 0]
        assert stored.shape == (20, 3, 36, 48) and stored.any()
        demo.reset(seed=0)
        np.testing.assert_array_equal(stored[0], np.transpose(demo.unwrapped.observe()["rgb"], (2, 0, 1)))
    finally:
        train.close()
        demo.close()


def test_scripted_policy_on_an_image_only_observation_says_what_it_needs():
    from rl_environments.manipulation_scripted import scripted_policy

    env = uniros.make("RX200PushGoalSim-v0", rgb_obs_only=True, image_width=48, image_height=36)
    try:
        obs, _ = env.reset(seed=0)
        with pytest.raises(ValueError, match="needs it next to the images"):
            scripted_policy(env)(obs)
    finally:
        env.close()
