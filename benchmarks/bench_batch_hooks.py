"""What a task's batched step hooks buy a batched vector env: the same env with and without them,
measured side by side in one run.

One batched vector env (N robots on composed nodes) is stepped with random actions in alternating
rounds: with the task's batched step hooks (``rl_environments.reach_batch``) and with each env
running its own hooks (``vec.batch.hooks = None``). Each round's figure is env steps per second of
this thread's CPU time (with one node every hook and the physics run on this thread, so a noisy
neighbour's share of the core does not count), or of wall time with ``--wall`` (use it for
``--num-nodes 2``, whose physics also runs on a worker thread). The medians of the rounds and their
ratio are printed.

    python benchmarks/bench_batch_hooks.py [--env RX200ReacherGoalSim-v0] [--num-envs 8]
                                           [--num-nodes 1] [--rounds 5] [--seconds 1.5] [--wall]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import uniros


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="RX200ReacherGoalSim-v0")
    parser.add_argument("--num-envs", type=int, default=8)
    parser.add_argument("--num-nodes", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=1.5)
    parser.add_argument("--wall", action="store_true", help="wall time instead of this thread's CPU time")
    args = parser.parse_args()
    clock = time.perf_counter if args.wall else time.thread_time
    vec = uniros.make_vec(args.env, args.num_envs, vectorization_mode="batched", num_sim_steps=10,
                          vector_kwargs={"num_nodes": args.num_nodes})
    try:
        hooks = vec.batch.hooks
        if hooks is None:
            raise SystemExit(f"{args.env} has no batched step hooks")
        vec.reset(seed=0)
        rng = np.random.default_rng(0)
        actions = [rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32) for _ in range(64)]
        for a in actions[:20]:
            vec.step(a)

        def rate() -> float:
            n, start, deadline = 0, clock(), time.perf_counter() + args.seconds
            while time.perf_counter() < deadline:
                vec.step(actions[n % 64])
                n += 1
            return args.num_envs * n / (clock() - start)

        rates: dict[str, list[float]] = {"own hooks": [], "batched hooks": []}
        for _ in range(args.rounds):
            for name, value in (("own hooks", None), ("batched hooks", hooks)):
                vec.batch.hooks = value
                rates[name].append(rate())
    finally:
        vec.close()
    unit = "wall" if args.wall else "CPU"
    print(f"{args.env}, N={args.num_envs}, {args.num_nodes} composed node(s): env steps per {unit} second")
    medians = {}
    for name, values in rates.items():
        medians[name] = float(np.median(values))
        print(f"  {name:14s} median {medians[name]:7,.0f}  ({1e6 / medians[name]:5.1f} us per env step)"
              f"  rounds: {', '.join(f'{v:,.0f}' for v in values)}")
    print(f"batched hooks / own hooks: {medians['batched hooks'] / medians['own hooks']:.2f}x")


if __name__ == "__main__":
    main()
