"""Gazebo camera sensors of a URDF (``<gazebo reference="link"><sensor type="camera">``) become
MuJoCo cameras fixed to their link, named ``"<entity>/<sensor>"`` in a world."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multiros.sim.description import SourcePolicy, load_description
from multiros.sim.errors import DescriptionError
from multiros.sim.render import camera_pose, project_points


def _urdf(sensors: str, link: str = "base") -> str:
    return f"""<robot name="cams">
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual>
  </link>
  <gazebo reference="{link}">{sensors}</gazebo>
</robot>"""


def _camera(name: str, pose: str = "1 -0.5 0.7 0 0.4 2.6", fov: str = "1.0", image: str = "640 480") -> str:
    width, height = image.split()
    return (f'<sensor type="camera" name="{name}"><pose>{pose}</pose><camera><horizontal_fov>{fov}</horizontal_fov>'
            f"<image><width>{width}</width><height>{height}</height></image></camera></sensor>")


def test_a_camera_sensor_becomes_a_camera_looking_along_its_x_axis(index, make_world):
    desc = load_description(_urdf(_camera("front")), index=index)
    model = desc.spec.compile()
    assert model.ncam == 1 and model.camera(0).name == "front"
    # MuJoCo keeps the vertical angle: 2 atan(tan(1.0 / 2) * 480 / 640).
    assert model.cam_fovy[0] == pytest.approx(2 * math.degrees(math.atan(math.tan(0.5) * 0.75)))
    world = make_world()
    world.spawn("robot", desc, pose=([0.2, 0.1, 0.0], [1, 0, 0, 0]))
    pos, axes, _ = camera_pose(world.model, world.data, "robot/front")
    assert np.allclose(pos, [1.2, -0.4, 0.7])
    pitch, yaw = 0.4, 2.6  # Gazebo: +x forward, +z up; roll 0
    forward = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch)])
    assert np.allclose(-axes[:, 2], forward) and axes[2, 1] > 0  # looks along +x of the pose, image up is up
    (uv,), (depth,) = project_points(world.model, world.data, "robot/front", [pos + 2 * forward], width=64, height=48)
    assert np.allclose(uv, [32, 24]) and depth == pytest.approx(2.0)


def test_camera_sensors_are_accepted_from_untrusted_text(index):
    text = _urdf(_camera("a") + _camera("b", pose="0 0 1 0 1.5 0", fov="0.5", image="100 100"))
    model = load_description(text, index=index, policy=SourcePolicy()).spec.compile()
    assert [model.camera(i).name for i in range(model.ncam)] == ["a", "b"]
    assert model.cam_fovy[1] == pytest.approx(math.degrees(0.5))


def test_other_sensors_and_plugins_are_ignored(index):
    text = _urdf('<sensor type="ray" name="lidar"><pose>0 0 0 0 0 0</pose></sensor>'
                 '<material>Gazebo/Grey</material>')
    assert load_description(text, index=index).spec.compile().ncam == 0


@pytest.mark.parametrize(("sensors", "link", "message"), [
    (_camera("c"), "nowhere", "names no link"),
    (_camera(""), "base", "needs a name"),
    (_camera("c") + _camera("c"), "base", "needs a name of its own"),
    (_camera("c", pose="1 2 3"), "base", "must be 6 finite numbers"),
    (_camera("c", pose="nan 0 0 0 0 0"), "base", "must be 6 finite numbers"),
    (_camera("c", pose="1e9 0 0 0 0 0"), "base", "position beyond"),
    (_camera("c", fov="3.5"), "base", "horizontal_fov"),
    (_camera("c", fov="inf"), "base", "horizontal_fov"),
    (_camera("c", image="0 480"), "base", "image"),
])
def test_bad_camera_sensors_are_refused_by_name(index, sensors, link, message):
    with pytest.raises(DescriptionError, match=message):
        load_description(_urdf(sensors, link), index=index, policy=SourcePolicy())
