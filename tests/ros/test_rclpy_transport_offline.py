"""The rclpy transport's decisions that need no rclpy: which transport a program gets, the errors for a
missing rclpy, an unloadable RMW_IMPLEMENTATION, a missing or different interface package, and the
interface builder's choices. (The transport itself runs against real rclpy in tests/ros2_rclpy, .ci/rclpy.)"""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import pytest

from multiros.ros import Context
from multiros.ros.exceptions import TransportError
from multiros.ros.interface_build import (
    USED_TYPES,
    _cmakelists,
    _definition_dir,
    _selected_files,
    fix_exported_paths,
)
from multiros.ros.interfaces import get_message, type_hash
from multiros.ros.transport import wire_transport
from multiros.ros.transport.rclpy import loader
from multiros.ros.transport.rclpy.types import InstalledTypes, InterfaceMismatchError, MissingInterfacePackageError


def test_explicit_choice_wins_then_the_environment_then_rclpy_when_importable(monkeypatch) -> None:
    monkeypatch.setattr(loader, "rclpy_available", lambda: True)
    assert wire_transport("zenoh", env={"UNIROS_TRANSPORT": "rclpy"}) == "zenoh"
    assert wire_transport(None, env={"UNIROS_TRANSPORT": "zenoh"}) == "zenoh"
    assert wire_transport(None, env={}) == "rclpy"
    assert wire_transport(None, env={}, prefer_rclpy=False) == "zenoh"  # process mode: our own Zenoh router
    monkeypatch.setattr(loader, "rclpy_available", lambda: False)
    assert wire_transport(None, env={}) == "zenoh"


@pytest.mark.skipif(loader.rclpy_available(), reason="rclpy is installed here")
def test_rclpy_not_importable_is_a_clear_error() -> None:
    with pytest.raises(TransportError, match=r"needs rclpy, which is not importable.*source your ROS 2"):
        Context(transport="rclpy").init()


def test_an_rmw_implementation_rcl_cannot_load_is_refused_before_rclpy_loads(tmp_path, monkeypatch) -> None:
    # A stand-in rclpy that does what rcl does at load time with a foreign RMW_IMPLEMENTATION.
    fake = tmp_path / "rclpy"
    fake.mkdir()
    (fake / "__init__.py").write_text(textwrap.dedent("""
        import os, sys
        sys.stderr.write("[ERROR] [rcl]: Expected RMW implementation identifier of '%s' but instead found "
                         "'rmw_fastrtps_cpp', exiting with 102.\\n" % os.environ["RMW_IMPLEMENTATION"])
        sys.exit(102)
    """))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    monkeypatch.setenv("RMW_IMPLEMENTATION", "rmw_zenoh_cpp")
    monkeypatch.setattr(loader, "_checked", {})
    assert "rclpy" not in sys.modules
    with pytest.raises(TransportError) as caught:
        loader.check_rmw_implementation()
    text = str(caught.value)
    assert "RMW_IMPLEMENTATION='rmw_zenoh_cpp'" in text and "code 102" in text
    assert "instead found 'rmw_fastrtps_cpp'" in text and "unset RMW_IMPLEMENTATION" in text
    monkeypatch.delenv("RMW_IMPLEMENTATION")
    loader.check_rmw_implementation()  # unset: rcl's default, nothing probed


