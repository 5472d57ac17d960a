"""The RX200 push Real twin on the physics stand-in: success with and without perturbed physics.

Issue 51's second goal needs push tried where a gap hurts: masses, frictions, the tracker's noise and
latency. For each perturbation (``--perturb``: ``none`` and ``hard`` by default; a profile, a YAML file
or ``KEY=LOW:HIGH``) this starts ``uniros-fake-robot --arm config/arms/rx200.yaml --physics push
--physics-perturb P --physics-seed S`` (plus ``--tracker-noise``, ``--tracker-latency`` and ``--gap``)
on a private Zenoh router on a free loopback port (never 7447; ROS domain ``$ROS_DOMAIN_ID``, never 0),
a fresh robot and router per row and policy (each policy meets the same draws and object placements),
and plays ``--episodes`` episodes of ``RX200PushGoalReal-v0``:

* with the task's scripted policy (``env.unwrapped.task.scripted_policy()``), in this process;
* with ``--run RUNDIR`` (repeatable): the trained policy through ``uniros eval RUNDIR --env
  RX200PushGoalReal-v0``, the path every uniros evaluation takes, in a child process joined to the graph.

Between episodes the stand-in puts the cube back in the start box when the arm returns to its start pose
(``--physics-reset random``); the Real twin samples its goal independently, so some episodes start with
the cube already within the success distance: the scripted rows count them (``trivial``).

    python benchmarks/bench_push_stand_in.py [--episodes 20] [--perturb none hard] [--seed 0]
        [--tracker-noise 0.002 --tracker-latency 0.03] [--gap mild] [--run runs/push_nominal ...]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "config" / "arms" / "rx200.yaml"
REAL_ID = "RX200PushGoalReal-v0"
_RATE = re.compile(r"success rate ([0-9.]+) \[([0-9.]+), ([0-9.]+)\]")


def _stand_in_args(perturb: str, args: argparse.Namespace) -> list[str]:
    out = ["--arm", str(args.arm), "--physics", "push", "--physics-perturb", perturb, "--physics-seed",
           str(args.seed), "--tracker-noise", str(args.tracker_noise), "--tracker-latency", str(args.tracker_latency),
           "--log-level", "WARNING"]
    return out + (["--gap", args.gap, "--gap-seed", str(args.seed)] if args.gap else [])


def scripted(ctx: Any, episodes: int, seed: int, pose_timeout: float) -> dict[str, Any]:
    """The scripted push policy for ``episodes`` episodes (episode i reset with ``seed + i``)."""
    import uniros
    from uniros.evaluation import wilson_interval

    env = uniros.make(REAL_ID, context=ctx, startup_timeout=30.0, joint_state_timeout=5.0,
                      object_pose_timeout=pose_timeout)
    wins, trivial, moved, seconds = 0, 0, [], []
    try:
        task = env.unwrapped.task
        policy = task.scripted_policy()
        for i in range(episodes):
            t0 = time.perf_counter()
            obs, info = env.reset(seed=seed + i)
            policy.reset()
            start = task.object_position()
            trivial += int(np.linalg.norm(start - task.goal) <= task.tolerance)
            done = False
            while not done:
                obs, _, terminated, truncated, info = env.step(policy(obs))
                done = terminated or truncated
            wins += int(bool(info.get("is_success")))
            moved.append(float(np.linalg.norm(task.object_position() - start)))
            seconds.append(time.perf_counter() - t0)
    finally:
        env.close()
    low, high = wilson_interval(wins, episodes)
    return {"rate": wins / episodes, "ci": (low, high), "trivial": trivial, "moved": float(np.mean(moved)),
            "seconds": float(np.mean(seconds))}


def trained(ctx: Any, run: Path, episodes: int, timeout: float) -> str:
    """``uniros eval RUN --env RX200PushGoalReal-v0`` in a child process on ``ctx``'s graph: its success line."""
    from multiros.ros.processes import child_environment, private_environment

    env = private_environment()
    env.update(child_environment(ctx))  # UNIROS_TRANSPORT=zenoh, UNIROS_ZENOH_ROUTER
    env["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "egl")
    cmd = [sys.executable, "-m", "uniros.cli", "eval", str(run), "--env", REAL_ID, "--episodes", str(episodes)]
    try:
        proc = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"FAILED: timed out after {timeout:.0f} s"
    found = _RATE.findall(proc.stdout)
    if proc.returncode != 0 or not found:
        lines = [line for line in (proc.stderr or proc.stdout).strip().splitlines() if line.strip()]
        return f"FAILED (rc {proc.returncode}): {lines[-1][:300] if lines else '(no output)'}"
    rate, low, high = found[-1]
    return f"{float(rate):.2f} [{low}, {high}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=20, help="episodes per row (20)")
    parser.add_argument("--perturb", nargs="+", default=["none", "hard"],
                        help="--physics-perturb of each row: a profile (none, mild, hard), a YAML file or KEY=LOW:HIGH")
    parser.add_argument("--seed", type=int, default=0, help="--physics-seed (and --gap-seed), and the first episode's")
    parser.add_argument("--tracker-noise", type=float, default=0.0, help="m, the tracker's position noise (0)")
    parser.add_argument("--tracker-latency", type=float, default=0.0, help="s, the tracker's latency (0)")
    parser.add_argument("--gap", help="the stand-in's --gap profile too (latency, lag, offsets, joint_states faults)")
    parser.add_argument("--run", type=Path, action="append", default=[], help="a trained run directory (repeatable)")
    parser.add_argument("--no-scripted", action="store_true", help="only the --run policies")
    parser.add_argument("--pose-timeout", type=float, default=2.0,
                        help="the scripted rows' object_pose_timeout, s (2: a loaded machine pauses the tracker)")
    parser.add_argument("--arm", type=Path, default=ARM, help="the arm file the stand-in plays (its push twin)")
    parser.add_argument("--eval-timeout", type=float, default=1800.0, help="seconds one uniros eval may take")
    args = parser.parse_args()
    for run in args.run:
        if not (run / "run.json").is_file():
            parser.error(f"--run {run}: not a run directory (no run.json)")
    if args.arm != ARM:
        parser.error("the benchmark plays RX200PushGoalReal-v0: --arm must be config/arms/rx200.yaml")
    if os.environ.get("ROS_DOMAIN_ID", "0") == "0":  # never domain 0 (a user's robots)
        os.environ["ROS_DOMAIN_ID"] = str(101 + os.getpid() % 100)
    from multiros.hardware.process import FakeRobotProcess
    from multiros.ros.processes import private_context
    from rl_environments.arm_file import load_arm_file

    namespace = load_arm_file(args.arm).real.namespace
    rows: list[tuple[str, str, str]] = []
    policies: list[Path | None] = ([] if args.no_scripted else [None]) + list(args.run)
    for perturb in args.perturb:
        stand_in = _stand_in_args(perturb, args)
        print("$ uniros-fake-robot " + " ".join(stand_in), flush=True)
        for run in policies:  # a fresh stand-in each: the same draws, the same object placements
            ctx = private_context()
            try:
                robot = FakeRobotProcess(None, context=ctx, module="uniros.fake_robot", namespace=namespace,
                                         args=stand_in, timeout_sec=120.0, cwd=str(ROOT))
                try:
                    if run is None:
                        r = scripted(ctx, args.episodes, args.seed, args.pose_timeout)
                        text = (f"{r['rate']:.2f} [{r['ci'][0]:.2f}, {r['ci'][1]:.2f}]  trivial {r['trivial']}, "
                                f"cube moved {r['moved']:.3f} m, {r['seconds']:.1f} s/ep")
                    else:
                        text = trained(ctx, run, args.episodes, args.eval_timeout)
                finally:
                    robot.stop()
            finally:
                ctx.try_shutdown()
            rows.append((perturb, "scripted" if run is None else run.name, text))
            print(f"  {rows[-1][1]}: {text}", flush=True)
    print(f"\n{REAL_ID} on the physics stand-in (--physics-seed {args.seed}, tracker noise {args.tracker_noise} m, "
          f"latency {args.tracker_latency} s, gap {args.gap or 'none'}): success over {args.episodes} episodes "
          "[95% CI]")
    for perturb, policy, text in rows:
        print(f"{perturb:<12} {policy:<24} {text}")


if __name__ == "__main__":
    main()
