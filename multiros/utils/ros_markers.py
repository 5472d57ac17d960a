"""Goal and debug markers: ``visualization_msgs/Marker`` messages published through a node.

The MuJoCo simulation node subscribes to ``/visualization_marker`` (and ``/visualization_marker_array``)
and draws world-frame markers into rendered images and the viewer; RViz shows the same messages.

MultiROS' ``RosMarker`` kept its publisher on rospy's global node; here the node is the first
argument. Orientations are ``(w, x, y, z)`` tuples (the project's convention) or
``geometry_msgs/Quaternion`` messages, identity by default. Markers are visual side effects: update
them from a step/reset hook, never from ``compute_reward`` (HER calls it on batches).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy.typing as npt

from multiros.ros.interfaces import get_message

Marker = get_message("visualization_msgs/msg/Marker")
MarkerArray = get_message("visualization_msgs/msg/MarkerArray")
ColorRGBA = get_message("std_msgs/msg/ColorRGBA")
Pose = get_message("geometry_msgs/msg/Pose")

DEFAULT_TOPIC = "/visualization_marker"
DEFAULT_ARRAY_TOPIC = "/visualization_marker_array"


def _set_duration(msg: Any, seconds: float) -> None:
    if seconds < 0:
        raise ValueError(f"marker lifetime must be >= 0 seconds (0 = forever), got {seconds}")
    sec = int(seconds)
    msg.sec, msg.nanosec = sec, int(round((seconds - sec) * 1e9))


class RosMarker:
    """One marker with MultiROS' setters; :meth:`publish` sends it.

    Args:
        node: the ``multiros.ros.Node`` publishing it (or an env exposing ``.node``).
        frame_id: the pose's frame (the simulation node draws ``"world"`` markers).
        ns, marker_id: the marker's identity; publishing again with the same pair moves it.
        marker_type: a ``Marker`` type constant (``Marker.SPHERE`` by default).
        marker_topic: topic to publish on.
        action: ``Marker.ADD`` (add or modify), ``Marker.DELETE`` or ``Marker.DELETEALL``.
        pose: a ``geometry_msgs/Pose`` (instead of ``position``/``orientation``).
        position: ``(x, y, z)``.
        orientation: ``(w, x, y, z)`` or a ``Quaternion`` message.
        lifetime: seconds before the marker disappears (0 = forever).
        scale: ``(x, y, z)`` full extents in metres (a sphere's diameter).
        color: ``(r, g, b, a)`` in ``[0, 1]`` or a ``ColorRGBA``.
        publisher: share an existing publisher instead of creating one.
    """

    def __init__(
        self,
        node: Any,
        frame_id: str = "world",
        ns: str = "",
        marker_type: int = Marker.SPHERE,
        marker_topic: str = DEFAULT_TOPIC,
        marker_id: int = 0,
        action: int = Marker.ADD,
        pose: Any = None,
        position: npt.ArrayLike | None = None,
        orientation: Any = None,
        lifetime: float = 0.0,
        scale: Sequence[float] | None = (0.05, 0.05, 0.05),
        color: Any = (1.0, 0.0, 0.0, 1.0),
        publisher: Any = None,
    ) -> None:
        node = node if hasattr(node, "create_publisher") else getattr(node, "node", node)
        self.node = node
        self._owns_publisher = publisher is None
        self.publisher = publisher if publisher is not None else node.create_publisher(Marker, marker_topic, 10)
        self.marker = Marker()
        self.marker.pose.orientation.w = 1.0
        self.set_frame_id(frame_id)
        self.set_ns(ns)
        self.set_id(marker_id)
        self.set_type(marker_type)
        self.set_action(action)
        if pose is not None:
            self.set_pose(pose)
        if position is not None:
            self.set_position(position)
        if orientation is not None:
            self.set_orientation(orientation)
        self.set_duration(lifetime)
        if scale is not None:
            self.set_scale(scale)
        if color is not None:
            self.set_color(color)

    # -- setters (MultiROS names) -----------------------------------------------------------
    def set_frame_id(self, frame_id: str) -> None:
        self.marker.header.frame_id = frame_id

    def set_ns(self, ns: str) -> None:
        self.marker.ns = ns

    def set_id(self, marker_id: int) -> None:
        self.marker.id = int(marker_id)

    def set_type(self, marker_type: int) -> None:
        self.marker.type = int(marker_type)

    def set_action(self, action: int) -> None:
        self.marker.action = int(action)

    def set_pose(self, pose: Any) -> None:
        self.marker.pose = pose

    def set_position(self, position: npt.ArrayLike) -> None:
        p = self.marker.pose.position
        p.x, p.y, p.z = (float(v) for v in position)

    def set_orientation(self, orientation: Any) -> None:
        """``(w, x, y, z)`` or a ``Quaternion`` message; a zero quaternion is refused."""
        if hasattr(orientation, "w"):
            w, x, y, z = orientation.w, orientation.x, orientation.y, orientation.z
        else:
            w, x, y, z = (float(v) for v in orientation)
        if w == x == y == z == 0.0:
            raise ValueError("marker orientation (0, 0, 0, 0) is not a rotation; use (1, 0, 0, 0) for none")
        o = self.marker.pose.orientation
        o.w, o.x, o.y, o.z = w, x, y, z

    def set_duration(self, duration: float) -> None:
        """Lifetime in seconds (0 = forever)."""
        _set_duration(self.marker.lifetime, float(duration))

    def set_scale(self, scale: Sequence[float]) -> None:
        s = self.marker.scale
        s.x, s.y, s.z = (float(v) for v in scale)

    def set_color(self, color: Any = None, r: float | None = None, g: float | None = None, b: float | None = None,
                  a: float | None = None) -> None:
        """Set the colour from ``(r, g, b, a)``/``ColorRGBA`` and/or single channels."""
        c = self.marker.color
        if color is not None:
            if hasattr(color, "r"):
                c.r, c.g, c.b, c.a = color.r, color.g, color.b, color.a
            else:
                values = [float(v) for v in color]
                c.r, c.g, c.b = values[:3]
                c.a = values[3] if len(values) > 3 else 1.0
        for name, value in (("r", r), ("g", g), ("b", b), ("a", a)):
            if value is not None:
                setattr(c, name, float(value))

    # -- sending ----------------------------------------------------------------------------
    def publish(self) -> None:
        """Send the marker as it is now."""
        self.publisher.publish(self.marker)

    def update(self, position: npt.ArrayLike | None = None, orientation: Any = None, r: float | None = None,
               g: float | None = None, b: float | None = None, a: float | None = None,
               duration: float | None = None) -> None:
        """Change position/orientation/colour/lifetime and publish (action ``ADD``)."""
        if position is not None:
            self.set_position(position)
        if orientation is not None:
            self.set_orientation(orientation)
        self.set_color(None, r, g, b, a)
        if duration is not None:
            self.set_duration(duration)
        self.set_action(Marker.ADD)
        self.publish()

    def delete(self) -> None:
        """Remove this marker (publishes action ``DELETE``); :meth:`update` shows it again."""
        self.set_action(Marker.DELETE)
        self.publish()

    def destroy(self) -> None:
        """Destroy the publisher this marker created."""
        if self._owns_publisher and self.publisher is not None:
            self.node.destroy_publisher(self.publisher)
        self.publisher = None


def goal_marker(node: Any, position: npt.ArrayLike, *, diameter: float = 0.05,
                color: Sequence[float] = (0.0, 1.0, 0.0, 0.8), ns: str = "goal", marker_id: int = 0) -> RosMarker:
    """A world-frame sphere at ``position``, published once; call ``.update(position=...)`` to move it."""
    marker = RosMarker(node, "world", ns, Marker.SPHERE, marker_id=marker_id, position=position,
                       scale=(diameter, diameter, diameter), color=color)
    marker.publish()
    return marker


class RosMarkerArray:
    """Several markers sent together as one ``visualization_msgs/MarkerArray``.

    Args:
        node: the publishing node.
        marker_topic: topic of the array.
    """

    def __init__(self, node: Any, marker_topic: str = DEFAULT_ARRAY_TOPIC) -> None:
        node = node if hasattr(node, "create_publisher") else getattr(node, "node", node)
        self.node = node
        self.publisher = node.create_publisher(MarkerArray, marker_topic, 10)
        self.markers: list[RosMarker] = []

    def add_marker(self, marker: RosMarker) -> None:
        self.markers.append(marker)

    def remove_marker(self, marker_id: int, ns: str | None = None) -> None:
        """Forget markers with this id (and ns) and delete them from the display."""
        gone = [m for m in self.markers if m.marker.id == marker_id and (ns is None or m.marker.ns == ns)]
        for m in gone:
            m.set_action(Marker.DELETE)
        self._send(gone)
        self.markers = [m for m in self.markers if m not in gone]

    def get_marker_by_id(self, marker_id: int) -> RosMarker | None:
        return next((m for m in self.markers if m.marker.id == marker_id), None)

    def publish(self) -> None:
        self._send(self.markers)

    def delete_all_markers(self) -> None:
        """Clear the display (``DELETEALL``); the markers stay in this array."""
        clear = Marker()
        clear.action = Marker.DELETEALL
        self.publisher.publish(MarkerArray(markers=[clear]))

    def remove_all_markers(self) -> None:
        """Clear the display and forget every marker."""
        self.delete_all_markers()
        self.markers = []

    def _send(self, markers: Sequence[RosMarker]) -> None:
        self.publisher.publish(MarkerArray(markers=[m.marker for m in markers]))

    def destroy(self) -> None:
        self.node.destroy_publisher(self.publisher)


__all__ = ["Marker", "MarkerArray", "RosMarker", "RosMarkerArray", "goal_marker"]
