"""The light URDF reader agrees with yourdfpy (the reference) on the shipped robots and fixtures."""

from __future__ import annotations

import io
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yourdfpy

from multiros.sim.description import xacro_to_urdf
from multiros.sim.errors import DescriptionError
from multiros.sim.urdf_model import parse_urdf
from rl_environments.robots import abb_irb120_description, rx200_description

FIXTURE = Path(__file__).parent / "data" / "test_arm_description" / "urdf" / "mesh_arm.urdf"


def _tf(origin):
    """yourdfpy leaves an absent <origin> as None; it means the identity."""
    return np.eye(4) if origin is None else origin


def _sources():
    yield "rx200", xacro_to_urdf(rx200_description.URDF_XACRO, {"robot_name": "rx200"})
    yield "irb120", xacro_to_urdf(abb_irb120_description.URDF_XACRO)
    yield "mesh_arm", FIXTURE.read_text()


@pytest.mark.parametrize(("name", "urdf"), list(_sources()), ids=lambda v: v if len(v) < 20 else "")
def test_matches_yourdfpy(name, urdf):
    ours = parse_urdf(ET.fromstring(urdf), name)
    ref = yourdfpy.URDF.load(io.BytesIO(urdf.encode()), build_scene_graph=False, load_meshes=False,
                             load_collision_meshes=False).robot
    assert [link.name for link in ours.links] == [link.name for link in ref.links]
    for a, b in zip(ours.links, ref.links):
        assert (a.inertial is None) == (b.inertial is None)
        if a.inertial is not None:
            assert a.inertial.mass == pytest.approx(b.inertial.mass)
            np.testing.assert_allclose(a.inertial.inertia, b.inertial.inertia)
            np.testing.assert_allclose(a.inertial.origin, _tf(b.inertial.origin), atol=1e-12)
        assert len(a.visuals) == len(b.visuals) and len(a.collisions) == len(b.collisions)
        for ga, gb in zip(a.collisions + a.visuals, b.collisions + b.visuals):
            np.testing.assert_allclose(ga.origin, _tf(gb.origin), atol=1e-12)
            for kind in ("box", "cylinder", "sphere", "mesh"):
                assert (getattr(ga.geometry, kind) is None) == (getattr(gb.geometry, kind) is None)
    assert [j.name for j in ours.joints] == [j.name for j in ref.joints]
    for a, b in zip(ours.joints, ref.joints):
        assert (a.type, a.parent, a.child) == (b.type, b.parent, b.child)
        np.testing.assert_allclose(a.origin, _tf(b.origin), atol=1e-12)
        if b.limit is not None and a.type != "fixed":
            for field in ("lower", "upper", "effort", "velocity"):
                va, vb = getattr(a.limit, field), getattr(b.limit, field)
                assert (va is None and vb in (None, 0.0)) or va == pytest.approx(vb), (a.name, field, va, vb)
        assert (a.mimic is None) == (b.mimic is None)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("<robot name='r'><link name='a'><inertial><mass value='heavy'/></inertial></link></robot>", "mass"),
        ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='spinning'>"
         "<parent link='a'/><child link='b'/></joint></robot>", "type 'spinning'"),
        ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
         "<parent link='a'/><child link='b'/></joint></robot>", "needs a <limit>"),
        ("<robot name='r'><link name='a'><visual><origin xyz='1 2'/><geometry><sphere radius='1'/></geometry>"
         "</visual></link></robot>", "origin xyz"),
        ("<model name='r'/>", "expected <robot>"),
    ],
)
def test_malformed_elements_are_named(text, match):
    with pytest.raises(DescriptionError, match=match):
        parse_urdf(ET.fromstring(text))


def test_a_non_positive_effort_or_velocity_is_read_as_unknown_and_said():
    """ROS tools load effort="-1" (some vendors write it for "not given"): unknown, with a note, not a refusal."""
    text = ("<robot name='r'><link name='a'/><link name='b'/><link name='c'/>"
            "<joint name='j1' type='revolute'><parent link='a'/><child link='b'/>"
            "<limit lower='-1' upper='1' effort='-1' velocity='0'/></joint>"
            "<joint name='j2' type='revolute'><parent link='b'/><child link='c'/>"
            "<limit lower='-1' upper='1' effort='5' velocity='2'/></joint></robot>")
    robot = parse_urdf(ET.fromstring(text))
    j1, j2 = robot.joints
    assert (j1.limit.effort, j1.limit.velocity) == (None, None)
    assert (j2.limit.effort, j2.limit.velocity) == (5.0, 2.0)
    assert robot.notes == ["joint 'j1' limit effort -1 <= 0 is read as unknown (no limit)",
                           "joint 'j1' limit velocity 0 <= 0 is read as unknown (no limit)"]
