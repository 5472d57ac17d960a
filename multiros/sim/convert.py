"""Conversions between ROS messages and the world's plain arrays (quaternion order included).

ROS quaternions are ``(x, y, z, w)`` fields; the world uses MuJoCo's ``(w, x, y, z)`` arrays.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multiros.ros.interfaces import get_message

Time = get_message("builtin_interfaces/msg/Time")
Pose = get_message("geometry_msgs/msg/Pose")

_NS_PER_S = 1_000_000_000


def time_msg(seconds: float) -> Any:
    """A ``builtin_interfaces/Time`` for a simulation time in seconds."""
    ns = int(round(seconds * _NS_PER_S))
    return Time(sec=ns // _NS_PER_S, nanosec=ns % _NS_PER_S)


def time_seconds(seconds: float) -> float:
    """A simulation time as a ``builtin_interfaces/Time`` carries it, in seconds: what
    ``sec + nanosec * 1e-9`` of :func:`time_msg` gives, without building the message."""
    ns = int(round(seconds * _NS_PER_S))
    return ns // _NS_PER_S + (ns % _NS_PER_S) * 1e-9


def pose_to_arrays(pose: Any) -> tuple[np.ndarray, np.ndarray]:
    """``geometry_msgs/Pose`` -> ``(xyz, wxyz)`` arrays (not normalised, not validated)."""
    p, q = pose.position, pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.w, q.x, q.y, q.z])


def fill_pose(pose: Any, position: np.ndarray, orientation_wxyz: np.ndarray) -> Any:
    """Write ``(xyz, wxyz)`` into a ``geometry_msgs/Pose`` and return it."""
    p, q = pose.position, pose.orientation
    p.x, p.y, p.z = float(position[0]), float(position[1]), float(position[2])
    q.w, q.x, q.y, q.z = (
        float(orientation_wxyz[0]),
        float(orientation_wxyz[1]),
        float(orientation_wxyz[2]),
        float(orientation_wxyz[3]),
    )
    return pose


def pose_from_row(row: np.ndarray) -> Any:
    """A new ``geometry_msgs/Pose`` from a ``[x, y, z, qw, qx, qy, qz]`` row."""
    return fill_pose(Pose(), row[:3], row[3:7])


def validate_quaternion(wxyz: np.ndarray) -> str | None:
    """Why a quaternion is unusable (zero, not finite), or ``None`` when it is fine."""
    if not np.all(np.isfinite(wxyz)):
        return f"quaternion {wxyz.tolist()} is not finite"
    if np.linalg.norm(wxyz) < 1e-9:
        return "quaternion is all zeros; use w=1 (x=y=z=0) for no rotation"
    return None
