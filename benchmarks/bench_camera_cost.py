"""What a camera costs an env step: a composed RX200 stepped in lockstep (StepRobot, 10 x 4 ms physics
steps with a position command, as the tasks step) with and without a camera image per step.

Variants, measured side by side in one run: no camera; the render camera read directly by the
composed client (``SimulationConnection.read_camera``: no messages) at 84 x 84 and at 480 x 640,
RGB and RGB + depth; and the same camera published on its Image topic (640 x 480) to a subscriber
in the same process. Offscreen rendering: ``MUJOCO_GL=egl`` (set when no display exists).

    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_camera_cost.py            # 100 steps per variant
    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_camera_cost.py --steps 300 --repeats 3

Software GL (Mesa llvmpipe, what EGL gives a machine without a GPU) spends most of a frame on the
shadow map and multisampling, whatever the image size; a GPU renders these images in about a
millisecond.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

from multiros.ros.interfaces import get_message  # noqa: E402
from multiros.sim import launch  # noqa: E402

CAMERA = "rx200/render_camera"
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]


def run(conn, steps: int, read: dict | None) -> float:
    """Env steps per second over ``steps`` steps, each a StepRobot plus (optionally) one camera read."""
    client = conn.client
    rng = np.random.default_rng(0)
    targets = rng.uniform(-0.4, 0.4, size=(steps, len(ARM)))
    start = time.perf_counter()
    for q in targets:
        client.step_robot("rx200", {"arm_position_controller": q}, steps=10, frames=["rx200/ee_gripper_link"])
        if read is not None:
            conn.read_camera(CAMERA, **read)
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=2, help="rounds over all variants; the best of each is kept")
    args = parser.parse_args()
    conn = launch.connect("composed", timestep=0.004)
    try:
        conn.client.spawn_entity("rx200", uri="package://rx200_description/urdf/rx200.urdf.xacro?__controllers="
                                 "joint_state_broadcaster,arm_position_controller,gripper_controller")
        variants = {
            "no camera": None,
            "rgb 84x84 (read)": {"width": 84, "height": 84},
            "rgb 480x640 (read)": {"width": 640, "height": 480},
            "rgb+depth 84x84 (read)": {"width": 84, "height": 84, "depth": True},
            "rgb+depth 480x640 (read)": {"width": 640, "height": 480, "depth": True},
        }
        conn.read_camera(CAMERA, width=84, height=84)  # create the GL context outside the timings
        best: dict[str, float] = {}
        Image = get_message("sensor_msgs/msg/Image")
        for _ in range(args.repeats):
            for name, read in variants.items():
                best[name] = max(best.get(name, 0.0), run(conn, args.steps, read))
            received = []
            sub = conn.node.create_subscription(Image, "/rx200/render_camera/image_raw", received.append, 2)
            rate = run(conn, args.steps, None)  # the node renders and publishes after each step
            conn.node.destroy_subscription(sub)
            best["rgb 480x640 (topic)"] = max(best.get("rgb 480x640 (topic)", 0.0), rate)
        base = best["no camera"]
        print(f"composed RX200, StepRobot 10 x 4 ms, {args.steps} steps, best of {args.repeats}")
        print(f"{'variant':28} {'steps/s':>9} {'x no camera':>12} {'ms/step extra':>14}")
        for name, rate in best.items():
            extra = 1000.0 / rate - 1000.0 / base
            print(f"{name:28} {rate:9.0f} {rate / base:12.2f} {extra:14.2f}")
    finally:
        conn.close()


if __name__ == "__main__":
    main()
