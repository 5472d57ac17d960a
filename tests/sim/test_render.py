"""Offscreen rendering (headless EGL), markers, viewer refusal without a display."""

from __future__ import annotations

import numpy as np
import pytest

import multiros.sim  # noqa: F401  (chooses MUJOCO_GL=egl before mujoco is imported, when headless)
from multiros.sim.errors import RenderError

ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
BALL = "package://test_arm_description/urdf/ball.xml"

pytestmark = pytest.mark.slow  # each test creates an EGL context (~2 s)


@pytest.fixture
def renderer(arm_world):
    from multiros.sim.render import Renderer

    r = Renderer(arm_world)
    try:
        r.rgb(width=32, height=24)
    except RenderError as exc:
        r.close()
        pytest.skip(f"no GL backend: {exc}")
    yield r
    r.close()


def test_rgb_and_depth(renderer):
    rgb = renderer.rgb(width=160, height=120)
    depth = renderer.depth(width=160, height=120)
    assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8 and rgb.std() > 0
    assert depth.shape == (120, 160) and depth.dtype == np.float32
    assert 0.1 < depth.min() < depth.max()


def test_free_camera_and_named_camera_errors(renderer):
    from multiros.sim.render import FreeCamera

    far = renderer.depth(FreeCamera(lookat=(0, 0, 0.3), distance=3.0), width=64, height=48)
    near = renderer.depth(FreeCamera(lookat=(0, 0, 0.3), distance=1.0), width=64, height=48)
    assert near[24, 32] < far[24, 32]
    with pytest.raises(RenderError, match="camera 'nope' not found"):
        renderer.rgb("nope", width=32, height=24)


def test_marker_changes_image_not_physics(renderer, arm_world):
    cam = dict(width=80, height=60)
    plain = renderer.rgb(**cam)
    nbody = arm_world.model.nbody
    renderer.show_marker("goal", "sphere", (0.0, 0.0, 0.3), size=(0.1, 0.1, 0.1), rgba=(1, 0, 0, 1))
    renderer.show_marker("dir", "arrow", (0.0, 0.0, 0.3), direction=(0.2, 0, 0))
    marked = renderer.rgb(**cam)
    assert np.abs(marked.astype(int) - plain.astype(int)).sum() > 0
    assert arm_world.model.nbody == nbody
    renderer.delete_marker()
    assert renderer.markers == {}
    with pytest.raises(ValueError):
        renderer.show_marker("x", "arrow", (0, 0, 0))


def test_renderer_survives_recompile(renderer, arm_world):
    renderer.rgb(width=32, height=24)
    arm_world.spawn("ball", BALL, pose=([0.3, 0, 0.3], [1, 0, 0, 0]))
    assert renderer.rgb(width=32, height=24).shape == (24, 32, 3)


def test_viewer_refuses_without_display(arm_world, monkeypatch):
    from multiros.sim.render import open_viewer

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RenderError, match="needs a display"):
        open_viewer(arm_world)


def test_renderer_is_usable_from_another_thread(renderer, arm_world):
    # The node renders in one service's thread and recompiles (which frees renderers) in another's:
    # a GL context left current in the rendering thread made the spawn fail (EGL_BAD_ACCESS).
    import threading

    images = []
    worker = threading.Thread(target=lambda: images.append(renderer.rgb(width=32, height=24)))
    worker.start()
    worker.join(timeout=30)
    assert len(images) == 1
    arm_world.spawn("ball", BALL, pose=([0.3, 0, 0.3], [1, 0, 0, 0]))
    assert renderer.rgb(width=32, height=24).shape == (24, 32, 3)


def test_projected_points_land_on_their_markers(renderer):
    from multiros.sim.render import FreeCamera

    for camera in (None, FreeCamera(lookat=(0.2, 0.1, 0.3), distance=1.2, azimuth=60, elevation=-30)):
        for point in ((0.3, 0.2, 0.5), (-0.4, 0.1, 0.2)):
            renderer.show_marker("p", "sphere", point, size=(0.02, 0.02, 0.02), rgba=(0, 1, 0, 1))
            image = renderer.rgb(camera, width=320, height=200).astype(int)
            rows, cols = np.nonzero((image[..., 1] > 100) & (image[..., 1] > image[..., 0] + 60))
            (uv,), (depth,) = renderer.project([point], camera, width=320, height=200)
            assert depth > 0 and len(cols) > 0
            assert abs(cols.mean() + 0.5 - uv[0]) < 2 and abs(rows.mean() + 0.5 - uv[1]) < 2
