"""Arm files that extend another (``extends:``) and the camera an arm observes through (``camera.defaults``):
the shipped RX200Zed2 is the RX200's arm file with the Zed2 option and its camera."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import rl_environments
from rl_environments.arm_file import ArmFileError, load_arm_file

SHIPPED = rl_environments.shipped_arm_file("ur5e.yaml").parent  # type: ignore[union-attr] - a checkout's or an install's


def test_the_zed2_variant_is_the_rx200s_file_with_its_camera():
    rx200, zed2 = load_arm_file(SHIPPED / "rx200.yaml"), load_arm_file(SHIPPED / "rx200_zed2.yaml")
    assert zed2.name == "RX200Zed2" and zed2.robot_name == rx200.robot_name == "rx200"
    assert dict(zed2.xacro_args) == {"robot_name": "rx200", "use_zed2": "true"}
    assert zed2.camera_defaults == {"camera_name": "zed2_left", "rgb_plus_depth_plus_normal_obs": True}
    for key in ("joints", "home", "gripper", "reach", "manipulation", "real", "controllers_file", "camera_topics"):
        assert getattr(zed2, key) == getattr(rx200, key), key


def _write(path: Path, data: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_an_extended_files_relative_paths_stay_relative_to_it(tmp_path):
    base = yaml.safe_load((SHIPPED / "ur5e.yaml").read_text())
    base["description"]["controllers"] = "ur5e/controllers.yaml"
    base_path = _write(tmp_path / "vendor" / "ur5e.yaml", base)
    variant = _write(tmp_path / "mine" / "ur5e_fast.yaml", {"format": 1, "extends": "../vendor/ur5e.yaml",
                                                             "name": "UR5eFast", "reach": {"delta_coeff": 0.08}})
    spec = load_arm_file(variant)
    assert spec.controllers_file == str(base_path.parent / "ur5e" / "controllers.yaml")
    assert spec.reach["delta_coeff"] == 0.08 and spec.reach["reach_tolerance"] == base["reach"]["reach_tolerance"]


@pytest.mark.parametrize(("extends", "message"), [
    ("self.yaml", "extends itself"),
    ("missing.yaml", "arm file not found"),
    (3, "key 'extends' must name an arm file"),
])
def test_bad_extends_are_one_line_errors(tmp_path, extends, message):
    path = _write(tmp_path / "self.yaml", {"format": 1, "extends": extends, "name": "Loop"})
    with pytest.raises(ArmFileError, match=message) as err:
        load_arm_file(path)
    assert "\n" not in str(err.value)


def test_a_chain_of_extends_is_bounded(tmp_path):
    _write(tmp_path / "a0.yaml", yaml.safe_load((SHIPPED / "ur5e.yaml").read_text()))
    for i in range(1, 7):
        _write(tmp_path / f"a{i}.yaml", {"format": 1, "extends": f"a{i - 1}.yaml", "name": f"A{i}"})
    assert load_arm_file(tmp_path / "a4.yaml").name == "A4"
    with pytest.raises(ArmFileError, match="more than 4 arm files extend one another"):
        load_arm_file(tmp_path / "a6.yaml")


def test_camera_defaults_take_camera_keywords_only(tmp_path):
    data = yaml.safe_load((SHIPPED / "ur5e.yaml").read_text())
    data["camera"]["defaults"] = {"camera_nam": "x"}
    with pytest.raises(ArmFileError, match="'camera.defaults.camera_nam' is not a camera keyword; did you mean "
                                           "'camera_name'"):
        load_arm_file(_write(tmp_path / "arm.yaml", data))
    data["camera"]["defaults"] = {"image_width": [1, 2]}
    with pytest.raises(ArmFileError, match="camera.defaults' must map camera keywords to values"):
        load_arm_file(_write(tmp_path / "arm.yaml", data))
