"""LeRobot's evaluation runs uniros IDs through the ``gym_uniros`` plugin (docs/lerobot.md).

* ``lerobot-eval --env.discover_packages_path=gym_uniros --env.type=uniros --env.task=<ID>`` with a
  policy LeRobot builds from scratch (SAC, random weights: LeRobot's own "random policy"), as a user
  runs it: the command, its metrics, its videos.
* LeRobot's ``make_env`` and ``eval_policy_all`` with uniros' scripted policy behind LeRobot's policy
  interface: the success LeRobot measures is the env's ``is_success``.

Run by ``.ci/lerobot`` in ``.venv-lerobot``; skipped where LeRobot is not installed.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # seconds each: simulations, a LeRobot process

RE = "RX200ReacherGoalSim-v0"
PNP = "RX200PnPGoalSim-v0"


def test_lerobot_eval_runs_a_uniros_id(lerobot_path: str, tmp_path: Path) -> None:
    exe = shutil.which("lerobot-eval", path=str(Path(sys.executable).parent))
    assert exe, "lerobot-eval is not installed next to this python"
    out = tmp_path / "eval"
    env = {**os.environ, "PYTHONPATH": lerobot_path}
    args = [exe, "--env.discover_packages_path=gym_uniros", "--env.type=uniros", f"--env.task={RE}",
            "--env.episode_length=15", "--env.env_kwargs={ee_action_type: true}", "--policy.type=sac",
            "--policy.device=cpu", "--eval.n_episodes=2", "--eval.batch_size=2", f"--output_dir={out}", "--seed=3"]
    proc = subprocess.run(args, env=env, capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    info = json.loads((out / "eval_info.json").read_text())
    overall = info["overall"]
    assert overall["n_episodes"] == 2 and 0.0 <= overall["pc_success"] <= 100.0
    assert overall["avg_sum_reward"] < 0  # the reach's dense reward: minus the distance, every step
    assert info["per_group"]["uniros"]["n_episodes"] == 2
    videos = [Path(p) for p in overall["video_paths"]]
    assert len(videos) == 2 and all(v.stat().st_size > 0 for v in videos)
    assert "Overall Aggregated Metrics" in proc.stdout


def _scripted_policy(env_id: str, n_envs: int, **kwargs: Any) -> Any:
    """uniros' scripted policy of ``env_id`` as a LeRobot policy (what LeRobot's rollout calls of one): it
    reads ``observation.state`` and ``observation.environment_state`` (achieved_goal, desired_goal)."""
    import torch
    from lerobot.policies.pretrained import PreTrainedPolicy
    from lerobot.policies.sac.configuration_sac import SACConfig

    import uniros

    class ScriptedPolicy(PreTrainedPolicy):  # type: ignore[misc]
        config_class = SACConfig
        name = "uniros_scripted"

        def __init__(self) -> None:
            super().__init__(SACConfig(device="cpu"))
            env = uniros.make(env_id, **kwargs)
            try:
                self.n_achieved = int(env.observation_space["achieved_goal"].shape[0])
                self.scripts = [env.unwrapped.task.scripted_policy() for _ in range(n_envs)]
            finally:
                env.close()

        def reset(self) -> None:
            for script in self.scripts:
                script.reset()

        def select_action(self, batch: dict[str, Any], **_: Any) -> Any:
            state = batch["observation.state"].numpy()
            goals = batch["observation.environment_state"].numpy()
            n = self.n_achieved
            actions = [script({"observation": s, "achieved_goal": g[:n], "desired_goal": g[n:]})
                       for script, s, g in zip(self.scripts, state, goals, strict=True)]
            return torch.as_tensor(np.stack(actions), dtype=torch.float32)

        def predict_action_chunk(self, batch: dict[str, Any], **_: Any) -> Any:
            return self.select_action(batch)[:, None]

        def forward(self, batch: dict[str, Any]) -> Any:
            raise NotImplementedError("a scripted policy does not learn")

        def get_optim_params(self) -> dict[str, Any]:
            return {}

    return ScriptedPolicy()


@pytest.mark.parametrize(("env_id", "kwargs", "at_least"), [(RE, {"ee_action_type": True}, 100.0), (PNP, {}, 75.0)])
def test_lerobots_eval_loop_measures_the_uniros_success(lerobot_path: str, env_id: str, kwargs: dict[str, Any],
                                                        at_least: float) -> None:
    from lerobot.envs.factory import make_env
    from lerobot.envs.utils import close_envs
    from lerobot.processor import PolicyProcessorPipeline
    from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action
    from lerobot.scripts.lerobot_eval import eval_policy_all

    import gym_uniros

    cfg = gym_uniros.UnirosEnv(task=env_id, env_kwargs=kwargs, render_mode=None)
    assert cfg.type == "uniros" and cfg.gym_id == f"gym_uniros/{env_id}"
    assert cfg.features_map["agent_pos"] == "observation.state"
    envs = make_env(cfg, n_envs=2)
    identity = PolicyProcessorPipeline(steps=[])
    actions = PolicyProcessorPipeline(steps=[], to_transition=policy_action_to_transition,
                                      to_output=transition_to_policy_action)
    try:
        info = eval_policy_all(envs, _scripted_policy(env_id, 2, **kwargs), identity, identity, identity, actions,
                               n_episodes=4, start_seed=100)
    finally:
        close_envs(envs)
    overall = info["overall"]
    assert overall["n_episodes"] == 4
    assert overall["pc_success"] >= at_least, overall
