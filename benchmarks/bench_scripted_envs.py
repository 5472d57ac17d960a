"""The scripted push and pick-and-place policies through the registered IDs of every arm: success over
fixed seeds, and env steps per second.

Each ID is made with ``uniros.make`` (a composed simulation node, its own) and driven for N episodes
(seeds 0..N-1, the registration's 50 steps of 40 ms) by
``rl_environments.manipulation_scripted.scripted_policy``, which reads only the observation and
returns end-effector deltas plus a gripper command. Success is the task's: the cube within 5 cm of
the goal at the episode's last step (Fetch's). The goal of issue 29: >= 0.8 for each arm and task.

    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_scripted_envs.py   # every arm with a gripper, 4 IDs, 30 seeds
    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_scripted_envs.py --ids UR5ePushGoalSim-v0 --seeds 10

The lean test of the same (``tests/tasks/test_arm_envs.py``) runs a few seeds per arm and task.
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import uniros  # noqa: E402
from rl_environments import ARMS, ENV_IDS  # noqa: E402
from rl_environments.manipulation_scripted import run_episode, scripted_policy  # noqa: E402

# every registered arm with a gripper (the shipped ones and those of UNIROS_ARMS): an arm without one has no
# push or pick-and-place IDs
DEFAULT_IDS = [env_id for arm in ARMS for task in ("Push", "PushGoal", "PnP", "PnPGoal")
               if (env_id := f"{arm}{task}Sim-v0") in ENV_IDS]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ids", nargs="+", default=DEFAULT_IDS)
    parser.add_argument("--seeds", type=int, default=30, help="episodes per ID (seeds 0..N-1)")
    parser.add_argument("--json", help="also write the results to this file")
    args = parser.parse_args()
    rows = []
    print(f"{'ID':24} {'success':>8} {'steps/s':>8} {'s/episode':>10}  failures (seed: reason)")
    for env_id in args.ids:
        env = uniros.make(env_id)
        try:
            policy = scripted_policy(env)
            failures, steps = [], 0
            start = time.perf_counter()
            for seed in range(args.seeds):
                result = run_episode(env, policy, seed=seed)
                steps += result["steps"]
                if not result["is_success"]:
                    failures.append(f"{seed}: {result['truncated_reason'] or 'not at the goal'}")
            elapsed = time.perf_counter() - start
        finally:
            env.close()
        rate = 1.0 - len(failures) / args.seeds
        rows.append({"id": env_id, "success": rate, "steps_per_s": steps / elapsed, "seeds": args.seeds,
                     "failures": failures})
        print(f"{env_id:24} {rate:8.2f} {steps / elapsed:8.0f} {elapsed / args.seeds:10.2f}  {', '.join(failures)}",
              flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
