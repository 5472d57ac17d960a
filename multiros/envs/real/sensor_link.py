"""Sensors beside a real robot's joints, as their drivers publish them: camera images
(``sensor_msgs/Image``) and a tracked object's pose (``geometry_msgs/PoseStamped``).

Each topic keeps its newest valid message with the local monotonic time it arrived; every message
is checked first (sizes, encodings, finite numbers, the frame it is in) and a malformed one is
dropped and counted, with its reason kept for the error message. A value older than the caller's
limit is stale: :class:`StaleSensorError` (a :class:`~multiros.envs.real.errors.StaleStateError`), and
the env stops as it does for stale joint states. Nothing here imports the simulation.

Images: ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8`` and ``mono8`` become ``(H, W, 3)`` uint8 RGB; depth
``32FC1`` (metres, REP 118: NaN/inf kept for the caller to map) and ``16UC1`` (millimetres, 0 =
unknown: NaN) become ``(H, W)`` float32 metres. At most 4096 pixels a side.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar

import numpy as np

from multiros.envs.real.errors import StaleStateError
from multiros.ros.interfaces import get_message
from multiros.ros.qos import qos_profile_sensor_data

__all__ = ["ImageTopic", "LatestMessage", "PoseTopic", "StaleSensorError", "image_from_msg", "pose_from_msg"]

Image = get_message("sensor_msgs/msg/Image")
PoseStamped = get_message("geometry_msgs/msg/PoseStamped")

MAX_SIDE = 4096
MAX_POSITION = 100.0  # m: a tracked object farther than this from the frame's origin is a broken message
_RGB_ENCODINGS = {"rgb8": (3, [0, 1, 2]), "bgr8": (3, [2, 1, 0]), "rgba8": (4, [0, 1, 2]), "bgra8": (4, [2, 1, 0]),
                  "mono8": (1, [0, 0, 0])}

T = TypeVar("T")


class StaleSensorError(StaleStateError):
    """A sensor's messages stopped arriving (or only malformed ones arrive): the env stopped commanding."""


def image_from_msg(msg: Any, kind: str) -> tuple[np.ndarray | None, str | None]:
    """An Image message as ``(H, W, 3)`` uint8 RGB (``kind="rgb"``) or ``(H, W)`` float32 metres
    (``kind="depth"``), or ``(None, why it is unusable)``."""
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    encoding = str(msg.encoding).lower()
    if not (1 <= height <= MAX_SIDE and 1 <= width <= MAX_SIDE):
        return None, f"image size {width} x {height} is not within 1..{MAX_SIDE} a side"
    data = bytes(msg.data)
    if kind == "rgb":
        if encoding not in _RGB_ENCODINGS:
            return None, f"encoding {msg.encoding!r} is not an RGB encoding ({', '.join(_RGB_ENCODINGS)})"
        channels, order = _RGB_ENCODINGS[encoding]
        itemsize = 1
    else:
        if encoding not in ("32fc1", "16uc1"):
            return None, f"encoding {msg.encoding!r} is not a depth encoding (32FC1 metres, 16UC1 millimetres)"
        channels, order = 1, [0]
        itemsize = 4 if encoding == "32fc1" else 2
    row = width * channels * itemsize
    if step < row or step > 16 * row or len(data) < step * (height - 1) + row:
        return None, f"{len(data)} data bytes and step {step} do not hold {width} x {height} {msg.encoding} pixels"
    rows = np.frombuffer(data, dtype=np.uint8, count=step * (height - 1) + row)
    rows = np.lib.stride_tricks.as_strided(rows, (height, row), (step, 1))
    if kind == "rgb":
        pixels = rows.reshape(height, width, channels)
        return np.ascontiguousarray(pixels[:, :, order]), None
    big = bool(msg.is_bigendian)
    dtype = np.dtype((">" if big else "<") + ("f4" if itemsize == 4 else "u2"))
    values = np.ascontiguousarray(rows).view(dtype).reshape(height, width)
    if itemsize == 2:
        metres = values.astype(np.float32) / 1000.0
        metres[values == 0] = np.nan
        return metres, None
    return values.astype(np.float32), None


def pose_from_msg(msg: Any, frame_id: str | None) -> tuple[tuple[np.ndarray, np.ndarray] | None, str | None]:
    """A PoseStamped as ``(position (3,), orientation (w, x, y, z) unit)``, or ``(None, why not)``.
    ``frame_id``: the frame the pose must be in (``None``: any)."""
    if frame_id is not None and str(msg.header.frame_id).strip("/") != frame_id.strip("/"):
        return None, f"pose in frame {msg.header.frame_id!r}, expected {frame_id!r}"
    p, q = msg.pose.position, msg.pose.orientation
    position = np.array([p.x, p.y, p.z], dtype=np.float64)
    quat = np.array([q.w, q.x, q.y, q.z], dtype=np.float64)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat))):
        return None, "pose contains NaN or infinite values"
    if np.max(np.abs(position)) > MAX_POSITION:
        return None, f"position {np.round(position, 3).tolist()} is farther than {MAX_POSITION:g} m"
    norm = float(np.linalg.norm(quat))
    if not 0.9 <= norm <= 1.1:
        return None, f"orientation {np.round(quat, 4).tolist()} (w, x, y, z) is not a unit quaternion (norm {norm:.3g})"
    return (position, quat / norm), None


