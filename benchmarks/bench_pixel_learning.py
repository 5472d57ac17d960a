"""Learning from pixels: HER + SAC on the RX200's goal reach observed through a camera, next to the
same run on the state observation. Not a test (hours on a CPU); run once, read the figures.

Every run: ``RX200ReacherGoalSim-v0`` (100 steps, 2 cm), Stable-Baselines3 SAC with
``MultiInputPolicy`` and ``HerReplayBuffer`` (future, 4 goals), rl-zoo3's FetchReach settings (gamma
0.95, ent_coef auto, net [64, 64]), one torch thread, the same seed; goal vectors normalised
(``VecNormalize`` on the vector keys only; images channel-first below it). On a CPU the CNN's
gradient steps are most of the cost: an 84 x 84 image with batch 256 took over a second per step
here, so the default image is 48 x 48 from the arm's default camera (``CAMERA_VIEW``: in front of
the arm, to its right, 25 degrees down; the arm dark on a grey floor, the gripper in view over the
whole goal box). Camera images carry no goal marker: the goal is only ever the vector.

* ``state``: joint-delta actions; the observation dict as registered (``observation`` = EE
  position, joints, previous action, joint velocities). lr 1e-3, batch 128.
* ``state_ee``: as ``state`` with end-effector delta actions (``ee_action_type=True``) and the
  shipped training config's lr 3e-3, batch 256, learning_starts 500: the side-by-side of
  ``pixels_strict``.
* ``pixels``: joint-delta actions, ``rgb_obs_only=True``: ``observation`` is the camera's RGB image
  (``--size`` pixels a side, uint8), ``achieved_goal`` (the EE position) and ``desired_goal`` stay
  vectors, as HER needs them. Actor and critics share SB3's ``CombinedExtractor`` (NatureCNN to 64
  features, the vectors flattened). This run can learn from its two vectors alone.
* ``pixels_blind``: as ``pixels``, but the policy and critics do not see ``achieved_goal`` (HER
  still relabels with it). SB3's shared extractor, trained by the actor loss only (below).
* ``pixels_strict``: **the policy and critics see the image and ``desired_goal``, nothing else**: no
  ``achieved_goal``, no joint or EE state; HER relabels goals with ``achieved_goal`` in the replay
  buffer, as it must. End-effector delta actions (as the shipped configs): the policy needs the goal
  minus the EE position, the EE position read from the pixels. uniros' ``drq_sac``
  (:class:`uniros.pixel_sac.DrQSAC`, DrQ's recipe on SB3's SAC; its docstring says why SB3's own
  options fall short) with its ``ImageEncoder`` told to ignore ``achieved_goal``:

  - one image encoder (NatureCNN to 50 features, LayerNorm, tanh), shared by actor and critics and
    **trained by the critic loss; the actor reads its features detached** (SAC-AE, DrQ). SB3's SAC
    with ``share_features_extractor=True`` trains a shared CNN from the actor loss only (its critic
    computes the features with gradients off, its critic optimiser leaves the extractor out), which
    is what ``pixels_blind`` does;
  - DrQ's random shift: each sampled batch's images, observations and next observations, padded by
    ``--shift`` pixels (edge replicated) and cropped back at a random offset, **independent for the
    observation and the next observation** (as DrQ). Rollouts and evaluation see unshifted images.

  The figures in docs/tasks.md were measured with this benchmark's own copy of the same code (commit
  "bench_pixel_learning: pixels_strict ..."), since moved into ``uniros.pixel_sac``: with the same
  seed both give bit-identical networks after 200 updates.

Every ``--eval-every`` env steps: success rate over ``--eval-episodes`` deterministic episodes, their
median final distance to the goal (cm), and the wall clock (training only, evaluation excluded).
Prints a table per run, writes ``--json``.

    MUJOCO_GL=egl nice .venv/bin/python benchmarks/bench_pixel_learning.py --steps 20000 --json /tmp/pixels.json
    MUJOCO_GL=egl nice .venv/bin/python benchmarks/bench_pixel_learning.py --runs pixels_strict \\
        --steps 40000 --eval-every 2000 --eval-episodes 20 --json /tmp/pix_strict.json
    MUJOCO_GL=egl nice .venv/bin/python benchmarks/bench_pixel_learning.py --runs state_ee \\
        --steps 10000 --eval-every 1000 --eval-episodes 20
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

ENV_ID = "RX200ReacherGoalSim-v0"


@dataclass(frozen=True)
class Run:
    """One benchmark run: what the env gives, what the networks see, how they learn."""

    image: bool  # rgb_obs_only: ``observation`` is the camera image
    ee_actions: bool  # ee_action_type: end-effector deltas (else joint deltas)
    seen: tuple[str, ...] | None  # the observation keys the networks read (None: all)
    critic_encoder: bool  # uniros.pixel_sac.DrQSAC (else SB3's SAC, shared extractor)
    learning_rate: float
    batch_size: int
    learning_starts: int
    tau: float
    sees: str  # printed in the header


RUNS = {
    "state": Run(False, False, None, False, 1e-3, 128, 1000, 0.005,
                 "state observation, achieved_goal, desired_goal"),
    "state_ee": Run(False, True, None, False, 3e-3, 256, 500, 0.005,
                    "state observation, achieved_goal, desired_goal"),
    "pixels": Run(True, False, None, False, 1e-3, 128, 1000, 0.005, "image, achieved_goal, desired_goal"),
    "pixels_blind": Run(True, False, ("observation", "desired_goal"), False, 1e-3, 128, 1000, 0.005,
                        "image, desired_goal (SB3 shared extractor: actor-loss trained)"),
    "pixels_strict": Run(True, True, ("observation", "desired_goal"), True, 1e-3, 128, 1000, 0.01,
                         "image, desired_goal ONLY (drq_sac: critic-trained encoder, random shift)"),
}


def make_env(run: Run, size: int, seed: int) -> Any:
    import uniros

    kwargs: dict[str, Any] = {"seed": seed, "ee_action_type": run.ee_actions}
    if run.image:
        kwargs.update(rgb_obs_only=True, image_width=size, image_height=size)
    return uniros.make(ENV_ID, **kwargs)


def evaluate(model: Any, env: Any, vec_norm: Any, episodes: int, seed: int) -> tuple[float, float]:
    """Success rate of the deterministic policy over ``episodes`` fresh episodes, and the median final
    distance to the goal (m; from the env's ``achieved_goal``, which the strict runs do not see)."""
    successes = 0
    distances = []
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
        distances.append(float(np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"])))
    return successes / episodes, float(np.median(distances))


def build_model(name: str, run: Run, vec_norm: Any, args: argparse.Namespace) -> Any:
    from stable_baselines3 import SAC, HerReplayBuffer
    from stable_baselines3.common.torch_layers import CombinedExtractor

    buffer_kwargs: dict[str, Any] = {"n_sampled_goal": 4, "goal_selection_strategy": "future"}
    algorithm: type = SAC
    extra: dict[str, Any] = {}
    extractor: dict[str, Any] = {"features_extractor_kwargs": {"cnn_output_dim": 64}}
    if run.critic_encoder:
        from uniros.pixel_sac import DrQSAC, ImageEncoder

        algorithm, extra = DrQSAC, {"image_shift": args.shift}
        extractor = {"features_extractor_class": ImageEncoder,
                     "features_extractor_kwargs": {"image_features": 50, "ignore_keys": ["achieved_goal"]}}
    elif run.seen is not None:
        seen_keys = run.seen

        class SeenKeysExtractor(CombinedExtractor):
            """SB3's extractor over the run's keys only."""

            def __init__(self, observation_space: Any, **kwargs: Any) -> None:
                from gymnasium import spaces

                seen = {k: v for k, v in observation_space.spaces.items() if k in seen_keys}
                super().__init__(spaces.Dict(seen), **kwargs)

        extractor["features_extractor_class"] = SeenKeysExtractor
    return algorithm(
        "MultiInputPolicy", vec_norm, replay_buffer_class=HerReplayBuffer, replay_buffer_kwargs=buffer_kwargs,
        learning_rate=args.lr or run.learning_rate, buffer_size=args.buffer,
        batch_size=args.batch or run.batch_size, gamma=0.95, tau=run.tau,
        learning_starts=args.learning_starts if args.learning_starts is not None else run.learning_starts,
        ent_coef="auto", train_freq=1, gradient_steps=1,
        policy_kwargs={"net_arch": [64, 64], "share_features_extractor": True, **extractor},
        seed=args.seed, verbose=0, device="cpu", **extra)


def train(name: str, args: argparse.Namespace) -> dict[str, Any]:
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize, VecTransposeImage

    torch.set_num_threads(1)
    run = RUNS[name]
    train_env = make_env(run, args.size, args.seed)
    eval_env = make_env(run, args.size, args.seed + 10_000)
    # Images channel-first below the normaliser (SB3 stores the normaliser's original observations).
    vec = VecTransposeImage(DummyVecEnv([lambda: train_env]))
    keys = ["achieved_goal", "desired_goal"] + ([] if run.image else ["observation"])
    vec_norm = VecNormalize(vec, norm_obs=True, norm_reward=False, norm_obs_keys=keys, gamma=0.95)
    model = build_model(name, run, vec_norm, args)
    curve: list[dict[str, float]] = []
    trained = 0.0
    steps = 0
    image = f", rgb_obs_only {args.size}x{args.size}" if run.image else ""
    actions = "EE-delta" if run.ee_actions else "joint-delta"
    print(f"\n{name}: {ENV_ID}{image}, {actions} actions; the policy and critics see: {run.sees}")
    print(f"  lr {model.learning_rate}, batch {model.batch_size}, learning_starts {model.learning_starts}, "
          f"tau {model.tau}" + (f", shift {args.shift} px" if run.critic_encoder else ""))
    print(f"{'steps':>7} {'success':>8} {'dist cm':>8} {'train s':>8} {'ms/step':>8}")
    try:
        while steps < args.steps:
            chunk = min(args.eval_every, args.steps - steps)
            start = time.perf_counter()
            model.learn(chunk, reset_num_timesteps=False)
            trained += time.perf_counter() - start
            steps += chunk
            vec_norm.training = False
            rate, distance = evaluate(model, eval_env, vec_norm, args.eval_episodes, args.seed + 20_000 + steps)
            vec_norm.training = True
            curve.append({"steps": steps, "success": rate, "train_seconds": trained, "median_distance": distance})
            print(f"{steps:7d} {rate:8.2f} {100 * distance:8.1f} {trained:8.0f} {1000 * trained / steps:8.1f}",
                  flush=True)
            if args.json:
                _save(args.json, name, curve)
    finally:
        vec_norm.close()
        eval_env.close()
    return {"run": name, "curve": curve}


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
    parser.add_argument("--runs", nargs="+", default=["state", "pixels"], choices=list(RUNS))
    parser.add_argument("--steps", type=int, default=20_000, help="env steps per run")
    parser.add_argument("--size", type=int, default=48, help="image side in pixels (pixel runs)")
    parser.add_argument("--buffer", type=int, default=50_000,
                        help="replay buffer size (images: ~2 x size^2 x 3 B each)")
    parser.add_argument("--batch", type=int, help="batch size (default: the run's)")
    parser.add_argument("--lr", type=float, help="learning rate (default: the run's)")
    parser.add_argument("--learning-starts", type=int, help="default: the run's")
    parser.add_argument("--shift", type=int, default=4, help="pixels_strict: random shift in pixels (0: none)")
    parser.add_argument("--eval-every", type=int, default=1000)
    parser.add_argument("--eval-episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the curves here (rewritten after each evaluation)")
    args = parser.parse_args()
    for run in args.runs:
        train(run, args)


if __name__ == "__main__":
    main()
