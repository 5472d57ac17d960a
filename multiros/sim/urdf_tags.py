"""The URDF tags beside the kinematic tree: ``<ros2_control>`` joints, the controllers file of a
``<gazebo><plugin>``, and ``<gazebo reference="link">`` camera sensors.

A camera sensor becomes a MuJoCo camera fixed to its link, named after the sensor (in a world,
``"<entity>/<sensor name>"``), for rendered images (``RenderCamera``'s ``camera`` field):

.. code-block:: xml

    <gazebo reference="base_link">
      <sensor type="camera" name="render_camera">
        <pose>1.0 -0.6 0.7 0 0.45 2.6</pose>      <!-- x y z roll pitch yaw in the link frame -->
        <camera>
          <horizontal_fov>1.0</horizontal_fov>   <!-- radians -->
          <image><width>640</width><height>480</height></image>
        </camera>
      </sensor>
    </gazebo>

As in Gazebo, the camera looks along the pose's +x axis with +z up. MuJoCo keeps a camera's
vertical field of view at every image size: it is ``2 atan(tan(horizontal_fov / 2) * height / width)``
of the sensor's image (SDF defaults: 1.047 rad, 320 x 240).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from multiros.sim.errors import DescriptionError, PackageNotFoundError
from multiros.sim.limits import DescriptionLimits
from multiros.sim.packages import PackageIndex
from multiros.sim.trust import SourcePolicy

__all__ = ["CAMERA_SENSOR_TYPES", "Ros2ControlJoint", "add_gazebo_cameras", "parse_controllers_file",
           "parse_ros2_control"]

#: ``<sensor type>`` values read as cameras (Gazebo Classic and Gazebo Sim spellings).
CAMERA_SENSOR_TYPES = ("camera", "depth", "depth_camera", "rgbd_camera")
_MAX_IMAGE_SIDE = 16384


@dataclass(frozen=True)
class Ros2ControlJoint:
    """A ``<joint>`` of the URDF's ``<ros2_control>`` tag."""

    name: str
    command_interfaces: tuple[str, ...]
    state_interfaces: tuple[str, ...]
    initial_position: float | None = None


def parse_ros2_control(root: ET.Element, source: str = "<string>") -> tuple[Ros2ControlJoint, ...]:
    """The joints of every ``<ros2_control>`` tag, with their position ``initial_value``."""
    joints: list[Ros2ControlJoint] = []
    for tag in root.iter("ros2_control"):
        for j in tag.findall("joint"):
            initial = None
            for si in j.findall("state_interface"):
                if si.get("name") == "position":
                    for param in si.findall("param"):
                        if param.get("name") == "initial_value" and param.text:
                            try:
                                initial = float(param.text.strip())
                            except ValueError:
                                initial = None
                            if initial is not None and not math.isfinite(initial):
                                raise DescriptionError(f"{source}: ros2_control joint '{j.get('name', '')}' "
                                                       f"initial_value {param.text.strip()!r} is not finite",
                                                       source=source)
            joints.append(Ros2ControlJoint(
                name=j.get("name", ""),
                command_interfaces=tuple(c.get("name", "") for c in j.findall("command_interface")),
                state_interfaces=tuple(s.get("name", "") for s in j.findall("state_interface")),
                initial_position=initial))
    return tuple(joints)


def parse_controllers_file(root: ET.Element, index: PackageIndex, source: str,
                           policy: SourcePolicy | None = None) -> Path | None:
    """The controllers YAML a ``<plugin><parameters>`` tag names (gz_ros2_control style), if any."""
    for plugin in root.iter("plugin"):
        for param in plugin.iter("parameters"):
            text = (param.text or "").strip()
            if text.endswith((".yaml", ".yml")):
                try:
                    if policy is not None:
                        return policy.resolve(text, index, what="controllers file")
                    return index.resolve_uri(text)
                except PackageNotFoundError as exc:
                    raise DescriptionError(f"{source}: controllers file '{text}': {exc}", source=source,
                                           missing_assets=True) from exc
    return None


