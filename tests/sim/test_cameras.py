"""Camera topics of the simulation node (multiros.sim.cameras): the real drivers' topic names, the
Image topic carrying the pixels a composed client reads, depth in metres, images following the
arm, rendering only when someone subscribes or reads (once per state), and a clear error without GL."""

from __future__ import annotations

import time

import numpy as np
import pytest

import multiros.sim  # noqa: F401  (headless MuJoCo)
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_message
from multiros.sim import launch
from multiros.sim.cameras import CameraIntrinsics, camera_specs
from multiros.sim.errors import RenderError
from multiros.sim.limits import MAX_CAMERA_PIXELS

Image = get_message("sensor_msgs/msg/Image")
CameraInfo = get_message("sensor_msgs/msg/CameraInfo")
ZED = "/rx200/zed2/zed_node"
RX200_ZED2 = "package://rx200_description/urdf/rx200.urdf.xacro?use_zed2=true"
# A camera 1 m above the floor (z = 0), looking straight down (a Gazebo camera looks along its +x),
# 64 x 48 pixels with a 60 degree vertical field of view.
DOWN_CAMERA = f"""<robot name="overhead"><link name="world"/><link name="mount"/>
  <joint name="fix" type="fixed"><parent link="world"/><child link="mount"/><origin xyz="1.5 1.5 1.0"/></joint>
  <gazebo reference="mount"><sensor type="depth" name="down"><pose>0 0 0 0 {np.pi / 2} 0</pose>
    <camera><horizontal_fov>{2 * np.arctan(np.tan(np.radians(30)) * 64 / 48)}</horizontal_fov>
      <image><width>64</width><height>48</height></image></camera></sensor></gazebo></robot>"""

pytestmark = pytest.mark.slow  # an EGL context per module (~2 s) and a few renders


@pytest.fixture(scope="module")
def conn():
    connection = launch.connect("composed", timestep=0.004)
    try:
        connection.client.spawn_entity("rx200", uri=RX200_ZED2, position=(0.0, 0.0, 0.0))
        connection.client.spawn_entity("overhead", resource_string=DOWN_CAMERA)
        try:
            connection.read_camera("overhead/down", width=8, height=8)
        except RenderError as exc:
            pytest.skip(f"no GL backend: {exc}")
        yield connection
    finally:
        connection.close()


def _receive(conn, topics: dict[str, type], steps: int = 1) -> dict[str, list]:
    """Subscribe, step the simulation, and collect messages per topic until one shows the state after
    the step (a new subscriber may first get the image of the state before it)."""
    received: dict[str, list] = {t: [] for t in topics}
    subs = [conn.node.create_subscription(kind, topic, received[topic].append, 10) for topic, kind in topics.items()]
    try:
        conn.client.step_simulation(steps)
        now = conn.sim_node.world.time
        executor = SingleThreadedExecutor(context=conn.context)
        executor.add_node(conn.node)
        deadline = time.monotonic() + 30.0

        def after_step(messages: list) -> bool:
            stamp = messages[-1].header.stamp if messages else None
            return stamp is not None and abs(stamp.sec + stamp.nanosec * 1e-9 - now) < 1e-6

        while not all(after_step(m) for m in received.values()) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        executor.remove_node(conn.node)
    finally:
        for sub in subs:
            conn.node.destroy_subscription(sub)
    assert all(after_step(m) for m in received.values()), {t: len(m) for t, m in received.items()}
    return received


def test_cameras_publish_under_the_real_drivers_topics(conn):
    specs = {s.camera: s for s in conn.sim_node.camera_specs()}
    left = specs["rx200/zed2_left"]
    assert (left.rgb_topic, left.rgb_info_topic) == (f"{ZED}/rgb/image_rect_color", f"{ZED}/rgb/camera_info")
    assert (left.depth_topic, left.depth_info_topic) == (f"{ZED}/depth/depth_registered", f"{ZED}/depth/camera_info")
    assert (left.width, left.height, left.frame_id) == (640, 360, "rx200/zed2_left_camera_optical_frame")
    right = specs["rx200/zed2_right"]
    assert right.rgb_topic == f"{ZED}/right/image_rect_color" and not right.depth
    # A plugin-less camera: gazebo_ros_camera's defaults under the entity's namespace; an MJCF camera too.
    assert specs["rx200/render_camera"].rgb_topic == "/rx200/render_camera/image_raw"
    assert specs["overhead/down"].rgb_info_topic == "/overhead/down/camera_info"
    assert (specs["overhead/down"].width, specs["overhead/down"].height) == (64, 48)


