"""``uniros sysid`` end to end: a bag recorded from the stand-in robot with a known gap, fitted.

1. ``uniros-fake-robot --arm config/arms/rx200.yaml --gap hard`` (command latency 0.1 s, lag 0.25 s,
   backlash, droop, noise, dropped, late and jittered joint_states; ``--gap none --time-constant T``
   for the lag alone) on a private Zenoh router on a free loopback port (never 7447);
2. for ``--seconds`` (60) a seeded, varied command sequence on its arm controller's
   ``joint_trajectory`` topic (steps and linear ramps of every size, some at the joints' velocity
   limits), while a small recorder (uniros' own ROS layer) records ``/rx200/joint_states`` and the
   commands as the robot receives them, written into a rosbag with rosbags (sqlite3 or MCAP);
3. ``uniros sysid BAG --arm config/arms/rx200.yaml`` (its table), then the recovered latency and
   lag against the known ones, and their relative error (the goal: within 20 %).

    python benchmarks/bench_sysid.py [--seconds 60] [--gap hard] [--time-constant 0.25] [--storage mcap]
                                     [--keep DIR]

The fake robot applies a command at its next control update (100 Hz), so the latency it shows is
the profile's plus about half an update period and the transport's milliseconds. The robot is
stopped by PID.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "config" / "arms" / "rx200.yaml"
STATES, TRAJ = "/rx200/joint_states", "/rx200/arm_controller/joint_trajectory"
JOINTS = ("waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate")
INIT = np.array([0.0, -0.64, 0.8, 0.43, 0.0])  # reach.init_joint_pos: clear of the limits both ways


class Recorder:
    """Records joint states and trajectories as CDR (rosbags' serialiser), stamped on receipt."""

    def __init__(self, ctx: Any, store: Any) -> None:
        from multiros.ros import Node
        from multiros.ros.executors import SingleThreadedExecutor
        from multiros.ros.interfaces import get_message

        self.store = store
        self.rows: list[tuple[str, str, int, bytes]] = []
        self.counts: dict[str, int] = {STATES: 0, TRAJ: 0}
        self._lock = threading.Lock()
        self.node = Node(f"sysid_recorder_{os.getpid()}", context=ctx)
        self.state_sub = self.node.create_subscription(get_message("sensor_msgs/msg/JointState"), STATES,
                                                       self._on_state, 100)
        self.cmd_sub = self.node.create_subscription(get_message("trajectory_msgs/msg/JointTrajectory"), TRAJ,
                                                     self._on_trajectory, 100)
        self._executor = SingleThreadedExecutor(context=ctx)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._executor.spin, daemon=True)
        self._thread.start()

    def _time(self, stamp: Any) -> Any:
        return self.store.types["builtin_interfaces/msg/Time"](sec=int(stamp.sec), nanosec=int(stamp.nanosec))

    def _header(self, header: Any) -> Any:
        return self.store.types["std_msgs/msg/Header"](stamp=self._time(header.stamp), frame_id=str(header.frame_id))

    def _add(self, topic: str, msgtype: str, msg: Any) -> None:
        now = time.time_ns()
        data = bytes(self.store.serialize_cdr(msg, msgtype))
        with self._lock:
            self.rows.append((topic, msgtype, now, data))
            self.counts[topic] += 1

    def _on_state(self, msg: Any) -> None:
        t = self.store.types
        f64 = lambda v: np.asarray(v, dtype=np.float64)  # noqa: E731
        self._add(STATES, "sensor_msgs/msg/JointState", t["sensor_msgs/msg/JointState"](
            header=self._header(msg.header), name=list(msg.name), position=f64(msg.position),
            velocity=f64(msg.velocity), effort=f64(msg.effort)))

    def _on_trajectory(self, msg: Any) -> None:
        t = self.store.types
        points = [t["trajectory_msgs/msg/JointTrajectoryPoint"](
            positions=np.asarray(p.positions, dtype=np.float64), velocities=np.asarray(p.velocities, dtype=np.float64),
            accelerations=np.zeros(0), effort=np.zeros(0),
            time_from_start=t["builtin_interfaces/msg/Duration"](sec=int(p.time_from_start.sec),
                                                                 nanosec=int(p.time_from_start.nanosec)))
            for p in msg.points]
        self._add(TRAJ, "trajectory_msgs/msg/JointTrajectory", t["trajectory_msgs/msg/JointTrajectory"](
            header=self._header(msg.header), joint_names=list(msg.joint_names), points=points))

    def count(self, topic: str) -> int:
        with self._lock:
            return self.counts[topic]

    def write(self, path: Path, storage: str) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        with self._lock:
            rows = sorted(self.rows, key=lambda r: r[2])
        with Writer(path, version=9, storage_plugin=plugin) as writer:
            conns: dict[str, Any] = {}
            for topic, msgtype, stamp, data in rows:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=self.store)
                writer.write(conns[topic], stamp, data)

    def close(self) -> None:
        self._executor.shutdown()
        self._thread.join(timeout=2.0)
        self.node.destroy_node()


