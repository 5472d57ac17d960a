from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from multiros.ros import Context, Node
from multiros.sim.errors import PackageNotFoundError
from multiros.sim.packages import PackageIndex
from multiros.utils import ros_common


@pytest.fixture
def pkg(tmp_path):
    root = tmp_path / "my_task_pkg"
    (root / "config").mkdir(parents=True)
    (root / "urdf").mkdir()
    (root / "package.xml").write_text("<package><name>my_task_pkg</name></package>")
    (root / "config" / "task.yaml").write_text(
        "my_task:\n  reward_coefficient: 2.5\n  joints: [a, b]\n  limits: [0, 1.5]\n  nested: {flag: true, n: 3}\n"
    )
    (root / "urdf" / "arm.urdf.xacro").write_text(
        '<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:arg name="prefix" default="p_"/><link name="$(arg prefix)base"/></robot>'
    )
    return PackageIndex([tmp_path], use_entry_points=False, environ={})


@pytest.fixture
def node():
    ctx = Context(transport="inproc").init()
    yield Node("task_node", context=ctx)
    ctx.try_shutdown()


def test_package_path_and_exists(pkg, tmp_path):
    assert ros_common.get_package_path("my_task_pkg", index=pkg) == tmp_path / "my_task_pkg"
    assert ros_common.check_package_exists("my_task_pkg", index=pkg)
    assert not ros_common.check_package_exists("no_such_pkg", index=pkg)
    with pytest.raises(PackageNotFoundError, match="no_such_pkg"):
        ros_common.get_package_path("no_such_pkg", index=pkg)


def test_shipped_description_package_is_found():
    assert (ros_common.get_package_path("rx200_description") / "urdf" / "rx200.urdf.xacro").is_file()


@pytest.mark.parametrize("file", ["task.yaml", "config/task.yaml"])
def test_ros_load_yaml_in_config_folder_or_relative(pkg, file):
    data = ros_common.ros_load_yaml(pkg="my_task_pkg", file=file, index=pkg)
    assert data["my_task"]["reward_coefficient"] == 2.5
    assert ros_common.get_param(data, "my_task/reward_coefficient") == 2.5
    assert ros_common.get_param(data, "my_task.nested.n") == 3
    assert ros_common.get_param(data, "my_task/missing", None) is None
    with pytest.raises(KeyError, match="my_task/missing"):
        ros_common.get_param(data, "my_task/missing")


def test_multiros_keywords(pkg, tmp_path):
    data = ros_common.ros_load_yaml(pkg_name="my_task_pkg", file_name="task.yaml", index=pkg)
    assert data["my_task"]["joints"] == ["a", "b"]
    data = ros_common.ros_load_yaml(file_abs_path=tmp_path / "my_task_pkg" / "config" / "task.yaml")
    assert "my_task" in data


def test_missing_yaml_names_the_places_searched(pkg):
    with pytest.raises(FileNotFoundError, match="nope.yaml.*config"):
        ros_common.ros_load_yaml(pkg="my_task_pkg", file="nope.yaml", index=pkg)


def test_yaml_declared_as_node_parameters(pkg, node):
    ros_common.ros_load_yaml(pkg="my_task_pkg", file="task.yaml", node=node, index=pkg)
    assert ros_common.get_param(node, "my_task/reward_coefficient") == 2.5
    assert ros_common.get_param(node, "/my_task/joints") == ["a", "b"]
    assert ros_common.get_param(node, "my_task.limits") == [0.0, 1.5]
    assert ros_common.get_param(node, "my_task/nested/flag") is True
    assert ros_common.has_param(node, "my_task/nested/n")
    # loading again sets the already declared parameters
    ros_common.set_param(node, "my_task/reward_coefficient", 3.0)
    assert ros_common.get_param(node, "my_task/reward_coefficient") == 3.0
    with pytest.raises(KeyError, match="no parameter 'other'"):
        ros_common.get_param(node, "other")


def test_yaml_under_namespace(pkg, node):
    ros_common.ros_load_yaml(pkg="my_task_pkg", file="task.yaml", ns="/robot1", node=node, index=pkg)
    assert ros_common.get_param(node, "robot1/my_task/reward_coefficient") == 2.5


