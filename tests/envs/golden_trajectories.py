"""Recorded trajectories of the shipped simulated envs, the yardstick of behaviour across rewrites.

Each case makes one env (or a batched vector env of several), resets it with fixed seeds, steps it
with fixed random actions across episode ends and records what it returns: observations, rewards,
terminations, truncations and ``is_success``. ``tests/envs/data/golden_trajectories.npz`` holds what
the env core returned when it was recorded; ``test_golden_trajectories.py`` checks today's code
returns the same (to 1e-9), one env at a time and batched.

Re-record only when a change of behaviour is intended (say so in the commit):

    python tests/envs/golden_trajectories.py
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

DATA = Path(__file__).resolve().parent / "data" / "golden_trajectories.npz"
STEPS = 40  # env steps per case
HORIZON = 15  # max_episode_steps: every case crosses episode ends

# (case name, env ID, keyword arguments)
CASES: list[tuple[str, str, dict[str, Any]]] = [
    ("rx200_reach", "RX200ReacherSim-v0", {}),
    ("rx200_reach_shaped", "RX200ReacherSim-v0", {"simple_dense_reward": False, "delta_action": False}),
    ("rx200_reach_goal", "RX200ReacherGoalSim-v0", {}),
    ("rx200_reach_goal_ee", "RX200ReacherGoalSim-v0", {"ee_action_type": True, "reward_type": "dense"}),
    ("rx200_reach_goal_abs", "RX200ReacherGoalSim-v0", {"delta_action": False}),
    ("irb120_reach", "ABBIRB120ReacherEnv-v0", {}),
    ("irb120_reach_goal", "ABBIRB120ReacherGoalEnv-v0", {}),
    ("rx200_push", "RX200PushSim-v0", {}),
    ("rx200_push_goal", "RX200PushGoalSim-v0", {}),
    ("rx200_push_goal_joint", "RX200PushGoalSim-v0", {"ee_action_type": False}),
    ("rx200_pnp", "RX200PnPSim-v0", {}),
    ("rx200_pnp_goal", "RX200PnPGoalSim-v0", {}),
]
SEEDS = (3, 4)  # one recording per seed; a batched env of len(SEEDS) envs replays them all at once


def _flat(obs: Any) -> np.ndarray:
    if isinstance(obs, dict):
        return np.concatenate([np.asarray(obs[k], dtype=np.float64).ravel() for k in sorted(obs)])
    return np.asarray(obs, dtype=np.float64).ravel()


def actions_for(space: Any, case: str, seed: int) -> np.ndarray:
    """The fixed actions of one recording (uniform in the Box action space, a few outside it)."""
    rng = np.random.default_rng([seed, sum(map(ord, case))])
    low, high = space.low.astype(np.float64), space.high.astype(np.float64)
    acts = rng.uniform(low - 0.1 * (high - low), high + 0.1 * (high - low), size=(STEPS, *space.shape))
    return acts.astype(np.float32)


def record_single(env_id: str, kwargs: dict[str, Any], case: str, seed: int) -> dict[str, np.ndarray]:
    """One env, reset with ``seed`` and stepped ``STEPS`` times (reset without a seed after an episode end)."""
    import uniros

    env = uniros.make(env_id, max_episode_steps=HORIZON, **kwargs)
    try:
        obs, info = env.reset(seed=seed)
        acts = actions_for(env.action_space, case, seed)
        out: dict[str, list[Any]] = {"obs": [_flat(obs)], "reward": [], "terminated": [], "truncated": [],
                                     "success": [bool(info.get("is_success", False))]}
        for a in acts:
            obs, reward, terminated, truncated, info = env.step(a)
            out["obs"].append(_flat(obs))
            out["reward"].append(float(reward))
            out["terminated"].append(bool(terminated))
            out["truncated"].append(bool(truncated))
            out["success"].append(bool(info.get("is_success", False)))
            if terminated or truncated:
                obs, info = env.reset()
                out["obs"].append(_flat(obs))
                out["success"].append(bool(info.get("is_success", False)))
        return {k: np.asarray(v) for k, v in out.items()}
    finally:
        env.close()


def record_batched(env_id: str, kwargs: dict[str, Any], case: str, num_nodes: int = 1) -> list[dict[str, np.ndarray]]:
    """``len(SEEDS)`` envs of a batched vector env (SAME_STEP autoreset), each as :func:`record_single` records it."""
    from gymnasium.vector import AutoresetMode

    import uniros

    n = len(SEEDS)
    vec = uniros.make_vec(env_id, n, vectorization_mode="batched", max_episode_steps=HORIZON,
                          vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP, "num_nodes": num_nodes}, **kwargs)
    try:
        outs: list[dict[str, list[Any]]] = [
            {"obs": [], "reward": [], "terminated": [], "truncated": [], "success": []} for _ in range(n)]
        # each env is reset with its own seed, as the single recordings are
        obs, info = vec.reset(seed=list(SEEDS))
        for i in range(n):
            outs[i]["obs"].append(_flat({k: v[i] for k, v in obs.items()} if isinstance(obs, dict) else obs[i]))
            outs[i]["success"].append(bool(info.get("is_success", np.zeros(n, bool))[i]))
        acts = np.stack([actions_for(vec.single_action_space, case, s) for s in SEEDS], axis=1)
        for a in acts:
            obs, reward, terminated, truncated, info = vec.step(a)
            for i in range(n):
                ended = bool(terminated[i] or truncated[i])
                if ended:
                    last_obs = info["final_obs"][i]
                    last_success = bool(info["final_info"]["is_success"][i])  # gymnasium 1.x: a dict of arrays
                else:
                    last_obs = {k: v[i] for k, v in obs.items()} if isinstance(obs, dict) else obs[i]
                    last_success = bool(info["is_success"][i])
                o = outs[i]
                o["obs"].append(_flat(last_obs))
                o["reward"].append(float(reward[i]))
                o["terminated"].append(bool(terminated[i]))
                o["truncated"].append(bool(truncated[i]))
                o["success"].append(last_success)
                if ended:
                    o["obs"].append(_flat({k: v[i] for k, v in obs.items()} if isinstance(obs, dict) else obs[i]))
                    o["success"].append(bool(info["is_success"][i]))
        return [{k: np.asarray(v) for k, v in o.items()} for o in outs]
    finally:
        vec.close()


def load() -> dict[str, np.ndarray]:
    with np.load(DATA) as data:
        return dict(data)


def main() -> None:
    arrays: dict[str, np.ndarray] = {}
    for case, env_id, kwargs in CASES:
        for seed in SEEDS:
            for key, value in record_single(env_id, kwargs, case, seed).items():
                arrays[f"{case}/{seed}/{key}"] = value
        print(f"recorded {case}", flush=True)
    DATA.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(DATA, **arrays)
    print(f"wrote {DATA} ({DATA.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
