"""Cameras of the simulation node: every camera of a description published as a real camera
driver publishes it, and read directly by a composed client.

Each camera sensor of a URDF (``<gazebo reference="link"><sensor type="camera|depth|...">``, which
:mod:`multiros.sim.urdf_tags` makes a MuJoCo camera) and each camera of an MJCF entity becomes:

* ``sensor_msgs/Image`` (``rgb8``) and ``sensor_msgs/CameraInfo``;
* for depth sensors (``type`` ``depth``, ``depth_camera`` or ``rgbd_camera``) also a depth image,
  ``sensor_msgs/Image`` ``32FC1`` in metres (distance along the optical axis, as ROS depth images;
  pixels that see nothing hold ``+inf``, "no return" as REP 118 has it) and its ``CameraInfo``.

Topic names follow the ``gazebo_ros_camera`` plugin, so a description written for Gazebo publishes
where its real twin's driver does. With a ``<plugin>`` in the sensor: ``<ros><namespace>``
(absolute, or relative to the entity's namespace), ``<camera_name>`` (default: the sensor's name),
``<frame_name>`` and ``<ros><remapping>from:=to</remapping>``, applied to the plugin's relative
names ``<camera_name>/image_raw``, ``<camera_name>/camera_info``, ``<camera_name>/depth/image_raw``
and ``<camera_name>/depth/camera_info``. Without a plugin: ``<entity namespace>/<sensor>/image_raw``
and so on. A Zed2 modelled that way (``rx200_description``'s ``use_zed2``) publishes
``/<ns>/zed2/zed_node/rgb/image_rect_color``, ``.../rgb/camera_info``,
``.../depth/depth_registered``; generic cameras ``.../image_raw`` and ``.../camera_info``.
MJCF cameras: ``<entity namespace>/<camera>/image_raw`` and ``camera_info``, at ``resolution``
(default 640 x 480).

Images are rendered offscreen (headless: ``MUJOCO_GL=egl`` or ``osmesa``) only when someone
subscribes or reads. Reads (an env's observations) render under the node's lock, at most once per
camera, image kind and size for one state of the world; topics are rendered beside the physics at
each camera's capped rate by :mod:`multiros.sim.camera_stream`, which publishes a read's image of
the same state as is. A camera sensor renders fast (:attr:`CameraHub.fast`: no shadows, no
reflections, no multisampling; in software GL about a tenth of a full-quality frame), topics and
reads alike; the node's ``RenderCamera`` service and an env's ``render()`` keep the full quality.
The frame id is the camera's optical frame in the node's TF tree (:mod:`multiros.sim.tf_tree`:
``<entity>/<frame_name>``, default ``<entity>/<sensor>_optical_frame``). A ``<hack_baseline>`` in
the plugin (a stereo pair's right camera) gives its ``CameraInfo`` ``P[3] = -fx * baseline``. The
intrinsics are a pinhole's (no distortion): ``fy = fx = height / (2 tan(fovy / 2))``, the principal
point at the image centre.
"""

from __future__ import annotations

import dataclasses
import math
import re
import threading
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from multiros.sim import convert
from multiros.sim.errors import RenderError
from multiros.sim.limits import MAX_CAMERA_PIXELS
from multiros.sim.urdf_tags import CAMERA_SENSOR_TYPES

__all__ = ["CameraFrame", "CameraHub", "CameraIntrinsics", "CameraSpec", "camera_specs", "fill_camera_info",
           "fill_image"]

DEPTH_SENSOR_TYPES = ("depth", "depth_camera", "rgbd_camera")
_MAX_SIDE = 4096
_NAME = re.compile(r"^/?[A-Za-z_~][A-Za-z0-9_/~]*$")
_DEFAULT_SIZE = (640, 480)