def test_image_topics_carry_the_pixels_a_composed_client_reads(conn):
    topics = {f"{ZED}/rgb/image_rect_color": Image, f"{ZED}/depth/depth_registered": Image,
              f"{ZED}/rgb/camera_info": CameraInfo}
    received = _receive(conn, topics)
    frame = conn.read_camera("rx200/zed2_left", depth=True)  # the state the last message shows
    rgb, depth = received[f"{ZED}/rgb/image_rect_color"][-1], received[f"{ZED}/depth/depth_registered"][-1]
    assert (rgb.encoding, rgb.height, rgb.width, rgb.step) == ("rgb8", 360, 640, 3 * 640)
    assert bytes(rgb.data) == np.asarray(frame.rgb).tobytes()
    assert (depth.encoding, depth.is_bigendian) == ("32FC1", 0)
    np.testing.assert_array_equal(np.frombuffer(bytes(depth.data), "<f4").reshape(360, 640), frame.depth)
    info = received[f"{ZED}/rgb/camera_info"][-1]
    np.testing.assert_allclose(np.asarray(info.k).reshape(3, 3), frame.intrinsics.k)
    assert info.header.frame_id == rgb.header.frame_id == "rx200/zed2_left_camera_optical_frame"
    assert rgb.header.stamp == info.header.stamp


def test_depth_is_metres_along_the_optical_axis(conn):
    frame = conn.read_camera("overhead/down", rgb=False, depth=True)
    assert frame.depth.dtype == np.float32 and frame.depth.shape == (48, 64)
    # The floor is a plane 1 m away, square to the view: every pixel's z-depth is 1 m.
    np.testing.assert_allclose(frame.depth, 1.0, atol=2e-3)
    # fovy 60 degrees over 48 rows: fy = 24 / tan(30 degrees).
    assert frame.intrinsics == CameraIntrinsics(64, 48, 24 / np.tan(np.radians(30)), 24 / np.tan(np.radians(30)),
                                                31.5, 23.5)


def test_images_follow_the_arm_and_render_once_per_state(conn):
    client = conn.client
    first = conn.read_camera("rx200/zed2_left")
    again = conn.read_camera("rx200/zed2_left")
    assert again.rgb is first.rgb, "the same state is rendered once"
    client.set_robot_joint_state("rx200", ["waist", "shoulder", "elbow"], [0.8, 0.4, -0.6])
    moved = conn.read_camera("rx200/zed2_left")
    changed = np.abs(moved.rgb.astype(int) - first.rgb.astype(int)).sum(axis=2) > 30
    assert changed.mean() > 0.005, f"only {changed.mean():.4f} of the pixels changed"
    client.set_robot_joint_state("rx200", ["waist", "shoulder", "elbow"], [0.0, 0.0, 0.0])


def test_renders_only_for_subscribers_or_reads(conn, monkeypatch):
    renderer = conn.sim_node._get_renderer()
    stream = conn.sim_node.camera_stream
    calls = []
    real = renderer.render

    def counting(camera, **kwargs):
        calls.append(camera)
        return real(camera, **kwargs)

    monkeypatch.setattr(renderer, "render", counting)
    before = stream.renders
    conn.client.step_simulation(3)
    assert calls == [] and stream.renders == before, "nobody subscribed: nothing rendered"
    _receive(conn, {"/overhead/down/image_raw": Image}, steps=1)
    # The topic's image is rendered beside the physics (multiros.sim.camera_stream): once for the new
    # subscriber if it came before the step, once for the new state; the observations' renderer is not used.
    assert before + 1 <= stream.renders <= before + 2 and calls == []


