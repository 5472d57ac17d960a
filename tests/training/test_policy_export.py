"""`uniros export`: the ONNX policy's actions equal SB3's ``predict(deterministic=True)`` (after the evaluation's
``VecNormalize.normalize_obs``) within 1e-5 on 1,000 observations, for a plain and a goal env, with and without
VecNormalize, for SAC, TD3, DDPG, TQC and PPO; its record says what ``uniros deploy`` needs.

The models are untrained (their weights need not be good) but their statistics are not trivial: the normaliser has
seen a few hundred random steps, so its means, variances and clip all act.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

import gymnasium as gym  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
import point_goal_env  # noqa: E402

from uniros.onnx_policy import OnnxPolicy  # noqa: E402
from uniros.policy_export import export_policy, export_run, sample_observations, sb3_actions  # noqa: E402
from uniros.policy_metadata import METADATA_KEY, OBS_INPUT  # noqa: E402

N = 1000
PLAIN, GOAL = "Pendulum-v1", point_goal_env.ENV_ID


def _algorithm(name: str) -> type:
    if name == "tqc":
        return pytest.importorskip("sb3_contrib").TQC
    import stable_baselines3

    return getattr(stable_baselines3, name.upper())


def _model(algo: str, env_id: str, normalize: bool, folder: Path) -> tuple[Path, object, object]:
    """An untrained model of ``algo`` on ``env_id`` saved as uniros saves one (``<model>.zip`` and, with
    ``normalize``, ``<model>.vecnormalize.pkl`` after 300 random steps)."""
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = DummyVecEnv([lambda: gym.make(env_id)])
    stats = None
    if normalize:
        venv = stats = VecNormalize(venv, clip_obs=5.0)
        venv.reset()
        for _ in range(300):
            venv.step(np.array([venv.action_space.sample()]))
    goal = env_id == GOAL
    kwargs: dict = {"device": "cpu", "seed": 0}
    if algo == "ppo":
        kwargs["n_steps"] = 64
    else:
        kwargs["buffer_size"] = 1000
        if goal:
            kwargs.update(replay_buffer_class=HerReplayBuffer, learning_starts=20)
    model = _algorithm(algo)("MultiInputPolicy" if goal else "MlpPolicy", venv, **kwargs)
    path = folder / "best_model.zip"
    model.save(path)
    if stats is not None:
        stats.save(str(folder / "best_model.vecnormalize.pkl"))
        stats.training = False
    venv.close()
    return path, model, stats


#: Each algorithm on a plain and a goal env, with and without statistics; two of them run by default.
CASES = [pytest.param(algo, env_id, normalize, id=f"{algo}-{'goal' if env_id == GOAL else 'plain'}-"
                      f"{'vecnormalize' if normalize else 'raw'}",
                      marks=() if (algo, env_id, normalize) in {("sac", GOAL, True), ("ppo", PLAIN, False)}
                      else pytest.mark.slow)
         for algo in ("sac", "td3", "ddpg", "tqc", "ppo") for env_id in (PLAIN, GOAL) for normalize in (False, True)]


@pytest.mark.parametrize(("algo", "env_id", "normalize"), CASES)
def test_onnx_actions_equal_sb3s(algo: str, env_id: str, normalize: bool, tmp_path: Path) -> None:
    path, model, stats = _model(algo, env_id, normalize, tmp_path)
    result = export_policy(path, tmp_path / "policy.onnx", env_id=env_id, check_samples=0)
    observations = sample_observations(model.observation_space, N, seed=123)  # type: ignore[attr-defined]
    expected = sb3_actions(model, stats, observations)
    policy = OnnxPolicy(result.path)
    got = policy.act_batch(observations if isinstance(observations, dict) else {OBS_INPUT: observations})
    assert got.shape == expected.shape == (N, *model.action_space.shape)  # type: ignore[attr-defined]
    assert np.max(np.abs(got - expected)) <= 1e-5
    one = {k: v[0] for k, v in observations.items()} if isinstance(observations, dict) else observations[0]
    assert np.max(np.abs(policy.act(one) - expected[0])) <= 1e-5  # one raw observation, as deploy feeds it
    meta = policy.metadata
    assert meta.normalized is normalize and meta.algorithm == algo
    assert meta.keys == (("achieved_goal", "desired_goal", "observation") if env_id == GOAL else None)


def test_export_run_writes_the_record_deploy_reads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import onnx

    from uniros.cli import main

    run = tmp_path / "run"
    run.mkdir()
    _model("sac", GOAL, True, run)
    arm = "arms/MyArm.yaml"
    kwargs = {"reward_type": "dense", "max_episode_steps": 10}
    (run / "run.json").write_text(json.dumps({"env_id": "RX200ReacherGoalSim-v0", "arm_file": arm,
                                              "env_kwargs": kwargs}))
    assert main(["export", str(run)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {run / 'best_model.onnx'}: SAC policy of RX200ReacherGoalSim-v0" in out
    assert "on 1000 sampled observations" in out
    model = onnx.load(run / "best_model.onnx")
    assert min(o.version for o in model.opset_import if o.domain in ("", "ai.onnx")) >= 17
    record = json.loads({p.key: p.value for p in model.metadata_props}[METADATA_KEY])
    assert record["env_id"] == "RX200ReacherGoalSim-v0" and record["arm_file"] == arm
    assert record["env_kwargs"] == kwargs and record["algorithm"] == "sac" and record["layout"] == "keys"
    assert [i["name"] for i in record["inputs"]] == ["achieved_goal", "desired_goal", "observation"]
    assert record["action_low"] == [-1.0, -1.0] and record["action_high"] == [1.0, 1.0]
    assert record["control_period"] == pytest.approx(0.1)  # the Real twin's 10 Hz loop
    assert record["normalized"] is True and record["clip_obs"] == 5.0 and record["uniros_version"]
    assert main(["export", str(run), "--model", "final", "--output", str(tmp_path / "x.onnx")]) == 2
    assert "has no final_model.zip" in capsys.readouterr().err


def test_export_refuses_what_it_cannot_export(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from stable_baselines3 import DQN

    from uniros.cli import main

    run = tmp_path / "run"
    run.mkdir()
    DQN("MlpPolicy", gym.make("CartPole-v1"), device="cpu", buffer_size=100).save(run / "best_model.zip")
    (run / "run.json").write_text(json.dumps({"env_id": "CartPole-v1"}))
    assert main(["export", str(run)]) == 2
    assert "exporting DQN is not supported" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "nowhere")]) == 2
    assert "is not a run directory" in capsys.readouterr().err


def test_without_onnxscript_the_export_says_what_to_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    from uniros.policy_export import ExportError

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "onnxscript" else
                        find_spec(name, *a))
    path, _, _ = _model("sac", PLAIN, False, tmp_path)
    with pytest.raises(ExportError, match="needs onnxscript"):
        export_policy(path, tmp_path / "policy.onnx", env_id=PLAIN)
    assert not (tmp_path / "policy.onnx").exists()


def test_export_run_falls_back_to_the_final_model(tmp_path: Path) -> None:
    path, _, _ = _model("td3", PLAIN, False, tmp_path)
    path.rename(tmp_path / "final_model.zip")
    (tmp_path / "run.json").write_text(json.dumps({"env_id": PLAIN}))
    result = export_run(tmp_path, check_samples=10)
    assert result.path == tmp_path / "final_model.onnx" and result.metadata.control_period is None
