"""The rclpy transport next to Zenoh and the composed default, measured in one run.

Run in the venv ``.ci/rclpy`` makes (rclpy + Fast DDS from PyPI and the built interface packages)::

    .venv-rclpy/bin/python benchmarks/bench_rclpy.py [--steps 200] [--rounds 5] [--commands 100] [--conversion]

Prints:

* env steps/s of ``RX200ReacherGoalSim-v0`` composed (in-process), and with ``sim_mode="process"``
  (the simulation node in a child process) over Zenoh and over rclpy/Fast DDS;
* a Real env's command-to-state latency against ``uniros-fake-robot`` on each transport: from
  publishing a trajectory command until the first ``joint_states`` message showing the commanded
  joint moving (the fake robot publishes at 500 Hz here, so 1-2 ms of each figure is its period);
* ``--conversion``: what converting a 6-joint JointState costs each way (the figures quoted in
  ``multiros/ros/transport/rclpy/transport.py``).

Every measurement runs side by side in this one process, on this machine's current load; compare
the ratios, not the absolute numbers. ROS traffic stays on localhost on a private domain.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

import uniros  # noqa: E402
from multiros.ros import Context  # noqa: E402
from multiros.ros.processes import private_context  # noqa: E402

ENV_ID = "RX200ReacherGoalSim-v0"
REAL_ID = "RX200ReacherGoalReal-v0"


def step_rates(steps: int, rounds: int, modes: dict[str, dict]) -> dict[str, list[float]]:
    """Env steps/s per mode, all envs open at once and stepped in turn, ``rounds`` times: each
    round's figures share the machine's load of that moment."""
    envs = {label: uniros.make(ENV_ID, **kw) for label, kw in modes.items()}
    rates: dict[str, list[float]] = {label: [] for label in modes}
    try:
        rng = np.random.default_rng(0)
        for env in envs.values():
            env.reset(seed=0)
            for _ in range(20):  # warm-up: first calls build codecs and connections
                env.step(env.action_space.sample())
        for _ in range(rounds):
            actions = [rng.uniform(-1, 1, (5,)).astype(np.float32) for _ in range(steps)]
            for label, env in envs.items():
                t0 = time.perf_counter()
                for i, a in enumerate(actions):
                    _obs, _r, term, trunc, _info = env.step(a)
                    if term or trunc:
                        env.reset(seed=i)
                rates[label].append(steps / (time.perf_counter() - t0))
        return rates
    finally:
        for env in envs.values():
            env.close()


def command_latencies(ctx: Context, commands: int) -> list[float]:
    from multiros.hardware.process import FakeRobotProcess

    robot = FakeRobotProcess("rx200", context=ctx, args=["--rate", "500", "--time-constant", "0.02"],
                             timeout_sec=60.0)
    try:
        env = uniros.make(REAL_ID, context=ctx, startup_timeout=30.0)
        try:
            env.reset(seed=0)
            core = env.unwrapped
            link, arm = core.link, core.arm_controller
            joints = list(core.arm_joints)
            out = []
            for k in range(commands):
                before = link.states.sample(joints)
                target = before.position.copy()
                target[0] += 0.02 if k % 2 == 0 else -0.02
                t0 = time.monotonic()
                link.publish_trajectory(arm, joints, target, 0.05)
                last = t0
                while True:  # the first joint_states message after t0 that shows the waist moving
                    s = link.states.wait_for(joints, last, 2.0)
                    if s is None or s.received <= last or time.monotonic() - t0 > 2.0:
                        raise RuntimeError("the fake robot did not move within 2 s")
                    if abs(s.position[0] - before.position[0]) > 1e-6:
                        out.append(s.received - t0)
                        break
                    last = s.received
                time.sleep(0.02)  # let it settle before the next command
            return out
        finally:
            env.close()
    finally:
        robot.stop()


def conversion() -> None:
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState as RclpyJointState

    from multiros.ros.interfaces import deserialize_message as our_deserialize
    from multiros.ros.interfaces import get_message
    from multiros.ros.interfaces import serialize_message as our_serialize

    JointState = get_message("sensor_msgs/msg/JointState")
    ours = JointState(name=[f"j{i}" for i in range(6)], position=[0.1 * i for i in range(6)],
                      velocity=[0.0] * 6, effort=[0.0] * 6)
    theirs = deserialize_message(our_serialize(ours), RclpyJointState)

    def copy_to_rclpy(m):
        r = RclpyJointState()
        r.header.stamp.sec, r.header.stamp.nanosec = m.header.stamp.sec, m.header.stamp.nanosec
        r.header.frame_id = m.header.frame_id
        r.name, r.position, r.velocity, r.effort = list(m.name), m.position, m.velocity, m.effort
        return r

    def copy_from_rclpy(r):
        m = JointState()
        m.header.stamp.sec, m.header.stamp.nanosec = r.header.stamp.sec, r.header.stamp.nanosec
        m.header.frame_id = r.header.frame_id
        m.name, m.position = list(r.name), list(r.position)
        m.velocity, m.effort = list(r.velocity), list(r.effort)
        return m

    cases = [
        ("topic out: our CDR (publish_raw)", our_serialize, ours),
        ("uniros -> rclpy by CDR", lambda m: deserialize_message(our_serialize(m), RclpyJointState), ours),
        ("uniros -> rclpy, field copy (one type)", copy_to_rclpy, ours),
        ("rclpy -> uniros by CDR", lambda r: our_deserialize(serialize_message(r), JointState, trailing="ignore"),
         theirs),
        ("rclpy -> uniros, field copy (one type)", copy_from_rclpy, theirs),
    ]
    print("\nconversion of a 6-joint JointState (us per message):")
    for label, fn, arg in cases:
        n = 5000
        t0 = time.perf_counter()
        for _ in range(n):
            fn(arg)
        print(f"  {label:42s} {(time.perf_counter() - t0) / n * 1e6:7.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=200, help="env steps per mode and round")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--commands", type=int, default=100)
    parser.add_argument("--conversion", action="store_true")
    opts = parser.parse_args()

    print(f"{ENV_ID}: env steps/s, {opts.rounds} interleaved rounds of {opts.steps} steps (median; per-round ratio)")
    rates = step_rates(opts.steps, opts.rounds, {
        "composed (inproc)": {},
        "process over Zenoh": {"sim_mode": "process", "transport": "zenoh"},
        "process over rclpy/Fast DDS": {"sim_mode": "process", "transport": "rclpy"},
    })
    base = rates["composed (inproc)"]
    for label, values in rates.items():
        ratio = statistics.median(v / b for v, b in zip(values, base))
        print(f"  {label:30s} {statistics.median(values):8.0f} steps/s  ({ratio:.2f}x composed)")
    zen, ros = rates["process over Zenoh"], rates["process over rclpy/Fast DDS"]
    print(f"  rclpy / Zenoh (process mode): {statistics.median(r / z for r, z in zip(ros, zen)):.2f}x")

    print(f"\n{REAL_ID} against uniros-fake-robot: command-to-state latency ({opts.commands} commands)")
    for label, make_ctx in (("Zenoh", private_context), ("rclpy/Fast DDS", lambda: Context(transport="rclpy").init())):
        ctx = make_ctx()
        try:
            lat = sorted(command_latencies(ctx, opts.commands))
        finally:
            ctx.try_shutdown()
        p90 = lat[int(0.9 * (len(lat) - 1))]
        print(f"  {label:16s} median {statistics.median(lat) * 1e3:6.2f} ms   p90 {p90 * 1e3:6.2f} ms")
    if opts.conversion:
        conversion()


if __name__ == "__main__":
    main()
