"""No CLI error line is longer than 2,000 characters, whatever a file it read held."""

from __future__ import annotations

import json

from uniros.cli import main as cli


def test_a_crafted_run_folder_is_a_bounded_error(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"env_id": "X" * 125_000, "algo": "sac"}))
    (run / "best_model.zip").write_bytes(b"")
    assert cli(["eval", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("uniros eval: error: ") and len(err) < 2100 and "characters more)" in err