def drive(ctx: Any, seconds: float, seed: int) -> int:
    """Publish the command sequence for ``seconds``: a new target every 0.5-1.8 s, most joints moving
    each time by up to 0.45 rad, a quarter of them as linear ramps of 0.2-0.6 s. Returns how many."""
    from multiros.ros import Node
    from multiros.ros.interfaces import get_message

    JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
    Point = get_message("trajectory_msgs/msg/JointTrajectoryPoint")
    Duration = get_message("builtin_interfaces/msg/Duration")
    rng = np.random.default_rng(seed)
    node = Node(f"sysid_driver_{os.getpid()}", context=ctx)
    try:
        pub = node.create_publisher(JointTrajectory, TRAJ, 10)
        if not ctx.wait_for(lambda: pub.get_subscription_count() >= 2, 30.0):  # the robot and the recorder
            raise RuntimeError(f"nobody subscribed to {TRAJ} within 30 s")
        target = INIT.copy()
        sent, start = 0, time.monotonic()
        next_at = start
        while next_at - start < seconds:
            move = rng.random(len(JOINTS)) < 0.7
            target = np.where(move, INIT + rng.uniform(-0.45, 0.45, len(JOINTS)), target)
            ramp = float(rng.uniform(0.2, 0.6)) if rng.random() < 0.25 else 0.0
            point = Point(positions=target.astype(np.float64), velocities=np.zeros(0),
                          time_from_start=Duration(sec=0, nanosec=int(ramp * 1e9)))
            delay = next_at - time.monotonic()
            if delay > 0:
                time.sleep(delay)  # the drive's schedule, not a wait for anything to settle
            pub.publish(JointTrajectory(joint_names=list(JOINTS), points=[point]))
            sent += 1
            next_at += float(rng.uniform(0.5, 1.8))
        return sent
    finally:
        node.destroy_node()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="how long to drive and record (60)")
    parser.add_argument("--gap", default="hard", help="the fake robot's --gap profile (none, mild, hard)")
    parser.add_argument("--time-constant", type=float, default=None,
                        help="the fake robot's --time-constant (the lag when the profile sets none)")
    parser.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3")
    parser.add_argument("--seed", type=int, default=1, help="the command sequence's and the gap's seed")
    parser.add_argument("--keep", type=Path, help="keep the bag in this folder")
    args = parser.parse_args()

    from rosbags.typesys import Stores, get_typestore

    from multiros.hardware.gap import load_gap_profile
    from multiros.hardware.process import FakeRobotProcess
    from multiros.ros.processes import private_context
    from uniros.sysid import format_report
    from uniros.sysid_bag import default_topics, read_recording
    from uniros.sysid_fit import fit_recording

    profile = load_gap_profile(args.gap)
    known_tau = profile.time_constant or args.time_constant or 0.1
    known_latency = profile.latency
    robot_args = ["--arm", str(ARM), "--start", "init", "--gap", args.gap, "--gap-seed", str(args.seed),
                  "--log-level", "WARNING"]
    if args.time_constant is not None:
        robot_args += ["--time-constant", str(args.time_constant)]
    work = Path(tempfile.mkdtemp(prefix="uniros_sysid_"))
    store = get_typestore(Stores.ROS2_JAZZY)
    ctx = private_context()
    try:
        t0 = time.perf_counter()
        robot = FakeRobotProcess(None, context=ctx, args=robot_args, namespace="/rx200", module="uniros.fake_robot",
                                 timeout_sec=60.0, cwd=str(work))
        try:
            recorder = Recorder(ctx, store)
            try:
                if not ctx.wait_for(lambda: recorder.count(STATES) >= 10, 30.0):
                    raise RuntimeError(f"no joint states on {STATES} within 30 s")
                started = time.perf_counter()
                sent = drive(ctx, args.seconds, args.seed)
                seen = recorder.count(STATES)  # the last command's response: 1.5 s more of joint states
                ctx.wait_for(lambda: recorder.count(STATES) >= seen + 150, 10.0)
                recorded = time.perf_counter() - started
            finally:
                recorder.close()
        finally:
            robot.stop()
        bag = work / "rx200_sysid"
        recorder.write(bag, args.storage)
        t1 = time.perf_counter()
        rec, summary = read_recording(bag, joints=JOINTS, controller_joints=JOINTS,
                                      topics=default_topics("/rx200", "arm_controller", "/rx200/joint_states"))
        from rl_environments.arm import chain_of
        from rl_environments.arm_file import load_arm_file

        chain = chain_of(load_arm_file(ARM))
        limits = [float(chain.velocity_limits[list(chain.joint_names).index(j)]) for j in JOINTS]
        fit = fit_recording(rec, velocity_limits=limits)
        fit_s = time.perf_counter() - t1
        print(f"uniros-fake-robot --arm rx200.yaml --gap {args.gap} (seed {args.seed}): {sent} commands over "
              f"{recorded:.1f} s, {summary.states:,} joint states recorded ({args.storage}); set-up and recording "
              f"{t1 - t0:.0f} s, read and fit {fit_s:.1f} s")
        print(format_report(summary, fit))
        identified = [j for j in fit.joints if j.identified]
        taus = np.array([j.time_constant for j in identified])
        tau_err = np.abs(taus - known_tau) / known_tau
        print()
        print(f"{'':<24} {'known':>8} {'recovered':>10} {'rel. error':>11}")
        if known_latency > 0:
            lat_err = abs(fit.latency - known_latency) / known_latency
            print(f"{'latency s':<24} {known_latency:>8.3f} {fit.latency:>10.4f} {lat_err:>10.1%}")
        else:
            lat_err = math.nan
            print(f"{'latency s':<24} {known_latency:>8.3f} {fit.latency:>10.4f} {'(abs.)':>11}")
        for j, err in zip(identified, tau_err):
            print(f"{'lag s, ' + j.joint:<24} {known_tau:>8.3f} {j.time_constant:>10.4f} {err:>10.1%}")
        print(f"{'lag s, median':<24} {known_tau:>8.3f} {float(np.median(taus)):>10.4f} "
              f"{abs(float(np.median(taus)) - known_tau) / known_tau:>10.1%}")
        ok = (math.isnan(lat_err) or lat_err <= 0.2) and bool(np.all(tau_err <= 0.2))
        print(f"goal (latency and every joint's lag within 20 %): {'met' if ok else 'NOT met'}")
        if args.keep:
            shutil.copytree(bag, args.keep / bag.name, dirs_exist_ok=True)
            print(f"bag kept in {args.keep / bag.name}")
    finally:
        ctx.try_shutdown()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
