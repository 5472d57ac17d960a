"""Scripted push and pick-and-place on the VX300S, UR5e and Ned2: success over fixed seeds.

Each arm, its table and its cube are spawned on a composed simulation node (``multiros.sim.launch``,
4 ms physics steps, 40 ms control steps) and driven by ``rl_environments.arm_validation``'s
closed-loop scripted policies through the node's StepRobot service: the arm's group position
controller gets the top-down IK (``rl_environments.arm_ik``) of an end-effector target, the
gripper's controller its finger target. Success is Fetch's: the cube's centre within 5 cm of the
goal at the episode's last step (200 control steps, 8 s). Seeds 0..N-1 draw the cube's start, its
yaw and the goal (Fetch-style: push goals on the table, pick-and-place goals lifted half the time).

The goal (issue 29): >= 0.8 for each arm and task, proving physics, kinematics and grasp before
task envs are wired.

    .venv/bin/python benchmarks/bench_arm_grasps.py                       # 3 arms x 2 tasks x 30 seeds
    .venv/bin/python benchmarks/bench_arm_grasps.py --arms ned2 --tasks pnp --seeds 10
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from multiros.sim import launch
from rl_environments.arm_validation import ARMS, ArmScene, run_pick_and_place, run_push

TASKS = {"push": run_push, "pnp": run_pick_and_place}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--arms", nargs="+", default=sorted(ARMS), choices=sorted(ARMS))
    parser.add_argument("--tasks", nargs="+", default=["push", "pnp"], choices=sorted(TASKS))
    parser.add_argument("--seeds", type=int, default=30, help="episodes per arm and task (seeds 0..N-1)")
    parser.add_argument("--json", help="also write the results to this file")
    args = parser.parse_args()
    rows = []
    print(f"{'arm':8} {'task':5} {'success':>8} {'mean dist':>10} {'s/episode':>10}  failures")
    for arm in args.arms:
        for task in args.tasks:
            conn = launch.connect("composed", timestep=0.004)
            try:
                scene = ArmScene(arm, conn)
                start = time.perf_counter()
                results = [TASKS[task](scene, seed) for seed in range(args.seeds)]
                elapsed = time.perf_counter() - start
            finally:
                conn.close()
            rate = float(np.mean([r.success for r in results]))
            failures = [(seed, round(r.distance, 3)) for seed, r in enumerate(results) if not r.success]
            print(f"{arm:8} {task:5} {rate:8.2f} {np.mean([r.distance for r in results]):10.3f} "
                  f"{elapsed / args.seeds:10.2f}  {failures}", flush=True)
            rows.append({"arm": arm, "task": task, "seeds": args.seeds, "success_rate": rate,
                         "mean_distance": float(np.mean([r.distance for r in results])),
                         "seconds_per_episode": elapsed / args.seeds, "failed_seeds": failures})
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=2)


if __name__ == "__main__":
    main()
