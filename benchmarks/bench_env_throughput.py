"""Env steps per second of the goal envs, as ratios to FetchReach-v4 measured in the same run.

Cases: FetchReach-v4 (gymnasium-robotics, the anchor), each uniros goal env with the simulation
node composed in this process (called directly), the RX200 reach also at 10 physics steps per env
step (40 ms, FetchReach-v4's own step; its default is 25: 100 ms, MultiROS' 10 Hz), and with the
node in a child process over Zenoh. Also the time from ``uniros.make`` to the first observation.
Rounds are interleaved so that machine noise hits every case alike; medians are printed.

    python benchmarks/bench_env_throughput.py [--seconds 3] [--rounds 3] [--no-process]

Goals: one composed RX200ReacherGoalSim-v0 >= 3x one FetchReach-v4 (issue 26); node in another
process >= 1x; make -> first observation <= 1.5 s.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from fetch_compat import make_fetch_reach


def steps_per_second(env, seconds: float, seed: int = 0) -> float:
    """Random actions, reset on episode end; 50 warm-up steps, then ``seconds`` of timed steps."""
    rng = np.random.default_rng(seed)
    env.action_space.seed(seed)
    env.reset(seed=seed)
    for _ in range(50):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    n, start = 0, time.perf_counter()
    deadline = start + seconds
    while True:
        for _ in range(50):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            n += 1
            if terminated or truncated:
                env.reset(seed=int(rng.integers(1 << 30)))
        now = time.perf_counter()
        if now >= deadline:
            return n / (now - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="timed seconds per case and round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--no-process", action="store_true", help="skip the cross-process (Zenoh) cases")
    args = parser.parse_args()

    import uniros

    cases: dict[str, Callable[[], object]] = {"FetchReach-v4": make_fetch_reach}
    for env_id in ("RX200ReacherGoalSim-v0", "ABBIRB120ReacherGoalEnv-v0"):
        cases[f"{env_id} composed"] = lambda e=env_id: uniros.make(e)
        if env_id.startswith("RX200"):
            cases[f"{env_id} composed, 40 ms steps"] = lambda e=env_id: uniros.make(e, num_sim_steps=10)
        if not args.no_process:
            cases[f"{env_id} process/zenoh"] = lambda e=env_id: uniros.make(e, sim_mode="process")

    startup: dict[str, list[float]] = {}
    rates: dict[str, list[float]] = {name: [] for name in cases}
    for r in range(args.rounds):
        for name, factory in cases.items():
            t0 = time.perf_counter()
            env = factory()
            env.reset(seed=r)
            startup.setdefault(name, []).append(time.perf_counter() - t0)
            try:
                rates[name].append(steps_per_second(env, args.seconds, seed=r))
            finally:
                env.close()
            print(f"round {r + 1}: {name:42s} {rates[name][-1]:8.0f} steps/s", flush=True)

    fetch = statistics.median(rates["FetchReach-v4"])
    print()
    print(f"{'case':42s} {'steps/s (median)':>16s} {'x FetchReach-v4':>16s} {'make->obs s':>12s} {'cold':>6s}")
    for name in cases:
        med = statistics.median(rates[name])
        warm = statistics.median(startup[name][1:] or startup[name])
        print(f"{name:42s} {med:16.0f} {med / fetch:16.2f} {warm:12.2f} {startup[name][0]:6.2f}")
    print("make->obs: median over rounds after the first; cold: the first round (imports, xacro, model "
          "compile, child start). Run this script in a fresh process for the cold figure of the first case.")
    rx200 = statistics.median(rates["RX200ReacherGoalSim-v0 composed"])
    print(f"\none composed RX200ReacherGoalSim-v0 (its default 100 ms steps): {rx200 / fetch:.2f}x one "
          f"FetchReach-v4 (goal >= 3x); per round: "
          + ", ".join(f"{r / f:.2f}" for r, f in zip(rates["RX200ReacherGoalSim-v0 composed"], rates["FetchReach-v4"])))


if __name__ == "__main__":
    main()
