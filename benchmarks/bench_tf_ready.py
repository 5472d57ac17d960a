"""How soon does a tf2 listener resolve every link and camera frame of the simulation node's robot
from ``world``? Paused and playing, for a listener that is there when the robot appears and for one
that joins later (rviz2 started afterwards).

A node holds the RX200 with its Zed2 (its launched robot, as ``uniros-sim --robot`` spawns it); a
user's node in its own Zenoh session subscribes ``/tf`` and ``/tf_static`` (transient local) and
walks the tree. Printed: seconds from the robot's spawn (or from the listener's start) until every
link of ``robot_description`` and every camera frame resolves, and the doubled prefixes seen. A listener
"starting now" starts right after the spawn; one "starting 2 s later" gets only the latched
``/tf_static`` and what the node publishes from then on (paused: its 4 Hz heartbeat).

    MUJOCO_GL=egl .venv/bin/python benchmarks/bench_tf_ready.py

Goal (issue 35): within 1 s of start, paused or playing; no doubled prefix.
"""

from __future__ import annotations

import socket
import time
import xml.etree.ElementTree as ET

from multiros.ros import Context, Node
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_message
from multiros.ros.qos import DurabilityPolicy, QoSProfile
from multiros.sim.node import SimulationNode, SimulationState

TFMessage = get_message("tf2_msgs/msg/TFMessage")
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
RX200_ZED2 = "package://rx200_description/urdf/rx200.urdf.xacro"


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


class Tree:
    """The latest transform of each child frame, from /tf and /tf_static."""

    def __init__(self, node: Node) -> None:
        self.parents: dict[str, str] = {}
        node.create_subscription(TFMessage, "/tf", self._take, 100)
        node.create_subscription(TFMessage, "/tf_static", self._take, LATCHED)

    def _take(self, msg) -> None:
        for tf in msg.transforms:
            self.parents[tf.child_frame_id] = tf.header.frame_id

    def resolves(self, frame: str) -> bool:
        seen = set()
        while frame != "world":
            if frame in seen or frame not in self.parents:
                return False
            seen.add(frame)
            frame = self.parents[frame]
        return True


def time_to_tree(user_ctx: Context, frames: list[str], name: str) -> tuple[float, int]:
    """Seconds from now until every frame resolves (a listener started now), and doubled prefixes."""
    node = Node(name, context=user_ctx)
    executor = SingleThreadedExecutor(context=user_ctx)
    executor.add_node(node)
    start = time.monotonic()
    tree = Tree(node)
    try:
        while not all(tree.resolves(f) for f in frames):
            if time.monotonic() - start > 30.0:
                return float("inf"), -1
            executor.spin_once(timeout_sec=0.01)
        elapsed = time.monotonic() - start
        doubled = sum(1 for f in tree.parents if f.startswith("rx200/rx200/") or "//" in f)
    finally:
        executor.remove_node(node)
        node.destroy_node()
    return elapsed, doubled


def main() -> None:
    endpoint = _free_endpoint()
    sim_ctx = Context(transport="zenoh", env={}, router_endpoint=endpoint).init()
    user_ctx = Context(transport="zenoh", env={}, router_endpoint=endpoint).init()
    node = SimulationNode("mujoco_sim", context=sim_ctx)
    try:
        with node.lock:
            node.world.spawn("rx200", RX200_ZED2, xacro_args={"robot_name": "rx200", "use_zed2": "true"})
            node._attach_robot("rx200")
        links = [link.get("name") for link in ET.fromstring(node.world.entity("rx200").description).findall("link")]
        frames = [link for link in links if link != "world"] + [spec.frame_id for spec in node.camera_specs()]
        print(f"RX200 + Zed2: {len(links)} links ('world' is the world frame), {len(frames) - len(links) + 1} "
              f"camera frames; a listener in its own Zenoh session")
        print(f"{'state':8s} {'listener':22s} {'seconds':>8s} {'doubled':>8s}")
        for state in ("paused", "playing"):
            if state == "playing":
                node._set_state(SimulationState.STATE_PLAYING)
            for label in ("starts now", "starts 2 s later"):
                if label != "starts now":
                    time.sleep(2.0)  # the listener comes later: only the latched and heartbeat messages reach it
                seconds, doubled = time_to_tree(user_ctx, frames, f"listener_{state}_{label.split()[1]}")
                print(f"{state:8s} {label:22s} {seconds:8.3f} {doubled:8d}", flush=True)
    finally:
        node.destroy_node()
        for ctx in (sim_ctx, user_ctx):
            ctx.try_shutdown()


if __name__ == "__main__":
    main()