def test_errors_name_the_camera_and_the_fix(conn, monkeypatch):
    with pytest.raises(RenderError, match="camera 'rx200/nope' not found"):
        conn.read_camera("rx200/nope")
    with pytest.raises(RenderError, match="not within 1..4096"):
        conn.read_camera("overhead/down", width=0)
    # No GL: reading says how to fix it; a subscribed camera stops publishing with that message
    # instead of failing the step.
    import mujoco

    renderer = conn.sim_node._get_renderer()
    renderer.close()

    def no_gl(*args, **kwargs):
        raise RuntimeError("gladLoadGL error")

    monkeypatch.setattr(mujoco, "Renderer", no_gl)
    conn.client.set_robot_joint_state("rx200", ["waist"], [0.1])  # a new state: no cached image
    with pytest.raises(RenderError, match="MUJOCO_GL=egl"):
        conn.read_camera("overhead/down", width=16, height=12)
    errors = []
    conn.sim_node.camera_stream.drop_renderers()
    monkeypatch.setattr(conn.sim_node.camera_stream, "_error", errors.append)
    sub = conn.node.create_subscription(Image, "/overhead/down/image_raw", lambda msg: None, 1)
    try:
        conn.client.step_simulation(2)
        deadline = time.monotonic() + 10.0  # the camera thread renders beside the step
        while not errors and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        conn.node.destroy_subscription(sub)
    assert len(errors) == 1 and "MUJOCO_GL=egl" in errors[0]
    (entry,) = [e for e in conn.sim_node.cameras.entries() if e.spec.camera == "overhead/down"]
    assert entry.failed, "the camera stops publishing (its error is logged once), the node goes on"
    monkeypatch.undo()
    with conn.sim_node.lock:
        conn.sim_node._attach_robot("overhead")  # publishing again


def test_camera_specs_read_plugin_names_without_gl():
    urdf = """<robot name="r"><link name="l"/>
      <gazebo reference="l"><sensor type="rgbd_camera" name="cam">
        <camera><image><width>32</width><height>24</height></image></camera>
        <update_rate>30</update_rate>
        <plugin name="p" filename="libgazebo_ros_camera.so"><hack_baseline>0.07</hack_baseline>
          <ros><namespace>head</namespace>
          <remapping>~/eye/image_raw:=eye/color</remapping></ros><camera_name>eye</camera_name></plugin>
      </sensor><sensor type="camera" name="bad name!"/></gazebo></robot>"""

    class Model:
        ncam = 1

        @staticmethod
        def camera(i):
            return type("C", (), {"name": "robot/cam"})

    (spec,) = camera_specs("robot", "/robot", urdf, Model())
    assert spec.rgb_topic == "/robot/head/eye/color" and spec.rgb_info_topic == "/robot/head/eye/camera_info"
    assert spec.depth_topic == "/robot/head/eye/depth/image_raw" and (spec.width, spec.height) == (32, 24)
    assert (spec.rate, spec.baseline, spec.frame_name) == (30.0, 0.07, "")


# A camera 1 m above the floor looking straight up: it sees nothing at all.
UP_CAMERA = DOWN_CAMERA.replace('name="overhead"', 'name="skyward"').replace('"mount"', '"sky_mount"').replace(
    'name="down"', 'name="up"').replace(f"0 {np.pi / 2} 0</pose>", f"0 {-np.pi / 2} 0</pose>")


def test_depth_with_no_return_is_infinity_as_rep_118_has_it(conn):
    assert UP_CAMERA != DOWN_CAMERA and f"{-np.pi / 2}" in UP_CAMERA
    conn.client.spawn_entity("skyward", resource_string=UP_CAMERA)
    try:
        frame = conn.read_camera("skyward/up", rgb=False, depth=True)
        assert np.isposinf(frame.depth).all(), "no return reads +inf, not the far clipping plane"
        received = _receive(conn, {"/skyward/up/depth/image_raw": Image})
        depth = received["/skyward/up/depth/image_raw"][-1]
        assert np.isposinf(np.frombuffer(bytes(depth.data), "<f4")).all()
        assert np.isfinite(conn.read_camera("overhead/down", rgb=False, depth=True).depth).all()
    finally:
        conn.client.delete_entity("skyward")


