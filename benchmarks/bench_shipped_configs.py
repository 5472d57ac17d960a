"""Learning check of the training configs uniros ships: each ID trained with its own
``config/training/<ID>.yaml`` through ``uniros train``'s code path (a run directory, checkpoints,
evaluations on the seeded episodes), then its best model evaluated as ``uniros eval`` does.

Prints, per ID: the evaluation success against env steps (with 95 % Wilson intervals), the first
step count at which an evaluation reached ``--target``, the training seconds (evaluation and
checkpoints excluded), and the final evaluation of the best model over ``--final-episodes``
episodes. Not a test: push and pick-and-place take hours on two cores (run them with ``nice``, one
process per ID). ``--n-envs 8`` trains 8 envs in one simulation node (docs/training.md).

    .venv/bin/python benchmarks/bench_shipped_configs.py --ids RX200ReacherGoalSim-v0 RX200ReacherSim-v0
    nice .venv/bin/python benchmarks/bench_shipped_configs.py --ids RX200PushGoalSim-v0 --out /tmp/bench_push
    .venv/bin/python benchmarks/bench_shipped_configs.py --ids RX200ReacherGoalSim-v0 --n-envs 8 --steps 6000
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

import rl_environments
from uniros.evaluation import EVAL_SEED, evaluate, format_success
from uniros.model_files import load_for_eval
from uniros.run_envs import make_env
from uniros.training import (
    default_config_for,
    load_training_config,
    note_updates_per_env_step,
    run_training,
    start_run,
)


def run(env_id: str, args: argparse.Namespace) -> dict:
    config = copy.deepcopy(load_training_config(args.config) if args.config else default_config_for(env_id))
    if args.steps:
        config.training_steps = args.steps
    if args.n_envs:
        config.n_envs = args.n_envs
    if args.eval_freq:
        config.eval_freq = args.eval_freq
    config.seed = args.seed
    config.progress_bar, config.video = False, False
    note = note_updates_per_env_step(config)
    if note:
        print(f"note: {note}", flush=True)
    name = f"{env_id}_s{args.seed}_n{config.n_envs}_{time.strftime('%Y%m%d-%H%M%S')}"
    run_dir = start_run(env_id, config, output=args.out, name=name)
    started = time.perf_counter()

    def report(steps: int, seconds: float, rate: float) -> None:
        print(f"{env_id:28s} {steps:8d} steps  {seconds:8.0f} s  eval success "
              f"{format_success(rate, config.eval_episodes)}", flush=True)

    result = run_training(run_dir, env_id, config, target=args.target, on_eval=report,
                          on_note=lambda text: print(f"note: {text}", flush=True))
    wall = time.perf_counter() - started
    model_path = result.files.get("best_model", result.files["final_model"])
    env = make_env(env_id, **config.env_kwargs)
    try:
        model, normalizer = load_for_eval(model_path, env)
        final = evaluate(model, env, args.final_episodes, seed=EVAL_SEED, normalizer=normalizer)
    finally:
        env.close()
    row = {"env_id": env_id, "n_envs": config.n_envs, "seed": args.seed, "steps": result.total_steps,
           "first_target": result.steps_to_success, "seconds_to_target": result.seconds_to_success,
           "train_seconds": result.train_seconds, "wall_seconds": wall, "final": final,
           "evaluations": result.evaluations, "run_dir": str(run_dir.root)}
    print(f"{env_id:28s} done: first eval >= {args.target} at {result.steps_to_success} steps "
          f"({result.seconds_to_success and round(result.seconds_to_success)} s); final evaluation of "
          f"{model_path.name} over {args.final_episodes} episodes: "
          f"{format_success(final['success_rate'], args.final_episodes)}; {result.train_seconds:.0f} s training, "
          f"{wall:.0f} s wall", flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ids", nargs="+", default=list(rl_environments.ENV_IDS), choices=rl_environments.ENV_IDS)
    parser.add_argument("--config", help="train with this YAML instead of the shipped one (a candidate for it)")
    parser.add_argument("--steps", type=int, help="override training_steps (default: the config's)")
    parser.add_argument("--n-envs", type=int, help="override n_envs")
    parser.add_argument("--eval-freq", type=int, help="override eval_freq")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--target", type=float, default=0.9)
    parser.add_argument("--final-episodes", type=int, default=50)
    parser.add_argument("--out", type=Path, default=Path("bench_shipped_configs"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [run(env_id, args) for env_id in args.ids]
    first = f"first >= {args.target:.2f}"
    print(f"\n{'ID':28s} {'n':>2s} {first:>14s} {'train s':>8s} {'final success':>20s}")
    for row in rows:
        final = row["final"]
        print(f"{row['env_id']:28s} {row['n_envs']:2d} {row['first_target'] or '-'!s:>14s} "
              f"{row['train_seconds']:8.0f} {format_success(final['success_rate'], int(final['episodes'])):>20s}")
    out = args.out / f"results_{time.strftime('%Y%m%d-%H%M%S')}.json"
    out.write_text(json.dumps(rows, indent=1, default=str))
    print(f"results: {out}")


if __name__ == "__main__":
    main()
