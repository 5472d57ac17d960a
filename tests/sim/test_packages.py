"""Package index: extra paths, entry points, AMENT_PREFIX_PATH, ROS_PACKAGE_PATH, URIs, errors."""

from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path

import pytest

from multiros.sim.errors import PackageNotFoundError
from multiros.sim.packages import ENTRY_POINT_GROUP, PackageIndex

DATA = Path(__file__).parent / "data"


def test_extra_path_parent_and_root():
    assert PackageIndex([DATA], environ={}).find_package_share("test_arm_description") == \
        DATA / "test_arm_description"
    root = DATA / "test_arm_description"
    assert PackageIndex([root], environ={}).find_package_share("test_arm_description") == root


def test_entry_point(monkeypatch):
    ep = importlib.metadata.EntryPoint(name="fake_description", value="multiros.sim", group=ENTRY_POINT_GROUP)

    def fake_entry_points(group=None):
        return [ep] if group == ENTRY_POINT_GROUP else []

    monkeypatch.setattr("multiros.sim.packages.entry_points", fake_entry_points)
    found = PackageIndex(environ={}).find_package_share("fake_description")
    assert found == Path(__import__("multiros.sim").sim.__file__).parent


def test_ament_prefix_path(tmp_path):
    share = tmp_path / "install" / "share" / "my_pkg"
    share.mkdir(parents=True)
    env = {"AMENT_PREFIX_PATH": os.pathsep.join([str(tmp_path / "nope"), str(tmp_path / "install")])}
    assert PackageIndex(use_entry_points=False, environ=env).find_package_share("my_pkg") == share


def test_ros_package_path_finds_nested_package_xml(tmp_path):
    pkg = tmp_path / "ws" / "src" / "some_dir"
    pkg.mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>renamed_pkg</name></package>")
    env = {"ROS_PACKAGE_PATH": str(tmp_path / "ws")}
    assert PackageIndex(use_entry_points=False, environ=env).find_package_share("renamed_pkg") == pkg


def test_not_found_lists_searched_places(tmp_path):
    env = {"AMENT_PREFIX_PATH": str(tmp_path / "prefix"), "ROS_PACKAGE_PATH": str(tmp_path / "rpp")}
    index = PackageIndex([tmp_path / "extra"], use_entry_points=False, environ=env)
    with pytest.raises(PackageNotFoundError) as info:
        index.find_package_share("missing_pkg")
    msg = str(info.value)
    assert "package 'missing_pkg' not found; searched:" in msg
    for part in ("extra", "prefix", "rpp"):
        assert str(tmp_path / part) in msg
    assert info.value.package == "missing_pkg"


def test_resolve_uri_forms(index, tmp_path):
    assert index.resolve_uri("package://test_arm_description/meshes/link_box.stl").is_file()
    assert index.resolve_uri(f"file://{tmp_path}/a b.stl") == tmp_path / "a b.stl"
    assert index.resolve_uri("meshes/x.stl", base_dir=tmp_path) == tmp_path / "meshes" / "x.stl"
    assert index.resolve_uri("/abs/x.stl", base_dir=tmp_path) == Path("/abs/x.stl")
    with pytest.raises(PackageNotFoundError):
        index.resolve_uri("package://nope_pkg/x.stl")
