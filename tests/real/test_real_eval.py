"""`uniros eval MODEL --env RX200ReacherGoalReal-v0`: a model of the simulated env runs unchanged on the Real twin."""

from __future__ import annotations

from pathlib import Path

import pytest

import uniros
from multiros.ros.processes import child_environment, private_context

from .conftest import StandIn

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]


def _untrained_her_model(env_id: str, path: Path) -> Path:
    from stable_baselines3 import SAC, HerReplayBuffer

    env = uniros.make(env_id)
    try:
        model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer, buffer_size=1000, device="cpu")
        model.save(path)
    finally:
        env.close()
    return path.with_suffix(".zip")


def test_eval_of_a_sim_model_on_the_real_env(tmp_path: Path, monkeypatch, capsys) -> None:
    pytest.importorskip("stable_baselines3")
    from uniros.cli import main

    model = _untrained_her_model("RX200ReacherGoalSim-v0", tmp_path / "rx200_sac")
    graph = private_context()
    robot = None
    try:
        robot = StandIn("fake", graph)
        for key, value in child_environment(graph).items():  # the CLI joins the graph the environment names
            monkeypatch.setenv(key, value)
        assert main(["eval", str(model), "--env", "RX200ReacherGoalReal-v0", "--episodes", "1"]) == 0
        assert "RX200ReacherGoalReal-v0: success rate" in capsys.readouterr().out
    finally:
        if robot is not None:
            robot.stop()
        graph.try_shutdown()


def test_eval_on_an_env_with_other_spaces_is_a_clear_error(tmp_path: Path, capsys) -> None:
    pytest.importorskip("stable_baselines3")
    from uniros.cli import main

    model = _untrained_her_model("ABBIRB120ReacherGoalEnv-v0", tmp_path / "irb_sac")
    assert main(["eval", str(model), "--env", "RX200ReacherGoalSim-v0", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "cannot run on RX200ReacherGoalSim-v0" in err and "observation space" in err


def test_a_sim_models_task_options_carry_over_to_its_real_twin(tmp_path: Path) -> None:
    import json

    from uniros.model_files import saved_env_kwargs

    model = tmp_path / "best_model.zip"
    model.write_bytes(b"")
    (tmp_path / "run.json").write_text(json.dumps({
        "env_id": "RX200ReacherGoalSim-v0",
        "env_kwargs": {"ee_action_type": True, "reward_type": "dense", "sim_mode": "process", "transport": "inproc",
                       "num_sim_steps": 10},
    }))
    assert saved_env_kwargs(model, "RX200ReacherGoalReal-v0") == {"ee_action_type": True, "reward_type": "dense"}
    assert saved_env_kwargs(model, "RX200ReacherGoalSim-v0")["sim_mode"] == "process"
    assert saved_env_kwargs(model, "ABBIRB120ReacherGoalEnv-v0") == {}  # another task: its options may not apply
