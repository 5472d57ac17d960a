"""`uniros train ID` with the config shipped for every simulated ID, from the command line: a short
run (200 steps) of the real thing, demonstrations and HER included, then `uniros eval` on it.
Whether the configs learn is benchmarks/bench_shipped_configs.py's job (hours for push)."""

from __future__ import annotations

import json

import pytest

import rl_environments
from uniros.cli import main as cli_main


@pytest.mark.slow
@pytest.mark.parametrize("env_id", rl_environments.ENV_IDS)
def test_uniros_train_runs_every_shipped_config(env_id, tmp_path, capsys):
    out = tmp_path / "runs"
    assert cli_main(["train", env_id, "--steps", "200", "--output", str(out), "--name", "r", "--eval-episodes", "1",
                     "--no-video", "--no-progress"]) == 0
    text = capsys.readouterr()
    assert f"on {env_id} for 200 steps (config: " in text.out and "Traceback" not in text.err
    run = out / "r"
    meta = json.loads((run / "run.json").read_text())
    assert meta["status"] == "finished" and meta["steps"] == 200
    assert (run / "final_model.zip").is_file()
    assert cli_main(["eval", str(run), "--episodes", "1"]) == 0
    assert f"{env_id}: success rate " in capsys.readouterr().out
