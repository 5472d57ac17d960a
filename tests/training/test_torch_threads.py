"""uniros train's torch thread setting (``torch_threads`` in the training YAML)."""

from __future__ import annotations

import os

import pytest

torch = pytest.importorskip("torch")

from uniros.train_config import default_config_for, parse_training_config  # noqa: E402
from uniros.trainer import apply_torch_threads  # noqa: E402


@pytest.fixture
def restore_threads():
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)


def test_one_thread_by_default(restore_threads):
    config = parse_training_config({"training_steps": 10})
    assert config.torch_threads == 1
    assert apply_torch_threads(config.torch_threads) == 1
    assert torch.get_num_threads() == 1


def test_threads_capped_at_the_cpu_count_and_zero_means_all(restore_threads):
    cores = os.cpu_count() or 1
    assert apply_torch_threads(cores + 7) == cores
    assert torch.get_num_threads() == cores
    assert apply_torch_threads(0) == cores


def test_shipped_configs_train_on_one_thread():
    for env_id in ("RX200ReacherGoalSim-v0", "ABBIRB120ReacherGoalEnv-v0"):
        assert default_config_for(env_id).torch_threads == 1