def test_camera_topics_are_rendered_beside_the_steps_at_most_at_their_rate(conn):
    stream = conn.sim_node.camera_stream
    stream.set_rate("overhead/down", 4.0)
    sub = conn.node.create_subscription(Image, "/overhead/down/image_raw", lambda msg: None, 1)
    try:
        before, start = stream.renders, time.monotonic()
        # Lockstep as fast as the node steps: every step a new state, far more than 4 per second.
        while (elapsed := time.monotonic() - start) < 1.0 or stream.renders == before:
            assert elapsed < 30.0, "no image rendered for a subscriber"
            conn.client.step_simulation(1)
        rendered = stream.renders - before
    finally:
        conn.node.destroy_subscription(sub)
        stream.set_rate("overhead/down", None)
    # Frames start at least 1/4 s apart: at most one per period in the time measured, one more that
    # started just before it.
    assert 1 <= rendered <= 4.0 * elapsed + 2, (rendered, elapsed)


def _intruder(name: str, namespace: str) -> str:
    return DOWN_CAMERA.replace('name="overhead"', f'name="{name}"').replace(
        "</camera></sensor>", '</camera><plugin name="p" filename="libgazebo_ros_camera.so"><ros>'
        f"<namespace>{namespace}</namespace></ros><camera_name>rgb</camera_name></plugin></sensor>")


@pytest.mark.parametrize(("namespace", "why"), [
    ("/rx200/zed2/zed_node", "entity 'rx200' publishes /rx200/zed2/zed_node/rgb/"),  # the Zed2's own topics
    ("/rx200/spy", "is in entity 'rx200''s namespace /rx200"),  # new topics in the robot's namespace
])
def test_a_sensor_plugin_cannot_publish_into_another_entitys_namespace(conn, caplog, namespace, why):
    """A stranger's description whose sensor plugin names another robot's namespace (absolute) gets no
    camera topics there: the entity is spawned, its camera is not published (an error on a wire graph;
    INFO on this in-process one, where it is a vector env's second robot of one description), and the
    log says why; the camera is still read as an observation, at its size."""
    before = {s.rgb_topic for s in conn.sim_node.cameras.specs()}
    with caplog.at_level("INFO"):
        conn.client.spawn_entity("intruder", resource_string=_intruder("intruder", namespace), position=(3.0, 3.0, 0))
    try:
        specs = conn.sim_node.cameras.specs()
        assert not [s for s in specs if s.entity == "intruder"]
        assert {s.rgb_topic for s in specs} == before
        assert "entity 'intruder': camera 'intruder/down' is not published" in caplog.text and why in caplog.text
        assert conn.read_camera("intruder/down").rgb.shape == (48, 64, 3)
    finally:
        conn.client.delete_entity("intruder")


def test_cameras_beyond_the_nodes_pixel_limit_are_not_published(conn, caplog):
    """The node publishes at most ``max_pixels`` of camera images in all (MAX_CAMERA_PIXELS: eight 1080p
    sensors); a camera beyond it is not published, says why, and is still read as an observation."""
    hub = conn.sim_node.cameras
    published = sum(s.width * s.height for s in hub.specs())
    hub.max_pixels = published + 64 * 48 - 1  # one pixel short of another 64 x 48 camera
    try:
        with caplog.at_level("INFO"):
            conn.client.spawn_entity("extra", resource_string=DOWN_CAMERA.replace('name="overhead"', 'name="extra"'),
                                     position=(4.0, 4.0, 0.0))
        try:
            assert not [s for s in hub.specs() if s.entity == "extra"]
            assert "camera 'extra/down' is not published: the node publishes" in caplog.text
            assert "MAX_CAMERA_PIXELS" in caplog.text
            assert conn.read_camera("extra/down").rgb.shape == (48, 64, 3)
        finally:
            conn.client.delete_entity("extra")
    finally:
        hub.max_pixels = MAX_CAMERA_PIXELS
