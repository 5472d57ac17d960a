"""A task's view camera as an entity of the world: a URDF holding one depth camera sensor, aimed at a point.

A task that observes through a camera of its own (not one of the robot's description) has the
simulation node spawn this entity; the node then renders and publishes it as any described camera
(``<namespace>/camera/image_raw``, ``.../camera_info``, ``.../depth/image_raw``: gazebo_ros_camera's
names).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["VIEW_CAMERA", "camera_entity_urdf", "look_at_rpy"]

VIEW_CAMERA = "camera"  # the sensor's name (its topics: <namespace>/camera/...)


def look_at_rpy(position: Sequence[float], lookat: Sequence[float]) -> tuple[float, float]:
    """Pitch and yaw (rad) of a Gazebo camera (looking along +x, +z up) at ``position`` aimed at ``lookat``."""
    d = np.subtract(lookat, position)
    return float(math.atan2(-d[2], math.hypot(d[0], d[1]))), float(math.atan2(d[1], d[0]))


def camera_entity_urdf(position: Sequence[float], lookat: Sequence[float], width: int, height: int,
                       fovy_deg: float, namespace: str) -> str:
    """A URDF holding one depth camera sensor (``camera``) at the entity's origin, aimed at ``lookat``
    (the entity is spawned at ``position``), publishing as gazebo_ros_camera does in ``namespace``:
    ``<namespace>/camera/image_raw``, ``.../camera_info``, ``.../depth/image_raw``.

    The mount is a prismatic joint of zero travel (horizontal): a description without a joint would be a
    free-floating object and fall, one with a joint is a fixed-base entity."""
    pitch, yaw = look_at_rpy(position, lookat)
    hfov = 2.0 * math.atan(math.tan(math.radians(fovy_deg) / 2.0) * width / height)
    return (
        '<robot name="observation_camera">\n'
        '  <link name="world"/>\n'
        '  <link name="camera_link"><inertial><mass value="0.01"/>'
        '<inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial></link>\n'
        '  <joint name="camera_mount" type="prismatic"><parent link="world"/><child link="camera_link"/>'
        '<axis xyz="1 0 0"/><limit lower="0" upper="0" effort="1" velocity="1"/></joint>\n'
        '  <gazebo reference="camera_link">\n'
        f'    <sensor type="depth" name="{VIEW_CAMERA}">\n'
        f'      <pose>0 0 0 0 {pitch!r} {yaw!r}</pose>\n'
        f'      <camera><horizontal_fov>{hfov!r}</horizontal_fov>'
        f'<image><width>{width}</width><height>{height}</height></image></camera>\n'
        f'      <plugin name="{VIEW_CAMERA}" filename="libgazebo_ros_camera.so">'
        f'<ros><namespace>{namespace}</namespace></ros><camera_name>{VIEW_CAMERA}</camera_name></plugin>\n'
        '    </sensor>\n'
        '  </gazebo>\n'
        '</robot>\n'
    )
