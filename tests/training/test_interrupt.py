"""Ctrl-C and SIGTERM during training, in process: the first signal ends training at the next env step,
with the model whole (never a checkpoint of a half-done optimizer update); a second one interrupts at once
and writes no checkpoint of its own."""

from __future__ import annotations

import os
import signal

import gymnasium as gym
import pytest

from uniros.interrupts import TrainingInterrupted
from uniros.train_config import parse_training_config
from uniros.trainer import Paths, Session, latest_checkpoint

CONFIG = {"algorithm": "sac", "training_steps": 400, "eval_freq": 0, "save_freq": 100, "progress_bar": False,
          "sac_params": {"learning_starts": 50, "batch_size": 16, "buffer_size": 1000}}


def _session(tmp_path, resume=None) -> Session:
    config = parse_training_config(CONFIG)
    paths = Paths(checkpoints=tmp_path / "checkpoints")
    paths.checkpoints.mkdir(exist_ok=True)
    session = Session(config, gym.make("Pendulum-v1"), paths=paths, success_info=False)
    session.build(resume=resume)
    return session


def _signal_inside_gradient_step(session: Session, signals: list[int], at_call: int) -> dict[str, int]:
    """Send ``signals`` to this process inside the model's ``at_call``-th ``train`` call, before its update."""
    model, original = session.model, session.model.train
    counts = {"started": 0, "finished": 0}

    def train(*args, **kwargs):
        counts["started"] += 1
        if counts["started"] == at_call:
            for signum in signals:
                os.kill(os.getpid(), signum)
        original(*args, **kwargs)
        counts["finished"] += 1

    model.train = train
    return counts


def _adam_states_whole(optimizer) -> bool:
    return all({"step", "exp_avg", "exp_avg_sq"} <= set(state) for state in optimizer.state.values())


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_first_signal_finishes_the_update_then_checkpoints(tmp_path, signum):
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}  # SIG_IGN in a background job
    session = _session(tmp_path)
    counts = _signal_inside_gradient_step(session, [signum], at_call=120)
    try:
        with pytest.raises(TrainingInterrupted) as caught:
            session.learn()
    finally:
        session.close()
    assert caught.value.signum == signum and caught.value.exit_code == 128 + signum
    assert counts["finished"] == counts["started"] == 120, "the update the signal arrived in did not complete"
    ckpt = caught.value.checkpoint
    assert ckpt is not None and ckpt.steps == session.model.num_timesteps < CONFIG["training_steps"]
    assert f"checkpoint at {ckpt.steps} steps" in str(caught.value)
    for optimizer in (session.model.actor.optimizer, session.model.critic.optimizer):
        assert optimizer.state and _adam_states_whole(optimizer)
    assert {s: signal.getsignal(s) for s in before} == before  # handlers restored

    resumed = _session(tmp_path, resume=ckpt)
    try:
        resumed.learn()
        assert resumed.model.num_timesteps == CONFIG["training_steps"]
    finally:
        resumed.close()


def test_second_signal_interrupts_at_once_without_a_new_checkpoint(tmp_path):
    session = _session(tmp_path)
    counts = _signal_inside_gradient_step(session, [signal.SIGINT, signal.SIGINT], at_call=120)
    try:
        with pytest.raises(TrainingInterrupted) as caught:
            session.learn()
    finally:
        session.close()
    assert counts["finished"] == counts["started"] - 1 == 119
    newest = latest_checkpoint(tmp_path / "checkpoints")[0]
    assert caught.value.checkpoint == newest and newest.steps == 100  # the last periodic one, not one at 170


def test_a_signal_before_the_first_checkpoint_says_so(tmp_path):
    session = _session(tmp_path)
    _signal_inside_gradient_step(session, [signal.SIGTERM, signal.SIGTERM], at_call=1)
    try:
        with pytest.raises(TrainingInterrupted, match="before the first checkpoint"):
            session.learn()
    finally:
        session.close()
