"""The node side of ``uniros_interfaces/srv/RenderCamera`` and ``visualization_msgs/Marker`` display:
images of the world as ``sensor_msgs/Image`` messages, markers drawn into them."""

from __future__ import annotations

from typing import Any

import numpy as np

from multiros.sim import convert
from multiros.sim.errors import RenderError
from multiros.sim.render import Renderer

__all__ = ["Renderer", "apply_marker", "render_image_msgs"]

_MAX_PIXELS = 4096 * 4096
# visualization_msgs/Marker types and actions this node draws.
_KINDS = {0: "arrow", 1: "box", 2: "sphere", 3: "cylinder"}
_ADD, _DELETE, _DELETEALL = 0, 2, 3


def render_image_msgs(renderer: Renderer, request: Any, response: Any, sim_time: float) -> None:
    """Fill ``response.image`` for a ``RenderCamera`` request.

    Raises:
        RenderError: the image size is out of range or rendering failed.
    """
    width = int(request.width) or 640
    height = int(request.height) or 480
    if width * height > _MAX_PIXELS:
        raise RenderError(f"image {width}x{height} is larger than {_MAX_PIXELS} pixels")
    camera = request.camera or None
    image = renderer.render(camera, width=width, height=height, depth=bool(request.depth))
    msg = response.image
    msg.header.stamp = convert.time_msg(sim_time)
    msg.header.frame_id = request.camera or "default_camera"
    msg.height, msg.width = int(image.shape[0]), int(image.shape[1])
    if request.depth:
        data = np.ascontiguousarray(image, dtype=np.float32)
        msg.encoding, msg.step = "32FC1", 4 * msg.width
    else:
        data = np.ascontiguousarray(image, dtype=np.uint8)
        msg.encoding, msg.step = "rgb8", 3 * msg.width
    msg.is_bigendian = 0
    msg.data = data.tobytes()


def image_to_array(msg: Any) -> np.ndarray:
    """A ``sensor_msgs/Image`` (``rgb8`` or ``32FC1``) as an array (HxWx3 uint8 or HxW float32)."""
    if msg.encoding == "rgb8":
        return np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)
    if msg.encoding == "32FC1":
        return np.frombuffer(bytes(msg.data), dtype=np.float32).reshape(msg.height, msg.width)
    raise ValueError(f"image encoding {msg.encoding!r} is not rgb8 or 32FC1")


def apply_marker(renderer: Renderer, marker: Any) -> None:
    """Show, move or delete a ``visualization_msgs/Marker`` in rendered images (world frame only)."""
    key = f"{marker.ns}/{marker.id}"
    if marker.action == _DELETEALL:
        renderer.delete_marker(None)
        return
    if marker.action == _DELETE:
        renderer.delete_marker(key)
        return
    kind = _KINDS.get(int(marker.type))
    if kind is None or marker.header.frame_id not in ("", "world"):
        return
    position, quat = convert.pose_to_arrays(marker.pose)
    s, c = marker.scale, marker.color
    # ROS scales are full extents (diameter, edge length); MuJoCo sizes are radii and half-lengths.
    half = (s.x / 2, s.y / 2, s.z / 2)
    direction = None
    if kind == "arrow":
        w, x, y, z = quat / (np.linalg.norm(quat) or 1.0)
        direction = s.x * np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])
        half = (s.y / 2, s.y / 2, s.x)
    renderer.show_marker(key, kind, position, size=half, rgba=(c.r, c.g, c.b, c.a or 1.0), direction=direction)
