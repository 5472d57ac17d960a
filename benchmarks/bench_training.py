"""HER + SAC learning speed: eval success at checkpoints, steps and wall-clock to success >= 0.9.

Trains ``RX200ReacherGoalSim-v0`` and ``ABBIRB120ReacherGoalEnv-v0`` with the configs uniros
ships (``config/training/<id>.yaml``), and ``FetchReach-v4`` with the same hyperparameters as the
anchor, in one run with fixed seeds. Training wall-clock excludes evaluation (as in
``reference/perf_anchors.md`` §5).

    python benchmarks/bench_training.py [--envs RX200ReacherGoalSim-v0 ...] [--seeds 0] [--steps N]

Goals (DESIGN §5): RX200 <= 10k steps and <= 2 min to 0.9; IRB120 <= 20k steps.
"""

from __future__ import annotations

import argparse
import copy

from fetch_compat import make_fetch_reach

from uniros.training import default_config_for, train

DEFAULT_ENVS = ("RX200ReacherGoalSim-v0", "ABBIRB120ReacherGoalEnv-v0", "FetchReach-v4")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", nargs="+", default=list(DEFAULT_ENVS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--steps", type=int, help="override training_steps")
    parser.add_argument("--target", type=float, default=0.9)
    parser.add_argument("--stop-at-success", action="store_true", help="stop a run once it reaches the target")
    args = parser.parse_args()

    rows = []
    for env_id in args.envs:
        for seed in args.seeds:
            is_fetch = env_id == "FetchReach-v4"
            config = copy.deepcopy(default_config_for("RX200ReacherGoalSim-v0" if is_fetch else env_id))
            config.seed = seed
            if is_fetch:
                config.env_kwargs = {}
                config.training_steps = min(config.training_steps, 10_000)
            if args.steps:
                config.training_steps = args.steps
            if args.stop_at_success:
                config.stop_at_success = args.target
            print(f"== {env_id} seed {seed}: {config.training_steps} steps", flush=True)

            def report(steps: int, seconds: float, rate: float) -> None:
                print(f"   steps {steps:6d}  train {seconds:7.1f} s  eval success {rate:.2f}", flush=True)

            result = train(env_id, config, target=args.target, on_eval=report,
                           make_env=make_fetch_reach if is_fetch else None)
            rows.append((env_id, seed, result))

    print()
    print(f"{'env':30s} {'seed':>4s} {f'steps to >={args.target:.1f}':>14s} {'train s to it':>13s} "
          f"{'final success':>13s} {'s / 1k steps':>12s}")
    for env_id, seed, result in rows:
        final = result.evaluations[-1][2] if result.evaluations else float("nan")
        per_k = 1000 * result.train_seconds / max(1, result.total_steps)
        steps = "-" if result.steps_to_success is None else str(result.steps_to_success)
        secs = "-" if result.seconds_to_success is None else f"{result.seconds_to_success:.1f}"
        print(f"{env_id:30s} {seed:4d} {steps:>14s} {secs:>13s} {final:13.2f} {per_k:12.2f}")


if __name__ == "__main__":
    main()
