"""How ``uniros.make_vec`` scales with the cores, next to its physics limit, in one run.

Prints (env steps/s, random actions, episodes autoreset as they end):

* one env (``uniros.make``) at its default step, and its physics limit: ``mj_step`` alone in the
  same world, replayed from the states its step calls start from (``PhysicsLimit``), with the env's
  physics steps per env step; the fraction reached;
* ``uniros.make_vec(ID, N)`` at its defaults (a share of the envs per core: this process steps one,
  a worker process each of the others, shared memory) for N = 1, 8, 32, 128, with the time it took
  to make, to reset, and from reset to the first step;
* for each make_vec(N) with workers, how much of the wall clock each share spent stepping its envs
  (``WorkerVectorEnv.worker_stats``): near 1 means they are the bound, well below 1 that they wait
  for the exchange or for the slowest of them; and how long each share's thread waited for a core per
  step (the spin's gate: another program on the cores shows there);
* ``make_vec(ID, 8, sim_mode="process")`` (a worker process per node, shared memory) against the same
  K nodes composed on threads of this process and against K process-mode nodes called over Zenoh
  from this process (``workers=0``), interleaved;
* ``make_vec(ID, 8)`` and process mode again with ``pin_workers=True`` (each worker process on a core
  of its own), and ``make_vec(ID, 8)`` with ``spin_wait_sec=0`` (no spin, then block), interleaved with
  the rest;
* the same N on one composed node in this process (``vector_kwargs={"workers": 0, "num_nodes": 1}``),
  for N <= ``--inproc-max``;
* the physics limit over all cores: ``mj_step`` alone in each worker's world (N/K robots), K
  threads at once (``mj_step`` releases the GIL), and the fraction make_vec reached;
* one FetchReach-v4 (gymnasium-robotics, patched by fetch_compat) and gymnasium's
  ``AsyncVectorEnv(shared_memory=True)`` of FetchReach-v4 over the same cores (K and 8 processes).

The ratios of the goals (issue 36) are measured interleaved, all contenders open at once and stepped
in turn for ``--rounds`` rounds, medians of the ratios within each round: make_vec(8) at its defaults
against the same 8 envs on one node in this process, and against the 8 envs' physics limit on all
cores; one env against its physics limit. On a shared machine the load moves: compare ratios.

    python benchmarks/bench_scaling.py [--seconds 2] [--sizes 1,8,32,128] [--env RX200ReacherGoalSim-v0]
                                       [--rounds 3] [--plot docs/_static/vec_scaling.png]
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from collections.abc import Callable

import mujoco
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fetch_compat import make_fetch_reach  # noqa: E402

import uniros  # noqa: E402
from multiros.envs.batch import usable_cores  # noqa: E402
from multiros.envs.spin_wait import QUEUED_TO_SPIN  # noqa: E402


class Stepper:
    """An env or vector env kept open; ``rate(seconds)`` steps it with random actions (env steps/s)."""

    def __init__(self, env, single: bool = False) -> None:
        self.env, self.single = env, single
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        space = env.action_space
        self.actions = [rng.uniform(space.low, space.high).astype(space.dtype) for _ in range(64)]
        self.n = 1 if single else env.num_envs

    def step(self, action: np.ndarray) -> None:
        if self.single:
            _, _, term, trunc, _ = self.env.step(action)
            if term or trunc:
                self.env.reset()
        else:
            self.env.step(action)

    def rate(self, seconds: float) -> float:
        for a in self.actions[:3]:
            self.step(a)
        calls, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            self.step(self.actions[calls % 64])
            calls += 1
        return self.n * calls / (time.perf_counter() - start)

    def close(self) -> None:
        self.env.close()


class PhysicsLimit:
    """``mj_step`` alone in the world of ``n`` robots of ``env_id`` (on one in-process node), on
    ``threads`` threads at once, each with its own ``MjData``: env steps/s of ``n * threads`` envs.

    Each ``mj_step`` starts from the state one of the env's own step calls started from, its new
    commands written (``World.step_start_state``), so the physics timed is the physics the env runs.
    A state read after a step holds the previous commands instead; the arm then coasts to targets it
    has nearly reached, and its step costs about 3 % less than the env's own (RX200: 643 us vs 665 us)."""

    def __init__(self, env_id: str, n: int, threads: int, **kwargs) -> None:
        vec = uniros.make_vec(env_id, n, vectorization_mode="batched", vector_kwargs={"num_nodes": 1}, **kwargs)
        try:
            world = vec.batch.connections[0].sim_node.world
            self.model, self.steps = world.model, vec.batch.num_sim_steps
            rng = np.random.default_rng(1)
            space = vec.action_space
            vec.reset(seed=0)
            self.states = []
            for i in range(256):  # four episodes of the reach; every fourth step call's start kept
                vec.step(rng.uniform(space.low, space.high).astype(space.dtype))
                if i % 4 == 0:
                    self.states.append(world.step_start_state())
        finally:
            vec.close()
        self.n: float = n  # envs each world stands for
        self.threads = threads

    def rate(self, seconds: float) -> float:
        kind = mujoco.mjtState.mjSTATE_INTEGRATION
        counts = [0] * self.threads
        barrier = threading.Barrier(self.threads + 1)

        def work(t: int) -> None:
            d = mujoco.MjData(self.model)
            barrier.wait()
            end = time.perf_counter() + seconds
            calls = 0
            while time.perf_counter() < end:
                mujoco.mj_setState(self.model, d, self.states[calls % len(self.states)], kind)
                mujoco.mj_step(self.model, d, nstep=self.steps)
                calls += 1
            counts[t] = calls

        pool = [threading.Thread(target=work, args=(t,)) for t in range(self.threads)]
        for th in pool:
            th.start()
        barrier.wait()
        start = time.perf_counter()
        for th in pool:
            th.join()
        return self.n * sum(counts) / (time.perf_counter() - start)


