"""What a camera costs an env step, measured side by side in one run.

Two parts:

1. ``node``: a composed RX200 stepped in lockstep (StepRobot, 10 x 4 ms physics steps with a
   position command, as the tasks step) with and without a camera image per step: the render
   camera read directly by the composed client (``SimulationConnection.read_camera``: no messages)
   at 84 x 84 and at 480 x 640, RGB and RGB + depth; and the same camera published on its Image
   topic (640 x 480) to a subscriber in the same process.
2. ``envs``: whole env steps (``env.step``: the task, the step call, the observation) of registered
   IDs made with ``uniros.make``: no camera, then camera observations (``rgb_obs_only``,
   ``rgb_plus_depth_plus_normal_obs``) at 84 x 84 and 480 x 640, in the fast rendering of camera
   sensors (no shadows, reflections or multisampling: the default) and in full quality (the node's
   ``cameras.fast = False``, for comparison only).

Offscreen rendering: ``MUJOCO_GL=egl`` (set when no display exists).

    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_camera_cost.py            # both parts, 100 steps per variant
    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_camera_cost.py --parts envs --ids VX300SPnPGoalSim-v0

Software GL (Mesa llvmpipe, what EGL gives a machine without a GPU) spends most of a full-quality
frame on the shadow map and multisampling, whatever the image size; a GPU renders these images in
about a millisecond.
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


ENV_VARIANTS: dict[str, dict | None] = {
    "no camera": None,
    "rgb 84x84": {"rgb_obs_only": True, "image_width": 84, "image_height": 84},
    "rgb 84x84 full quality": {"rgb_obs_only": True, "image_width": 84, "image_height": 84, "_full": True},
    "rgb+depth+state 84x84": {"rgb_plus_depth_plus_normal_obs": True, "image_width": 84, "image_height": 84},
    "rgb 480x640": {"rgb_obs_only": True, "image_width": 640, "image_height": 480},
    "rgb 480x640 full quality": {"rgb_obs_only": True, "image_width": 640, "image_height": 480, "_full": True},
    "rgb+depth+state 480x640": {"rgb_plus_depth_plus_normal_obs": True, "image_width": 640, "image_height": 480},
}


def env_rate(env_id: str, steps: int, options: dict | None) -> float:
    """Env steps per second of ``env_id`` with camera ``options`` (after a reset and a warm-up step)."""
    import uniros

    kwargs = {k: v for k, v in (options or {}).items() if not k.startswith("_")}
    env = uniros.make(env_id, **kwargs)
    try:
        if options and options.get("_full"):
            env.unwrapped.sim_connection.sim_node.cameras.fast = False  # a benchmark may look inside
        env.reset(seed=0)
        env.action_space.seed(0)
        actions = [env.action_space.sample() for _ in range(steps)]
        env.step(actions[0])
        start = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        return steps / (time.perf_counter() - start)
    finally:
        env.close()


def run_envs(ids: list[str], steps: int, repeats: int) -> None:
    for env_id in ids:
        best: dict[str, float] = {}
        for _ in range(repeats):
            for name, options in ENV_VARIANTS.items():
                best[name] = max(best.get(name, 0.0), env_rate(env_id, steps, options))
        base = best["no camera"]
        print(f"\n{env_id}: env.step, {steps} steps, best of {repeats}")
        print(f"{'variant':28} {'steps/s':>9} {'x no camera':>12} {'ms/step extra':>14}")
        for name, rate in best.items():
            print(f"{name:28} {rate:9.1f} {rate / base:12.2f} {1000.0 / rate - 1000.0 / base:14.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=2, help="rounds over all variants; the best of each is kept")
    parser.add_argument("--parts", nargs="+", default=["node", "envs"], choices=["node", "envs"])
    parser.add_argument("--ids", nargs="+", default=["RX200ReacherSim-v0", "VX300SPnPGoalSim-v0"],
                        help="env IDs of the envs part")
    args = parser.parse_args()
    if "node" in args.parts:
        run_node(args.steps, args.repeats)
    if "envs" in args.parts:
        run_envs(args.ids, args.steps, args.repeats)


def run_node(steps: int, repeats: int) -> None:
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
        for _ in range(repeats):
            for name, read in variants.items():
                best[name] = max(best.get(name, 0.0), run(conn, steps, read))
            received = []
            sub = conn.node.create_subscription(Image, "/rx200/render_camera/image_raw", received.append, 2)
            rate = run(conn, steps, None)  # the node renders and publishes after each step
            conn.node.destroy_subscription(sub)
            best["rgb 480x640 (topic)"] = max(best.get("rgb 480x640 (topic)", 0.0), rate)
        base = best["no camera"]
        print(f"composed RX200, StepRobot 10 x 4 ms, {steps} steps, best of {repeats}")
        print(f"{'variant':28} {'steps/s':>9} {'x no camera':>12} {'ms/step extra':>14}")
        for name, rate in best.items():
            extra = 1000.0 / rate - 1000.0 / base
            print(f"{name:28} {rate:9.0f} {rate / base:12.2f} {extra:14.2f}")
    finally:
        conn.close()


if __name__ == "__main__":
    main()
