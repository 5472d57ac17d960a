"""Camera observations of the arm tasks, with MultiROS' keywords: an RGB image (``uint8``, H x W x 3)
and a depth image (``float32``, H x W, metres) in the observation, from the simulation node's camera
or, on a Real twin, from the ``sensor_msgs/Image`` topics of a real camera driver.

Modes (at most one; the default is the state observation alone, MultiROS' ``normal_obs_only``):

=====================================  ====================================  =================================
keyword                                plain env observation                 goal env observation
=====================================  ====================================  =================================
``rgb_obs_only=True``                  ``Dict(rgb)``                         ``Dict(observation=<the image>,
                                                                             achieved_goal, desired_goal)``
``rgb_plus_normal_obs=True``           ``Dict(observation, rgb)``            ``Dict(observation, achieved_goal,
                                                                             desired_goal, rgb)``
``rgb_plus_depth_plus_normal_obs``     ``Dict(observation, rgb, depth)``     the goal dict ``+ rgb, depth``
=====================================  ====================================  =================================

``observation`` is the state observation of the task without a camera. A goal env keeps its three
keys (HER and ``gymnasium_robotics.GoalEnv`` need them); with ``rgb_obs_only`` its ``observation`` is
the image. Depth is the distance along the optical axis in metres, clipped into ``[0, max_depth]``
(a real camera's invalid pixels, NaN or -inf, read 0; +inf reads ``max_depth``).

Options:

* ``image_width``, ``image_height``: the image size (default 84 x 84; a named camera: its sensor's
  size). At most 1920 x 1080, the simulation node's offscreen buffer.
* ``camera_position``, ``camera_lookat``: where the observation camera is and what it looks at
  (world frame of the task, metres; default: the arm's ``CAMERA_VIEW``), ``camera_fovy`` its vertical
  field of view (degrees, default 45). The env spawns it into the robot's namespace as a depth
  camera sensor of the observation's size, so the node publishes it on ``<namespace>/camera/image_raw``
  and ``<namespace>/camera/depth/image_raw`` (gazebo_ros_camera's names) with the observation's very
  pixels (one render serves both).
* ``camera_name``: use a camera of the robot's description instead (``"render_camera"``, the RX200's
  ``"zed2_left"``: ``use_zed2``), or of the world by its full name (``"<entity>/<camera>"``).
* Real twins: ``rgb_topic``, ``depth_topic`` (default: the simulated camera's topics, relative to the
  robot's namespace), ``image_timeout`` (s, default 0.5): an image older than that is stale, the env
  stops and raises, as for stale joint states. Images of another size are resized (nearest pixel).

The simulation renders offscreen (headless: ``MUJOCO_GL=egl`` or ``osmesa``) once per step, after the
physics, without shadows, reflections or multisampling (``multiros.sim.cameras``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.envs.connection import CameraRequest
from multiros.sim.view_camera import VIEW_CAMERA, camera_entity_urdf, look_at_rpy

__all__ = ["CAMERA_KEYWORDS", "Cameras", "CameraOptions", "MODES", "camera_entity_urdf", "look_at_rpy"]

_logger = logging.getLogger(__name__)

MODES = ("rgb_obs_only", "rgb_plus_normal_obs", "rgb_plus_depth_plus_normal_obs")
_SIM_ONLY = ("camera_position", "camera_lookat", "camera_fovy")
_REAL_ONLY = ("rgb_topic", "depth_topic", "image_timeout")
#: Every keyword the camera observations take (popped from an env's keyword arguments).
CAMERA_KEYWORDS = (*MODES, "normal_obs_only", "camera_name", "image_width", "image_height", "max_depth",
                   *_SIM_ONLY, *_REAL_ONLY)
MAX_WIDTH, MAX_HEIGHT = 1920, 1080  # the simulation node's offscreen buffer (multiros.sim.world_model)
MIN_SIDE = 8
DEFAULT_SIZE = 84  # DQN's 84 x 84: cheap to render and to learn from
CAMERA_ENTITY = VIEW_CAMERA  # the observation camera's sensor name (its topics: <namespace>/camera/...)


@dataclass(frozen=True)
class CameraOptions:
    """The camera observation an env was asked for (see the module docstring)."""

    mode: str
    camera_name: str | None
    width: int | None
    height: int | None
    position: tuple[float, float, float] | None
    lookat: tuple[float, float, float] | None
    fovy: float
    max_depth: float
    rgb_topic: str | None
    depth_topic: str | None
    image_timeout: float

    @property
    def depth(self) -> bool:
        return self.mode == "rgb_plus_depth_plus_normal_obs"

    @property
    def with_state(self) -> bool:
        return self.mode != "rgb_obs_only"


def _vec3(value: Any, name: str) -> tuple[float, float, float]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = np.empty(0)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > 100.0):
        raise ValueError(f"{name} must be 3 finite numbers (x, y, z in metres, within 100 m), got {value!r}")
    return float(arr[0]), float(arr[1]), float(arr[2])


def _side(value: Any, name: str, high: int) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not MIN_SIDE <= int(value) <= high:
        raise ValueError(f"{name} must be an integer from {MIN_SIDE} to {high} pixels, got {value!r}")
    return int(value)


def parse_camera_options(kwargs: dict[str, Any], owner: str, *, real: bool,
                         defaults: Mapping[str, Any] | None = None) -> CameraOptions | None:
    """Pop the camera keywords from ``kwargs`` and check them (``defaults``: an ID's, e.g. the Zed2
    variants' camera). ``None`` when no camera observation is asked for.

    Raises:
        ValueError: conflicting modes or options, sizes out of bounds, a bad pose.
    """
    given = {k: kwargs.pop(k) for k in CAMERA_KEYWORDS if k in kwargs}
    base = dict(defaults or {})
    if any(k in given for k in (*MODES, "normal_obs_only")):  # the caller's mode replaces the ID's
        base = {k: v for k, v in base.items() if k not in MODES}
    opts = {**base, **given}
    modes = [m for m in MODES if opts.get(m)]
    normal = opts.get("normal_obs_only")
    if len(modes) > 1:
        raise ValueError(f"{owner}: camera modes {modes} conflict: pick one of {list(MODES)}")
    if modes and normal:
        raise ValueError(f"{owner}: normal_obs_only=True conflicts with {modes[0]}=True (normal_obs_only means no "
                         "camera); pass one of them")
    if normal is False and not modes:
        raise ValueError(f"{owner}: normal_obs_only=False needs a camera mode: one of {list(MODES)}=True")
    if not modes:
        extra = sorted(set(given) - {"normal_obs_only"})
        if extra:
            raise ValueError(f"{owner}: camera option(s) {extra} given without a camera observation; add one of "
                             f"{list(MODES)}=True")
        return None
    ignored = sorted(set(given) & set(_SIM_ONLY if real else _REAL_ONLY))
    if ignored:
        _logger.warning("%s: %s ignored: %s", owner, ignored,
                        "a real camera is where it is mounted (its topics: rgb_topic=, depth_topic=)" if real else
                        "the simulation node publishes the camera's topics itself")
    name = opts.get("camera_name")
    if name is not None and (not isinstance(name, str) or not name.strip("/")):
        raise ValueError(f"{owner}: camera_name must be a camera's name, got {name!r}")
    position = None if opts.get("camera_position") is None else _vec3(opts["camera_position"], "camera_position")
    lookat = None if opts.get("camera_lookat") is None else _vec3(opts["camera_lookat"], "camera_lookat")
    if not real and name is not None and (position is not None or lookat is not None):
        raise ValueError(f"{owner}: camera_name={name!r} names an existing camera; camera_position/camera_lookat "
                         "place a new one: pass one or the other")
    if position is not None and lookat is not None and np.linalg.norm(np.subtract(position, lookat)) < 1e-3:
        raise ValueError(f"{owner}: camera_position and camera_lookat must be apart, got {position} and {lookat}")
    width = _side(opts.get("image_width"), "image_width", MAX_WIDTH)
    height = _side(opts.get("image_height"), "image_height", MAX_HEIGHT)
    if name is not None and (width is None) != (height is None):
        raise ValueError(f"{owner}: give both image_width and image_height, or neither (camera {name!r}'s own size)")
    fovy = opts.get("camera_fovy", 45.0)
    if isinstance(fovy, bool) or not isinstance(fovy, (int, float)) or not 1.0 <= float(fovy) <= 170.0:
        raise ValueError(f"{owner}: camera_fovy must be a number of degrees in [1, 170], got {fovy!r}")
    max_depth = opts.get("max_depth", 10.0)
    if isinstance(max_depth, bool) or not isinstance(max_depth, (int, float)) or not 0.0 < float(max_depth) <= 1e3:
        raise ValueError(f"{owner}: max_depth must be a number of metres in (0, 1000], got {max_depth!r}")
    timeout = opts.get("image_timeout", 0.5)
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0.0 < float(timeout) <= 60.0:
        raise ValueError(f"{owner}: image_timeout must be a number of seconds in (0, 60], got {timeout!r}")
    for key in ("rgb_topic", "depth_topic"):
        if opts.get(key) is not None and (not isinstance(opts[key], str) or not opts[key].strip("/")):
            raise ValueError(f"{owner}: {key} must be a topic name, got {opts[key]!r}")
    return CameraOptions(modes[0], name, width, height, position, lookat, float(fovy),
                         float(max_depth), opts.get("rgb_topic"), opts.get("depth_topic"), float(timeout))


class Cameras:
    """An env's camera observation, a component of the env (see the module docstring).

    The env makes it from the options it was given (:func:`parse_camera_options`) once its robot's
    connection is up; :meth:`open` opens the camera (a simulation renders a camera of the world,
    spawning the view camera first; a robot's connection subscribes to its driver's topics), reads a first
    image (a camera that cannot render, or a topic that never publishes, fails now) and gives the
    observation space with the images. Each step :meth:`add_images` puts them into N envs' results.

    Args:
        options: the camera asked for.
        connection: the robot's connection.
        view: the default camera, ``((x, y, z) lookat, distance, azimuth, elevation)`` relative to the
            robot base (metres, degrees): the arm file's ``camera.view``.
        topics: a described camera's ``(rgb, depth)`` topics, relative to the robot's namespace, when not
            ``<camera>/image_raw`` and ``<camera>/depth/image_raw`` (the arm file's ``camera.topics``).
        base_position: the robot base's world position.
    """

    def __init__(self, options: CameraOptions, connection: Any,
                 view: tuple[tuple[float, float, float], float, float, float],
                 topics: Mapping[str, tuple[str, str]], base_position: np.ndarray) -> None:
        self.options, self.connection = options, connection
        self.view, self.topics, self.base_position = view, dict(topics), np.asarray(base_position, dtype=np.float64)
        self.source = ""  # the camera as the connection names it
        self.image_size = (0, 0)  # (height, width)

    def open(self, state_space: spaces.Space[Any]) -> spaces.Dict:
        """Open the camera and return the observation space: ``state_space`` with the images."""
        options = self.options
        self.source, self.image_size = self.connection.open_camera(self.request())
        h, w = self.image_size
        rgb = spaces.Box(0, 255, (h, w, 3), dtype=np.uint8)
        depth = spaces.Box(0.0, options.max_depth, (h, w), dtype=np.float32)
        if isinstance(state_space, spaces.Dict):  # a goal env keeps its three keys
            parts = dict(state_space.spaces)
            if options.with_state:
                parts["rgb"] = rgb
            else:
                parts["observation"] = rgb
            if options.depth:
                parts["depth"] = depth
        else:
            parts = {"observation": state_space, "rgb": rgb} if options.with_state else {"rgb": rgb}
            if options.depth:
                parts["depth"] = depth
        return spaces.Dict(parts)

    def request(self) -> CameraRequest:
        """The camera the options ask for, as the connection opens it: a described camera by name, or the
        view camera placed by ``view`` around the base (unless placed by the options), of the observation's
        size; on a robot, the driver's topics (``topics``, or the simulated camera's ``<camera>/image_raw``
        and ``<camera>/depth/image_raw``)."""
        options = self.options
        name = options.camera_name
        short = (name or CAMERA_ENTITY).strip("/").rsplit("/", 1)[-1]
        rgb_default, depth_default = self.topics.get(short, (f"{short}/image_raw", f"{short}/depth/image_raw"))
        rgb_topic = options.rgb_topic or rgb_default
        depth_topic = (options.depth_topic or depth_default) if options.depth else None
        if name is not None:
            return CameraRequest(name, None, None, options.fovy, options.width, options.height, rgb_topic, depth_topic)
        (lx, ly, lz), dist, az, el = self.view
        lookat = options.lookat if options.lookat is not None else tuple(float(v) for v in
                                                                         self.base_position + (lx, ly, lz))
        if options.position is not None:
            position = options.position
        else:
            a, e = math.radians(az), math.radians(el)
            position = (lookat[0] - dist * math.cos(e) * math.cos(a), lookat[1] - dist * math.cos(e) * math.sin(a),
                        lookat[2] - dist * math.sin(e))
        return CameraRequest(None, (float(position[0]), float(position[1]), float(position[2])),
                             (float(lookat[0]), float(lookat[1]), float(lookat[2])), options.fovy,
                             options.width or DEFAULT_SIZE, options.height or DEFAULT_SIZE, rgb_topic, depth_topic)

    # -- images ---------------------------------------------------------------------------------
    def read_images(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The RGB (H x W x 3 uint8) and depth (H x W float32 metres, or None) images now."""
        options = self.options
        h, w = self.image_size
        # The same call on both sides: a simulation renders the camera; a robot's connection gives its
        # driver's newest images (a stale one stops the env, as stale joint states do).
        frame = self.connection.read_camera(self.source, rgb=True, depth=options.depth, width=w, height=h,
                                            max_age=options.image_timeout)
        rgb, depth = frame.rgb, frame.depth
        assert rgb is not None
        rgb = np.array(rgb, dtype=np.uint8, copy=True)
        if depth is not None:
            depth = np.nan_to_num(np.asarray(depth, dtype=np.float32), nan=0.0, posinf=options.max_depth, neginf=0.0)
            depth = np.clip(depth, 0.0, options.max_depth, dtype=np.float32)
        return rgb, depth

    def with_images(self, obs: Any) -> Any:
        """One env's observation with its images."""
        rgb, depth = self.read_images()
        return self.compose(obs, rgb, depth)

    def compose(self, obs: Any, rgb: np.ndarray, depth: np.ndarray | None) -> Any:
        options = self.options
        if isinstance(obs, dict):
            out = dict(obs)
            if options.with_state:
                out["rgb"] = rgb
            else:
                out["observation"] = rgb
        else:
            out = {"observation": obs, "rgb": rgb} if options.with_state else {"rgb": rgb}
        if depth is not None:
            out["depth"] = depth
        return out

    @staticmethod
    def add_images(cameras: Sequence[Cameras | None], results: StepResults) -> StepResults:
        """N envs' step results with their images (unchanged when the envs have no camera)."""
        if all(c is None for c in cameras):
            return results
        if any(c is None for c in cameras):
            raise ValueError("a batch mixes envs with and without camera observations")
        rows = [c.compose(results.obs_row(j), *c.read_images()) for j, c in enumerate(cameras)]  # type: ignore[union-attr]
        results.obs = {k: np.stack([row[k] for row in rows]) for k in rows[0]}
        return results
