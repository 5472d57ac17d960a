"""Process-mode envs started at once: 1, 2 and 4 owner processes, each with its own simulation node.

Each owner is an OS process that makes ``RX200ReacherGoalSim-v0`` with ``sim_mode="process"`` (a
child node behind a private Zenoh router), then steps random actions for a fixed wall-clock window.
All owners of a round start together; the script prints, per round, how many envs came up (every one
must: none may see another's node), the time to the first observation, and env steps/s per process
and in total, with the total as a ratio to the single-process round measured in the same run.

    python benchmarks/bench_process_parallel.py [--counts 1 2 4] [--seconds 8]

Nothing here uses the default router port or domain 0: every node is private to its owner.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import textwrap
import time

_OWNER = textwrap.dedent("""
    import json, sys, time
    t0 = time.perf_counter()
    import uniros
    env = uniros.make("RX200ReacherGoalSim-v0", sim_mode="process", timeout_sec=120.0)
    try:
        env.reset(seed=int(sys.argv[1]))
        ready = time.perf_counter() - t0
        # Start line: every owner measures the same window once all are up.
        print("ready", flush=True)
        sys.stdin.readline()
        env.action_space.seed(int(sys.argv[1]))
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < float(sys.argv[2]):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            steps += 1
            if terminated or truncated:
                env.reset()
        rate = steps / (time.perf_counter() - start)
        print(json.dumps({"ready_s": ready, "rate": rate, "node_pid": env.unwrapped.sim_connection.pid}), flush=True)
    finally:
        env.close()
""")


def run_round(count: int, seconds: float) -> dict:
    procs = [subprocess.Popen([sys.executable, "-c", _OWNER, str(i), str(seconds)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(count)]
    results, failures = [], []
    try:
        ready = [p for p in procs if p.stdout.readline().strip() == "ready"]
        for p in ready:
            p.stdin.write("go\n")
            p.stdin.flush()
        for p in procs:
            out, err = p.communicate(timeout=seconds + 120)
            lines = [ln for ln in out.splitlines() if ln.startswith("{")]
            if p.returncode == 0 and lines:
                results.append(json.loads(lines[-1]))
            else:
                failures.append(err.strip().splitlines()[-1] if err.strip() else f"exit {p.returncode}")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
    return {"count": count, "results": results, "failures": failures}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--seconds", type=float, default=8.0)
    args = parser.parse_args()

    rounds = [run_round(n, args.seconds) for n in args.counts]
    base = None
    print(f"{'processes':>9} {'up':>5} {'ready s (max)':>14} {'steps/s per process':>20} {'total steps/s':>14} "
          f"{'x 1 process':>11}")
    for r in rounds:
        rates = [x["rate"] for x in r["results"]]
        total = sum(rates)
        if r["count"] == 1 and rates:
            base = total
        ratio = f"{total / base:.2f}" if base else "-"
        per = f"{min(rates):.0f}-{max(rates):.0f}" if rates else "-"
        ready = max((x["ready_s"] for x in r["results"]), default=float("nan"))
        pids = {x["node_pid"] for x in r["results"]}
        print(f"{r['count']:>9} {len(r['results']):>2}/{r['count']:<2} {ready:>14.2f} {per:>20} {total:>14.0f} "
              f"{ratio:>11}")
        if len(pids) != len(r["results"]):
            print("   !! two owners shared a node pid")
        for failure in r["failures"]:
            print(f"   !! failed: {failure}")
    print(f"(machine: {time.strftime('%Y-%m-%d %H:%M')}, {args.seconds:g} s window per round; "
          "2 cores: beyond 2 processes the total is bounded by the CPU, not by collisions)")


if __name__ == "__main__":
    main()