def timed_make_vec(env_id: str, n: int, **kwargs) -> tuple[Stepper, dict[str, float]]:
    """make_vec(env_id, n) at its defaults, with the seconds it took to make, reset and step once."""
    t0 = time.perf_counter()
    vec = uniros.make_vec(env_id, n, **kwargs)
    t1 = time.perf_counter()
    vec.reset(seed=0)
    t2 = time.perf_counter()
    vec.step(vec.action_space.sample())
    t3 = time.perf_counter()
    return Stepper(vec), {"make": t1 - t0, "reset": t2 - t1, "reset_to_first_step": t3 - t1}


def layout(vec) -> str:
    """Where a vector env's shares run: worker processes, and this process."""
    workers = getattr(vec, "num_workers", 0)
    if not workers:
        return "this process"
    return f"{workers} worker process{'es' if workers > 1 else ''}" + (" + this process" if vec.local_rows else "")


def fetch_async(n: int, seconds: float) -> float:
    from gymnasium.vector import AsyncVectorEnv

    vec = AsyncVectorEnv([make_fetch_reach for _ in range(n)], shared_memory=True)
    try:
        return Stepper(vec).rate(seconds)
    finally:
        vec.close()


def interleaved(contenders: dict[str, Callable[[float], float]], rounds: int, seconds: float) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {name: [] for name in contenders}
    for _ in range(rounds):
        for name, rate in contenders.items():
            out[name].append(rate(seconds))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--sizes", default="1,8,32,128")
    parser.add_argument("--env", default="RX200ReacherGoalSim-v0")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of the interleaved goal ratios")
    parser.add_argument("--inproc-max", type=int, default=32, help="largest N measured on one node in-process")
    parser.add_argument("--plot", default="", help="write the scaling plot (PNG) here")
    args = parser.parse_args()
    k_all = usable_cores()
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"{args.env} at its default step; {k_all} cores this process may use (os.sched_getaffinity); "
          f"load average {os.getloadavg()[0]:.1f}", flush=True)

    # The goal ratios, interleaved: one env vs its physics; make_vec(8) vs one node and vs the 2-core limit.
    single = Stepper(uniros.make(args.env), single=True)
    single_limit = PhysicsLimit(args.env, 1, 1)
    vec8, _ = timed_make_vec(args.env, 8)
    one_node8 = Stepper(uniros.make_vec(args.env, 8, vector_kwargs={"workers": 0, "num_nodes": 1}))
    limit8 = PhysicsLimit(args.env, -(-8 // k_all), k_all)
    limit8.n = 8 / k_all  # the 8 envs' share per core
    # process mode (a worker process per node) against the same K nodes on threads of this process,
    # and against process-mode nodes called over Zenoh from this process (workers=0)
    k8 = min(8, k_all)
    process8 = Stepper(uniros.make_vec(args.env, 8, sim_mode="process"))
    threads8 = Stepper(uniros.make_vec(args.env, 8, vector_kwargs={"workers": 0, "num_nodes": k8}))
    zenoh8 = Stepper(uniros.make_vec(args.env, 8, sim_mode="process", vector_kwargs={"workers": 0, "num_nodes": k8}))
    # the same layouts with each worker pinned to a core of its own (pin_workers)
    pinned8 = Stepper(uniros.make_vec(args.env, 8, vector_kwargs={"pin_workers": True}))
    # and the default layout without spin-then-block (each side sleeps at once while it waits)
    asleep8 = Stepper(uniros.make_vec(args.env, 8, vector_kwargs={"spin_wait_sec": 0}))
    pinned_process8 = Stepper(uniros.make_vec(args.env, 8, sim_mode="process", vector_kwargs={"pin_workers": True}))
    got = interleaved({"one env": single.rate, "one env physics": single_limit.rate, "make_vec(8)": vec8.rate,
                       "make_vec(8) one node": one_node8.rate, "physics(8) all cores": limit8.rate,
                       "process(8)": process8.rate, "threads(8)": threads8.rate, "process(8) zenoh": zenoh8.rate,
                       "make_vec(8) pinned": pinned8.rate, "process(8) pinned": pinned_process8.rate,
                       "make_vec(8) no spin": asleep8.rate},
                      args.rounds, args.seconds)
    for s in (single, vec8, one_node8, process8, threads8, zenoh8, pinned8, pinned_process8, asleep8):
        s.close()
    med = {name: float(np.median(v)) for name, v in got.items()}
    ratio = lambda a, b: float(np.median(np.array(got[a]) / np.array(got[b])))  # noqa: E731
    print(f"\nInterleaved, {args.rounds} rounds of {args.seconds:g} s each (medians of the ratios within a round):")
    print(f"  one env: {med['one env']:,.0f}/s; mj_step alone in its world: {med['one env physics']:,.0f}/s; "
          f"fraction {ratio('one env', 'one env physics'):.2f} (goal >= 0.75)")
    print(f"  make_vec(8) defaults [{layout(vec8.env)}]: "
          f"{med['make_vec(8)']:,.0f}/s; same 8 on one node in-process: {med['make_vec(8) one node']:,.0f}/s; "
          f"ratio {ratio('make_vec(8)', 'make_vec(8) one node'):.2f}x (goal >= 1.7x on 2 cores)")
    print(f"  physics limit of 8 envs on {k_all} cores: {med['physics(8) all cores']:,.0f}/s; make_vec(8) reaches "
          f"{ratio('make_vec(8)', 'physics(8) all cores'):.2f} of it (goal >= 0.80)")
    print(f"  make_vec(8, sim_mode='process') [{k8} node processes, shared memory]: {med['process(8)']:,.0f}/s; "
          f"the same {k8} nodes on threads of this process: {med['threads(8)']:,.0f}/s; ratio "
          f"{ratio('process(8)', 'threads(8)'):.2f}x (goal >= 1: not slower than threads); {k8} process-mode nodes "
          f"called over Zenoh (workers=0): {med['process(8) zenoh']:,.0f}/s (shared memory "
          f"{ratio('process(8)', 'process(8) zenoh'):.2f}x that)")
    print(f"  pin_workers=True (a core per worker): make_vec(8) defaults {med['make_vec(8) pinned']:,.0f}/s "
          f"({ratio('make_vec(8) pinned', 'make_vec(8)'):.2f}x unpinned, "
          f"{ratio('make_vec(8) pinned', 'physics(8) all cores'):.2f} of the physics limit); process mode "
          f"{med['process(8) pinned']:,.0f}/s ({ratio('process(8) pinned', 'process(8)'):.2f}x unpinned, "
          f"{ratio('process(8) pinned', 'threads(8)'):.2f}x threads)")
    spin_us = getattr(vec8.env, "spin_wait_sec", 0.0) * 1e6
    print(f"  spin, then block (spin_wait_sec {spin_us:.0f} us in make_vec(8)'s default layout): "
          f"{ratio('make_vec(8)', 'make_vec(8) no spin'):.2f}x the same with spin_wait_sec=0 "
          f"({med['make_vec(8) no spin']:,.0f}/s); make_vec(8) {ratio('make_vec(8)', 'threads(8)'):.2f}x the 2 "
          "nodes on threads", flush=True)

    # The curve: make_vec(N) at defaults, one node in-process, physics limit on all cores.
    fetch = Stepper(make_fetch_reach(), single=True)
    fetch_rate = fetch.rate(args.seconds)
    fetch.close()
    rows = []
    for n in sizes:
        stepper, times = timed_make_vec(args.env, n)
        workers = getattr(stepper.env, "num_shares", 0)  # cores at work: the workers and this process's share
        stats = stepper.env.worker_stats() if workers else []
        wall = time.perf_counter()
        rate = stepper.rate(args.seconds)
        busy = ""
        if workers:  # how much of the wall clock each worker stepped rather than waited
            wall = time.perf_counter() - wall
            after = stepper.env.worker_stats()
            share = lambda key, ks, a=after, b=stats, w=wall: [(a[k][key] - b[k][key]) / w for k in ks]  # noqa: E731
            fractions = share("busy_seconds", range(len(after)))
            ks = range(1 if stepper.env.local_rows is not None else 0, len(after))  # the worker processes
            busy = (f"  shares busy {np.mean(fractions):.2f} of the wall clock (min {min(fractions):.2f}, "
                    f"max {max(fractions):.2f}); workers answering {np.mean(share('answer_seconds', ks)):.2f}, "
                    f"waiting for orders {np.mean(share('wait_seconds', ks)):.2f}")
            if stepper.env.local_rows is not None:
                busy += f"; this process waiting for their answers {share('wait_seconds', [0])[0]:.2f}"
            queued = [s["queued_per_step"] * 1e6 for s in after]
            busy += (f"; waiting for a core {min(queued):.0f}-{max(queued):.0f} us a step (spin while under "
                     f"{QUEUED_TO_SPIN * 1e6:.0f})")
            busy += f" [{layout(stepper.env)}]"
        stepper.close()
        k = max(1, workers)
        limit = PhysicsLimit(args.env, -(-n // k), k)
        limit.n = n / k
        phys = limit.rate(args.seconds)
        inproc = None
        if n <= args.inproc_max:
            one = Stepper(uniros.make_vec(args.env, n, vector_kwargs={"workers": 0, "num_nodes": 1}))
            inproc = one.rate(args.seconds)
            one.close()
        rows.append((n, workers, rate, inproc, phys, times))
        print(f"N={n:4d} shares={workers} make_vec {rate:9,.0f}/s  one node in-process "
              f"{'-' if inproc is None else f'{inproc:,.0f}/s'}  physics limit ({k} cores) {phys:9,.0f}/s  "
              f"fraction {rate / phys:.2f}  make {times['make']:.1f} s, reset {times['reset']:.2f} s, reset to "
              f"first step {times['reset_to_first_step']:.2f} s{busy}", flush=True)
    asyncs = {}
    for n in sorted({k_all, 8}):
        asyncs[n] = fetch_async(n, args.seconds)
    print(f"\none FetchReach-v4: {fetch_rate:,.0f}/s; AsyncVectorEnv(shared_memory=True) of FetchReach-v4: "
          + ", ".join(f"{n} procs {r:,.0f}/s ({r / fetch_rate:.2f}x one)" for n, r in asyncs.items()))
    best = max(asyncs.values())
    for n, _, rate, _, _, _ in rows:
        print(f"  make_vec({n}): {rate / fetch_rate:.2f}x one FetchReach-v4, {rate / best:.2f}x the best "
              "AsyncVectorEnv")
    if args.plot:
        plot(args.plot, args.env, k_all, rows, asyncs, fetch_rate)


def plot(path: str, env_id: str, k: int, rows: list, asyncs: dict[int, float], fetch_rate: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ns = [r[0] for r in rows]
    fig, ax = plt.subplots(figsize=(8.4, 4.0), dpi=120)
    ax.plot(ns, [r[4] for r in rows], "k--", marker="o", label=f"physics limit (mj_step alone, {k} cores)")
    ax.plot(ns, [r[2] for r in rows], marker="o", label="make_vec(N) defaults (a share per core)")
    inproc = [(r[0], r[3]) for r in rows if r[3] is not None]
    if inproc:
        ax.plot(*zip(*inproc), marker="s", label="one node in this process")
    best_n = max(asyncs, key=lambda n: asyncs[n])
    ax.axhline(asyncs[best_n], color="tab:red", ls=":", label=f"AsyncVectorEnv FetchReach-v4 ({best_n} procs)")
    ax.axhline(fetch_rate, color="tab:gray", ls=":", label="one FetchReach-v4")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("N envs")
    ax.set_ylabel("env steps / s")
    ax.set_title(f"{env_id}, {k} cores, load average {os.getloadavg()[0]:.1f}", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # beside the data
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
