"""QoS defaults and node parameters (declare/get/set, YAML files, -p)."""

from __future__ import annotations

from pathlib import Path

import pytest

from multiros import ros
from multiros.ros.parameters import parameters_from_yaml
from multiros.ros.qos import as_qos_profile, qos_compatible


def test_qos_defaults_match_ros() -> None:
    assert ros.QoSProfile() == ros.qos_profile_system_default
    d = ros.qos_profile_system_default
    assert (d.history, d.depth, d.reliability, d.durability) == (
        ros.HistoryPolicy.KEEP_LAST, 10, ros.ReliabilityPolicy.RELIABLE, ros.DurabilityPolicy.VOLATILE)
    s = ros.qos_profile_sensor_data
    assert (s.depth, s.reliability) == (5, ros.ReliabilityPolicy.BEST_EFFORT)
    assert ros.qos_profile_parameters.depth == 1000
    assert ros.qos_profile_services_default == ros.QoSProfile()
    assert as_qos_profile(7).depth == 7
    with pytest.raises(TypeError):
        as_qos_profile("10")  # type: ignore[arg-type]


def test_qos_compatibility() -> None:
    be, rel = ros.qos_profile_sensor_data, ros.QoSProfile()
    tl = ros.QoSProfile(durability=ros.DurabilityPolicy.TRANSIENT_LOCAL)
    assert qos_compatible(rel, be)
    assert not qos_compatible(be, rel)
    assert qos_compatible(tl, rel)
    assert not qos_compatible(rel, tl)


YAML = """
/**:
  ros__parameters:
    use_sim_time: true
    rate: 10.0
/robot/*:
  ros__parameters:
    arm:
      kp: 5.0
      joints: [a, b]
/robot/sim:
  ros__parameters:
    rate: 500.0
other:
  ros__parameters:
    rate: 1.0
"""


def test_yaml_wildcards_and_order(tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(YAML)
    assert parameters_from_yaml(path, "/robot/sim") == {
        "use_sim_time": True, "rate": 500.0, "arm.kp": 5.0, "arm.joints": ["a", "b"]}
    assert parameters_from_yaml(path, "/other") == {"use_sim_time": True, "rate": 1.0}
    assert parameters_from_yaml(path, "/x/y/other") == {"use_sim_time": True, "rate": 10.0}


def test_yaml_without_ros_parameters_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("node:\n  rate: 1\n")
    with pytest.raises(ValueError, match="ros__parameters"):
        parameters_from_yaml(path, "/node")


def test_node_parameters_from_params_file_and_cli(ctx: ros.Context, tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(YAML)
    node = ros.Node("sim", context=ctx, namespace="robot",
                    cli_args=["--ros-args", "--params-file", str(path), "-p", "extra:=[1, 2]"])
    assert node.get_parameter("use_sim_time").value is True
    assert node.declare_parameter("rate", 1.0).value == 500.0
    assert node.declare_parameter("arm.kp", 0.0).value == 5.0
    assert node.declare_parameter("extra", [0]).value == [1, 2]
    assert node.declare_parameter("undeclared_default", "x").value == "x"


def test_parameter_overrides_win(ctx: ros.Context, tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(YAML)
    node = ros.Node("sim", context=ctx, namespace="robot", cli_args=["--ros-args", "--params-file", str(path)],
                    parameter_overrides=[ros.Parameter("rate", value=42.0)])
    assert node.declare_parameter("rate", 1.0).value == 42.0


def test_declare_get_set(ctx: ros.Context) -> None:
    node = ros.Node("p", context=ctx)
    assert node.has_parameter("use_sim_time")
    assert node.get_parameter("use_sim_time").value is False
    node.declare_parameters("", [("gain", 1.5), ("name", "arm")])
    assert node.get_parameter("gain").value == 1.5
    results = node.set_parameters([ros.Parameter("gain", value=2.0), ros.Parameter("gain", value="str")])
    assert results[0].successful and not results[1].successful
    assert "gain" in results[1].reason
    assert node.get_parameter("gain").value == 2.0
    with pytest.raises(ros.ParameterNotDeclaredException, match="nope"):
        node.get_parameter("nope")
    with pytest.raises(ros.ParameterAlreadyDeclaredException):
        node.declare_parameter("gain", 1.0)
    ro = ros.ParameterDescriptor(read_only=True)
    node.declare_parameter("fixed", 3, ro)
    assert not node.set_parameters([ros.Parameter("fixed", value=4)])[0].successful
    res = node.set_parameters([ros.Parameter("missing", value=1)])[0]
    assert not res.successful and "not declared" in res.reason


def test_parameter_callback_can_reject(ctx: ros.Context) -> None:
    node = ros.Node("p", context=ctx)
    node.declare_parameter("rate", 10)
    node.add_on_set_parameters_callback(
        lambda ps: ros.SetParametersResult(successful=all(p.value > 0 for p in ps), reason="must be > 0"))
    assert node.set_parameters([ros.Parameter("rate", value=5)])[0].successful
    assert not node.set_parameters([ros.Parameter("rate", value=-1)])[0].successful
    assert node.get_parameter("rate").value == 5