@dataclass(frozen=True)
class CameraIntrinsics:
    """A pinhole camera's intrinsics (pixels; OpenCV/ROS convention, pixel centres at integers)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_fovy(cls, width: int, height: int, fovy_deg: float) -> CameraIntrinsics:
        f = 0.5 * height / math.tan(math.radians(fovy_deg) / 2.0)
        return cls(int(width), int(height), f, f, (width - 1) / 2.0, (height - 1) / 2.0)

    @property
    def k(self) -> np.ndarray:
        """The 3 x 3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CameraSpec:
    """One camera of the node: its MuJoCo name, image size, whether it has depth, and its topics
    (empty strings for the depth ones of an RGB camera).

    ``frame_id`` is the TF frame its headers carry (set by the node's TF tree,
    :mod:`multiros.sim.tf_tree`); ``frame_name`` the sensor's ``<frame_name>`` as written (``""``
    when none); ``baseline`` the plugin's ``<hack_baseline>`` in metres (the right camera of a stereo
    pair: its ``CameraInfo`` has ``P[3] = -fx * baseline``, as gazebo_ros_camera writes it);
    ``rate`` the sensor's ``<update_rate>`` in Hz (0: the node's default camera rate)."""

    camera: str
    entity: str
    width: int
    height: int
    depth: bool
    frame_id: str
    rgb_topic: str
    rgb_info_topic: str
    depth_topic: str = ""
    depth_info_topic: str = ""
    frame_name: str = ""
    baseline: float = 0.0
    rate: float = 0.0

    @property
    def topics(self) -> tuple[str, ...]:
        """The topics it publishes: image and camera_info, RGB and (when it has one) depth."""
        return tuple(t for t in (self.rgb_topic, self.rgb_info_topic, self.depth_topic, self.depth_info_topic) if t)

    @property
    def pixels(self) -> int:
        """Pixels of one of its images."""
        return self.width * self.height


@dataclass(frozen=True)
class CameraFrame:
    """What a camera saw at one state of the world.

    Attributes:
        camera: the MuJoCo camera name (``"<entity>/<sensor>"``).
        stamp: simulation time in seconds.
        rgb: ``(H, W, 3)`` uint8, or None when not asked for (read-only array).
        depth: ``(H, W)`` float32 metres, or None when not asked for (read-only array).
        intrinsics: the pinhole intrinsics of this image size (None when read through the node's
            RenderCamera service, which does not report them).
    """

    camera: str
    stamp: float
    rgb: np.ndarray | None
    depth: np.ndarray | None
    intrinsics: CameraIntrinsics | None


def _join(namespace: str, name: str) -> str:
    if name.startswith("/"):
        return name
    return "/".join(part for part in (namespace.rstrip("/"), name) if part) if namespace else "/" + name


def _text(element: ET.Element | None, path: str, default: str = "") -> str:
    found = element.find(path) if element is not None else None
    return (found.text or "").strip() if found is not None and found.text else default


def _number(element: ET.Element | None, path: str, default: float, low: float, high: float) -> float:
    """A number of the description, ``default`` when absent, not a number or outside ``[low, high]``."""
    try:
        value = float(_text(element, path, str(default)))
    except ValueError:
        return default
    return value if math.isfinite(value) and low <= value <= high else default


def _image_size(sensor: ET.Element) -> tuple[int, int]:
    width, height = 320, 240  # SDF's defaults, as multiros.sim.urdf_tags reads them
    try:
        width = int(float(_text(sensor, "camera/image/width", str(width))))
        height = int(float(_text(sensor, "camera/image/height", str(height))))
    except ValueError:
        pass  # the description loader already refused malformed sizes
    return max(1, min(width, _MAX_SIDE)), max(1, min(height, _MAX_SIDE))


def _urdf_specs(entity: str, namespace: str, text: str) -> list[CameraSpec]:
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return []
    specs = []
    for gazebo in root.findall("gazebo"):
        for sensor in gazebo.findall("sensor"):
            kind = sensor.get("type")
            name = (sensor.get("name") or "").strip()
            if kind not in CAMERA_SENSOR_TYPES or not name:
                continue
            plugin = sensor.find("plugin")
            ros = plugin.find("ros") if plugin is not None else None
            ns = _text(ros, "namespace")
            ns = ns if ns.startswith("/") else _join(namespace, ns) if ns else namespace
            cam = _text(plugin, "camera_name", name) if plugin is not None else name
            remap = {}
            for rule in ros.findall("remapping") if ros is not None else ():
                source, sep, target = (rule.text or "").strip().partition(":=")
                if sep:
                    remap[source.strip().lstrip("~/")] = target.strip()

            def topic(relative: str, cam: str = cam, remap: dict = remap, ns: str = ns) -> str:
                name = f"{cam}/{relative}" if cam else relative
                return _join(ns, remap.get(name, name))

            depth = kind in DEPTH_SENSOR_TYPES
            width, height = _image_size(sensor)
            frame = _text(plugin, "frame_name") if plugin is not None else ""
            specs.append(CameraSpec(
                camera=f"{entity}/{name}", entity=entity, width=width, height=height, depth=depth,
                frame_id=frame or f"{entity}/{name}_optical_frame", rgb_topic=topic("image_raw"),
                rgb_info_topic=topic("camera_info"), depth_topic=topic("depth/image_raw") if depth else "",
                depth_info_topic=topic("depth/camera_info") if depth else "", frame_name=frame,
                baseline=_number(plugin, "hack_baseline", 0.0, 0.0, 100.0),
                rate=_number(sensor, "update_rate", 0.0, 0.0, 1000.0)))
    return specs


