"""``uniros train --init-from MODEL``: a new run that starts from a trained model's weights (a warm
start, rl-zoo3's ``--trained-agent``) with its own config's hyperparameters, a fresh replay buffer
and step 0 (docs/training.md, "Starting from a trained model"). Models of another algorithm, other
spaces or other network sizes are refused with a clear error before a run folder is written.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

from uniros.cli import main as cli_main
from uniros.model_files import ModelFileError, init_parameters
from uniros.train_config import load_training_config
from uniros.trainer import build_model

from .conftest import POINT_GOAL_ENV as ENV

pytestmark = pytest.mark.usefixtures("point_goal_env_on_path")

CONFIG = """algorithm: {algo}
training_steps: {steps}
eval_freq: 0
save_freq: 20
normalize: false
use_HER: true
video: false
progress_bar: false
use_custom_policy: true
policy_params: {{net_arch: [{width}, {width}]}}
{algo}_params: {{learning_starts: 10, batch_size: 8, buffer_size: 2000, learning_rate: {lr}}}
"""


def _config(folder: Path, name: str, *, algo: str = "sac", steps: int = 40, width: int = 16,
            lr: float = 0.001) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(CONFIG.format(algo=algo, steps=steps, width=width, lr=lr))
    return path


def _model(folder: Path, name: str, **kwargs) -> tuple[object, Path]:
    """An untrained model of the config ``name`` on the point goal env, saved as ``folder/name.zip``."""
    config = load_training_config(_config(folder, name, **kwargs))
    model = build_model(config, gym.make(ENV))
    path = folder / f"{name}.zip"
    model.save(path)
    return model, path


def _tensors(model) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in model.policy.state_dict().items()}


def test_a_model_starts_from_the_saved_weights_with_its_own_hyperparameters(tmp_path):
    source, path = _model(tmp_path, "source", lr=0.001)
    with torch.no_grad():  # weights and an entropy coefficient no fresh model has
        for p in source.policy.parameters():
            p.add_(0.5)
        source.log_ent_coef.fill_(-3.0)
    source.save(path)
    config = load_training_config(_config(tmp_path, "fresh", lr=0.0003))
    model = build_model(config, gym.make(ENV))
    assert any(not torch.equal(a, b) for a, b in zip(_tensors(model).values(), _tensors(source).values()))

    init_parameters(model, path, "sac")

    for name, value in _tensors(source).items():
        assert torch.equal(model.policy.state_dict()[name], value), name
    assert float(model.log_ent_coef.detach()) == pytest.approx(-3.0)
    assert model.learning_rate == pytest.approx(0.0003)  # the new config's, not the saved model's
    assert model.num_timesteps == 0 and model.replay_buffer.size() == 0


def test_another_algorithm_other_networks_or_no_file_are_clear_errors(tmp_path):
    config = load_training_config(_config(tmp_path, "run", width=16))
    model = build_model(config, gym.make(ENV))
    before = _tensors(model)
    _, td3 = _model(tmp_path, "td3", algo="td3")
    with pytest.raises(ModelFileError, match=r"is a TD3 model; this run trains SAC"):
        init_parameters(model, td3, "sac")
    _, wide = _model(tmp_path, "wide", width=32)
    with pytest.raises(ModelFileError, match=r"does not fit this run's networks .*net_arch"):
        init_parameters(model, wide, "sac")
    with pytest.raises(ModelFileError, match=r"not found"):
        init_parameters(model, tmp_path / "nothing.zip", "sac")
    (tmp_path / "garbage.zip").write_bytes(b"not a zip")
    with pytest.raises(ModelFileError, match=r"not a readable SB3 model"):
        init_parameters(model, tmp_path / "garbage.zip", "sac")
    for name, value in before.items():  # the refused files changed nothing
        assert torch.equal(model.policy.state_dict()[name], value), name


@pytest.mark.slow
def test_uniros_train_init_from_a_run_records_it_and_trains_from_step_0(tmp_path, capsys):
    runs = tmp_path / "runs"
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "a", steps=40)), "--output", str(runs),
                     "--name", "source", "--eval-episodes", "0"]) == 0
    source = runs / "source" / "final_model.zip"
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "b", steps=30, lr=0.0005)), "--output",
                     str(runs), "--name", "warm", "--init-from", str(runs / "source"), "--seed", "7",
                     "--eval-episodes", "0"]) == 0
    meta = json.loads((runs / "warm" / "run.json").read_text())
    assert meta["init_from"] == str(source.resolve())
    assert meta["steps"] == 30  # from step 0, not on from the source's 40
    from stable_baselines3.common.save_util import load_from_zip_file

    data, warm, _ = load_from_zip_file(str(runs / "warm" / "final_model.zip"))
    _, start, _ = load_from_zip_file(str(source))
    assert data["learning_rate"] == pytest.approx(0.0005)  # the new config's
    moved = [float((warm["policy"][k] - start["policy"][k]).abs().max()) for k in start["policy"]]
    assert max(moved) > 0  # it trained on from the source's weights ...
    assert np.median(moved) < 0.1  # ... which 20 small updates moved only a little (a fresh init of seed 7: far more)

    capsys.readouterr()
    td3 = _model(tmp_path, "t", algo="td3")[1]
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "c", algo="sac")), "--output", str(runs),
                     "--name", "wrong", "--init-from", str(td3)]) != 0
    assert "is a TD3 model" in capsys.readouterr().err
    assert not (runs / "wrong").exists()
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "d", width=32)), "--output", str(runs),
                     "--name", "wider", "--init-from", str(source)]) != 0
    assert "does not fit this run's networks" in capsys.readouterr().err
    assert not (runs / "wider").exists()
    assert cli_main(["train", "--resume", str(runs / "warm"), "--init-from", str(source)]) != 0
    assert "drop --config, --name, --init-from and --init-buffer" in capsys.readouterr().err


@pytest.mark.slow
def test_init_buffer_starts_the_new_run_with_the_source_runs_replay_buffer(tmp_path, capsys):
    """``--init-from RUN --init-buffer``: the fine-tune's replay buffer begins with the source run's
    transitions (its newest checkpoint's buffer), recorded in run.json; a model file, a run that kept
    no buffer, or a buffer of another config are refused before anything is written."""
    from uniros.checkpoints import read_replay_buffer

    runs = tmp_path / "runs"
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "a", steps=40)), "--output", str(runs),
                     "--name", "source", "--eval-episodes", "0"]) == 0
    source_buffer = runs / "source" / "checkpoints" / "model_replay_buffer_40_steps.pkl"
    assert source_buffer.is_file()
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "b", steps=20)), "--output", str(runs),
                     "--name", "warm", "--init-from", str(runs / "source"), "--init-buffer",
                     "--eval-episodes", "0"]) == 0
    meta = json.loads((runs / "warm" / "run.json").read_text())
    assert meta["init_buffer"] == str(source_buffer.resolve()) and meta["steps"] == 20
    source = read_replay_buffer(source_buffer)
    warm = read_replay_buffer(runs / "warm" / "checkpoints" / "model_replay_buffer_20_steps.pkl")
    assert warm.size() == source.size() + 20  # the source's transitions, then the fine-tune's
    for key, rows in source.observations.items():
        assert np.array_equal(warm.observations[key][:source.size()], rows[:source.size()]), key
    assert np.array_equal(warm.actions[:source.size()], source.actions[:source.size()])

    capsys.readouterr()
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "c")), "--output", str(runs), "--name", "zip",
                     "--init-from", str(runs / "source" / "final_model.zip"), "--init-buffer"]) != 0
    assert "give --init-from a run directory" in capsys.readouterr().err
    source_buffer.unlink()
    assert cli_main(["train", ENV, "--config", str(_config(tmp_path, "d")), "--output", str(runs), "--name", "none",
                     "--init-from", str(runs / "source"), "--init-buffer"]) != 0
    assert "kept its replay buffer" in capsys.readouterr().err
    no_her = tmp_path / "no_her.yaml"
    no_her.write_text(_config(tmp_path, "e").read_text().replace("use_HER: true", "use_HER: false"))
    assert cli_main(["train", ENV, "--config", str(no_her), "--output", str(runs), "--name", "misfit",
                     "--init-from", str(runs / "warm"), "--init-buffer"]) != 0
    assert "does not fit this run" in capsys.readouterr().err
    assert sorted(p.name for p in runs.iterdir()) == ["source", "warm"]
