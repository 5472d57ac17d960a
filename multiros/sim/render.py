"""Offscreen RGB/depth images of a :class:`~multiros.sim.world.World`, goal markers, the viewer.

Headless rendering uses the backend ``import multiros`` chose when the user set no ``MUJOCO_GL``
(:mod:`multiros.gl_backend`: EGL on an NVIDIA GPU when its EGL vendor is installed, else software
EGL or OSMesa, said once at the first renderer). Markers are scene decorations added to each rendered
scene with ``mjv_initGeom``: they never take part in physics.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from multiros import gl_backend
from multiros.sim.errors import RenderError

_logger = logging.getLogger(__name__)

__all__ = ["FreeCamera", "Marker", "Renderer", "camera_pose", "depth_no_return", "display_available", "open_viewer",
           "project_points", "release_gl"]


def display_available() -> bool:
    """True when an X11 or Wayland display is set."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@dataclass(frozen=True)
class FreeCamera:
    """A free camera looking at ``lookat`` from ``distance``, ``azimuth`` and ``elevation`` (degrees)."""

    lookat: tuple[float, float, float] = (0.0, 0.0, 0.3)
    distance: float = 1.5
    azimuth: float = 135.0
    elevation: float = -25.0


@dataclass(frozen=True)
class Marker:
    """A visual marker: ``kind`` is ``"sphere"``, ``"box"`` or ``"arrow"`` (from ``position`` along
    ``direction``, ``size[0]`` = shaft radius, length = ``|direction|``)."""

    kind: str
    position: tuple[float, float, float]
    size: tuple[float, float, float] = (0.02, 0.02, 0.02)
    rgba: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.6)
    direction: tuple[float, float, float] | None = None


_KINDS = {"sphere": mujoco.mjtGeom.mjGEOM_SPHERE, "box": mujoco.mjtGeom.mjGEOM_BOX,
          "arrow": mujoco.mjtGeom.mjGEOM_ARROW}


def camera_pose(model: mujoco.MjModel, data: mujoco.MjData,
                camera: str | int | FreeCamera) -> tuple[np.ndarray, np.ndarray, float]:
    """Where a camera is: its position, its axes as matrix columns (x right, y up, looking along -z,
    MuJoCo's convention) and its vertical field of view in degrees. ``data`` must be after a forward
    pass (any stepped or rendered state is)."""
    if isinstance(camera, FreeCamera):
        az, el = np.radians(camera.azimuth), np.radians(camera.elevation)
        forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        up = np.array([-np.sin(el) * np.cos(az), -np.sin(el) * np.sin(az), np.cos(el)])
        pos = np.asarray(camera.lookat, dtype=float) - camera.distance * forward
        axes = np.column_stack([np.cross(forward, up), up, -forward])
        return pos, axes, float(model.vis.global_.fovy)
    cid = camera if isinstance(camera, int) else mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_CAMERA), camera)
    if not 0 <= cid < model.ncam:
        raise RenderError(f"camera {camera!r} not found; cameras: {[model.camera(i).name for i in range(model.ncam)]}")
    return data.cam_xpos[cid].copy(), data.cam_xmat[cid].reshape(3, 3).copy(), float(model.cam_fovy[cid])


