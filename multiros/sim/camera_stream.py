"""Camera topics rendered beside the physics, not in it: each camera at its own capped rate.

Why: rendering a subscribed camera after every step, inside the physics loop, held the world for
the whole frame: the playing node's real-time factor fell from 0.70 to 0.58 with the default camera
subscribed and to 0.14 with the Zed2 (its RGB, depth and right images). Here one thread of the node
serves every subscribed camera at most ``rate`` times per second of wall clock (the sensor's
``<update_rate>``, else the node's ``camera_rate``, 15 Hz by default), and only when the world
changed since its last image or a subscriber came (a paused world sends its image to a new
subscriber, then nothing new). Under the node's lock it only copies what the camera sees into a
MuJoCo scene (``mjv_updateScene``, tens of microseconds); the rendering and the message encoding
run after the lock is released, while the physics goes on. A
frame slower than the camera's period stretches it: the thread renders at most half of the time,
so a slow software renderer cannot take every core. When the playing node falls behind its
real-time factor while cameras render, one warning gives the measured cost and the fix.

Observation cameras (an env's images, read once per step in lockstep through
:meth:`~multiros.sim.cameras.CameraHub.read`) are not rendered here: they stay exactly as they were.
An image an observation already rendered for the same state is published as is.
"""

from __future__ import annotations

import copy
import threading
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from multiros.sim.cameras import CameraHub, fill_camera_info, fill_image
from multiros.sim.errors import RenderError
from multiros.sim.render import depth_no_return, release_gl

__all__ = ["DEFAULT_CAMERA_RATE", "CameraStream"]

DEFAULT_CAMERA_RATE = 15.0  # Hz
_IDLE_POLL_SEC = 0.1  # how often a camera nobody subscribes to checks again
_MAX_BUSY = 0.5  # the most of the wall clock the thread spends on frames
_WINDOW_SEC = 2.0  # cost accounting window of the slowdown warning


class _Camera:
    """A subscribed camera's schedule and cost."""

    __slots__ = ("due", "key", "listeners", "cost", "frames", "busy")

    def __init__(self) -> None:
        self.due = 0.0
        self.key: tuple = ()
        self.listeners = 0  # subscriptions to its topics at its last frame
        self.cost = 0.0  # seconds per frame, a running mean
        self.frames = 0
        self.busy = 0.0  # seconds spent in the current window


