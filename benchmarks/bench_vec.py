"""Total env steps per second of vector envs for N = 1, 2, 4, 8, 16, in one run.

Cases (random actions, episodes autoreset as they end):

* batched, composed, one node: ``uniros.make_vec(ID, N, vector_kwargs={"num_nodes": 1})``: one
  simulation node in this process holds the N robots, one call per vector step;
* batched, composed, K = 2 nodes in this process (N/2 robots each; their physics runs at once on
  worker threads, ``mj_step`` releases the GIL), N >= 2;
* batched, node in another process (``sim_mode="process"``, one node behind a private router);
* batched, K = 2 nodes in 2 processes (N/2 robots each), N >= 2;
* SB3 ``SubprocVecEnv`` over N separate uniros envs (each with its own composed node);
* gymnasium ``AsyncVectorEnv`` over N FetchReach-v4 (gymnasium-robotics, patched by fetch_compat);
* one FetchReach-v4, the anchor.

The physics limit is the raw ``mj_step`` rate of the batched env's own world (N robots, one
core), replayed from states of a random-action rollout, in env steps/s: ``N * calls/s`` with
``num_sim_steps`` physics steps per call. The batched composed rate is printed as a fraction of it.

    python benchmarks/bench_vec.py [--seconds 2] [--sizes 1,2,4,8,16] [--env RX200ReacherGoalSim-v0]
                                   [--num-sim-steps 10] [--goal-rounds 5] [--subproc]

Like for like with FetchReach-v4, whose env step is 40 ms of simulated time (20 x 2 ms), the uniros
envs run ``--num-sim-steps 10`` (10 x 4 ms) by default. The RX200 reach IDs' own default is 100 ms
(25 physics steps: MultiROS' 10 Hz and the Real twin's), 2.5x the physics per env step:
``--num-sim-steps 0`` measures at each env's default.

Goals (issue 26): ``uniros.make_vec(ID, 8)`` at its defaults (one composed node per core) >= 6x one
FetchReach-v4, and the push task's (``RX200PushGoalSim-v0``, 40 ms per step as Fetch's) >= 4x. The
table runs its cases one after another, so on a machine whose load changes (a shared one) its
ratios drift with the load; the goals are measured again interleaved (``--goal-rounds``): one
FetchReach-v4 and the vector envs all open at once, stepped in turn, the ratios taken within each
round (``--subproc`` adds SB3's ``SubprocVecEnv`` over 8 separate envs, issue 13's yardstick).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable

import mujoco
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fetch_compat import make_fetch_reach  # noqa: E402

import uniros  # noqa: E402


def _rate(step: Callable[[np.ndarray], object], sample: Callable[[], np.ndarray], n: int, seconds: float) -> float:
    actions = [sample() for _ in range(64)]
    for a in actions[:5]:  # warm up
        step(a)
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step(actions[calls % 64])
        calls += 1
    return n * calls / (time.perf_counter() - start)


class _Stepper:
    """An env (or a vector env) kept open: ``rate(seconds)`` steps it with random actions, a single
    env reset as its episodes end."""

    def __init__(self, env, single: bool = False) -> None:
        self.vec, self.single = env, single
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        space = env.action_space
        self.sample = lambda: rng.uniform(space.low, space.high).astype(space.dtype)
        self.n = 1 if single else env.num_envs

    def step(self, action: np.ndarray) -> None:
        if self.single:
            _, _, term, trunc, _ = self.vec.step(action)
            if term or trunc:
                self.vec.reset()
        else:
            self.vec.step(action)

    def rate(self, seconds: float) -> float:
        return _rate(self.step, self.sample, self.n, seconds)


def gym_vec_rate(vec, seconds: float) -> float:
    return _Stepper(vec).rate(seconds)


def physics_limit(vec, seconds: float) -> float:
    """Env steps/s of raw mj_step in the batched env's world (all N robots, one core), replayed from
    states a random-action rollout of that env went through (moving arms cost more constraint
    work than arms at rest)."""
    world = vec.batch.connections[0].sim_node.world
    m = world.model
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    rng = np.random.default_rng(1)
    space = vec.action_space
    states = []
    for _ in range(100):
        vec.step(rng.uniform(space.low, space.high).astype(space.dtype))
        state = np.empty(mujoco.mj_stateSize(m, spec))
        mujoco.mj_getState(m, world.data, state, spec)
        states.append(state)
    d = mujoco.MjData(m)
    steps = vec.batch.num_sim_steps
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        mujoco.mj_setState(m, d, states[calls % len(states)], spec)
        mujoco.mj_step(m, d, nstep=steps)
        calls += 1
    return vec.num_envs * calls / (time.perf_counter() - start)


def batched(env_id: str, n: int, seconds: float, **kwargs) -> tuple[float, float | None]:
    vec = uniros.make_vec(env_id, n, vectorization_mode="batched", **kwargs)
    try:
        rate = gym_vec_rate(vec, seconds)
        one_composed_node = kwargs.get("sim_mode", "composed") == "composed" and vec.batch.num_nodes == 1
        limit = physics_limit(vec, seconds / 2) if one_composed_node else None
        return rate, limit
    finally:
        vec.close()


def _make_uniros(env_id: str, **kwargs) -> Callable[[], object]:
    def make():
        return uniros.make(env_id, **kwargs)
    return make


class _SB3Stepper(_Stepper):
    """An SB3 ``VecEnv`` kept open (its action space is one env's: actions are drawn for all N)."""

    def __init__(self, venv) -> None:
        self.vec, self.single, self.n = venv, False, venv.num_envs
        venv.seed(0)
        venv.reset()
        rng = np.random.default_rng(0)
        space = venv.action_space
        self.sample = lambda: rng.uniform(space.low, space.high, (self.n, *space.shape)).astype(space.dtype)


def _subproc_venv(env_id: str, n: int, **kwargs):
    from stable_baselines3.common.vec_env import SubprocVecEnv

    return SubprocVecEnv([_make_uniros(env_id, **kwargs) for _ in range(n)])


def subproc(env_id: str, n: int, seconds: float, **kwargs) -> float:
    venv = _subproc_venv(env_id, n, **kwargs)
    try:
        return _SB3Stepper(venv).rate(seconds)
    finally:
        venv.close()


def fetch_async(n: int, seconds: float) -> float:
    from gymnasium.vector import AsyncVectorEnv

    vec = AsyncVectorEnv([make_fetch_reach for _ in range(n)])
    try:
        return gym_vec_rate(vec, seconds)
    finally:
        vec.close()


def fetch_single(seconds: float) -> float:
    env = make_fetch_reach()
    try:
        return _Stepper(env, single=True).rate(seconds)
    finally:
        env.close()


PUSH_ID = "RX200PushGoalSim-v0"


def interleaved_goal(env_id: str, rounds: int, seconds: float, subproc_too: bool, **knobs) -> None:
    """The goals measured side by side (issue 26): one FetchReach-v4 and, all open at once and stepped
    in turn round after round, ``uniros.make_vec(env_id, 8)`` at its defaults (one composed node per
    core), the same on one node, and the push task's ``make_vec(RX200PushGoalSim-v0, 8)`` at its
    defaults (40 ms per step, Fetch's); with ``subproc_too`` also SB3's ``SubprocVecEnv`` over 8
    separate envs. Ratios are taken within each round (FetchReach's rate before and after the others),
    so a change in the machine's load hits each about equally."""
    contenders = {
        f"make_vec({env_id}, 8) defaults": _Stepper(uniros.make_vec(env_id, 8, **knobs)),
        "same, one node": _Stepper(uniros.make_vec(env_id, 8, vector_kwargs={"num_nodes": 1}, **knobs)),
        f"make_vec({PUSH_ID}, 8) defaults": _Stepper(uniros.make_vec(PUSH_ID, 8)),
    }
    nodes = {name: c.vec.batch.num_nodes for name, c in contenders.items()}
    subprocs = _SB3Stepper(_subproc_venv(env_id, 8, **knobs)) if subproc_too else None
    fetch = _Stepper(make_fetch_reach(), single=True)
    vs_fetch: dict[str, list[float]] = {name: [] for name in contenders}
    vs_subproc: dict[str, list[float]] = {name: [] for name in contenders}
    try:
        for _ in range(rounds):
            anchor = fetch.rate(seconds / 2)
            rates = {name: c.rate(seconds) for name, c in contenders.items()}
            subproc_rate = subprocs.rate(seconds) if subprocs is not None else None
            anchor = (anchor + fetch.rate(seconds / 2)) / 2
            for name, rate in rates.items():
                vs_fetch[name].append(rate / anchor)
                if subproc_rate:
                    vs_subproc[name].append(rate / subproc_rate)
    finally:
        for c in contenders.values():
            c.vec.close()
        if subprocs is not None:
            subprocs.vec.close()
        fetch.vec.close()
    goals = {0: ">= 6x", 2: ">= 4x"}
    print(f"\nN=8, interleaved over {rounds} rounds (ratios to one FetchReach-v4 within each round; "
          f"{os.cpu_count()} CPUs):")
    for k, name in enumerate(contenders):
        goal = f", goal {goals[k]}" if k in goals else ""
        print(f"  {name} [{nodes[name]} composed node(s)]: median {np.median(vs_fetch[name]):.2f}x{goal} (rounds: "
              f"{', '.join(f'{v:.2f}' for v in vs_fetch[name])})")
        if vs_subproc[name]:
            print(f"    vs SubprocVecEnv over 8 uniros envs: median {np.median(vs_subproc[name]):.2f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--sizes", default="1,2,4,8,16")
    parser.add_argument("--env", default="RX200ReacherGoalSim-v0")
    parser.add_argument("--num-sim-steps", type=int, default=10,
                        help="physics steps per env step (10: 40 ms, FetchReach-v4's; 0: the env's default)")
    parser.add_argument("--goal-rounds", type=int, default=5,
                        help="rounds of the interleaved comparison of the goals at N = 8 (0: skip it)")
    parser.add_argument("--subproc", action="store_true", help="the interleaved rounds also step SubprocVecEnv")
    args = parser.parse_args()
    knobs = {"num_sim_steps": args.num_sim_steps} if args.num_sim_steps > 0 else {}
    sizes = [int(s) for s in args.sizes.split(",")]
    cols = ["batched composed", "composed 2 nodes", "batched process", "batched 2 procs", "SB3 SubprocVecEnv",
            "Async FetchReach", "physics limit", "fraction"]
    fetch = fetch_single(args.seconds)
    rows: dict[int, dict[str, float | None]] = {}
    for n in sizes:
        row: dict[str, float | None] = {}
        row["batched composed"], row["physics limit"] = batched(args.env, n, args.seconds,
                                                                vector_kwargs={"num_nodes": 1}, **knobs)
        row["fraction"] = row["batched composed"] / row["physics limit"]
        row["composed 2 nodes"] = batched(args.env, n, args.seconds, vector_kwargs={"num_nodes": 2},
                                          **knobs)[0] if n >= 2 else None
        row["batched process"], _ = batched(args.env, n, args.seconds, sim_mode="process", **knobs)
        row["batched 2 procs"] = batched(args.env, n, args.seconds, sim_mode="process",
                                         vector_kwargs={"num_nodes": 2}, **knobs)[0] if n >= 2 else None
        row["SB3 SubprocVecEnv"] = subproc(args.env, n, args.seconds, **knobs)
        row["Async FetchReach"] = fetch_async(n, args.seconds)
        rows[n] = row
        print(f"N={n:2d} " + "  ".join(f"{c}={row[c]:.3g}" if row[c] is not None else f"{c}=-" for c in cols),
              flush=True)
    per_step = f"num_sim_steps={args.num_sim_steps}" if knobs else "the env's default num_sim_steps"
    print(f"\n{args.env} ({per_step}): total env steps/s ({os.cpu_count()} CPUs); "
          f"one FetchReach-v4: {fetch:,.0f}/s")
    print(f"{'N':>3} " + " ".join(f"{c:>18}" for c in cols))
    for n, row in rows.items():
        cells = []
        for c in cols:
            v = row[c]
            cells.append(f"{'-':>18}" if v is None else f"{v:>18.2f}" if c == "fraction" else f"{v:>18,.0f}")
        print(f"{n:>3} " + " ".join(cells))
    if 8 in rows:
        r = rows[8]
        print(f"\nN=8 batched composed: {r['batched composed'] / fetch:.2f}x one FetchReach-v4 (goal >= 5x), "
              f"{r['batched composed'] / r['SB3 SubprocVecEnv']:.2f}x SubprocVecEnv over 8 uniros envs (goal >= 2x)")
        print(f"N=8 batched composed on 2 nodes: {r['composed 2 nodes'] / fetch:.2f}x one FetchReach-v4, "
              f"{r['composed 2 nodes'] / r['SB3 SubprocVecEnv']:.2f}x SubprocVecEnv")
        # Where the time goes: the goal as a time budget per env step, next to the physics' own cost.
        budget, physics, total = 1e6 / (5 * fetch), 1e6 / r["physics limit"], 1e6 / r["batched composed"]
        print(f"per env step at N=8: 5x FetchReach-v4 allows {budget:.0f} us; mj_step of this world takes "
              f"{physics:.0f} us, leaving {budget - physics:.0f} us for the node, task, client and vector env, "
              f"which take {total - physics:.0f} us now ({total:.0f} us in all); on 2 nodes "
              f"{1e6 / r['composed 2 nodes']:.0f} us in all")
    if args.goal_rounds > 0:
        interleaved_goal(args.env, args.goal_rounds, args.seconds, args.subproc, **knobs)


if __name__ == "__main__":
    main()