class LatestMessage(Generic[T]):
    """The newest valid value of a topic, with its local arrival time (thread-safe).

    Args:
        node: our ``multiros.ros.Node`` (spun elsewhere: a Real env's robot link spins it).
        msg_type, topic: what to subscribe to.
        convert: ``msg -> (value, None)`` or ``(None, reason)``.
        what: a name for messages (``"camera image"``).
    """

    def __init__(self, node: Any, msg_type: Any, topic: str, convert: Callable[[Any], tuple[T | None, str | None]],
                 what: str) -> None:
        self.node = node
        self.topic = topic
        self.what = what
        self._convert = convert
        self._cond = threading.Condition()
        self._value: T | None = None
        self.received: float | None = None
        self.received_count = 0
        self.malformed_count = 0
        self.last_error: str | None = None
        self._sub = node.create_subscription(msg_type, topic, self._on_message, qos_profile_sensor_data)

    def _on_message(self, msg: Any) -> None:
        try:
            value, reason = self._convert(msg)
        except (TypeError, ValueError, AttributeError, OverflowError) as exc:  # a message shaped unlike its type
            value, reason = None, f"unreadable message ({exc})"
        with self._cond:
            if value is None:
                self.malformed_count += 1
                self.last_error = reason
                return
            self._value = value
            self.received = time.monotonic()
            self.received_count += 1
            self._cond.notify_all()

    def describe_problem(self) -> str:
        if self.received_count == 0 and self.malformed_count == 0:
            return "nothing received"
        parts = [f"{self.received_count} valid"]
        if self.malformed_count:
            parts.append(f"{self.malformed_count} malformed (last: {self.last_error})")
        return ", ".join(parts)

    def latest(self, max_age: float) -> T:
        """The newest value, at most ``max_age`` seconds old.

        Raises:
            StaleSensorError: none yet, or older (the message says what arrived).
        """
        with self._cond:
            value, received = self._value, self.received
        now = time.monotonic()
        if value is None or received is None or now - received > max_age:
            age = "never" if received is None else f"{now - received:.3f} s ago"
            raise StaleSensorError(
                f"{self.what} on {self.topic} is stale: the last usable one arrived {age}, limit {max_age:g} s "
                f"({self.describe_problem()}). The env stopped commanding; the robot holds its last command. "
                "Check the sensor's driver (and the topic name), then reset the env or make a new one.")
        return value

    def wait_first(self, timeout: float) -> T:
        """The first value, waiting up to ``timeout`` seconds for it (:class:`StaleSensorError` otherwise)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._value is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._cond.wait(min(remaining, 0.1))
        return self.latest(max(timeout, 1e-3) if self._value is None else math.inf)

    def close(self) -> None:
        try:
            self.node.destroy_subscription(self._sub)
        except Exception:  # noqa: BLE001 - closing goes on
            pass


def resize_nearest(image: np.ndarray, height: int, width: int) -> np.ndarray:
    """``image`` (H x W or H x W x C) at ``height`` x ``width``, each pixel the nearest source pixel's."""
    if image.shape[0] == height and image.shape[1] == width:
        return image
    rows = np.minimum((np.arange(height) + 0.5) * image.shape[0] / height, image.shape[0] - 1).astype(np.intp)
    cols = np.minimum((np.arange(width) + 0.5) * image.shape[1] / width, image.shape[1] - 1).astype(np.intp)
    return image[rows][:, cols]


class ImageTopic(LatestMessage[np.ndarray]):
    """The newest image of a camera driver's ``sensor_msgs/Image`` topic (``kind``: ``"rgb"`` or ``"depth"``)."""

    def __init__(self, node: Any, topic: str, kind: str) -> None:
        if kind not in ("rgb", "depth"):
            raise ValueError(f"image kind {kind!r} is not 'rgb' or 'depth'")
        super().__init__(node, Image, topic, lambda msg: image_from_msg(msg, kind), f"{kind} image")


class PoseTopic(LatestMessage[tuple[np.ndarray, np.ndarray]]):
    """The newest pose of a tracked object (``geometry_msgs/PoseStamped`` in ``frame_id``, or any frame)."""

    def __init__(self, node: Any, topic: str, frame_id: str | None = None) -> None:
        super().__init__(node, PoseStamped, topic, lambda msg: pose_from_msg(msg, frame_id), "object pose")