def test_ros2_parameter_file_gives_the_node_its_section(tmp_path, node):
    f = tmp_path / "params.yaml"
    f.write_text("task_node:\n  ros__parameters:\n    gain: 4.0\nother_node:\n  ros__parameters:\n    gain: 1.0\n")
    ros_common.ros_load_yaml(path=f, node=node)
    assert ros_common.get_param(node, "gain") == 4.0


def test_load_urdf_by_package_with_args(pkg):
    urdf = ros_common.load_urdf("my_task_pkg", index=pkg)
    assert ET.fromstring(urdf).find("link").get("name") == "p_base"
    urdf = ros_common.load_urdf(pkg_name="my_task_pkg", file_name="arm.urdf.xacro", args_xacro=["prefix:=q_"],
                                index=pkg)
    assert ET.fromstring(urdf).find("link").get("name") == "q_base"
    urdf = ros_common.load_urdf("package://my_task_pkg/urdf/arm.urdf.xacro", xacro_args={"prefix": "r_"}, index=pkg)
    assert ET.fromstring(urdf).find("link").get("name") == "r_base"


def test_load_urdf_stores_robot_description(pkg, node):
    urdf = ros_common.load_urdf("my_task_pkg", index=pkg, node=node)
    assert ros_common.get_param(node, "robot_description") == urdf


def test_load_urdf_of_shipped_rx200():
    urdf = ros_common.load_urdf("rx200_description")
    links = {link.get("name") for link in ET.fromstring(urdf).iter("link")}
    assert "rx200/ee_gripper_link" in links


def test_load_urdf_errors(pkg):
    with pytest.raises(FileNotFoundError, match="not found"):
        ros_common.load_urdf("package://my_task_pkg/urdf/missing.urdf", index=pkg)
    with pytest.raises(ValueError, match="name:=value"):
        ros_common.load_urdf("my_task_pkg", xacro_args=["prefix"], index=pkg)


# -- processes --------------------------------------------------------------------------------------
@pytest.mark.multiprocess
def test_start_and_stop_by_pid():
    proc = ros_common.start_node_process([sys.executable, "-c", "import time; time.sleep(60)"])
    assert proc.pid in ros_common.running_processes()
    assert ros_common.stop_process(proc.pid) is True
    assert proc.poll() is not None
    assert proc.pid not in ros_common.running_processes()


@pytest.mark.multiprocess
def test_readiness_wait_and_early_exit(tmp_path):
    marker = tmp_path / "ready"
    code = f"import pathlib, time; pathlib.Path({str(marker)!r}).touch(); time.sleep(60)"
    proc = ros_common.start_node_process([sys.executable, "-c", code], ready=marker.exists, timeout_sec=30)
    assert marker.exists()
    ros_common.stop_process(proc)
    with pytest.raises(RuntimeError, match="exited with code 3"):
        ros_common.start_node_process([sys.executable, "-c", "raise SystemExit(3)"], ready=lambda: False,
                                      timeout_sec=30)


@pytest.mark.multiprocess
def test_readiness_timeout_stops_the_child():
    with pytest.raises(TimeoutError, match="not ready within 0.2 s"):
        ros_common.start_node_process([sys.executable, "-c", "import time; time.sleep(60)"],
                                      ready=lambda: False, timeout_sec=0.2)
    assert ros_common.running_processes() == []


def test_shell_strings_and_foreign_pids_refused():
    with pytest.raises(TypeError, match="not a shell command line"):
        ros_common.start_node_process("roscore -p 11311")
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        with pytest.raises(ValueError, match="refusing to signal"):
            ros_common.stop_process(other.pid)
        assert other.poll() is None
    finally:
        other.kill()
        other.wait(timeout=10)


@pytest.mark.slow
@pytest.mark.multiprocess
def test_kill_all_only_touches_own_children():
    outsider = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    mine = [ros_common.start_python_node("http.server", "0", "--bind", "127.0.0.1",
                                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
    try:
        stopped = ros_common.ros_kill_all_processes()
        assert sorted(stopped) == sorted(p.pid for p in mine)
        assert all(p.poll() is not None for p in mine)
        assert outsider.poll() is None
        assert ros_common.kill_all_ros_and_gazebo() == []
    finally:
        outsider.kill()
        outsider.wait(timeout=10)
