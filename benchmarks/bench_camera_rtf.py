"""Do subscribed cameras slow a playing simulation? Its real-time factor without and with image
subscriptions, side by side in one run.

A node plays the RX200 with its Zed2 in real time (``--play``'s mode, target real-time factor 1.0,
and ``--as-fast-as-possible``: target <= 0, so the figure is the physics throughput). A user's node
on the same graph (its own Zenoh session through the node's router, as rviz2 would be; or
``--transport inproc``) subscribes, phase by phase:

* nothing;
* the default camera's image (``/rx200/render_camera/image_raw``, 640 x 480 RGB);
* every Zed2 image (left RGB, depth, right RGB; 640 x 360 each) and their camera_info;

first as the node renders them now (``stream``: on the camera thread, at most ``camera_rate`` images
a second), then as it did before (``inline``: every subscribed camera rendered and published inside
the physics loop after each chunk, emulated here by the same code called from the loop). Each
phase prints the real-time factor (simulated seconds per wall second), the images received per
second and the ratio to the phase without subscribers.

    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_camera_rtf.py                  # 4 s a phase
    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_camera_rtf.py --seconds 8 --as-fast-as-possible

Goal (issue 35): with an image subscription, the real-time factor within 10 % of without.
"""

from __future__ import annotations

import argparse
import os
import socket
import threading
import time

os.environ.setdefault("MUJOCO_GL", "egl")

from multiros.ros import Context, Node  # noqa: E402
from multiros.ros.executors import SingleThreadedExecutor  # noqa: E402
from multiros.ros.interfaces import get_message  # noqa: E402
from multiros.sim.cameras import fill_camera_info, fill_image  # noqa: E402
from multiros.sim.node import SimulationNode, SimulationState  # noqa: E402

Image = get_message("sensor_msgs/msg/Image")
CameraInfo = get_message("sensor_msgs/msg/CameraInfo")
RX200_ZED2 = "package://rx200_description/urdf/rx200.urdf.xacro"
ZED = "/rx200/zed2/zed_node"
PHASES: dict[str, list[tuple[type, str]]] = {
    "nothing subscribed": [],
    "default camera image": [(Image, "/rx200/render_camera/image_raw")],
    "Zed2 left + depth + right": [(Image, f"{ZED}/rgb/image_rect_color"), (Image, f"{ZED}/depth/depth_registered"),
                                  (Image, f"{ZED}/right/image_rect_color"), (CameraInfo, f"{ZED}/rgb/camera_info"),
                                  (CameraInfo, f"{ZED}/right/camera_info")],
}


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def render_inline(node: SimulationNode) -> None:
    """What the node did before: each subscribed camera rendered and published in the physics loop
    (the lock held), after every chunk."""
    hub = node.cameras
    stamp = float(node.world.time)
    for entry in hub.entries():
        spec = entry.spec
        kinds = [(False, entry.rgb, entry.rgb_info)] + ([(True, entry.depth, entry.depth_info)] if spec.depth else [])
        for depth, image_pub, info_pub in kinds:
            if image_pub.has_subscribers():
                image = hub._image(spec.camera, spec.width, spec.height, depth)
                image_pub.publish(fill_image(Image(), image, stamp, spec.frame_id))
            if info_pub.has_subscribers():
                info_pub.publish(fill_camera_info(CameraInfo(), hub.intrinsics(spec.camera, spec.width, spec.height),
                                                  stamp, spec.frame_id, spec.baseline))


def measure(node: SimulationNode, user: Node, topics: list[tuple[type, str]], seconds: float) -> tuple[float, float]:
    """(real-time factor, images received per second) over ``seconds`` after a warm-up."""
    received = [0]

    def count(msg) -> None:
        received[0] += isinstance(msg, Image)

    subs = [user.create_subscription(kind, topic, count, 2) for kind, topic in topics]
    try:
        # Warm-up: subscriptions matched, renderers made (GL contexts take seconds in software GL),
        # until every image topic has delivered one image (at most 60 s), and 1 s at least.
        images = sum(kind is Image for kind, _ in topics)
        start = time.monotonic()
        while time.monotonic() - start < 1.0 or (received[0] < images and time.monotonic() - start < 60.0):
            time.sleep(0.05)
        sim0, wall0, got0 = node.world.time, time.monotonic(), received[0]
        time.sleep(seconds)
        sim1, wall1, got1 = node.world.time, time.monotonic(), received[0]
    finally:
        for sub in subs:
            user.destroy_subscription(sub)
    return (sim1 - sim0) / (wall1 - wall0), (got1 - got0) / (wall1 - wall0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=4.0, help="measured seconds per phase")
    parser.add_argument("--transport", choices=["zenoh", "inproc"], default="zenoh")
    parser.add_argument("--as-fast-as-possible", action="store_true", help="target real-time factor <= 0")
    parser.add_argument("--camera-rate", type=float, default=15.0)
    opts = parser.parse_args()

    if opts.transport == "inproc":
        sim_ctx = user_ctx = Context(transport="inproc").init()
    else:
        endpoint = _free_endpoint()
        sim_ctx = Context(transport="zenoh", env={}, router_endpoint=endpoint).init()
        user_ctx = Context(transport="zenoh", env={}, router_endpoint=endpoint).init()
    target = 0.0 if opts.as_fast_as_possible else 1.0
    node = SimulationNode("mujoco_sim", context=sim_ctx, real_time_factor=target, camera_rate=opts.camera_rate)
    with node.lock:
        node.world.spawn("rx200", RX200_ZED2, xacro_args={"robot_name": "rx200", "use_zed2": "true"})
        node._attach_robot("rx200")
    user = Node("viewer", context=user_ctx)
    executor = SingleThreadedExecutor(context=user_ctx)
    executor.add_node(user)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    node._set_state(SimulationState.STATE_PLAYING)
    print(f"RX200 + Zed2 playing, target real-time factor {target if target > 0 else 'as fast as possible'}, "
          f"transport {opts.transport}, camera_rate {opts.camera_rate} Hz, {opts.seconds} s a phase")
    print(f"{'mode':8s} {'subscribed':28s} {'RTF':>6s} {'images/s':>9s} {'vs nothing':>10s}")
    try:
        for mode in ("stream", "inline"):
            if mode == "inline":
                node.camera_stream.close()
                node._runner.on_chunk = lambda world: (node._after_realtime_chunk(world), render_inline(node))
            base = None
            for label, topics in PHASES.items():
                rtf, images = measure(node, user, topics, opts.seconds)
                base = rtf if base is None else base
                print(f"{mode:8s} {label:28s} {rtf:6.3f} {images:9.1f} {rtf / base:10.2f}", flush=True)
    finally:
        stop.set()
        spinner.join(timeout=5.0)
        node.destroy_node()
        for ctx in {sim_ctx, user_ctx}:
            ctx.try_shutdown()


if __name__ == "__main__":
    main()
