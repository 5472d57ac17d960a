"""``uniros record`` writes LeRobot v3.0 datasets whose every frame reads back equal (with uniros' reader,
and with LeRobot's where it imports), and ``--demos`` puts them into a replay buffer or refuses them in one line.

LeRobot's reader runs in ``.venv-lerobot`` (docs/datasets.md): ``.venv-lerobot/bin/python -m pytest
tests/training/test_recording.py -p no:randomly -k lerobot``; in the project venv that test is skipped.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import json
import sys
import types
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("pyarrow")

from uniros.demonstrations_io import DemonstrationsError, fill_replay_buffer_from_dataset, load_demonstrations
from uniros.lerobot_dataset import DatasetFormatError, DatasetWriter
from uniros.lerobot_dataset_reader import read_dataset
from uniros.recording import main as record_main
from uniros.recording import record
from uniros.run_envs import make_env

ENV_ID = "RX200PushGoalSim-v0"
EPISODES = 3


class _Tape(gym.Wrapper):  # type: ignore[type-arg]
    """Keeps every observation, action and reward the env saw, to compare the dataset against."""

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        self.obs: list[Any] = []
        self.actions: list[np.ndarray] = []
        self.rewards: list[float] = []
        self.finals: list[Any] = []

    def reset(self, **kwargs: Any) -> Any:
        obs, info = self.env.reset(**kwargs)
        self.obs.append(obs)
        return obs, info

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.actions.append(np.array(action))
        self.rewards.append(float(reward))
        if terminated or truncated:
            self.finals.append(obs)
        else:
            self.obs.append(obs)
        return obs, reward, terminated, truncated, info


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, _Tape]:
    """3 scripted RX200 push episodes, recorded, and what the env saw while they were."""
    out = tmp_path_factory.mktemp("rec") / "push"
    env = _Tape(make_env(ENV_ID))
    policy = env.unwrapped.task.scripted_policy()
    try:
        result = record(env, policy, EPISODES, out, env_id=ENV_ID, seed=7, progress=False, reset=policy.reset)
    finally:
        env.close()
    assert result["frames"] == len(env.actions)
    return out, env


def test_every_frame_reads_back_equal(recorded: tuple[Path, _Tape]) -> None:
    out, tape = recorded
    ds = read_dataset(out)
    assert [e.index for e in ds.episodes] == list(range(EPISODES))
    assert ds.info["uniros"]["env_id"] == ENV_ID and ds.info["total_frames"] == len(tape.actions)
    frames = {k: np.concatenate([e.frames[k] for e in ds.episodes]) for k in ds.episodes[0].frames}
    np.testing.assert_array_equal(frames["observation.state"], np.stack([o["observation"] for o in tape.obs]))
    np.testing.assert_array_equal(frames["observation.desired_goal"], np.stack([o["desired_goal"] for o in tape.obs]))
    np.testing.assert_array_equal(frames["observation.achieved_goal"], np.stack([o["achieved_goal"] for o in tape.obs]))
    np.testing.assert_array_equal(frames["action"], np.stack(tape.actions).astype(np.float32))
    np.testing.assert_array_equal(frames["next.reward"], np.float32(tape.rewards))
    # The goals under LeRobot's name, laid out as a LeRobot eval of the env (uniros.lerobot_env) passes them
    from uniros.lerobot_env import LeRobotEnv

    lerobot_env = LeRobotEnv(make_env(ENV_ID), ENV_ID)
    try:
        first, _ = lerobot_env.reset(seed=7)  # the first recorded episode's seed
    finally:
        lerobot_env.close()
    np.testing.assert_array_equal(first["environment_state"], frames["observation.environment_state"][0])
    assert ds.info["uniros"]["environment_state"] == ["achieved_goal", "desired_goal"]
    np.testing.assert_array_equal(frames["observation.environment_state"],
                                  np.stack([np.concatenate([o["achieved_goal"], o["desired_goal"]])
                                            for o in tape.obs]).astype(np.float32))
    for ep, final in zip(ds.episodes, tape.finals, strict=True):
        assert ep.task == "push the cube to the goal" and ep.success is not None
        assert ep.frames["next.done"][-1] and not ep.frames["next.done"][:-1].any()
        assert ep.success == bool(ep.frames["next.success"][-1])
        np.testing.assert_array_equal(ep.final["observation.state"], final["observation"].astype(np.float64))


def test_every_task_of_the_table_has_its_words() -> None:
    """A dataset's task string is the task in words for every row of the task table (a reach dataset's was
    its env ID), the env ID only for an env of one's own."""
    from rl_environments.env_ids import TASKS
    from uniros.recording import TASK_TEXT, task_text

    assert set(TASKS) <= set(TASK_TEXT)
    for env_id, words in (("RX200ReacherGoalSim-v0", "move the end effector to the goal"),
                          ("IRB120SlideGoalSim-v0", "slide the puck to the goal")):
        env = make_env(env_id)
        try:
            assert task_text(env, env_id) == words
        finally:
            env.close()
    assert task_text(gym.make("CartPole-v1"), "CartPole-v1") == "CartPole-v1"


