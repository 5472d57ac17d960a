"""Learning from pixels: HER + SAC on the RX200's goal reach observed through a camera, next to the
same run on the state observation. Not a test (hours on a CPU); run once, read the figures.

Both runs: ``RX200ReacherGoalSim-v0`` at its defaults (joint-delta actions, 100 steps, 2 cm), Stable-
Baselines3 SAC with ``MultiInputPolicy`` and ``HerReplayBuffer`` (future, 4 goals), rl-zoo3's
FetchReach settings (gamma 0.95, ent_coef auto, net [64, 64]) with lr 1e-3, batch 128, one torch
thread, the same seed; goal vectors normalised (``VecNormalize`` on the vector keys only); actor
and critics share the features extractor (SB3's ``CombinedExtractor``: NatureCNN to 64 features for
an image, the vectors flattened). On a CPU the CNN's gradient steps are most of the cost: an 84 x 84
image with batch 256 took over a second per step here, so the default image is 48 x 48.

* ``state``: the observation dict as registered (``observation`` = EE position, joints, previous
  action, joint velocities).
* ``pixels``: ``rgb_obs_only=True``: ``observation`` is the camera's RGB image (``--size`` pixels a
  side, uint8), so the arm's configuration comes from pixels only;
  ``achieved_goal`` (the EE position) and ``desired_goal`` stay vectors, as HER needs them.
* ``pixels_blind``: as ``pixels``, but the policy and critics do not see ``achieved_goal`` (HER
  still relabels with it): where the gripper is must be read from the image. ``pixels`` can learn
  from its two vectors alone (EE position and goal), so only this run shows learning from pixels.

Every ``--eval-every`` env steps: success rate over ``--eval-episodes`` deterministic episodes, and
the wall clock (training only, evaluation excluded). Prints a table per run, writes ``--json``.

    MUJOCO_GL=egl nice .venv/bin/python benchmarks/bench_pixel_learning.py --steps 20000 --json /tmp/pixels.json
    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_pixel_learning.py --runs pixels --steps 600 --eval-every 300
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

ENV_ID = "RX200ReacherGoalSim-v0"


def make_env(run: str, size: int, seed: int) -> Any:
    import uniros

    kwargs: dict[str, Any] = {"seed": seed}
    if run != "state":
        kwargs.update(rgb_obs_only=True, image_width=size, image_height=size)
    return uniros.make(ENV_ID, **kwargs)


def evaluate(model: Any, env: Any, vec_norm: Any, episodes: int, seed: int) -> float:
    """Success rate of the deterministic policy over ``episodes`` fresh episodes."""
    successes = 0
    for k in range(episodes):
        obs, info = env.reset(seed=seed + k)
        done = False
        while not done:
            batch = {key: np.asarray(v)[None] for key, v in obs.items()}
            if batch["observation"].ndim == 4:  # an image: channel-first, as the model was trained
                batch["observation"] = batch["observation"].transpose(0, 3, 1, 2)
            action, _ = model.predict(vec_norm.normalize_obs(batch), deterministic=True)
            obs, _, terminated, truncated, info = env.step(action[0])
            done = terminated or truncated
        successes += bool(info.get("is_success"))
    return successes / episodes


def train(run: str, args: argparse.Namespace) -> dict[str, Any]:
    import torch
    from stable_baselines3 import SAC, HerReplayBuffer
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize, VecTransposeImage

    torch.set_num_threads(1)
    extractor: dict[str, Any] = {}
    if run == "pixels_blind":
        from stable_baselines3.common.torch_layers import CombinedExtractor

        class WithoutAchievedGoal(CombinedExtractor):
            """SB3's extractor over every key but ``achieved_goal``."""

            def __init__(self, observation_space: Any, **kwargs: Any) -> None:
                from gymnasium import spaces

                seen = {k: v for k, v in observation_space.spaces.items() if k != "achieved_goal"}
                super().__init__(spaces.Dict(seen), **kwargs)

        extractor = {"features_extractor_class": WithoutAchievedGoal}
    train_env = make_env(run, args.size, args.seed)
    eval_env = make_env(run, args.size, args.seed + 10_000)
    # Images channel-first below the normaliser (SB3 stores the normaliser's original observations).
    vec = VecTransposeImage(DummyVecEnv([lambda: train_env]))
    keys = ["achieved_goal", "desired_goal"] + (["observation"] if run == "state" else [])
    vec_norm = VecNormalize(vec, norm_obs=True, norm_reward=False, norm_obs_keys=keys, gamma=0.95)
    model = SAC("MultiInputPolicy", vec_norm, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
                learning_rate=1e-3, buffer_size=args.buffer, batch_size=args.batch, gamma=0.95, tau=0.005,
                learning_starts=args.learning_starts, ent_coef="auto", train_freq=1, gradient_steps=1,
                policy_kwargs={"net_arch": [64, 64], "share_features_extractor": True,
                               "features_extractor_kwargs": {"cnn_output_dim": 64}, **extractor},
                seed=args.seed, verbose=0, device="cpu")
    curve: list[dict[str, float]] = []
    trained = 0.0
    steps = 0
    seen = f" rgb_obs_only {args.size}x{args.size}" if run != "state" else ""
    seen += " (policy without achieved_goal)" if run == "pixels_blind" else ""
    print(f"\n{run}: {ENV_ID}{seen}")
    print(f"{'steps':>7} {'success':>8} {'train s':>8} {'ms/step':>8}")
    try:
        while steps < args.steps:
            chunk = min(args.eval_every, args.steps - steps)
            start = time.perf_counter()
            model.learn(chunk, reset_num_timesteps=False)
            trained += time.perf_counter() - start
            steps += chunk
            vec_norm.training = False
            rate = evaluate(model, eval_env, vec_norm, args.eval_episodes, args.seed + 20_000 + steps)
            vec_norm.training = True
            curve.append({"steps": steps, "success": rate, "train_seconds": trained})
            print(f"{steps:7d} {rate:8.2f} {trained:8.0f} {1000 * trained / steps:8.1f}", flush=True)
            if args.json:
                _save(args.json, run, curve)
    finally:
        vec_norm.close()
        eval_env.close()
    return {"run": run, "curve": curve}


def _save(path: str, run: str, curve: list[dict[str, float]]) -> None:
    data: dict[str, Any] = {}
    if os.path.exists(path):
        with open(path) as f:
            data = json.load(f)
    data[run] = curve
    with open(path, "w") as f:
        json.dump(data, f, indent=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", nargs="+", default=["state", "pixels"], choices=["state", "pixels", "pixels_blind"])
    parser.add_argument("--steps", type=int, default=20_000, help="env steps per run")
    parser.add_argument("--size", type=int, default=48, help="image side in pixels (pixels run)")
    parser.add_argument("--buffer", type=int, default=50_000,
                        help="replay buffer size (images: ~2 x size^2 x 3 B each)")
    parser.add_argument("--batch", type=int, default=128)
    parser.add_argument("--learning-starts", type=int, default=1000)
    parser.add_argument("--eval-every", type=int, default=1000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the curves here (rewritten after each evaluation)")
    args = parser.parse_args()
    for run in args.runs:
        train(run, args)


if __name__ == "__main__":
    main()