def camera_specs(entity: str, namespace: str, description: str, model: mujoco.MjModel) -> list[CameraSpec]:
    """The cameras of one entity: its URDF's camera sensors, or its MJCF cameras. Cameras whose
    topic names are not valid ROS names, or that the model lacks, are left out."""
    ns = namespace.rstrip("/")
    text = description.lstrip()
    if text.startswith("<robot") or "<robot" in text[:2000]:
        specs = _urdf_specs(entity, ns, description)
    else:
        specs = []
        for cid in range(model.ncam):
            full = model.camera(cid).name
            if not full.startswith(f"{entity}/"):
                continue
            short = full[len(entity) + 1:]
            res = model.cam_resolution[cid]  # MJCF resolution="w h" (1 1 when not given)
            width, height = (int(res[0]), int(res[1])) if res[0] > 1 else _DEFAULT_SIZE
            specs.append(CameraSpec(full, entity, min(width, _MAX_SIDE), min(height, _MAX_SIDE), False,
                                    f"{full}_optical_frame", _join(ns, f"{short}/image_raw"),
                                    _join(ns, f"{short}/camera_info")))
    known = {model.camera(i).name for i in range(model.ncam)}
    return [s for s in specs if s.camera in known and all(_NAME.match(t) for t in s.topics)]


def fill_image(msg: Any, image: np.ndarray, stamp: float, frame_id: str) -> Any:
    """Write an ``(H, W, 3)`` uint8 image (``rgb8``) or an ``(H, W)`` float32 depth image
    (``32FC1``, metres) into a ``sensor_msgs/Image``."""
    msg.header.stamp = convert.time_msg(stamp)
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(image.shape[0]), int(image.shape[1])
    if image.ndim == 3:
        msg.encoding, msg.step = "rgb8", 3 * msg.width
        data = np.ascontiguousarray(image, dtype=np.uint8)
    else:
        msg.encoding, msg.step = "32FC1", 4 * msg.width
        data = np.ascontiguousarray(image, dtype="<f4")
    msg.is_bigendian = 0
    msg.data = data.tobytes()
    return msg


def fill_camera_info(msg: Any, intrinsics: CameraIntrinsics, stamp: float, frame_id: str,
                     baseline: float = 0.0) -> Any:
    """Write a pinhole ``sensor_msgs/CameraInfo`` (``plumb_bob`` without distortion); ``baseline``
    (metres, the right camera of a stereo pair) sets ``P[3] = -fx * baseline`` (the ``Tx`` of
    ``sensor_msgs/CameraInfo``'s projection matrix)."""
    msg.header.stamp = convert.time_msg(stamp)
    msg.header.frame_id = frame_id
    msg.width, msg.height = intrinsics.width, intrinsics.height
    msg.distortion_model = "plumb_bob"
    msg.d = np.zeros(5)
    msg.k = intrinsics.k.ravel()
    msg.r = np.eye(3).ravel()
    p = np.zeros((3, 4))
    p[:, :3] = intrinsics.k
    p[0, 3] = -intrinsics.fx * float(baseline)
    msg.p = p.ravel()
    return msg


@dataclass
class _Publishers:
    spec: CameraSpec
    rgb: Any
    rgb_info: Any
    depth: Any = None
    depth_info: Any = None
    failed: bool = False


@dataclass
class _Cache:
    key: tuple = ()
    images: dict[tuple[str, int, int, bool], np.ndarray] = field(default_factory=dict)


