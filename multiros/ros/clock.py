"""Minimal ROS clock and time (``Node.get_clock().now()``): system time in nanoseconds."""

from __future__ import annotations

import time
from dataclasses import dataclass

__all__ = ["Time", "Clock"]


@dataclass(frozen=True, order=True)
class Time:
    """A point in time in nanoseconds since the epoch."""

    nanoseconds: int = 0

    def seconds_nanoseconds(self) -> tuple[int, int]:
        return divmod(self.nanoseconds, 1_000_000_000)

    def to_msg(self) -> object:
        """A ``builtin_interfaces/msg/Time`` message (needs the interface types)."""
        from multiros.ros.interfaces import get_message

        sec, nanosec = self.seconds_nanoseconds()
        return get_message("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec)


class Clock:
    """System (wall) clock. Simulation time is published on ``/clock`` by the sim node."""

    def now(self) -> Time:
        return Time(time.time_ns())
