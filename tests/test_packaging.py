"""The installed distribution ships every package and the data the library loads at run time."""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parent.parent


def _source_packages() -> set[str]:
    found = set()
    for top in ("gym_uniros", "multiros", "uniros", "rl_environments"):
        for dirpath, dirnames, filenames in os.walk(ROOT / top):
            dirnames[:] = [d for d in dirnames if d != "__pycache__"]
            if "__init__.py" in filenames:
                found.add(str(Path(dirpath).relative_to(ROOT)).replace(os.sep, "."))
    return found


def test_every_package_directory_is_listed_in_pyproject():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    missing = _source_packages() - listed
    assert not missing, f"add these packages to [tool.setuptools] packages in pyproject.toml: {sorted(missing)}"


def test_task_configs_and_templates_are_installed():
    configs = {p.name for p in resources.files("rl_environments.config").iterdir()}
    assert "irb120_reacher_task_config.yaml" in configs
    arms = {p.name for p in resources.files("rl_environments.config").joinpath("arms").iterdir()}
    assert {"rx200.yaml", "vx300s.yaml", "ur5e.yaml", "ned2.yaml", "irb120.yaml"} <= arms
    tasks = {p.name for p in resources.files("rl_environments.config").joinpath("training", "tasks").iterdir()}
    assert {"Reacher.yaml", "ReacherGoal.yaml", "Push.yaml", "PushGoal.yaml", "PnP.yaml", "PnPGoal.yaml"} <= tasks
    templates = {p.name for p in resources.files("uniros.templates").iterdir()}
    assert {"MyRobotEnv.py", "MyTaskEnv.py", "CustomRobotEnv.py", "CustomTaskEnv.py"} <= templates


def test_interface_definitions_are_installed():
    root = resources.files("multiros.ros.definitions")
    for pkg, kind, name in [
        ("sensor_msgs", "msg", "JointState.msg"),
        ("action_msgs", "srv", "CancelGoal.srv"),
        ("uniros_interfaces", "srv", "StepRobot.srv"),
    ]:
        assert root.joinpath(pkg, kind, name).is_file(), f"{pkg}/{kind}/{name} not installed"
    distros = resources.files("multiros.ros").joinpath("distros")
    for distro in ("humble", "jazzy", "kilted", "rolling"):
        for pkg, kind, name in [
            ("simulation_interfaces", "srv", "StepSimulation.srv"),
            ("controller_manager_msgs", "srv", "SwitchController.srv"),
        ]:
            assert distros.joinpath(distro, pkg, kind, name).is_file(), f"{distro}/{pkg}/{kind}/{name} not installed"
        assert distros.joinpath(distro, "simulation_interfaces", "package.xml").is_file()