def _installed(tmp_path: Path, monkeypatch, recorded_hash: str) -> InstalledTypes:
    """A fake installed std_msgs (Python package + rosidl's type description) in a prefix of its own."""
    site = tmp_path / "lib" / "python3" / "site-packages"
    (site / "std_msgs" / "msg").mkdir(parents=True)
    (site / "std_msgs" / "__init__.py").write_text("")
    (site / "std_msgs" / "msg" / "__init__.py").write_text("class String:\n    pass\n")
    share = tmp_path / "share" / "std_msgs" / "msg"
    share.mkdir(parents=True)
    (share / "String.json").write_text(json.dumps(
        {"type_hashes": [{"type_name": "std_msgs/msg/String", "hash_string": recorded_hash}]}))
    monkeypatch.syspath_prepend(str(site))
    for name in ("std_msgs", "std_msgs.msg"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    return InstalledTypes()


def test_the_installed_type_must_hash_like_ours(tmp_path, monkeypatch) -> None:
    String = get_message("std_msgs/msg/String")
    same = _installed(tmp_path / "a", monkeypatch, type_hash(String))
    assert same.resolve(String, "publisher on '/chatter'", offer=True).__name__ == "String"
    other = _installed(tmp_path / "b", monkeypatch, "RIHS01_" + "0" * 64)
    with pytest.raises(InterfaceMismatchError, match=r"subscription on '/chatter'.*differs from the one uniros uses"):
        other.resolve(String, "subscription on '/chatter'", offer=False)


def test_a_missing_package_names_the_distribution_package_and_the_builder(monkeypatch) -> None:
    monkeypatch.setenv("ROS_DISTRO", "jazzy")
    with pytest.raises(MissingInterfacePackageError) as caught:
        InstalledTypes().rclpy_class("simulation_interfaces/srv/SpawnEntity", "service '/mujoco_sim/spawn_entity'")
    text = str(caught.value)
    assert "ros-jazzy-simulation-interfaces" in text and "uniros-build-interfaces simulation_interfaces" in text
    with pytest.raises(MissingInterfacePackageError, match="uniros' own and in no ROS distribution"):
        InstalledTypes().rclpy_class("uniros_interfaces/srv/StepRobot", "service '/mujoco_sim/step_robot'")


def test_only_used_covers_what_the_node_and_envs_use_with_their_nested_types() -> None:
    from multiros.sim.services import CONTROLLER_SERVICES, SIM_SERVICES

    for table in (SIM_SERVICES, CONTROLLER_SERVICES):
        for type_name in table.values():
            pkg, kind, name = type_name.split("/")
            if pkg in USED_TYPES:
                assert f"{kind}/{name}" in USED_TYPES[pkg], type_name
    files = _selected_files(_definition_dir("control_msgs", "jazzy"), "control_msgs",
                            USED_TYPES["control_msgs"])
    assert files == ["action/FollowJointTrajectory.action", "msg/JointComponentTolerance.msg",
                     "msg/JointTolerance.msg"]
    text = _cmakelists("control_msgs", files, ["action_msgs", "trajectory_msgs"])
    assert 'rosidl_generate_interfaces(${PROJECT_NAME}\n  "action/FollowJointTrajectory.action"' in text
    assert "DEPENDENCIES action_msgs trajectory_msgs" in text
    assert "AMENT_EXTENSIONS_rosidl_generate_idl_interfaces" not in text  # every generator by default


def test_python_only_drops_the_cpp_generators_and_keeps_what_rclpy_loads() -> None:
    import re

    text = _cmakelists("tf2_msgs", ["msg/TFMessage.msg"], ["geometry_msgs"], python_only=True)
    filters = [line for line in text.splitlines() if line.startswith("list(FILTER")]
    assert len(filters) == 1
    # The filter comes after every find_package (finding a message package registers the C++ generators
    # again) and before the generation that runs the registered ones.
    assert text.index(filters[0]) > text.rindex("find_package(")
    assert text.index(filters[0]) < text.index("rosidl_generate_interfaces(")
    regex = re.search(r'EXCLUDE REGEX "(.*)"', filters[0]).group(1)
    registered = ["rosidl_generator_type_description:x.cmake", "rosidl_generator_c:x.cmake",
                  "rosidl_generator_cpp:x.cmake", "rosidl_typesupport_fastrtps_c:x.cmake",
                  "rosidl_typesupport_fastrtps_cpp:x.cmake", "rosidl_typesupport_introspection_c:x.cmake",
                  "rosidl_typesupport_introspection_cpp:x.cmake", "rosidl_typesupport_c:x.cmake",
                  "rosidl_typesupport_cpp:x.cmake", "rosidl_generator_py:x.cmake"]
    kept = [r.split(":")[0] for r in registered if not re.search(regex, r)]  # CMake's regex here is also Python's
    assert kept == ["rosidl_generator_type_description", "rosidl_generator_c", "rosidl_typesupport_fastrtps_c",
                    "rosidl_typesupport_introspection_c", "rosidl_typesupport_c", "rosidl_generator_py"]


def test_the_wheels_exported_python_paths_are_rewritten(tmp_path) -> None:
    cmake = tmp_path / "share" / "std_msgs" / "cmake"
    cmake.mkdir(parents=True)
    path = cmake / "export_std_msgs__rosidl_generator_pyExport.cmake"
    path.write_text('INTERFACE_INCLUDE_DIRECTORIES "/opt/python/cp311-cp311/include/python3.11;'
                    '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"')
    assert fix_exported_paths(tmp_path) == 1
    assert "/opt/python" not in path.read_text()


def test_each_transport_names_how_it_reaches_peers(monkeypatch) -> None:
    """Error messages (a Real env without its robot) name the transport in use, not always Zenoh."""
    from multiros.ros.transport import make_transport

    ctx = Context(transport="inproc")
    assert ctx.reach() == "the inproc transport"  # not opened yet
    assert make_transport("inproc", ctx).reach() == "the inproc transport (this process only)"
    zenoh = make_transport("zenoh", Context(transport="zenoh", env={"UNIROS_ZENOH_ROUTER": "tcp/127.0.0.1:17447"}))
    assert zenoh.reach() == "Zenoh router tcp/127.0.0.1:17447 (UNIROS_ZENOH_ROUTER)"
    monkeypatch.setenv("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
    rclpy_transport = make_transport("rclpy", Context(transport="rclpy"))
    assert rclpy_transport.reach() == "ROS 2 middleware rmw_cyclonedds_cpp (RMW_IMPLEMENTATION)"
    monkeypatch.delenv("RMW_IMPLEMENTATION")
    assert "Zenoh" not in rclpy_transport.reach() and "RMW_IMPLEMENTATION" in rclpy_transport.reach()


def test_uniros_train_notes_the_graph_through_the_transport_it_uses(monkeypatch) -> None:
    from uniros.cli import _shared_graph_note

    monkeypatch.setenv("ROS_DOMAIN_ID", "0")
    monkeypatch.delenv("RMW_IMPLEMENTATION", raising=False)
    monkeypatch.delenv("UNIROS_TRANSPORT", raising=False)
    note = _shared_graph_note("RX200ReacherGoalReal-v0", {"transport": "rclpy"})
    assert note is not None and "through rclpy on its default middleware (RMW_IMPLEMENTATION)" in note
    assert "Zenoh" not in note and "set ROS_DOMAIN_ID per user" in note
    monkeypatch.setattr(loader, "rclpy_available", lambda: True)
    assert "through rclpy" in (_shared_graph_note("RX200ReacherGoalReal-v0", {}) or "")  # a Real env's default
    monkeypatch.setattr(loader, "rclpy_available", lambda: False)
    assert "through the Zenoh router" in (_shared_graph_note("RX200ReacherGoalReal-v0", {}) or "")
    assert "through the Zenoh router" in (_shared_graph_note("RX200ReacherGoalSim-v0", {"transport": "zenoh"}) or "")
    assert _shared_graph_note("RX200ReacherGoalSim-v0", {}) is None  # in-process: no graph
