"""Lockstep env-style steps of the simulation node against the physics limit, in one run.

* raw ``mj_step`` rate of the RX200 model (``nstep=N`` per call, the physics limit);
* ``StepRobot`` round trips (a position command + N physics steps + joint state + EE pose) with the
  node composed in this process (in-process transport), and in a child process over Zenoh;
* the composed case again with the robot randomised (:data:`RANDOMISED`: scaled masses, damping and
  servo gains, and command shaping: latency, jitter, lag and offsets, :mod:`multiros.sim.entity_properties`),
  what a randomised env's world costs per step.

Each env-style rate is also printed as a fraction of the physics limit (raw rate / N).

    python benchmarks/bench_sim_node.py [--steps-per-call 20] [--seconds 3] [--no-process]
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from multiros.ros import Context, Node
from multiros.sim.client import SimulationClient
from multiros.sim.launch import compose, connect
from multiros.sim.world import World, WorldOptions

RX200 = "package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
RX200_CONTROLLERS = "joint_state_broadcaster,arm_position_controller,gripper_controller"
EE = "rx200/ee_gripper_link"


def raw_rate(n: int, seconds: float) -> float:
    world = World(WorldOptions())
    world.spawn("rx200", "package://rx200_description/urdf/rx200.urdf.xacro", xacro_args={"robot_name": "rx200"})
    m, d = world.model, world.data
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        mujoco.mj_step(m, d, nstep=n)
        steps += n
    return steps / (time.perf_counter() - start)


#: A randomised RX200's rows, as rl_environments.randomization draws them for the sim2real configs.
RANDOMISED = [("body", "", "mass", 1.1), ("joint", "", "damping", 1.5), ("actuator", "", "gain", 0.9),
              ("command", "", "latency", 0.1), ("command", "", "jitter", 0.03), ("command", "", "seed", 3.0),
              ("command", "", "time_constant", 0.2), ("command", "", "offset", 0.02)]


def lockstep_rate(client: SimulationClient, n: int, seconds: float, rows: list | None = None) -> tuple[float, float]:
    client.spawn_entity("rx200", uri=f"{RX200}&__controllers={RX200_CONTROLLERS}", namespace="/rx200")
    if rows:
        client.set_entity_properties("rx200", rows)
    rng = np.random.default_rng(0)
    targets = rng.uniform(-0.5, 0.5, (256, 5))
    lat = []
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        t = time.perf_counter()
        client.step_robot("rx200", {"arm_position_controller": targets[calls % 256]}, n, [EE])
        lat.append(time.perf_counter() - t)
        calls += 1
    return calls / (time.perf_counter() - start), float(np.median(lat))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps-per-call", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--no-process", action="store_true")
    args = parser.parse_args()
    n = args.steps_per_call

    raw = raw_rate(n, args.seconds)
    limit = raw / n
    rows = [("raw mj_step (physics steps/s)", raw, None, None)]

    ctx = Context(transport="inproc").init()
    try:
        compose("mujoco_sim", context=ctx)
        client = SimulationClient(Node("bench", context=ctx), "/mujoco_sim")
        rate, lat = lockstep_rate(client, n, args.seconds)
        rows.append(("StepRobot composed (inproc)", rate, rate / limit, lat))
    finally:
        ctx.try_shutdown()
    ctx = Context(transport="inproc").init()
    try:
        compose("mujoco_sim", context=ctx)
        client = SimulationClient(Node("bench", context=ctx), "/mujoco_sim")
        rate, lat = lockstep_rate(client, n, args.seconds, RANDOMISED)
        rows.append(("StepRobot composed, randomised", rate, rate / limit, lat))
    finally:
        ctx.try_shutdown()

    if not args.no_process:
        conn = connect("process", timeout_sec=30.0)
        try:
            rate, lat = lockstep_rate(conn.client, n, args.seconds)
            rows.append(("StepRobot child process (zenoh)", rate, rate / limit, lat))
        finally:
            conn.close()

    print(f"RX200, {n} physics steps of {WorldOptions().timestep * 1000:g} ms per env step; "
          f"physics limit {limit:.0f} env steps/s")
    print(f"{'case':36s} {'rate /s':>10s} {'x physics limit':>16s} {'median latency ms':>18s}")
    for name, rate, frac, lat in rows:
        frac_s = "" if frac is None else f"{frac:.2f}"
        lat_s = "" if lat is None else f"{lat * 1e3:.3f}"
        print(f"{name:36s} {rate:10.0f} {frac_s:>16s} {lat_s:>18s}")


if __name__ == "__main__":
    main()
