"""Learning benchmark: HER + TQC on RX200PushGoalSim-v0 / RX200PnPGoalSim-v0 next to FetchPush-v4 /
FetchPickAndPlace-v4, same algorithm, settings and step budget, in one run; learning curves to a PNG.

Settings start from rl-zoo3's ``FetchPush-v1`` (tqc.yml; ``--algo sac`` swaps TQC for SAC):
MultiInputPolicy, HerReplayBuffer (future, 4 goals), gamma 0.95, lr 1e-3, tau 0.05, batch 2048,
net [512, 512, 512], 2 critics.
``--batch-size``/``--net`` shrink the network for short runs on a small machine (say so when you
report them). ``--demos N`` adds N scripted episodes (``rl_environments.manipulation_scripted``) to
the RX200 agents' replay buffers before learning (Fetch has no scripted policy here: the
comparison is then not like for like; the demos' transitions are not counted in the step budget).

The goal (issue 14): push >= 0.8 eval success within 120k steps and ahead of FetchPush-v4 at the
same step count; pick-and-place: the success at 200k steps, whatever it is. A full run takes hours
on two cores: ``--steps`` sets the budget.

    .venv/bin/python benchmarks/bench_manipulation.py --steps 120000                 # the issue's run
    .venv/bin/python benchmarks/bench_manipulation.py --steps 4000 --eval-every 1000 \
        --batch-size 256 --net 256,256 --demos 10                                      # a smoke run
    .venv/bin/python benchmarks/bench_manipulation.py --tasks push --steps 120000 --algo sac \
        --batch-size 256 --net 256,256 --demos 50 --parallel              # docs/tasks.md's run (2 cores)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import gymnasium as gym

sys.path.insert(0, str(Path(__file__).resolve().parent))

PAIRS = {"push": ("RX200PushGoalSim-v0", "FetchPush-v4"), "pnp": ("RX200PnPGoalSim-v0", "FetchPickAndPlace-v4")}


def make_env(env_id: str) -> gym.Env:
    if env_id.startswith("Fetch"):
        import gymnasium_robotics
        from fetch_compat import patch_gymnasium_robotics

        gym.register_envs(gymnasium_robotics)
        patch_gymnasium_robotics()
        return gym.make(env_id)
    import uniros

    return uniros.make(env_id)


def evaluate(model, env: gym.Env, episodes: int, seed: int) -> float:
    """Success rate at the last step of ``episodes`` deterministic episodes (Fetch's measure)."""
    wins = 0
    for k in range(episodes):
        obs, info = env.reset(seed=seed + k)
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        wins += int(bool(info.get("is_success")))
    return wins / episodes


def run(env_id: str, args: argparse.Namespace) -> dict:
    import torch
    from sb3_contrib import TQC
    from stable_baselines3 import SAC, HerReplayBuffer

    torch.set_num_threads(1)  # about 1.8x faster here than torch's default
    env, eval_env = make_env(env_id), make_env(env_id)
    net = [int(n) for n in args.net.split(",")]
    algo = {"tqc": TQC, "sac": SAC}[args.algo]
    model = algo("MultiInputPolicy", env, buffer_size=1_000_000, batch_size=args.batch_size, gamma=0.95,
                learning_rate=1e-3, tau=0.05, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs={"goal_selection_strategy": "future", "n_sampled_goal": 4},
                policy_kwargs={"net_arch": net, "n_critics": 2}, seed=args.seed, verbose=0)
    demo = None
    if args.demos and not env_id.startswith("Fetch"):
        from rl_environments.manipulation_scripted import fill_replay_buffer

        demo = fill_replay_buffer(model, env, args.demos, seed=10_000)
    curve, t0 = [], time.monotonic()
    done_steps = 0
    while done_steps < args.steps:
        chunk = min(args.eval_every, args.steps - done_steps)
        model.learn(chunk, reset_num_timesteps=False)
        done_steps += chunk
        success = evaluate(model, eval_env, args.eval_episodes, seed=100_000)
        curve.append((done_steps, success, time.monotonic() - t0))
        print(f"{env_id:24s} {done_steps:8d} steps  eval success {success:.2f}  ({time.monotonic() - t0:.0f} s)",
              flush=True)
    env.close()
    eval_env.close()
    return {"env_id": env_id, "curve": curve, "demos": demo}


def plot(results: list[dict], path: Path, args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(args.tasks), figsize=(6 * len(args.tasks), 4), squeeze=False)
    for ax, task in zip(axes[0], args.tasks):
        for res in results:
            if res["env_id"] in PAIRS[task]:
                steps, success, _ = zip(*res["curve"])
                ax.plot(steps, success, marker="o", label=res["env_id"])
        ax.set_title(f"HER + {args.algo.upper()}, {task} (batch {args.batch_size}, net {args.net}, demos {args.demos})")
        ax.set_xlabel("environment steps")
        ax.set_ylabel(f"eval success ({args.eval_episodes} episodes)")
        ax.set_ylim(-0.05, 1.05)
        ax.grid(True)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=120_000, help="env steps per agent")
    parser.add_argument("--tasks", nargs="+", default=["push", "pnp"], choices=sorted(PAIRS))
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--batch-size", type=int, default=2048)
    parser.add_argument("--net", default="512,512,512", help="hidden layer sizes, comma-separated")
    parser.add_argument("--demos", type=int, default=0, help="scripted episodes in the RX200 buffers")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--algo", choices=("tqc", "sac"), default="tqc",
                        help="TQC (rl-zoo3's choice for FetchPush) or SAC (about 1.5x cheaper per gradient step here)")
    parser.add_argument("--parallel", action="store_true",
                        help="train the agents at once, one process each (same settings, side by side: on two "
                             "cores a push pair takes the time of one agent)")
    parser.add_argument("--only", choices=("rx200", "fetch"), default=None,
                        help="run one side of each pair (e.g. the RX200 without --demos: Fetch's like-for-like twin)")
    parser.add_argument("--out", type=Path, default=Path("bench_manipulation"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    env_ids = [env_id for task in args.tasks for env_id in PAIRS[task]
               if args.only is None or env_id.startswith("Fetch") == (args.only == "fetch")]
    if args.parallel:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(len(env_ids)) as pool:
            results = pool.starmap(run, [(env_id, args) for env_id in env_ids])
    else:
        results = [run(env_id, args) for env_id in env_ids]
    png = args.out / "learning_curves.png"
    plot(results, png, args)
    (args.out / "results.json").write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                                        "results": results}, indent=1))
    print(f"\nalgo={args.algo} steps={args.steps} batch={args.batch_size} net={args.net} demos={args.demos} "
          f"seed={args.seed}")
    for res in results:
        steps, success, seconds = res["curve"][-1]
        best = max(s for _, s, _ in res["curve"])
        demo = f", demos: {res['demos']['transitions']:.0f} transitions" if res["demos"] else ""
        print(f"{res['env_id']:24s} final success {success:.2f} at {steps} steps (best {best:.2f}), "
              f"{seconds:.0f} s{demo}")
    print(f"learning curves: {png}")


if __name__ == "__main__":
    main()
