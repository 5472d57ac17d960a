"""Descriptions: xacro with args and $(find), URDF -> MjSpec details, meshes, MJCF, bad input."""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from multiros.sim.description import MeshCache, load_description, xacro_to_urdf
from multiros.sim.errors import DescriptionError

DATA = Path(__file__).parent / "data"
PKG = DATA / "test_arm_description"
ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
MESH_ARM = "package://test_arm_description/urdf/mesh_arm.urdf"


def test_xacro_args_and_find(index):
    urdf = xacro_to_urdf(PKG / "urdf" / "arm.urdf.xacro", {"link_length": "0.3", "prefix": "a_"}, index=index)
    assert 'name="a_joint1"' in urdf
    assert 'xyz="0 0 0.3"' in urdf
    assert str(PKG / "config" / "arm_controllers.yaml") in urdf  # $(find test_arm_description)
    assert "ament_index_python" not in sys.modules or sys.modules["ament_index_python"].__file__


def test_xacro_string_with_find(index):
    text = ('<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r"><xacro:arg name="n" default="x"/>'
            '<link name="$(arg n)"/><xacro:property name="p" value="$(find test_arm_description)"/>'
            '<link name="${p.split(\'/\')[-1]}"/></robot>')
    urdf = xacro_to_urdf(text, {"n": "base"}, index=index)
    assert '<link name="base"/>' in urdf and '<link name="test_arm_description"/>' in urdf


def test_xacro_unknown_package_and_bad_syntax(index, tmp_path):
    bad = tmp_path / "bad.urdf.xacro"
    bad.write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r">'
                   '<link name="$(find no_such_pkg)"/></robot>')
    with pytest.raises(DescriptionError, match="no_such_pkg") as info:
        load_description(bad, index=index)
    assert str(bad) in str(info.value) and info.value.missing_assets
    broken = tmp_path / "broken.urdf.xacro"
    broken.write_text('<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r"><link name="a">')
    with pytest.raises(DescriptionError, match="broken.urdf.xacro"):
        load_description(broken, index=index)


def test_urdf_joint_properties(index, mesh_cache):
    desc = load_description(ARM_XACRO, index=index, mesh_cache=mesh_cache, default_armature=0.02)
    model = desc.spec.compile()
    j1, j2 = model.joint("joint1"), model.joint("joint2")
    np.testing.assert_allclose(j1.range, [-3.1, 3.1])
    np.testing.assert_allclose(j2.range, [-1.8, 1.8])
    assert int(model.jnt_limited[j1.id]) == 1
    assert model.dof_damping[j1.dofadr[0]] == pytest.approx(0.1)
    assert model.dof_frictionloss[j1.dofadr[0]] == pytest.approx(0.01)
    assert model.dof_armature[j1.dofadr[0]] == pytest.approx(0.02)
    np.testing.assert_allclose(model.jnt_actfrcrange[j1.id], [-20, 20])
    info = {j.name: j for j in desc.joints}
    assert info["joint3"].effort == 8 and info["joint3"].velocity == 3.0
    assert desc.actuated_joints == ("joint1", "joint2", "joint3")
    assert desc.ros2_control[1].initial_position == pytest.approx(0.3)
    assert desc.controllers_yaml == PKG / "config" / "arm_controllers.yaml"


def test_every_link_is_a_site_including_fixed_children(index, mesh_cache):
    desc = load_description(ARM_XACRO, index=index, mesh_cache=mesh_cache)
    model = desc.spec.compile()
    for link in ("world", "base_link", "link1", "link2", "link3", "ee_link"):
        assert model.site(link).id >= 0
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # ee_link is 0.05 + 0.1 + 0.2 + 0.15 above the base at zero joint angles
    np.testing.assert_allclose(data.site("ee_link").xpos, [0, 0, 0.5], atol=1e-9)


def test_visuals_are_non_colliding(index, mesh_cache):
    model = load_description(ARM_XACRO, index=index, mesh_cache=mesh_cache).spec.compile()
    visual = [g for g in range(model.ngeom) if int(model.geom_group[g]) == 2]
    assert visual and all(model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0 for g in visual)
    assert any(model.geom_contype[g] != 0 for g in range(model.ngeom))


def test_degenerate_inertia_fixed(index, mesh_cache):
    model = load_description(MESH_ARM, index=index, mesh_cache=mesh_cache).spec.compile()
    base, link1 = model.body("base_link"), model.body("link1")
    assert base.mass[0] > 0 and np.all(base.inertia > 0)
    a, b, c = np.sort(link1.inertia)
    assert a + b >= c  # triangle inequality restored
    assert int(model.jnt_limited[model.joint("hinge").id]) == 0  # continuous