class CameraStream:
    """The thread publishing a node's camera topics (see the module docstring).

    Args:
        hub: the node's cameras (specs, publishers, the observations' image cache).
        world: the node's world.
        lock: the node's lock.
        rate: default images per second of a camera without ``<update_rate>`` (> 0).
        pacing: ``() -> (playing, target real-time factor, measured real-time factor or None)``.
        warn, error: log a warning / an error.
    """

    def __init__(self, hub: CameraHub, world: Any, lock: Any, *, rate: float = DEFAULT_CAMERA_RATE,
                 pacing: Callable[[], tuple[bool, float, float | None]] = lambda: (False, 0.0, None),
                 warn: Callable[[str], None] = lambda text: None,
                 error: Callable[[str], None] = lambda text: None) -> None:
        if not (isinstance(rate, (int, float)) and np.isfinite(rate) and rate > 0):
            raise ValueError(f"camera_rate must be a positive number of images per second, got {rate!r}")
        self.hub, self.world, self.lock = hub, world, lock
        self.rate = float(rate)
        self._rates: dict[str, float] = {}
        self._pacing, self._warn, self._error = pacing, warn, error
        self._cameras: dict[str, _Camera] = {}
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._model: Any = None
        self._renderers_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._window = time.monotonic()
        self.warned = False
        self._built = False  # a renderer was made in the current window (its stall is not the cameras' pace)
        self.renders = 0  # frames rendered by this thread (the rest came from the observations' cache)

    # -- settings -------------------------------------------------------------------------------
    def set_rate(self, camera: str, rate: float | None) -> None:
        """Images per second of one camera (None: back to its sensor's or the default)."""
        if rate is None:
            self._rates.pop(camera, None)
            return
        if not (isinstance(rate, (int, float)) and np.isfinite(rate) and rate > 0):
            raise ValueError(f"camera {camera!r}: rate must be a positive number of images per second, got {rate!r}")
        self._rates[camera] = float(rate)

    def rate_of(self, spec: Any) -> float:
        """The images per second of a camera: set here, else its sensor's ``<update_rate>``, else the default."""
        return self._rates.get(spec.camera) or spec.rate or self.rate

    # -- thread ---------------------------------------------------------------------------------
    def start(self) -> None:
        """Start the thread (once)."""
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._run, name="uniros-cameras", daemon=True)
            self._thread.start()

    def close(self) -> None:
        """Stop the thread and free its renderers."""
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=10.0)
        self.drop_renderers()

    def drop_renderers(self) -> None:
        """Free the thread's renderers (GL contexts); made again at the next frame."""
        with self._renderers_lock:
            for r in self._renderers.values():
                r.close()
            self._renderers.clear()
            self._model = None

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            wait = _IDLE_POLL_SEC
            for entry in self.hub.entries():
                if self._stop.is_set():
                    return
                if entry.failed:
                    continue
                state = self._cameras.setdefault(entry.spec.camera, _Camera())
                if state.due <= now:
                    self._serve(entry, state)
                    now = time.monotonic()
                wait = min(wait, max(0.0, state.due - now))
            self._check_pace(time.monotonic())
            self._stop.wait(max(wait, 0.002))

    # -- one camera -----------------------------------------------------------------------------
    def _serve(self, entry: Any, state: _Camera) -> None:
        spec = entry.spec
        kinds = [(False, entry.rgb, entry.rgb_info)] + ([(True, entry.depth, entry.depth_info)] if spec.depth else [])
        wanted = [(depth, image_pub, info_pub, image_pub.has_subscribers(), info_pub.has_subscribers())
                  for depth, image_pub, info_pub in kinds]
        wanted = [w for w in wanted if w[3] or w[4]]
        start = time.monotonic()
        period = 1.0 / self.rate_of(spec)
        if not wanted:
            state.due = start + min(period, _IDLE_POLL_SEC)
            state.listeners = 0
            return
        listeners = sum(pub.get_subscription_count() for w in wanted for pub in w[1:3])
        images: dict[bool, np.ndarray] = {}
        built = False
        try:
            built = self._ensure_renderer(spec)
            with self.lock:
                key = self.hub.state_key()
                if key == state.key and listeners <= state.listeners:  # nothing new to see, nobody new
                    state.due = start + period
                    state.listeners = listeners
                    return
                stamp = float(self.world.time)
                intrinsics = self.hub.intrinsics(spec.camera, spec.width, spec.height)
                render = []
                for depth, _, _, want_image, _ in wanted:
                    if want_image:
                        cached = self.hub.cached(spec.camera, spec.width, spec.height, depth, key)
                        if cached is not None:
                            images[depth] = cached
                        else:
                            render.append(depth)
                if render:
                    self._renderers_lock.acquire()  # held until the frame is read back, after the lock
                    try:
                        renderer = self._scene(spec)
                    except BaseException:
                        self._renderers_lock.release()
                        raise
                    if renderer is None:  # a recompile since the renderer was made: next time
                        self._renderers_lock.release()
                        state.due = start
                        return
            if render:
                try:
                    for depth in render:
                        images[depth] = self._render(renderer, depth)
                    self.renders += 1
                finally:
                    release_gl(renderer)
                    self._renderers_lock.release()
        except RenderError as exc:
            entry.failed = True
            self._error(f"camera {spec.camera!r} stopped publishing: {exc}")
            return
        for depth, image_pub, info_pub, want_image, want_info in wanted:
            if want_image:
                image_pub.publish(fill_image(self.hub.image_type(), images[depth], stamp, spec.frame_id))
            if want_info:
                info_pub.publish(fill_camera_info(self.hub.info_type(), intrinsics, stamp, spec.frame_id,
                                                  0.0 if depth else spec.baseline))
        cost = time.monotonic() - start
        state.key, state.listeners = key, listeners
        self._built = self._built or built
        if not built:  # a frame that made a GL context is no measure of the next ones
            state.cost = cost if state.frames == 0 else 0.8 * state.cost + 0.2 * cost
            state.frames += 1
            state.busy += cost
        state.due = start + max(period, cost / _MAX_BUSY)

    def _ensure_renderer(self, spec: Any) -> bool:
        """Make the renderer of the camera's image size if there is none for the world's model;
        whether it made one. The GL context (seconds in software GL) is made on a copy of the model
        with the node's lock released: the physics goes on meanwhile."""
        key = (spec.width, spec.height)
        with self.lock:
            model = self.world.model
            with self._renderers_lock:
                if model is self._model and key in self._renderers:
                    return False
            if spec.width > model.vis.global_.offwidth or spec.height > model.vis.global_.offheight:
                raise RenderError(f"image size {spec.width}x{spec.height} exceeds the offscreen buffer "
                                  f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}")
            private = copy.copy(model)  # milliseconds; the same model, its settings ours to change
        private.vis.quality.shadowsize, private.vis.quality.offsamples = 0, 0  # no shadows, no multisampling
        try:
            r = mujoco.Renderer(private, height=spec.height, width=spec.width, max_geom=10000)
        except Exception as exc:  # GL context creation fails with assorted errors
            raise RenderError(f"offscreen rendering is unavailable ({exc}); on a headless machine set "
                              f"MUJOCO_GL=egl (or osmesa) before importing mujoco") from exc
        release_gl(r)
        with self._renderers_lock:
            if model is not self._model:  # a recompile: contexts of the old model go
                for old in self._renderers.values():
                    old.close()
                self._renderers.clear()
                self._model = model
            previous = self._renderers.pop(key, None)
            if previous is not None:
                previous.close()
            self._renderers[key] = r
        return True

    def _scene(self, spec: Any) -> mujoco.Renderer | None:
        """The thread's renderer of this image size with the camera's view of the world now, or
        None when the world recompiled since it was made (caller holds the node's lock and the
        renderers' lock)."""
        model = self.world.model
        r = self._renderers.get((spec.width, spec.height))
        if model is not self._model or r is None:
            return None
        cid = mujoco.mj_name2id(model, int(mujoco.mjtObj.mjOBJ_CAMERA), spec.camera)
        if cid < 0:
            raise RenderError(f"camera {spec.camera!r} not found")
        self.world.sync_kinematics()
        r.update_scene(self.world.data, camera=cid)
        r.scene.flags[int(mujoco.mjtRndFlag.mjRND_SHADOW)] = 0
        r.scene.flags[int(mujoco.mjtRndFlag.mjRND_REFLECTION)] = 0
        return r

    @staticmethod
    def _render(r: mujoco.Renderer, depth: bool) -> np.ndarray:
        if not depth:
            return r.render()
        r.enable_depth_rendering()
        try:
            return depth_no_return(r.render(), r.model)
        finally:
            r.disable_depth_rendering()

    # -- the slowdown warning -------------------------------------------------------------------
    def _check_pace(self, now: float) -> None:
        if now - self._window < _WINDOW_SEC:
            return
        elapsed, self._window = now - self._window, now
        busy = {name: s.busy for name, s in self._cameras.items() if s.busy > 0}
        costs = {name: s.cost for name, s in self._cameras.items() if s.busy > 0}
        for s in self._cameras.values():
            s.busy = 0.0
        built, self._built = self._built, False
        if self.warned or not busy or built:
            return
        playing, target, measured = self._pacing()
        if not playing or target <= 0 or measured is None or measured >= 0.9 * target:
            return
        self.warned = True
        share = sum(busy.values()) / elapsed
        each = ", ".join(f"{name} {1000 * cost:.0f} ms" for name, cost in costs.items())
        self._warn(f"camera rendering for subscribers costs {1000 * sum(costs.values()):.0f} ms a frame ({each}; "
                   f"{100 * share:.0f} % of the wall clock) and the simulation runs at real-time factor "
                   f"{measured:.2f} of {target:.2f}; lower the camera rate (the node's camera_rate, "
                   f"uniros-sim --camera-rate, or the sensor's <update_rate>) or subscribe fewer cameras")
