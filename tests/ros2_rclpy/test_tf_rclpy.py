"""TF of ``uniros-sim --transport rclpy`` as a plain rclpy user (no uniros import) sees it over Fast
DDS: /tf_static (transient local) and /tf, paused, give every link of ``/rx200/robot_description``
and every Zed2 camera frame from ``world``, by the URDF's names (no doubled prefix); the right
camera's camera_info carries its baseline and a frame of the tree."""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ET

import pytest

_NEEDED = ("rclpy", "tf2_msgs", "simulation_interfaces", "uniros_interfaces")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy and the interface packages .ci/rclpy builds (run by .ci/rclpy)", allow_module_level=True)

from plain_ros import PlainPeer, wait_until  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy_harness import uniros_script  # noqa: E402
from sensor_msgs.msg import CameraInfo  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

pytestmark = pytest.mark.slow

RX200_ZED2 = "rx200=package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200&use_zed2=true"
ZED = "/rx200/zed2/zed_node"
LATCHED = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def test_a_plain_rclpy_listener_resolves_every_link_and_camera_frame_from_world(program) -> None:
    sim = program([uniros_script("uniros-sim"), "--transport", "rclpy", "--robot", RX200_ZED2, "--log-level", "INFO"],
                  "uniros-sim")
    with PlainPeer("plain_tf_listener") as peer:
        sim.wait_ready("simulation node /mujoco_sim ready")
        parents: dict[str, str] = {}

        def take(msg) -> None:
            for tf in msg.transforms:
                parents[tf.child_frame_id] = tf.header.frame_id

        static_subscription = peer.node.create_subscription(TFMessage, "/tf_static", take, LATCHED)
        dynamic_subscription = peer.node.create_subscription(TFMessage, "/tf", take, 100)
        descriptions: list[str] = []
        description_subscription = peer.node.create_subscription(
            String, "/rx200/robot_description", lambda m: descriptions.append(m.data), LATCHED)
        infos, _ = peer.collect(CameraInfo, f"{ZED}/right/camera_info")

        def resolves(frame: str) -> bool:
            seen = set()
            while frame != "world":
                if frame in seen or frame not in parents:
                    return False
                seen.add(frame)
                frame = parents[frame]
            return True

        wait_until(lambda: descriptions, 30, "robot_description")
        links = [link.get("name") for link in ET.fromstring(descriptions[-1]).findall("link")]
        cameras = ["rx200/render_camera_optical_frame", "rx200/zed2_left_camera_optical_frame",
                   "rx200/zed2_right_camera_optical_frame"]
        wanted = [link for link in links if link != "world"] + cameras
        wait_until(lambda: all(resolves(f) for f in wanted), 30, "every link and camera frame from world (paused)")
        assert not any(f.startswith(("rx200/rx200/", "rx200/world")) for f in parents), sorted(parents)
        assert set(parents) == set(wanted)

        wait_until(lambda: infos, 30, "the right camera's camera_info")
        info = infos[-1]
        assert info.header.frame_id == "rx200/zed2_right_camera_optical_frame"
        assert info.p[3] == pytest.approx(-info.p[0] * 0.12)
        for sub in (static_subscription, dynamic_subscription, description_subscription):
            peer.node.destroy_subscription(sub)
