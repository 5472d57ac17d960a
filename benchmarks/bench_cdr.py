"""CDR micro-benchmark: serialize + deserialize a 6-joint JointState, ours vs rosbags, in one run.

Also times building a StepRobot response (the message the sim node builds every lockstep env step).
Per-call times are means over batches of 200 calls; median and p99 are over batches, interleaved
between codecs so both see the same machine load.

    PYTHONPATH=. python benchmarks/bench_cdr.py [--batches 300]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from multiros.ros.interfaces import deserialize_message, get_message, get_service, serialize_message


def _batch_us(fn, calls: int) -> float:
    start = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - start) / calls * 1e6


def _stats(samples: list[float]) -> tuple[float, float]:
    arr = np.asarray(samples)
    return float(np.median(arr)), float(np.percentile(arr, 99))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=300)
    parser.add_argument("--calls", type=int, default=200)
    args = parser.parse_args(argv)

    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    names = [f"joint_{i}" for i in range(6)]
    values = [np.linspace(-1.0, 1.0, 6) * k for k in (1.0, 2.0, 3.0)]

    joint_state = get_message("sensor_msgs/msg/JointState")
    header, stamp = get_message("std_msgs/msg/Header"), get_message("builtin_interfaces/msg/Time")
    ours = joint_state(header=header(stamp=stamp(sec=12, nanosec=345), frame_id="base_link"),
                       name=names, position=values[0], velocity=values[1], effort=values[2])
    t = ts.types
    theirs = t["sensor_msgs/msg/JointState"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=12, nanosec=345),
                                        frame_id="base_link"),
        name=names, position=values[0], velocity=values[1], effort=values[2])
    data = serialize_message(ours)
    assert bytes(ts.serialize_cdr(theirs, "sensor_msgs/msg/JointState")) == data, "codecs disagree"

    step = get_service("uniros_interfaces/srv/StepRobot").Response
    result, pose = get_message("simulation_interfaces/msg/Result"), get_message("geometry_msgs/msg/Pose")
    position = np.zeros(6)

    cases = {
        "ours ser+deser": lambda: deserialize_message(serialize_message(ours), joint_state),
        "rosbags ser+deser": lambda: ts.deserialize_cdr(ts.serialize_cdr(theirs, "sensor_msgs/msg/JointState"),
                                                        "sensor_msgs/msg/JointState"),
        "ours serialize": lambda: serialize_message(ours),
        "ours deserialize": lambda: deserialize_message(data, joint_state),
        "StepRobot response build": lambda: step(
            result=result(result=1), sim_time=stamp(sec=1, nanosec=2),
            joint_state=joint_state(name=names, position=position, velocity=position),
            frame_poses=[pose()]),
    }
    for fn in cases.values():  # warm up: generate codecs, fill caches
        _batch_us(fn, 50)
    samples: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(args.batches):
        for key, fn in cases.items():
            samples[key].append(_batch_us(fn, args.calls))

    print(f"JointState, 6 joints, {len(data)} bytes; {args.batches} batches x {args.calls} calls")
    print(f"{'case':28s} {'median us':>10s} {'p99 us':>10s}")
    for key, vals in samples.items():
        med, p99 = _stats(vals)
        print(f"{key:28s} {med:10.2f} {p99:10.2f}")
    ours_med = _stats(samples["ours ser+deser"])[0]
    theirs_med = _stats(samples["rosbags ser+deser"])[0]
    print(f"ratio rosbags/ours (ser+deser median): {theirs_med / ours_med:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
