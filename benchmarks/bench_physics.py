"""Physics cost of the World layer: raw ``mj_step`` vs ``World.step`` with controllers active.

Prints steps/s for, on the same compiled arm model, in one run:
  1. raw ``mujoco.mj_step(model, data, nstep)``;
  2. ``World.step(nstep)`` with a position controller (constant setpoint);
  3. ``World.step(nstep)`` with a joint trajectory controller updated every physics step;
and each World figure as a ratio of the raw rate.

    PYTHONPATH=. python benchmarks/bench_physics.py [--nstep 20] [--seconds 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.packages import PackageIndex
from multiros.sim.world import World

DATA = Path(__file__).resolve().parents[1] / "tests" / "sim" / "data"
ARM = "package://test_arm_description/urdf/arm.urdf.xacro"


def _rate(fn, nstep: int, seconds: float) -> float:
    fn()  # warm-up
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        fn()
        calls += 1
    return calls * nstep / (time.perf_counter() - start)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nstep", type=int, default=20, help="physics steps per call (an env step)")
    parser.add_argument("--seconds", type=float, default=2.0, help="time per measurement")
    args = parser.parse_args(argv)
    index = PackageIndex([DATA])

    def world_with(controller: str) -> World:
        world = World(package_index=index)
        world.spawn("arm", ARM, controllers=["joint_state_broadcaster", controller])
        return world

    pos_world = world_with("arm_position_controller")
    pos_world.set_command("arm", "", [0.3, 0.2, -0.2])
    jtc_world = world_with("arm_controller")
    # raw mj_step runs on the position world's own model and data: same state, same contacts
    raw_model, raw_data = pos_world.model, pos_world.data

    times = np.linspace(0.5, 1000.0, 2000)
    traj = np.stack([0.5 * np.sin(times), 0.3 * np.cos(times), 0.2 * np.sin(0.5 * times)], axis=1)
    jtc_world.set_trajectory("arm", "arm_controller", ["joint1", "joint2", "joint3"], traj, times)

    n = args.nstep
    rates: dict[str, list[float]] = {"raw": [], "pos": [], "jtc": []}
    for _ in range(3):  # interleaved repeats, medians: the machine is shared and noisy
        rates["raw"].append(_rate(lambda: mujoco.mj_step(raw_model, raw_data, n), n, args.seconds / 3))
        rates["pos"].append(_rate(lambda: pos_world.step(n), n, args.seconds / 3))
        rates["jtc"].append(_rate(lambda: jtc_world.step(n), n, args.seconds / 3))
    raw, pos, jtc = (float(np.median(rates[k])) for k in ("raw", "pos", "jtc"))
    print(f"model: 3-joint test arm, nq={raw_model.nq}, timestep={raw_model.opt.timestep}, nstep={n}")
    print(f"raw mj_step                      {raw:12,.0f} steps/s  (1.00)")
    print(f"World.step, position controller  {pos:12,.0f} steps/s  ({pos / raw:.2f} of raw)")
    print(f"World.step, trajectory ctrl/step {jtc:12,.0f} steps/s  ({jtc / raw:.2f} of raw)")
    print(f"env steps/s physics limit at nstep={n}: raw {raw / n:,.0f}, World+JTC {jtc / n:,.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
