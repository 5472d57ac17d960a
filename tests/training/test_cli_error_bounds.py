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


def test_a_run_folder_that_would_import_a_module_or_drive_a_robot_needs_its_id_typed(tmp_path, capsys, monkeypatch):
    """`uniros eval RUN` of someone's run folder: an env ID that imports a module or drives a real robot is
    evaluated only when typed (docs/trust.md); nothing is imported before."""
    import sys

    for env_id, why in (("evil_module_never_imported:Thing-v0", "imports the module 'evil_module_never_imported'"),
                        ("RX200ReacherGoalReal-v0", "drives a real robot")):
        run = tmp_path / env_id.replace(":", "_")
        run.mkdir()
        (run / "run.json").write_text(json.dumps({"env_id": env_id, "algo": "sac"}))
        (run / "best_model.zip").write_bytes(b"")
        assert cli(["eval", str(run)]) == 2
        err = capsys.readouterr().err
        assert why in err and f"`uniros eval {env_id} {run}`" in err, err
    assert "evil_module_never_imported" not in sys.modules
