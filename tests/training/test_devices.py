"""The torch device of a model (docs/training.md, "CPU or GPU"): ``device`` in every
``<algo>_params``, ``--device`` on ``uniros train``/``uniros eval`` and the trainer classes, what
``auto`` picks, loading onto the chosen device and a resumed run keeping its own. CUDA is mocked
(``uniros.devices._cuda_count``): the tests run on CPU-only machines; the device machine runs the
same code on a real GPU."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from gymnasium import spaces

import uniros.devices as devices
from uniros.algorithms import ALGORITHMS
from uniros.cli import main as cli_main
from uniros.devices import check_device, has_image, resolve_device
from uniros.train_config import TrainingConfigError, parse_training_config

HERE = Path(__file__).resolve().parent
ENV = "point_goal_env:UnirosTestPointGoal-v0"
IMAGE = spaces.Box(0, 255, (84, 84, 3), np.uint8)
VECTOR = spaces.Box(-1.0, 1.0, (6,), np.float32)


def _gpus(monkeypatch: pytest.MonkeyPatch, count: int) -> None:
    monkeypatch.setattr(devices, "_cuda_count", lambda: count)


# -- the YAML --------------------------------------------------------------------------------------
@pytest.mark.parametrize("algo", ALGORITHMS)
def test_every_algorithm_block_takes_a_device(algo):
    config = parse_training_config({"training_steps": 10, f"{algo}_params": {"device": " CUDA:1 "}}, "cfg.yaml")
    assert config.algorithm == algo and config.device == "cuda:1"
    assert config.to_dict()["model_params"][f"{algo}_params"]["device"] == "cuda:1"  # the run's config.yaml
    assert parse_training_config({"training_steps": 10, "algorithm": algo}).device == "auto"


@pytest.mark.parametrize(("params", "match"), [
    ({"device": "gpu"}, r"cfg.yaml: sac_params.device must be auto, cpu, cuda or cuda:N .*got 'gpu'"),
    ({"device": 0}, "sac_params.device must be auto, cpu, cuda or cuda:N"),
    ({"devcie": "cuda"}, "unknown key 'devcie'; did you mean 'device'"),
])
def test_a_bad_device_key_names_the_key(params, match):
    with pytest.raises(TrainingConfigError, match=match):
        parse_training_config({"training_steps": 10, "sac_params": params}, "cfg.yaml")


# -- what auto picks ---------------------------------------------------------------------------------
def test_auto_puts_image_policies_on_a_present_gpu_and_mlps_on_the_cpu(monkeypatch):
    both = spaces.Dict({"image": IMAGE, "observation": VECTOR})
    channel_first = spaces.Box(0, 255, (3, 84, 84), np.uint8)
    assert has_image(both) and has_image(channel_first) and not has_image(VECTOR)
    depth = spaces.Dict({"depth": spaces.Box(0.0, 10.0, (84, 84, 1), np.float32), "observation": VECTOR})
    assert not has_image(depth)  # float depth maps are vectors to SB3: an MLP
    _gpus(monkeypatch, 1)
    assert resolve_device("auto", both) == resolve_device(None, channel_first) == "cuda"
    assert resolve_device("auto", VECTOR) == resolve_device("auto", depth) == "cpu"
    assert resolve_device("cpu", both) == "cpu" and resolve_device("cuda", VECTOR) == "cuda"
    _gpus(monkeypatch, 0)
    assert resolve_device("auto", both) == "cpu"  # no GPU: the CPU, without a word


def test_a_missing_gpu_asked_for_is_a_one_line_error(monkeypatch):
    _gpus(monkeypatch, 0)
    with pytest.raises(TrainingConfigError, match=r"^--device 'cuda' asked for, but torch finds no CUDA GPU .*"
                                                  r"use --device cpu or auto$") as err:
        resolve_device("cuda", VECTOR, "--device")
    assert "\n" not in str(err.value)
    _gpus(monkeypatch, 2)
    assert resolve_device("cuda:1", IMAGE) == "cuda:1"
    with pytest.raises(TrainingConfigError, match=r"'cuda:2' asked for, but torch finds 2 CUDA GPU\(s\) "
                                                  r"\(cuda:0 to cuda:1\)"):
        resolve_device("cuda:2", IMAGE)
    assert check_device("Cuda:3") == "cuda:3"


# -- building and loading onto the device -------------------------------------------------------------
def test_models_build_and_load_onto_the_chosen_device(monkeypatch, tmp_path):
    """``build_model`` and ``load_model`` give SB3 the resolved device (CUDA mocked: SB3's
    ``load`` is spied on and given the CPU, so the test runs anywhere)."""
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv

    from uniros.trainer import build_model, load_model

    sys.path.insert(0, str(HERE))
    import point_goal_env

    venv = DummyVecEnv([point_goal_env.PointGoalEnv])
    config = parse_training_config({"training_steps": 10, "sac_params": {"buffer_size": 100, "device": "cpu"}})
    model = build_model(config, venv)
    assert str(model.device) == "cpu"
    model.save(tmp_path / "m.zip")
    seen: list[str] = []
    original = SAC.load.__func__

    def spy(cls, path, env=None, device="auto", **kwargs):
        seen.append(str(device))
        return original(cls, path, env=env, device="cpu", **kwargs)

    monkeypatch.setattr(SAC, "load", classmethod(spy))
    _gpus(monkeypatch, 1)
    load_model(tmp_path / "m.zip", venv, device="cuda:0")
    load_model(tmp_path / "m.zip", venv)  # auto: a vector policy stays on the CPU even with a GPU
    assert seen == ["cuda:0", "cpu"]
    _gpus(monkeypatch, 0)
    with pytest.raises(TrainingConfigError, match="no CUDA GPU"):
        load_model(tmp_path / "m.zip", venv, device="cuda")
    cuda = parse_training_config({"training_steps": 10, "sac_params": {"device": "cuda"}}, "gpu.yaml")
    with pytest.raises(TrainingConfigError, match="gpu.yaml: sac_params.device 'cuda' asked for"):
        build_model(cuda, venv)


def test_trainer_classes_take_a_device(monkeypatch, tmp_path):
    sys.path.insert(0, str(HERE))
    import point_goal_env

    from uniros.sb3 import SAC

    model = SAC(point_goal_env.PointGoalEnv(), tmp_path / "models", tmp_path / "logs", device="cpu", verbose=0)
    assert model.config.device == "cpu" and str(model.model.device) == "cpu"
    with pytest.raises(TrainingConfigError, match=r"SAC\(device=...\) must be auto, cpu, cuda or cuda:N"):
        SAC(point_goal_env.PointGoalEnv(), tmp_path / "m2", tmp_path / "l2", device="tpu")
    _gpus(monkeypatch, 0)
    with pytest.raises(TrainingConfigError, match="no CUDA GPU"):
        SAC(point_goal_env.PointGoalEnv(), tmp_path / "m3", tmp_path / "l3", device="cuda")


# -- the CLI: a run records its device, a resumed run keeps it ------------------------------------------
CONFIG = """algorithm: sac
eval_freq: 50
eval_episodes: 2
save_freq: 25
video: false
progress_bar: false
use_HER: true
sac_params: {learning_starts: 20, batch_size: 16, buffer_size: 2000}
"""


@pytest.mark.slow
def test_cli_device_is_recorded_and_kept_on_resume(monkeypatch, tmp_path, capsys):
    """``--steps`` stands in for the YAML's missing ``training_steps``; ``--device cpu`` goes into the
    run's config.yaml and run.json; a resume without ``--device`` keeps it, one with a missing GPU is
    refused in one line before anything changes."""
    sys.path.insert(0, str(HERE))
    (tmp_path / "cfg.yaml").write_text(CONFIG)
    runs = tmp_path / "runs"
    assert cli_main(["train", ENV, "--config", str(tmp_path / "cfg.yaml"), "--steps", "50", "--device", "cpu",
                     "--output", str(runs), "--name", "r", "--eval-episodes", "0"]) == 0
    out = capsys.readouterr().out
    assert "for 50 steps" in out and "trained 50 steps" in out and " on cpu" in out
    run = runs / "r"
    saved = yaml.safe_load((run / "config.yaml").read_text())["model_params"]
    assert saved["sac_params"]["device"] == "cpu" and saved["training_steps"] == 50
    assert json.loads((run / "run.json").read_text())["device"] == "cpu"
    _gpus(monkeypatch, 0)
    assert cli_main(["train", "--resume", str(run), "--steps", "75", "--device", "cuda", "--eval-episodes", "0"]) == 2
    err = capsys.readouterr().err
    assert "error: --device 'cuda' asked for, but torch finds no CUDA GPU" in err and "Traceback" not in err
    assert json.loads((run / "run.json").read_text())["steps"] == 50  # nothing resumed
    assert cli_main(["train", "--resume", str(run), "--steps", "75", "--eval-episodes", "0"]) == 0
    assert "trained 75 steps" in capsys.readouterr().out
    assert json.loads((run / "run.json").read_text())["device"] == "cpu"
    # a module:ID run is evaluated with its ID typed (docs/trust.md: its module's code runs)
    assert cli_main(["eval", ENV, str(run), "--episodes", "2", "--device", "cpu"]) == 0
    assert cli_main(["eval", ENV, str(run), "--episodes", "2", "--device", "cuda"]) == 2
    assert "no CUDA GPU" in capsys.readouterr().err


def test_steps_stand_in_for_a_missing_training_steps():
    with pytest.raises(TrainingConfigError, match=r"missing key 'training_steps' \(or pass --steps\)"):
        parse_training_config({"algorithm": "sac"}, "cfg.yaml")
    assert parse_training_config({"algorithm": "sac"}, "cfg.yaml", steps=500).training_steps == 500
    assert parse_training_config({"training_steps": 9}, "cfg.yaml", steps=500).training_steps == 9


def test_a_resumed_run_may_move_to_another_device():
    """The device is where the model computes, not what it is: an edit of config.yaml's device is
    taken on resume (the model loads onto the new one), unlike edits that would need another model."""
    from uniros.resume import resume_overrides

    started = parse_training_config({"training_steps": 10, "sac_params": {"device": "cuda", "gamma": 0.9}}, "r.yaml")
    moved = parse_training_config({"training_steps": 10, "sac_params": {"device": "cpu", "gamma": 0.9}}, "r.yaml")
    assert resume_overrides(started, moved) == {}
    other = parse_training_config({"training_steps": 10, "sac_params": {"device": "cpu", "buffer_size": 7}}, "r.yaml")
    with pytest.raises(TrainingConfigError, match="buffer_size"):
        resume_overrides(started, other)
