"""What N envs buy in wall clock to 0.9 success: HER + SAC on a batched vector env, N side by side.

One run trains the shipped config of ``--env`` (``config/training/<ID>.yaml``: HER + SAC, the
config's hyperparameters, normalised observations, one torch thread) on what ``uniros train
--n-envs N`` trains on, for each N and seed, everything else equal: one env for N = 1, and for
N > 1 an SB3 ``uniros.vec_env.BatchedVecEnv`` of N envs (one composed simulation node, one
``StepRobots`` request per vector step). Two ways to count updates:

* ``same``: ``train_freq`` 1 step, ``gradient_steps`` 1, so one gradient step per *vector* step: N
  env steps per update (what a config with ``gradient_steps: 1`` gets).
* ``per-env`` (the shipped configs: ``gradient_steps: -1``, SB3's "as many gradient steps as env
  steps collected"): N gradient steps per vector step, the same updates per env step as N = 1.

One setting must grow with N: HER samples only from ended episodes, so ``learning_starts`` is at
least N episodes' steps (N x 100 for the reach IDs: N >= 6 with the shipped 500), as ``uniros train``
raises it (``uniros.run_envs.fit_learning_starts``).

For every run: env steps and training seconds (evaluation excluded) to the first evaluation with
success >= ``--target`` (evaluation every ``--eval-freq`` env steps, ``--eval-episodes`` episodes of
one separate env, as ``bench_training.py``), and whether it held for ``--window`` steps after.

    nice python benchmarks/bench_vec_training.py                        # N = 1 2 4 8, seeds 0 1, both modes
    nice python benchmarks/bench_vec_training.py --n 1 4 --seeds 0 --modes same

The machine is shared: steps are robust to load, seconds are indicative.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import statistics
import sys
import time
from dataclasses import dataclass

from bench_training import _spread, _Watched

from uniros.run_envs import fit_learning_starts, make_train_env
from uniros.train_config import TrainingConfig, default_config_for


@dataclass
class Result:
    n: int
    mode: str
    seed: int
    steps_to: int | None
    seconds_to: float | None
    updates_to: int | None
    held_min: float | None
    rates: list[float]
    wall: float


def run_one(env_id: str, base: TrainingConfig, n: int, mode: str, seed: int, *, target: float, window: int,
            max_steps: int, eval_freq: int, eval_episodes: int) -> Result:
    import uniros

    config = copy.deepcopy(base)
    config.seed, config.training_steps, config.n_envs = seed, max_steps, n
    config.eval_freq = eval_freq  # env steps (the session evaluates every eval_freq // n vector steps)
    config.eval_episodes = eval_episodes
    config.progress_bar, config.stop_at_success = False, None
    config.algo_params["gradient_steps"] = -1 if mode == "per-env" else 1
    fit_learning_starts(env_id, config)  # as uniros train does: HER needs an ended episode first
    started = time.perf_counter()
    session = _Watched(config, make_train_env(env_id, config),
                       make_eval_env=lambda: uniros.make(env_id, **config.env_kwargs), target=target, window=window)
    try:
        session.build()
        session.learn()
    finally:
        session.close()
    first = session.steps_to_success
    held = None if first is None else min(r for s, _, r in session.curve if s >= first)
    starts = int(config.algo_params.get("learning_starts", 100))
    grads = n if mode == "per-env" else 1  # gradient steps per vector step
    updates = None if first is None else max(0, (first - starts) // n) * grads  # after learning_starts
    return Result(n, mode, seed, first, session.seconds_to_success, updates, held,
                  [r for _, _, r in session.curve], time.perf_counter() - started)


def summarise(results: list[Result], target: float, window: int) -> None:
    print(f"\n== summary: median [min-max] over seeds; 'held' = success stayed >= {target} for {window} env steps")
    header = (f"{'mode':8s} {'N':>3s} {'reached':>7s} {f'env steps to >={target}':>24s} {'train s to it':>20s} "
              f"{'updates to it':>20s} {'held':>5s}")
    print(header)
    print("-" * len(header))
    base: dict[str, float] = {}
    for mode in dict.fromkeys(r.mode for r in results):
        for n in sorted({r.n for r in results if r.mode == mode}):
            rows = [r for r in results if r.mode == mode and r.n == n]
            ok = [r for r in rows if r.steps_to is not None]
            secs = [float(r.seconds_to) for r in ok if r.seconds_to is not None]
            held = sum(1 for r in ok if r.held_min is not None and r.held_min >= target)
            if n == 1 and secs:
                base[mode] = statistics.median(secs)
            speed = f"  ({base[mode] / statistics.median(secs):.2f}x N=1's speed)" if secs and mode in base else ""
            print(f"{mode:8s} {n:>3d} {len(ok):>3d}/{len(rows):<3d} {_spread([r.steps_to for r in ok], '.0f'):>24s} "
                  f"{_spread(secs, '.1f'):>20s} {_spread([r.updates_to for r in ok], '.0f'):>20s} "
                  f"{held:>2d}/{len(ok):<2d}{speed}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="RX200ReacherGoalSim-v0")
    parser.add_argument("--n", nargs="+", type=int, default=[1, 2, 4, 8], help="numbers of envs")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    parser.add_argument("--modes", nargs="+", choices=("same", "per-env"), default=["same", "per-env"])
    parser.add_argument("--target", type=float, default=0.9)
    parser.add_argument("--window", type=int, default=1000, help="env steps watched after the first success")
    parser.add_argument("--max-steps", type=int, default=20_000)
    parser.add_argument("--eval-freq", type=int, default=500, help="env steps between evaluations")
    parser.add_argument("--eval-episodes", type=int, default=20)
    args = parser.parse_args()

    base = default_config_for(args.env)
    if not base.use_her or base.algorithm != "sac":
        print(f"note: the shipped config of {args.env} is {base.algorithm}{' + HER' if base.use_her else ''}")
    for n in args.n:
        raised = fit_learning_starts(args.env, dataclasses.replace(base, n_envs=n, algo_params=dict(base.algo_params)))
        if raised:
            print(f"note: N = {n}: {raised}")
    print(f"{args.env}, shipped config ({base.algorithm}, {base.algo_params}); N = {args.n}; seeds {args.seeds}; "
          f"modes {args.modes}; eval every {args.eval_freq} env steps over {args.eval_episodes} episodes; stop "
          f"{args.window} steps after the first success >= {args.target} or at {args.max_steps}", flush=True)
    results: list[Result] = []
    started = time.perf_counter()
    for seed in args.seeds:  # seeds outermost: a partial run still compares every N
        for mode in args.modes:
            for n in args.n:
                if mode == "per-env" and n == 1 and "same" in args.modes:
                    same = next(r for r in results if r.mode == "same" and r.n == 1 and r.seed == seed)
                    results.append(Result(**{**same.__dict__, "mode": mode}))  # identical settings
                    continue
                r = run_one(args.env, base, n, mode, seed, target=args.target, window=args.window,
                            max_steps=args.max_steps, eval_freq=args.eval_freq, eval_episodes=args.eval_episodes)
                results.append(r)
                to = "never" if r.steps_to is None else f"{r.steps_to} env steps / {r.seconds_to:.1f} s"
                print(f"{mode:8s} N={n:<2d} seed {seed}: >= {args.target} at {to} ({r.updates_to} updates); held "
                      f"min {'-' if r.held_min is None else f'{r.held_min:.2f}'}; wall {r.wall:.0f} s\n"
                      f"         success every {args.eval_freq}: {' '.join(f'{x:.2f}' for x in r.rates)}", flush=True)
    summarise(results, args.target, args.window)
    print(f"\ntotal wall clock {time.perf_counter() - started:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
