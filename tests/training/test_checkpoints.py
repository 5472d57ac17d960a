"""Checkpoint retention: over a long run the checkpoint folder keeps a bounded number of files, and
the replay buffers in it grow with the one buffer kept (linearly in the steps), not with every
checkpoint's buffer (quadratically, SB3's ``CheckpointCallback``)."""

from __future__ import annotations

import gymnasium as gym
import pytest

from uniros.train_config import parse_training_config
from uniros.trainer import Paths, Session

CHECKPOINTS = 20


def _run(tmp_path, **keep) -> list[tuple[int, int]]:
    """SAC on Pendulum with a checkpoint every 20 steps; (files, replay-buffer bytes) after each."""
    config = parse_training_config({
        "training_steps": 20 * CHECKPOINTS, "eval_freq": 0, "save_freq": 20, "normalize": True,
        "progress_bar": False, "use_custom_policy": True, "policy_params": {"net_arch": [4]}, **keep,
        "sac_params": {"learning_starts": 50, "batch_size": 8, "buffer_size": 10_000}})
    folder = tmp_path / "checkpoints"
    folder.mkdir(parents=True)
    session = Session(config, gym.make("Pendulum-v1"), paths=Paths(checkpoints=folder), success_info=False)
    seen = []
    original = session.checkpoint

    def checkpoint():
        ckpt = original()
        files = [p for p in folder.iterdir() if p.is_file()]
        seen.append((len(files), sum(p.stat().st_size for p in files if "replay_buffer" in p.name)))
        return ckpt

    session.checkpoint = checkpoint
    try:
        session.build()
        session.learn()
    finally:
        session.close()
    return seen


@pytest.mark.slow
def test_a_long_run_keeps_a_bounded_checkpoint_folder(tmp_path):
    bounded = _run(tmp_path / "default")
    assert len(bounded) == CHECKPOINTS
    # Three models with their statistics, one replay buffer, latest.json: from the third checkpoint on.
    assert {files for files, _ in bounded[2:]} == {3 + 3 + 1 + 1}
    everything = _run(tmp_path / "all", keep_checkpoints=0, keep_replay_buffers=0)
    assert everything[-1][0] == CHECKPOINTS * 3 + 1  # SB3's behaviour: every checkpoint, each with its buffer
    half, end = CHECKPOINTS // 2 - 1, CHECKPOINTS - 1
    # Doubling the steps doubles the one buffer kept (about), but quadruples the sum of all buffers.
    assert bounded[end][1] < 2.3 * bounded[half][1]
    assert everything[end][1] > 3.3 * everything[half][1]
    assert bounded[end][1] < everything[end][1] / 8