def project_points(model: mujoco.MjModel, data: mujoco.MjData, camera: str | int | FreeCamera,
                   points: Sequence[Sequence[float]] | np.ndarray, *, width: int = 640,
                   height: int = 480) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates ``(column, row)`` (N x 2, float, origin at the top-left corner) of world
    points in a ``width`` x ``height`` image of ``camera``, and their depth along the view axis in
    metres (negative: behind the camera). The vertical field of view is the camera's; the
    horizontal one follows the image's aspect ratio, as in rendered images."""
    pos, axes, fovy = camera_pose(model, data, camera)
    local = (np.atleast_2d(np.asarray(points, dtype=float)) - pos) @ axes
    depth = -local[:, 2]
    focal = 0.5 * height / np.tan(np.radians(fovy) / 2.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        cols = 0.5 * width + focal * local[:, 0] / depth
        rows = 0.5 * height - focal * local[:, 1] / depth
    return np.column_stack([cols, rows]), depth


def depth_no_return(depth: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """``depth`` (metres) with the pixels that saw nothing, which MuJoCo reads as the far clipping
    plane, set to ``+inf``: "no return" as REP 118 has it for ROS depth images (in place; returned)."""
    far = float(model.vis.map.zfar * model.stat.extent)
    depth[depth >= np.float32(far * (1.0 - 1e-4))] = np.inf
    return depth


def release_gl(renderer: mujoco.Renderer) -> None:
    """Leave ``renderer``'s GL context current in no thread.

    ``mujoco.Renderer`` makes its context current in the thread that creates or renders with it and
    leaves it there; EGL (and GLFW, OSMesa) then refuse it to every other thread, and the node
    renders in one service's thread but frees renderers after a recompile in another's.
    """
    ctx = getattr(renderer, "_gl_context", None)
    modules = [base.__module__ for base in type(ctx).__mro__] if ctx is not None else []
    try:
        if any(m.startswith("mujoco.egl") for m in modules):
            from mujoco import egl

            if egl.EGL_DISPLAY is not None:
                egl.EGL.eglMakeCurrent(egl.EGL_DISPLAY, egl.EGL.EGL_NO_SURFACE, egl.EGL.EGL_NO_SURFACE,
                                       egl.EGL.EGL_NO_CONTEXT)
        elif any(m.startswith("mujoco.glfw") for m in modules):
            import glfw

            glfw.make_context_current(None)
        elif any(m.startswith("mujoco.osmesa") for m in modules):
            from mujoco import osmesa

            osmesa.osmesa.OSMesaMakeCurrent(None, None, osmesa.GL.GL_FLOAT, 0, 0)
    except Exception:  # noqa: BLE001 - best effort: a context left current only matters across threads
        pass


class Renderer:
    """Renders images of a world; one MuJoCo renderer per image size, rebuilt after recompiles.

    Args:
        world: the world (its ``model``/``data`` are read at each render).
        max_geom: scene capacity (bodies' geoms plus markers).
    """

    def __init__(self, world, *, max_geom: int = 10000) -> None:
        self.world = world
        self.max_geom = max_geom
        self._renderers: dict[tuple[int, int, bool], mujoco.Renderer] = {}
        self._markers: dict[str, Marker] = {}
        # Markers change from the node's marker topic, in whichever thread delivers it, while an
        # image may be rendering in a service thread: this lock alone guards them (not the world's).
        self._markers_lock = threading.Lock()
        self._default_camera = FreeCamera(*world.options.camera) if hasattr(world, "options") else FreeCamera()
        world.add_change_callback(self._drop_renderers)

    # ------------------------------------------------------------------ markers
    def show_marker(self, marker_id: str, kind: str = "sphere", position: Sequence[float] = (0, 0, 0), *,
                    size: Sequence[float] = (0.02, 0.02, 0.02), rgba: Sequence[float] = (1.0, 0.0, 0.0, 0.6),
                    direction: Sequence[float] | None = None) -> None:
        """Add or replace a marker drawn in every rendered image (and the viewer)."""
        if kind not in _KINDS:
            raise ValueError(f"marker kind '{kind}' is not one of {sorted(_KINDS)}")
        values = list(position) + list(size) + list(rgba) + list(direction or ())
        if not np.all(np.isfinite(np.asarray(values, dtype=float))):
            raise ValueError(f"marker '{marker_id}': position/size/rgba must be finite")
        if kind == "arrow" and direction is None:
            raise ValueError(f"marker '{marker_id}': an arrow needs a direction")
        marker = Marker(kind, tuple(position), tuple(size), tuple(rgba),
                        tuple(direction) if direction is not None else None)
        with self._markers_lock:
            self._markers[marker_id] = marker

    def delete_marker(self, marker_id: str | None = None) -> None:
        """Remove one marker, or all of them when ``marker_id`` is None."""
        with self._markers_lock:
            if marker_id is None:
                self._markers.clear()
            else:
                self._markers.pop(marker_id, None)

    @property
    def markers(self) -> dict[str, Marker]:
        with self._markers_lock:
            return dict(self._markers)

    def add_markers_to_scene(self, scene: mujoco.MjvScene) -> None:
        """Append the markers to a scene (also used by the viewer's user scene)."""
        for marker in self.markers.values():
            if scene.ngeom >= scene.maxgeom:
                break
            geom = scene.geoms[scene.ngeom]
            mat = np.eye(3).ravel()
            size = np.asarray(marker.size, dtype=float)
            if marker.kind == "arrow":
                mujoco.mjv_initGeom(geom, int(_KINDS["arrow"]), np.zeros(3), np.zeros(3), mat,
                                    np.asarray(marker.rgba, dtype=np.float32))
                start = np.asarray(marker.position, dtype=float)
                mujoco.mjv_connector(geom, int(_KINDS["arrow"]), float(size[0]), start,
                                     start + np.asarray(marker.direction, dtype=float))
            else:
                mujoco.mjv_initGeom(geom, int(_KINDS[marker.kind]), size, np.asarray(marker.position, float),
                                    mat, np.asarray(marker.rgba, dtype=np.float32))
            scene.ngeom += 1

    # ------------------------------------------------------------------ images
    def _renderer(self, width: int, height: int, fast: bool = False) -> mujoco.Renderer:
        key = (int(width), int(height), bool(fast))
        r = self._renderers.get(key)
        if r is None:
            model = self.world.model
            if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
                raise RenderError(f"image size {width}x{height} exceeds the offscreen buffer "
                                  f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}")
            # A shadow map of about two texels per image pixel: MuJoCo's default 4096 x 4096 map is
            # most of a frame's cost in software GL (llvmpipe: ~110 ms of an 84 x 84 frame, ~2 ms
            # with the map at 512). The map size is read when the context is made.
            # A fast renderer (camera sensors' observations) draws no shadows, so it needs no map,
            # and no multisampling (the sample count is read when the context is made too).
            shadow, samples = int(model.vis.quality.shadowsize), int(model.vis.quality.offsamples)
            model.vis.quality.shadowsize = 0 if fast else min(shadow, max(512, 2 * max(key[:2])))
            if fast:
                model.vis.quality.offsamples = 0
            gl_backend.log_choice_once(_logger)
            try:
                r = mujoco.Renderer(model, height=key[1], width=key[0], max_geom=self.max_geom)
            except Exception as exc:  # GL context creation fails with assorted errors
                raise RenderError(f"offscreen rendering is unavailable ({exc}); on a headless machine set "
                                  f"MUJOCO_GL=egl (or osmesa) before importing mujoco") from exc
            finally:
                model.vis.quality.shadowsize, model.vis.quality.offsamples = shadow, samples
            release_gl(r)
            self._renderers[key] = r
        return r

    def _camera(self, camera: str | int | FreeCamera | None):
        if camera is None:
            camera = self._default_camera
        if isinstance(camera, FreeCamera):
            cam = mujoco.MjvCamera()
            cam.type = int(mujoco.mjtCamera.mjCAMERA_FREE)
            cam.lookat[:] = camera.lookat
            cam.distance, cam.azimuth, cam.elevation = camera.distance, camera.azimuth, camera.elevation
            return cam
        if isinstance(camera, str):
            cid = mujoco.mj_name2id(self.world.model, int(mujoco.mjtObj.mjOBJ_CAMERA), camera)
            if cid < 0:
                names = [self.world.model.camera(i).name for i in range(self.world.model.ncam)]
                raise RenderError(f"camera '{camera}' not found; cameras: {names} (or use a FreeCamera)")
            return cid
        return int(camera)

    def render(self, camera: str | int | FreeCamera | None = None, *, width: int = 640, height: int = 480,
               depth: bool = False, fast: bool = False, markers: bool = True) -> np.ndarray:
        """Render one image.

        Args:
            camera: a camera name or id of the model, a :class:`FreeCamera`, or None (the default view).
            width, height: image size in pixels.
            depth: return depth in metres (float32, HxW) instead of RGB (uint8, HxWx3).
            fast: no shadows, no reflections, no multisampling (what a camera sensor's observations
                need; in software GL a tenth of the cost, ``benchmarks/bench_camera_cost.py``).
            markers: draw the goal markers (a camera sensor does not: a real camera sees none).
        """
        r = self._renderer(width, height, fast)
        self.world.sync_kinematics()  # the image shows the joint state, not one physics step before it
        r.update_scene(self.world.data, camera=self._camera(camera))
        if fast:
            r.scene.flags[int(mujoco.mjtRndFlag.mjRND_SHADOW)] = 0
            r.scene.flags[int(mujoco.mjtRndFlag.mjRND_REFLECTION)] = 0
        if markers:
            self.add_markers_to_scene(r.scene)
        try:
            if depth:
                r.enable_depth_rendering()
                try:
                    return depth_no_return(r.render().copy(), r.model)
                finally:
                    r.disable_depth_rendering()
            return r.render().copy()
        finally:
            release_gl(r)

    def rgb(self, camera: str | int | FreeCamera | None = None, *, width: int = 640, height: int = 480) -> np.ndarray:
        """An RGB image (uint8, HxWx3)."""
        return self.render(camera, width=width, height=height)

    def depth(self, camera: str | int | FreeCamera | None = None, *, width: int = 640,
              height: int = 480) -> np.ndarray:
        """A depth image in metres (float32, HxW)."""
        return self.render(camera, width=width, height=height, depth=True)

    def project(self, points: Sequence[Sequence[float]] | np.ndarray, camera: str | int | FreeCamera | None = None,
                *, width: int = 640, height: int = 480) -> tuple[np.ndarray, np.ndarray]:
        """:func:`project_points` for this world and ``camera`` (None: the default view)."""
        camera = self._default_camera if camera is None else camera
        self.world.sync_kinematics()
        return project_points(self.world.model, self.world.data, camera, points, width=width, height=height)

    def _drop_renderers(self) -> None:
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()

    def close(self) -> None:
        """Close every cached renderer (their GL contexts)."""
        self._drop_renderers()


def open_viewer(world, renderer: Renderer | None = None):
    """Open MuJoCo's interactive passive viewer on the world (needs a display).

    The caller calls ``handle.sync()`` after stepping (under its lock) and ``handle.close()`` at
    the end. Markers of ``renderer`` are drawn in the viewer's user scene at each sync.

    Raises:
        RenderError: no display (DISPLAY/WAYLAND_DISPLAY unset) or the viewer cannot start.
    """
    if not display_available():
        raise RenderError("gui=True needs a display (DISPLAY or WAYLAND_DISPLAY is not set); run headless "
                          "(gui=False) and use offscreen rendering instead")
    try:
        import mujoco.viewer

        handle = mujoco.viewer.launch_passive(world.model, world.data)
    except Exception as exc:
        raise RenderError(f"the MuJoCo viewer could not start: {exc}") from exc
    if renderer is not None:
        with handle.lock():
            handle.user_scn.ngeom = 0
            renderer.add_markers_to_scene(handle.user_scn)
    return handle