def test_meshes_stl_obj_dae(index, mesh_cache, tmp_path):
    import trimesh

    model = load_description(MESH_ARM, index=index, mesh_cache=mesh_cache).spec.compile()
    assert model.nmesh == 3  # STL, scaled OBJ, OBJ
    dae = tmp_path / "pkg" / "cone.dae"
    dae.parent.mkdir()
    trimesh.creation.cone(radius=0.03, height=0.06).export(str(dae))
    urdf = (f'<robot name="d"><link name="a"><inertial><mass value="1"/><inertia ixx="1e-3" ixy="0" ixz="0" '
            f'iyy="1e-3" iyz="0" izz="1e-3"/></inertial><collision><geometry><mesh filename="file://{dae}"/>'
            f'</geometry></collision></link></robot>')
    desc = load_description(urdf, index=index, mesh_cache=mesh_cache)
    assert desc.spec.compile().nmesh == 1
    cached = list(mesh_cache.directory.glob("*.stl"))
    assert len(cached) == 1
    load_description(urdf, index=index, mesh_cache=mesh_cache)  # second load reuses the cache
    assert list(mesh_cache.directory.glob("*.stl")) == cached


def test_missing_mesh_names_file_and_paths(index, mesh_cache, tmp_path):
    urdf = tmp_path / "m.urdf"
    urdf.write_text('<robot name="m"><link name="a"><visual><geometry>'
                    '<mesh filename="package://test_arm_description/meshes/nope.stl"/></geometry></visual></link>'
                    '</robot>')
    with pytest.raises(DescriptionError) as info:
        load_description(urdf, index=index, mesh_cache=mesh_cache)
    msg = str(info.value)
    assert str(urdf) in msg and "nope.stl" in msg and "searched" in msg and str(PKG / "meshes") in msg
    assert info.value.missing_assets


@pytest.mark.parametrize("text, match", [
    ("<robot name='x'><link name='a'>", "malformed URDF"),
    ("<robot name='x'><link name='a'/><joint name='j' type='fixed'><parent link='a'/><child link='zz'/></joint>"
     "</robot>", "unknown link 'zz'"),
    ("<robot name='x'><link name='a'/><link name='b'/></robot>", "one tree"),
    ("<sdf version='1.6'/>", "unsupported root element"),
    ("<mujoco><worldbody><body><geom type='nonsense'/></body></worldbody></mujoco>", "invalid MJCF"),
    ("not xml at all", "not an XML description|not found"),
])
def test_malformed_inputs(index, mesh_cache, text, match):
    with pytest.raises(DescriptionError, match=match):
        load_description(text, index=index, mesh_cache=mesh_cache)


def test_malformed_file_is_named(index, tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><joint type='hinge' range='1'/></body></worldbody></mujoco>")
    with pytest.raises(DescriptionError, match=str(bad)):
        load_description(bad, index=index)


def test_mjcf_file_degrees_and_actuators_removed(index):
    desc = load_description("package://test_arm_description/urdf/pendulum.xml", index=index)
    assert desc.format == "mjcf" and [j.name for j in desc.joints] == ["swing"]
    assert desc.joints[0].upper == pytest.approx(np.pi / 2)
    model = desc.spec.compile()
    assert model.nu == 0 and model.site("bob").id >= 0 and model.site("tip").id >= 0


def test_an_unnamed_mjcf_joint_is_named_in_the_error(index):
    """Was an obscure compile error ("unknown transmission target 'u/'") from the actuator added for it."""
    text = ("<mujoco><worldbody><body name='b'><joint type='slide' axis='0 0 1'/><geom size='0.1' mass='1'/>"
            "</body></worldbody></mujoco>")
    with pytest.raises(DescriptionError, match="a slide joint of body 'b' has no name: give every hinge and slide"):
        load_description(text, index=index)


def test_mesh_cache_rejects_garbage(tmp_path):
    bad = tmp_path / "x.dae"
    bad.write_text("garbage")
    with pytest.raises(DescriptionError, match="x.dae"):
        MeshCache(tmp_path / "c").usable_path(bad)


_GRIPPER_URDF = (DATA / "gripper_drive_outside_ros2_control.urdf").read_text()


def test_a_drive_that_mimics_follow_is_actuated_when_ros2_control_leaves_it_out(index):
    """A vendor's arm block without the gripper (another driver runs it): the drive is still actuated in
    simulation, its mimic follows through the equality, and a joint no one mimics stays passive."""
    desc = load_description(_GRIPPER_URDF, index=index)
    assert desc.mimic_leaders == ("drive",)
    assert desc.actuated_joints == ("wrist", "drive")
    listed = _GRIPPER_URDF.replace("<joint name='wrist'><command_interface", "<joint name='drive'>"
                                   "<command_interface name='position'/></joint><joint name='wrist'><command_interface")
    assert load_description(listed, index=index).actuated_joints == ("drive", "wrist")
