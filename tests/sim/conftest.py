"""Fixtures for the MuJoCo world tests: a package index over tests/sim/data and small worlds."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
MESH_ARM = "package://test_arm_description/urdf/mesh_arm.urdf"
BALL = "package://test_arm_description/urdf/ball.xml"
PENDULUM = "package://test_arm_description/urdf/pendulum.xml"


@pytest.fixture
def index():
    from multiros.sim.packages import PackageIndex

    return PackageIndex([DATA], use_entry_points=False, environ={})


@pytest.fixture
def mesh_cache(tmp_path):
    from multiros.sim.description import MeshCache

    return MeshCache(tmp_path / "meshes")


@pytest.fixture
def make_world(index, tmp_path):
    from multiros.sim.world import World, WorldOptions

    worlds = []

    def make(**options):
        world = World(WorldOptions(**options), package_index=index, mesh_cache=tmp_path / "meshes")
        worlds.append(world)
        return world

    yield make
    for world in worlds:
        world.close()


@pytest.fixture
def arm_world(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO, initial=True)
    return world
