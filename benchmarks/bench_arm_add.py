"""``uniros arm add`` on a description, then the scripted policies on the IDs it registered: how well
an arm file inferred from a vendor's description serves the tasks (issue 34's goal: scripted reach
>= 0.95 over 30 seeds, push and pick-and-place >= 0.9 where the gripper grasps the cube).

Lay the vendor's description package out as a sourced workspace gives it (``<prefix>/share/<pkg>``)
and put ``<prefix>`` on ``AMENT_PREFIX_PATH``::

    AMENT_PREFIX_PATH=/tmp/ws/install .venv/bin/python benchmarks/bench_arm_add.py \\
        package://ur_description/urdf/ur.urdf.xacro --xacro-arg ur_type=ur5e --name VendorUR5e --seeds 30

Prints the time ``arm add`` took, its settle check and, per goal ID, the scripted success rate
with the failed seeds.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

import uniros
from rl_environments.arm_add import add_arm
from rl_environments.manipulation_scripted import run_episode, scripted_policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("uri")
    parser.add_argument("--name", required=True)
    parser.add_argument("--xacro-arg", action="append", default=[], metavar="K=V")
    parser.add_argument("--output", help="where the arm file goes (default: a temporary folder)")
    parser.add_argument("--seeds", type=int, default=30, help="episodes per ID (seeds 0..N-1)")
    args = parser.parse_args()
    out = args.output or tempfile.mkdtemp(prefix="bench_arm_add.")
    xacro_args = dict(item.split("=", 1) for item in args.xacro_arg)
    start = time.perf_counter()
    path, ids, draft = add_arm(args.uri, args.name, xacro_args=xacro_args, output=out, force=True)
    print(f"arm add: {path} in {time.perf_counter() - start:.1f} s; settle check {draft.settle_error:.4f} rad; "
          f"{len(ids)} IDs")
    for task in ("ReacherGoal", "PushGoal", "PnPGoal"):
        env_id = f"{args.name}{task}Sim-v0"
        if env_id not in ids:
            continue
        start = time.perf_counter()
        env = uniros.make(env_id, ee_action_type=True)
        try:
            policy = scripted_policy(env)
            results = [run_episode(env, policy, seed=s)["is_success"] for s in range(args.seeds)]
        finally:
            env.close()
        failed = [s for s, ok in enumerate(results) if not ok]
        print(f"{env_id:36s} scripted success {np.mean(results):.2f} over {args.seeds} seeds "
              f"({time.perf_counter() - start:.0f} s); failed seeds {failed}", flush=True)


if __name__ == "__main__":
    main()