def _numbers(text: str | None, count: int, what: str, source: str) -> list[float]:
    parts = (text or "").split()
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise DescriptionError(f"{source}: {what} must be {count} finite numbers, got {text!r}", source=source)
    return values


def add_gazebo_cameras(spec: mujoco.MjSpec, root: ET.Element, bodies: Mapping[str, str], source: str,
                       limits: DescriptionLimits) -> tuple[str, ...]:
    """Add a MuJoCo camera for each ``<gazebo reference="link">`` camera sensor; returns their names.

    ``bodies`` maps each link name to its body name in ``spec``.

    Raises:
        DescriptionError: an unknown link, a duplicate or empty name, a malformed or out-of-range
            pose, field of view or image size, or more cameras than links (the limits' ``max_bodies``).
    """
    names: list[str] = []
    for gazebo in root.findall("gazebo"):
        link = gazebo.get("reference")
        sensors = [s for s in gazebo.findall("sensor") if s.get("type") in CAMERA_SENSOR_TYPES]
        if not sensors:
            continue
        if link not in bodies:
            raise DescriptionError(f"{source}: <gazebo reference={link!r}> with a camera sensor names no link",
                                   source=source)
        for sensor in sensors:
            name = (sensor.get("name") or "").strip()
            what = f"camera sensor {name!r} of link {link!r}"
            if not name or name in names:
                raise DescriptionError(f"{source}: a camera sensor needs a name of its own (got {name!r})",
                                       source=source)
            if len(names) >= limits.max_bodies:
                raise DescriptionError(f"{source}: more than {limits.max_bodies} camera sensors; the node's "
                                       f"description limits allow one per link at most", source=source)
            pose = sensor.find("pose")
            x, y, z, roll, pitch, yaw = (_numbers(pose.text, 6, f"{what}: <pose>", source) if pose is not None
                                         else [0.0] * 6)
            if max(abs(x), abs(y), abs(z)) > limits.max_position:
                raise DescriptionError(f"{source}: {what}: position beyond {limits.max_position} m", source=source)
            camera = sensor.find("camera")
            hfov, width, height = 1.047, 320.0, 240.0
            if camera is not None:
                if camera.find("horizontal_fov") is not None:
                    (hfov,) = _numbers(camera.find("horizontal_fov").text, 1, f"{what}: <horizontal_fov>", source)
                image = camera.find("image")
                if image is not None:
                    if image.find("width") is not None:
                        (width,) = _numbers(image.find("width").text, 1, f"{what}: <image><width>", source)
                    if image.find("height") is not None:
                        (height,) = _numbers(image.find("height").text, 1, f"{what}: <image><height>", source)
            if not 0.01 <= hfov <= 3.0:
                raise DescriptionError(f"{source}: {what}: horizontal_fov {hfov} is not within [0.01, 3.0] rad",
                                       source=source)
            if not (1 <= width <= _MAX_IMAGE_SIDE and 1 <= height <= _MAX_IMAGE_SIDE):
                raise DescriptionError(f"{source}: {what}: image {width} x {height} is not within 1..{_MAX_IMAGE_SIDE} "
                                       f"pixels a side", source=source)
            fovy = 2.0 * math.degrees(math.atan(math.tan(hfov / 2.0) * height / width))
            # Gazebo: the camera looks along +x, +z up. MuJoCo: along -z, +y up (x right).
            sensor_rot = _rpy_matrix(roll, pitch, yaw)
            mj_rot = sensor_rot @ np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, np.ascontiguousarray(mj_rot).ravel())
            spec.body(bodies[link]).add_camera(name=name, pos=[x, y, z], quat=quat, fovy=fovy)
            names.append(name)
    return tuple(names)


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF/SDF fixed-axis roll, pitch, yaw: ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw),
                              math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])