class CameraHub:
    """The node's cameras: their publishers, a per-state image cache, and direct reads.

    Args:
        node: the simulation node (publishers are its; ``node.world``, ``node.lock``).
        renderer: returns the node's :class:`~multiros.sim.render.Renderer` (created on first use).
        log_error: reports a camera that cannot render (once per camera).
        log_unpublished: reports a camera that is not published (see ``attach``); ``log_error`` by default.

    Attributes:
        fast: render the cameras' images without shadows, reflections or multisampling (default True).
    """

    fast: bool = True

    def __init__(self, node: Any, renderer: Callable[[], Any], log_error: Callable[[str], None],
                 log_unpublished: Callable[[str], None] | None = None) -> None:
        from multiros.sim.distro_adapters import get_message

        self._node = node
        self._renderer = renderer
        self._log_error = log_error
        self._log_unpublished = log_unpublished or log_error
        self._image_type = get_message("sensor_msgs/msg/Image")
        self._info_type = get_message("sensor_msgs/msg/CameraInfo")
        self._entities: dict[str, list[_Publishers]] = {}
        self._unpublished: dict[str, list[CameraSpec]] = {}  # cameras read as observations only (_trespass)
        self.max_pixels = MAX_CAMERA_PIXELS  # of all published cameras' images together
        self._cache = _Cache()
        self._cache_lock = threading.Lock()

    # -- entities -----------------------------------------------------------------------------
    @property
    def entities(self) -> tuple[str, ...]:
        """Entities with cameras."""
        return tuple(self._entities)

    def attach(self, info: Any, frame_of: Callable[[CameraSpec], str] | None = None) -> None:
        """Create the publishers of an entity's cameras (``info``: its :class:`EntityInfo`);
        ``frame_of`` names each camera's TF frame (the node's TF tree)."""
        self.detach(info.name)
        world = self._node.world
        pubs = []
        for spec in camera_specs(info.name, info.namespace, info.description, world.model):
            trespass = self._trespass(info.name, spec, sum(e.spec.pixels for e in pubs))
            if trespass:  # still an observation camera of its env (read), with its size: only not published
                self._log_unpublished(f"entity {info.name!r}: camera {spec.camera!r} is not published: {trespass}")
                self._unpublished.setdefault(info.name, []).append(spec)
                continue
            if frame_of is not None:
                spec = dataclasses.replace(spec, frame_id=frame_of(spec))
            qos = 2  # the newest images only; reliable, as camera drivers' default publishers
            entry = _Publishers(spec, self._node.create_publisher(self._image_type, spec.rgb_topic, qos),
                                self._node.create_publisher(self._info_type, spec.rgb_info_topic, qos))
            if spec.depth:
                entry.depth = self._node.create_publisher(self._image_type, spec.depth_topic, qos)
                entry.depth_info = self._node.create_publisher(self._info_type, spec.depth_info_topic, qos)
            pubs.append(entry)
        if pubs:
            self._entities[info.name] = pubs

    def _trespass(self, name: str, spec: CameraSpec, pending: int = 0) -> str:
        """Why a camera of entity ``name`` may not publish its topics ('' when it may): a topic that
        another entity's camera publishes, or one inside another entity's namespace (a description's
        sensor plugin names its namespace, absolute ones included: a stranger's description must not
        publish images into another robot's camera topics), or more pixels than the node publishes in
        all (``max_pixels``; ``pending``: this entity's cameras accepted so far)."""
        published = pending + sum(e.spec.pixels for other, entries in self._entities.items()
                                  if other != name for e in entries)
        if published + spec.pixels > self.max_pixels:
            return (f"the node publishes {published:,} pixels of camera images already, and {spec.width} x "
                    f"{spec.height} more would pass its limit of {self.max_pixels:,} (multiros.sim.limits."
                    "MAX_CAMERA_PIXELS)")
        topics = spec.topics
        for other, entries in self._entities.items():
            if other == name:
                continue
            taken = {t for e in entries for t in e.spec.topics}
            clash = [t for t in topics if t in taken]
            if clash:
                return f"entity {other!r} publishes {clash[0]}"
        world = self._node.world
        own = world.entity(name).namespace.rstrip("/")
        for other in world.entity_names():
            if other == name:
                continue
            ns = world.entity(other).namespace.rstrip("/")
            if not ns or (own and (own == ns or own.startswith(ns + "/"))):
                continue  # the root namespace, or this entity lives inside the other's: its own topics
            inside = [t for t in topics if t == ns or t.startswith(ns + "/")]
            if inside:
                return f"{inside[0]} is in entity {other!r}'s namespace {ns} (a sensor plugin's <namespace>)"
        return ""

    def detach(self, name: str) -> None:
        """Destroy an entity's camera publishers."""
        self._unpublished.pop(name, None)
        for entry in self._entities.pop(name, []):
            for pub in (entry.rgb, entry.rgb_info, entry.depth, entry.depth_info):
                if pub is not None:
                    self._node.destroy_publisher(pub)

    def specs(self) -> list[CameraSpec]:
        """Every published camera."""
        return [entry.spec for entries in self._entities.values() for entry in entries]

    def entries(self) -> list[_Publishers]:
        """Every camera's spec and publishers (a copy of the list: the camera thread walks it)."""
        return [entry for entries in list(self._entities.values()) for entry in entries]

    def image_type(self) -> Any:
        return self._image_type()

    def info_type(self) -> Any:
        return self._info_type()

    def spec(self, camera: str) -> CameraSpec | None:
        for entries in self._entities.values():
            for entry in entries:
                if entry.spec.camera == camera:
                    return entry.spec
        for specs in self._unpublished.values():
            for spec in specs:
                if spec.camera == camera:
                    return spec
        return None

    # -- images -------------------------------------------------------------------------------
    def state_key(self) -> tuple:
        """What identifies the world's visible state (caller holds the node's lock)."""
        return self._state_key()

    def cached(self, camera: str, width: int, height: int, depth: bool, key: tuple) -> np.ndarray | None:
        """The image an observation rendered of state ``key``, if any."""
        with self._cache_lock:
            return self._cache.images.get((camera, width, height, depth)) if self._cache.key == key else None

    def _state_key(self) -> tuple:
        data = self._node.world.data
        return (self._node.world.time, data.qpos.tobytes(), data.mocap_pos.tobytes(), data.mocap_quat.tobytes(),
                id(self._node.world.model))

    def _image(self, camera: str, width: int, height: int, depth: bool) -> np.ndarray:
        """One image of the world's current state, rendered at most once per state (caller holds the
        node's lock)."""
        key = self._state_key()
        slot = (camera, width, height, depth)
        with self._cache_lock:
            if self._cache.key != key:
                self._cache = _Cache(key)
            image = self._cache.images.get(slot)
        if image is None:
            image = self._renderer().render(camera, width=width, height=height, depth=depth, fast=self.fast,
                                            markers=False)
            image.flags.writeable = False
            with self._cache_lock:
                if self._cache.key == key:
                    self._cache.images[slot] = image
        return image

    def intrinsics(self, camera: str, width: int, height: int) -> CameraIntrinsics:
        model = self._node.world.model
        cid = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_CAMERA), camera)
        if cid < 0:
            names = [model.camera(i).name for i in range(model.ncam)]
            raise RenderError(f"camera {camera!r} not found; cameras: {names}")
        return CameraIntrinsics.from_fovy(width, height, float(model.cam_fovy[cid]))

    def read(self, camera: str, *, rgb: bool = True, depth: bool = False, width: int | None = None,
             height: int | None = None) -> CameraFrame:
        """The camera's images of the world's current state (caller holds the node's lock).

        Raises:
            RenderError: an unknown camera, a size out of 1..4096, or no offscreen GL (the message
                says to set ``MUJOCO_GL=egl`` or ``osmesa``).
        """
        spec = self.spec(camera)
        w = int(width if width is not None else spec.width if spec else _DEFAULT_SIZE[0])
        h = int(height if height is not None else spec.height if spec else _DEFAULT_SIZE[1])
        if not (1 <= w <= _MAX_SIDE and 1 <= h <= _MAX_SIDE):
            raise RenderError(f"camera {camera!r}: image size {w} x {h} is not within 1..{_MAX_SIDE} pixels a side")
        intrinsics = self.intrinsics(camera, w, h)
        return CameraFrame(camera, float(self._node.world.time), self._image(camera, w, h, False) if rgb else None,
                           self._image(camera, w, h, True) if depth else None, intrinsics)

    def destroy(self) -> None:
        for name in list(self._entities):
            self.detach(name)
