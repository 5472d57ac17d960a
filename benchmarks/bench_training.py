"""HER + SAC learning speed of every shipped goal ID next to FetchReach-v4, over several seeds.

One run, two parts:

1. **Defaults, rl-zoo3's FetchReach hyperparameters** (``sac.yml``/``her.yml`` ``FetchReach-v1``:
   SAC, MultiInputPolicy, HER future x4, buffer 1e6, ent_coef auto, batch 256, gamma 0.95,
   lr 1e-3, learning_starts 1000, normalize, net [64, 64]) on each goal ID made with no options
   (``uniros.make(ID)``) and on ``FetchReach-v4`` (patched for mujoco >= 3.12, fetch_compat.py).
2. **What ``uniros train ID`` runs**: the config shipped for each goal ID
   (``config/training/<ID>.yaml``), the wall-clock setting.

For every run: env steps and training seconds (evaluation and saving excluded) to the first
evaluation with success >= ``--target``; the lowest success over the ``--window`` steps after it
(does it hold?); and the learner's cost per 1,000 env steps after ``learning_starts``. A run stops
``--window`` steps after its first success or at ``--max-steps``. Then median [min-max] over seeds.

    python benchmarks/bench_training.py                      # 3 seeds, both parts (~25-40 min here)
    python benchmarks/bench_training.py --seeds 0 --parts zoo --envs RX200ReacherGoalSim-v0 FetchReach-v4

Goals (DESIGN §5): steps to 0.9 at the defaults <= FetchReach-v4's in the same run; the IRB120 holds
>= 0.9 once reached, <= 10k steps; RX200 with the shipped config <= 30 s of training. The machine is
shared: compare steps (robust to load); seconds are indicative.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fetch_compat import make_fetch_reach

from uniros.train_config import TrainingConfig, default_config_for, parse_training_config
from uniros.trainer import Session

FETCH = "FetchReach-v4"

# rl-zoo3 hyperparams/sac.yml, FetchReach-v1 (the her.yml entry has the same values).
ZOO_FETCHREACH: dict[str, Any] = {
    "algorithm": "sac",
    "training_steps": 20_000,
    "normalize": True,
    "use_HER": True,
    "her_params": {"n_sampled_goal": 4, "goal_selection_strategy": "future"},
    "use_custom_policy": True,
    "policy_params": {"net_arch": [64, 64]},
    "sac_params": {"buffer_size": 1_000_000, "ent_coef": "auto", "batch_size": 256, "gamma": 0.95,
                   "learning_rate": 1e-3, "learning_starts": 1000},
}


def goal_ids() -> list[str]:
    """The shipped goal-conditioned reach IDs (those with a training config shipped with uniros)."""
    from uniros.train_config import shipped_config_ids

    return [i for i in shipped_config_ids() if "Goal" in i and "Reach" in i]


@dataclass
class _Watched(Session):
    """A session that stops ``window`` steps after its first success (or at its step budget)."""

    window: int = 2000
    curve: list[tuple[int, float, float]] = field(default_factory=list)

    def after_eval(self, steps: int, rate: float, mean_return: float, **kwargs: Any) -> bool:
        keep = super().after_eval(steps, rate, mean_return, **kwargs)
        self.curve.append((steps, self.evaluations[-1]["train_seconds"], rate))
        if self.steps_to_success is not None and steps >= self.steps_to_success + self.window:
            return False
        return keep


@dataclass
class RunResult:
    env_id: str
    part: str
    seed: int
    steps_to: int | None
    seconds_to: float | None
    held_min: float | None  # lowest success from the first success to the end of the window
    cost_per_k: float  # learner seconds per 1,000 env steps after learning_starts
    curve: list[tuple[int, float, float]]
    wall: float


def run_one(env_id: str, part: str, config: TrainingConfig, seed: int, *, target: float, window: int,
            max_steps: int, eval_freq: int, eval_episodes: int) -> RunResult:
    config = copy.deepcopy(config)
    config.seed, config.training_steps = seed, max_steps
    config.eval_freq, config.eval_episodes = eval_freq, eval_episodes
    config.progress_bar, config.stop_at_success = False, None
    if env_id == FETCH:
        factory: Callable[[], Any] = make_fetch_reach
    else:
        import uniros

        def factory() -> Any:
            return uniros.make(env_id, **config.env_kwargs)

    started = time.perf_counter()
    env = factory()
    session = _Watched(config, env, make_eval_env=factory, target=target, window=window)
    try:
        session.build()
        session.learn()
    finally:
        session.close()
    curve = session.curve
    first = session.steps_to_success
    held = None if first is None else min(r for s, _, r in curve if s >= first)
    starts = int(config.algo_params.get("learning_starts", 100))
    after = [(s, t) for s, t, _ in curve if s >= starts]
    cost = float("nan")
    if len(after) >= 2 and after[-1][0] > after[0][0]:
        cost = 1000 * (after[-1][1] - after[0][1]) / (after[-1][0] - after[0][0])
    return RunResult(env_id, part, seed, first, session.seconds_to_success, held, cost, curve,
                     time.perf_counter() - started)


def _same_learning(a: TrainingConfig, b: TrainingConfig) -> bool:
    """Same algorithm, hyperparameters, policy, HER, normalisation and env kwargs."""
    keys = ("algorithm", "algo_params", "use_her", "her_params", "policy_params", "normalize", "env_kwargs",
            "torch_threads")
    pa, pb = dict(a.policy_params or {}), dict(b.policy_params or {})
    for p in (pa, pb):
        if p.get("activation_fn", "relu") == "relu":
            p.pop("activation_fn", None)
    da = {k: getattr(a, k) for k in keys if k != "policy_params"}
    db = {k: getattr(b, k) for k in keys if k != "policy_params"}
    for d in (da, db):
        d["algo_params"] = {k: v for k, v in d["algo_params"].items()
                            if (k, v) not in {("tau", 0.005), ("train_freq", (1, "step")), ("gradient_steps", 1)}}
    return da == db and pa == pb


def _spread(values: list[float], fmt: str) -> str:
    if not values:
        return "-"
    med = statistics.median(values)
    return f"{med:{fmt}} [{min(values):{fmt}}-{max(values):{fmt}}]"


def summarise(results: list[RunResult], target: float, window: int) -> None:
    print()
    print(f"== summary: median [min-max] over seeds; 'held' = success stayed >= {target} for {window} steps "
          "after first reaching it")
    header = (f"{'part':5s} {'env':28s} {'reached':>7s} {f'steps to >={target}':>22s} {'train s to it':>20s} "
              f"{'held':>6s} {'min after':>9s} {'s / 1k steps':>18s}")
    print(header)
    print("-" * len(header))
    fetch_steps: dict[str, float] = {}
    keys: list[tuple[str, str]] = []
    for r in results:
        if (r.part, r.env_id) not in keys:
            keys.append((r.part, r.env_id))
    for part, env_id in keys:
        rows = [r for r in results if r.part == part and r.env_id == env_id]
        ok = [r for r in rows if r.steps_to is not None]
        steps = [float(r.steps_to) for r in ok]
        secs = [float(r.seconds_to) for r in ok if r.seconds_to is not None]
        held = sum(1 for r in ok if r.held_min is not None and r.held_min >= target)
        mins = [r.held_min for r in ok if r.held_min is not None]
        costs = [r.cost_per_k for r in rows if r.cost_per_k == r.cost_per_k]
        if env_id == FETCH and steps:
            fetch_steps[part] = statistics.median(steps)
        print(f"{part:5s} {env_id:28s} {len(ok):>3d}/{len(rows):<3d} {_spread(steps, '.0f'):>22s} "
              f"{_spread(secs, '.1f'):>20s} {held:>2d}/{len(ok):<3d} {min(mins) if mins else float('nan'):9.2f} "
              f"{_spread(costs, '.2f'):>18s}")
    fetch = fetch_steps.get("zoo")
    if fetch:
        print()
        for part, env_id in keys:
            if env_id == FETCH:
                continue
            steps = [float(r.steps_to) for r in results if r.part == part and r.env_id == env_id
                     and r.steps_to is not None]
            if steps:
                print(f"{part:5s} {env_id:28s} median steps / FetchReach-v4's (zoo, same run): "
                      f"{statistics.median(steps) / fetch:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", nargs="+", help="IDs (default: every shipped goal ID and FetchReach-v4)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--parts", nargs="+", choices=("zoo", "ship"), default=["zoo", "ship"])
    parser.add_argument("--target", type=float, default=0.9)
    parser.add_argument("--window", type=int, default=2000, help="steps watched after the first success")
    parser.add_argument("--max-steps", type=int, default=12_000)
    parser.add_argument("--eval-freq", type=int, default=500)
    parser.add_argument("--eval-episodes", type=int, default=20)
    args = parser.parse_args()

    envs = args.envs or [*goal_ids(), FETCH]
    zoo = parse_training_config(ZOO_FETCHREACH, "rl-zoo3 FetchReach-v1")
    plan: list[tuple[str, str, TrainingConfig]] = []
    for part in args.parts:
        for env_id in envs:
            if part == "zoo":
                plan.append((part, env_id, zoo))
            elif env_id != FETCH:
                shipped = default_config_for(env_id)
                if "zoo" in args.parts and _same_learning(shipped, zoo):
                    print(f"ship {env_id}: its shipped config is rl-zoo3's FetchReach settings (the zoo rows)")
                    continue
                plan.append((part, env_id, shipped))
    print(f"{len(plan)} settings x {len(args.seeds)} seeds; eval every {args.eval_freq} steps over "
          f"{args.eval_episodes} episodes; stop {args.window} steps after the first success >= {args.target} "
          f"or at {args.max_steps}", flush=True)
    results: list[RunResult] = []
    started = time.perf_counter()
    for seed in args.seeds:  # seeds outermost: a partial run still compares every env
        for part, env_id, config in plan:
            r = run_one(env_id, part, config, seed, target=args.target, window=args.window,
                        max_steps=args.max_steps, eval_freq=args.eval_freq, eval_episodes=args.eval_episodes)
            results.append(r)
            rates = " ".join(f"{rate:.2f}" for _, _, rate in r.curve)
            to = "never" if r.steps_to is None else f"{r.steps_to} steps / {r.seconds_to:.1f} s"
            print(f"{part:4s} {env_id:28s} seed {seed}: >= {args.target} at {to}; held min "
                  f"{'-' if r.held_min is None else f'{r.held_min:.2f}'}; {r.cost_per_k:.2f} s/1k; "
                  f"wall {r.wall:.0f} s\n     success every {args.eval_freq}: {rates}", flush=True)
    summarise(results, args.target, args.window)
    print(f"\ntotal wall clock {time.perf_counter() - started:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
