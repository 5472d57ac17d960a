"""A stand-in object tracker: an entity's pose from a physics stand-in, published as a tracker does.

A Real twin of push or pick-and-place reads the object's pose as ``geometry_msgs/PoseStamped`` on a
tracker's topic, in the robot's base frame (:mod:`multiros.envs.real.scene`). :class:`PoseTracker`
publishes a :class:`~multiros.hardware.physics_hardware.PhysicsHardware` entity's pose that way, at a
fixed rate, with a tracker's faults in known, seeded amounts: Gaussian noise on the position and a
latency (each message goes out ``latency`` seconds after its capture, stamped with the capture time).
``on_tick`` (optional) runs first at every tick, in the tracker's thread: the stand-in's "lab helper"
that puts the object back between episodes lives there.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from multiros.hardware.physics_hardware import PhysicsHardware
from multiros.ros.interfaces import get_message

__all__ = ["PoseTracker"]

_logger = logging.getLogger(__name__)
PoseStamped = get_message("geometry_msgs/msg/PoseStamped")
_NS_PER_S = 1_000_000_000
#: Most messages in flight (a 2 s latency at 1 kHz).
_MAX_IN_FLIGHT = 2048


class PoseTracker:
    """Publishes ``entity``'s pose relative to ``base`` on ``topic`` (see the module docstring).

    Args:
        node: the node that publishes (spun elsewhere).
        hardware: the physics stand-in holding the entity.
        entity: the tracked entity.
        topic: the tracker's topic (absolute).
        frame_id: the frame the poses are in (the robot's base link).
        base: the base's world position (m; the base is not rotated).
        rate: messages per second.
        noise: m, standard deviation of Gaussian noise on each position axis.
        latency: s, from a pose's capture to its message.
        rng: the noise's random stream.
        on_tick: called at every tick before the capture.
    """

    def __init__(self, node: Any, hardware: PhysicsHardware, entity: str, topic: str, frame_id: str,
                 base: Sequence[float], *, rate: float = 50.0, noise: float = 0.0, latency: float = 0.0,
                 rng: np.random.Generator | None = None, on_tick: Callable[[], None] | None = None) -> None:
        for what, value, lo, hi in (("rate", rate, 1e-3, 1000.0), ("noise", noise, 0.0, 1.0),
                                    ("latency", latency, 0.0, 2.0)):
            if not (math.isfinite(value) and lo <= value <= hi) or (what == "rate" and value <= 0):
                raise ValueError(f"tracker {what} must be within [{lo:g}, {hi:g}], got {value!r}")
        self.hardware, self.entity, self.frame_id = hardware, entity, frame_id
        self.base = np.asarray(base, dtype=np.float64).reshape(3)
        self.period, self.noise, self.latency = 1.0 / rate, float(noise), float(latency)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.on_tick = on_tick
        self.published = 0
        self.node = node
        self._pub = node.create_publisher(PoseStamped, topic, 10)
        self.topic = topic
        self._in_flight: deque[tuple[float, Any]] = deque(maxlen=_MAX_IN_FLIGHT)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="uniros-stand-in-tracker", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def message(self, captured: float) -> Any:
        """The entity's pose now as the tracker reports it (noise added), stamped ``captured``."""
        position, quat = self.hardware.pose(self.entity)
        position = position - self.base
        if self.noise > 0:
            position = position + self.rng.normal(0.0, self.noise, 3)
        msg = PoseStamped()
        ns = int(captured * _NS_PER_S)
        msg.header.stamp.sec, msg.header.stamp.nanosec = ns // _NS_PER_S, ns % _NS_PER_S
        msg.header.frame_id = self.frame_id
        p, q = msg.pose.position, msg.pose.orientation
        p.x, p.y, p.z = (float(v) for v in position)
        q.w, q.x, q.y, q.z = (float(v) for v in quat)
        return msg

    def _run(self) -> None:
        next_tick = time.monotonic()
        while True:
            wake = min(next_tick, self._in_flight[0][0]) if self._in_flight else next_tick
            if self._stop.wait(max(0.0, wake - time.monotonic())):
                return
            now = time.monotonic()
            try:
                if now >= next_tick:
                    if self.on_tick is not None:
                        self.on_tick()
                    msg = self.message(time.time())
                    if self.latency > 0:
                        self._in_flight.append((now + self.latency, msg))
                    else:
                        self._pub.publish(msg)
                        self.published += 1
                    next_tick += self.period
                    if next_tick <= now:
                        next_tick = now + self.period
                while self._in_flight and self._in_flight[0][0] <= now:
                    self._pub.publish(self._in_flight.popleft()[1])
                    self.published += 1
            except Exception:  # noqa: BLE001 - a transport hiccup must not stop the tracker
                _logger.exception("stand-in tracker")

    def destroy(self) -> None:
        """Stop publishing and destroy the publisher."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        try:
            self.node.destroy_publisher(self._pub)
        except Exception:  # noqa: BLE001 - closing goes on
            pass