def test_cli_records_and_refuses_an_existing_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ds"
    assert record_main([ENV_ID, "--policy", "scripted", "--episodes", "1", "--output", str(out), "--no-progress"]) == 0
    assert read_dataset(out).info["total_episodes"] == 1
    assert not (tmp_path / "ds.partial").exists()
    assert record_main([ENV_ID, "--policy", "scripted", "--episodes", "1", "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and len(err.strip().splitlines()) == 1


def test_demos_fill_a_her_buffer(recorded: tuple[Path, _Tape]) -> None:
    from stable_baselines3 import SAC, HerReplayBuffer

    out, tape = recorded
    env = make_env(ENV_ID)
    try:
        model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer, buffer_size=1000,
                    learning_starts=0, device="cpu")
        stats = fill_replay_buffer_from_dataset(model, out, env)
        episode = next(load_demonstrations(out, env))
    finally:
        env.close()
    assert stats["transitions"] == len(tape.actions) and stats["episodes"] == EPISODES
    assert model.replay_buffer.size() == len(tape.actions)
    np.testing.assert_array_equal(model.replay_buffer.observations["observation"][0, 0], tape.obs[0]["observation"])
    assert episode[-1].truncated and not episode[-1].terminated
    np.testing.assert_array_equal(episode[-1].next_obs["achieved_goal"], tape.finals[0]["achieved_goal"])
    np.testing.assert_array_equal(episode[0].next_obs["observation"], tape.obs[1]["observation"])


def _write(root: Path, state: np.ndarray, action_shape: int = 4) -> Path:
    feats = {"observation.state": {"dtype": "float32", "shape": [state.shape[1]]},
             "observation.achieved_goal": {"dtype": "float32", "shape": [3]},
             "observation.desired_goal": {"dtype": "float32", "shape": [3]},
             "action": {"dtype": "float32", "shape": [action_shape]},
             "next.reward": {"dtype": "float32", "shape": [1]}, "next.done": {"dtype": "bool", "shape": [1]},
             "next.success": {"dtype": "bool", "shape": [1]}}
    w = DatasetWriter(root, 25, feats)
    for i, s in enumerate(state):
        w.add_frame({"observation.state": s, "observation.achieved_goal": np.zeros(3),
                     "observation.desired_goal": np.zeros(3), "action": np.zeros(action_shape), "next.reward": -1.0,
                     "next.done": i == len(state) - 1, "next.success": False})
    w.save_episode("t", success=False, final={"observation.state": state[-1], "observation.achieved_goal": np.zeros(3),
                                              "observation.desired_goal": np.zeros(3)})
    return w.finalize()


@pytest.mark.parametrize("fault, expected", [
    ("nan", "NaN or infinite"),
    ("state_shape", "observation.state has shape [7]"),
    ("action_shape", "action has shape [2]"),
    ("no_info", "no meta/info.json"),
    ("bad_json", "not JSON"),
    ("old_version", "codebase_version 'v2.1'"),
    ("huge_version", "codebase_version 'vvvvv"),
    ("garbage_parquet", "not a readable parquet file"),
    ("frames_missing", "are not in its data file"),
    ("missing", "no such dataset folder"),
])
def test_bad_datasets_are_refused_in_one_line(tmp_path: Path, fault: str, expected: str) -> None:
    state = np.zeros((5, 30), np.float32)
    root = tmp_path / "ds"
    if fault == "nan":
        state[2, 4] = np.nan
    if fault != "missing":
        _write(root, state if fault != "state_shape" else state[:, :7],
               action_shape=2 if fault == "action_shape" else 4)
    info = root / "meta" / "info.json"
    if fault == "no_info":
        info.unlink()
    elif fault == "bad_json":
        info.write_text("{not json")
    elif fault in ("old_version", "huge_version", "frames_missing"):
        data = json.loads(info.read_text())
        versions = {"old_version": "v2.1", "huge_version": "v" * 500_000}  # the file's values are quoted short
        data["codebase_version"] = versions.get(fault, data["codebase_version"])
        info.write_text(json.dumps(data))
        if fault == "frames_missing":
            import pyarrow.parquet as pq

            path = root / "data" / "chunk-000" / "file-000.parquet"
            pq.write_table(pq.read_table(path).slice(0, 3), path)
    elif fault == "garbage_parquet":
        (root / "data" / "chunk-000" / "file-000.parquet").write_bytes(b"PAR1 not really")
    env = make_env(ENV_ID)
    try:
        with pytest.raises((DemonstrationsError, DatasetFormatError)) as exc:
            list(load_demonstrations(root, env))
    finally:
        env.close()
    message = str(exc.value)
    assert expected in message and "\n" not in message and len(message) < 1000, message[:2000]


# -- LeRobot's own reader (in .venv-lerobot) ---------------------------------------------------------
def _lerobot_dataset_class() -> Any:
    """LeRobot's ``LeRobotDataset``, or a skip. PyPI's torchvision for torch 2.13 is the CUDA build, which
    cannot import next to the CPU torch (``libc10_cuda.so``); LeRobot's dataset modules import it at the top
    and use it only for image transforms and its old video reader, neither of which state-only datasets
    touch, so a stand-in module takes its place here (and only here)."""
    # not importorskip("lerobot"): tests/lerobot/ is a namespace package "lerobot" on pytest's path
    if importlib.util.find_spec("lerobot") is None or importlib.util.find_spec("lerobot.datasets") is None:
        pytest.skip("LeRobot is not installed here (it runs in .venv-lerobot: docs/datasets.md)")
    try:
        import torchvision  # noqa: F401
    except (ImportError, RuntimeError):
        stand_in = types.ModuleType("torchvision")
        stand_in.__spec__ = importlib.machinery.ModuleSpec("torchvision", None)
        transforms = types.ModuleType("torchvision.transforms")
        transforms.__spec__ = importlib.machinery.ModuleSpec("torchvision.transforms", None)
        stand_in.transforms = transforms  # type: ignore[attr-defined]
        for name in [n for n in sys.modules if n == "torchvision" or n.startswith("torchvision.")]:
            del sys.modules[name]
        sys.modules["torchvision"], sys.modules["torchvision.transforms"] = stand_in, transforms
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    return LeRobotDataset


def test_lerobot_reads_every_frame_equal(recorded: tuple[Path, _Tape]) -> None:
    dataset_class = _lerobot_dataset_class()
    out, tape = recorded
    ds = dataset_class("uniros/test", root=out)
    assert ds.num_episodes == EPISODES and len(ds) == len(tape.actions)
    for i in range(len(ds)):
        item = ds[i]
        np.testing.assert_array_equal(item["observation.state"].numpy(), tape.obs[i]["observation"])
        np.testing.assert_array_equal(item["observation.desired_goal"].numpy(), tape.obs[i]["desired_goal"])
        np.testing.assert_array_equal(item["action"].numpy(), tape.actions[i].astype(np.float32))
        assert float(item["next.reward"]) == np.float32(tape.rewards[i])
        assert item["task"] == "push the cube to the goal"


@pytest.mark.slow
def test_uniros_train_demos_puts_the_recorded_episodes_in_the_buffer(recorded: tuple[Path, _Tape], tmp_path: Path,
                                                                    caplog: pytest.LogCaptureFixture,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """``uniros train ID --demos DATASET``: the run's config keeps the dataset and its episodes fill the replay
    buffer before learning; a dataset of another ID, or none, is one line and exit code 2 before a run is written."""
    import logging

    from uniros.cli import main

    path, _ = recorded
    with caplog.at_level(logging.INFO, logger="uniros.trainer"):
        assert main(["train", "RX200PushGoalSim-v0", "--demos", str(path), "--steps", "60", "--eval-episodes", "0",
                     "--output", str(tmp_path / "runs")]) == 0
    assert any("recorded episodes" in r.getMessage() and str(path) in r.getMessage() for r in caplog.records)
    (run,) = (tmp_path / "runs").iterdir()
    assert f"demos: {path}" in (run / "config.yaml").read_text()
    for bad, message in ((path, "recorded from 'RX200PushGoalSim-v0', not 'RX200PnPGoalSim-v0'"),
                         (tmp_path / "none", "no such dataset folder")):
        before = set((tmp_path / "runs").iterdir())
        capsys.readouterr()
        assert main(["train", "RX200PnPGoalSim-v0", "--demos", str(bad), "--steps", "60",
                     "--output", str(tmp_path / "runs")]) == 2
        assert message in capsys.readouterr().err
        assert set((tmp_path / "runs").iterdir()) == before
