"""The rclpy-shaped public API: names, classes, defaults, constants, equality, repr, pickling."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from multiros.ros import interfaces
from multiros.ros.interfaces import (
    dds_type_name,
    deserialize_message,
    get_action,
    get_message,
    get_service,
    list_types,
    serialize_message,
    type_hash,
)


def test_name_forms_resolve_to_the_same_class() -> None:
    cls = get_message("sensor_msgs/msg/JointState")
    assert get_message("sensor_msgs/JointState") is cls
    assert interfaces.sensor_msgs.msg.JointState is cls
    assert cls._type == "sensor_msgs/msg/JointState"
    assert "JointState" in dir(interfaces.sensor_msgs.msg)


def test_keyword_construction_defaults_and_constants() -> None:
    q = get_message("geometry_msgs/msg/Quaternion")()
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)  # upstream default w = 1
    step = get_service("simulation_interfaces/srv/StepSimulation")
    assert step.Request().steps == 1
    result = get_message("simulation_interfaces/msg/Result")
    assert result.RESULT_OK == 1 and result(result=result.RESULT_OK).result == 1
    assert get_message("visualization_msgs/msg/Marker").DELETEALL == 3
    desc = get_message("rcl_interfaces/msg/ParameterDescriptor")()
    assert desc.read_only is False and desc.floating_point_range == []
    js = get_message("sensor_msgs/msg/JointState")(name=["a", "b"], position=[0.1, 0.2])
    assert isinstance(js.position, np.ndarray) and js.position.dtype == np.float64
    assert js.velocity.shape == (0,)
    assert get_message("sensor_msgs/msg/CameraInfo")().k.shape == (9,)
    assert get_message("sensor_msgs/msg/Image")(data=[1, 2, 3]).data == b"\x01\x02\x03"


def test_equality_repr_copy_pickle() -> None:
    js_cls = get_message("sensor_msgs/msg/JointState")
    a = js_cls(name=["j"], position=[1.0])
    b = js_cls(name=["j"], position=np.array([1.0]))
    assert a == b and a != js_cls(name=["j"], position=[2.0])
    assert "sensor_msgs.msg.JointState(" in repr(a) and "position=array([1.])" in repr(a)
    assert copy.deepcopy(a) == a
    assert pickle.loads(pickle.dumps(a)) == a
    with pytest.raises(AttributeError):
        a.not_a_field = 1  # __slots__


def test_fields_and_field_types_like_rclpy() -> None:
    assert get_message("sensor_msgs/msg/JointState").get_fields_and_field_types() == {
        "header": "std_msgs/Header", "name": "sequence<string>", "position": "sequence<double>",
        "velocity": "sequence<double>", "effort": "sequence<double>"}
    types = get_message("rcl_interfaces/msg/ParameterDescriptor").get_fields_and_field_types()
    assert types["floating_point_range"] == "sequence<rcl_interfaces/FloatingPointRange, 1>"
    assert get_message("sensor_msgs/msg/CameraInfo").get_fields_and_field_types()["k"] == "double[9]"


def test_services_and_actions() -> None:
    srv = get_service("simulation_interfaces/srv/StepSimulation")
    assert srv._type == "simulation_interfaces/srv/StepSimulation"
    assert srv.Request._type == "simulation_interfaces/srv/StepSimulation_Request"
    assert srv.Event().request == [] and get_service("std_srvs/Trigger").Response().success is False
    assert interfaces.std_srvs.srv.SetBool is get_service("std_srvs/srv/SetBool")
    action = get_action("simulation_interfaces/action/SimulateSteps")
    assert action.Goal(steps=3).steps == 3 and action.Feedback().remaining_steps == 0
    assert action.Impl.SendGoalService.Request().goal == action.Goal()
    fb = action.Impl.FeedbackMessage(feedback=action.Feedback(completed_steps=2))
    assert deserialize_message(serialize_message(fb), type(fb)) == fb


def test_dds_type_names() -> None:
    assert dds_type_name("sensor_msgs/msg/JointState") == "sensor_msgs::msg::dds_::JointState_"
    assert dds_type_name("example_interfaces/srv/AddTwoInts") == "example_interfaces::srv::dds_::AddTwoInts_"
    assert dds_type_name("std_srvs/srv/Trigger_Request") == "std_srvs::srv::dds_::Trigger_Request_"
    assert dds_type_name("std_srvs/srv/Trigger_Response") == "std_srvs::srv::dds_::Trigger_Response_"


def test_list_types_and_required_packages() -> None:
    names = set(list_types())
    for required in ["builtin_interfaces/msg/Time", "std_msgs/msg/Float64MultiArray", "std_srvs/srv/Trigger",
                     "geometry_msgs/msg/TransformStamped", "sensor_msgs/msg/CameraInfo",
                     "trajectory_msgs/msg/JointTrajectory", "rosgraph_msgs/msg/Clock", "tf2_msgs/msg/TFMessage",
                     "visualization_msgs/msg/MarkerArray", "service_msgs/msg/ServiceEventInfo",
                     "rcl_interfaces/srv/SetParameters", "controller_manager_msgs/srv/SwitchController",
                     "simulation_interfaces/action/SimulateSteps", "uniros_interfaces/srv/StepRobot",
                     "example_interfaces/srv/AddTwoInts"]:
        assert required in names
    assert set(list_types("srv")) <= names


@pytest.mark.parametrize("distro", ["jazzy", "kilted", "rolling"])
def test_simulation_interfaces_complete(distro: str) -> None:
    from multiros.ros.interfaces.registry import DISTROS_ROOT, registry_for

    reference = DISTROS_ROOT / distro / "simulation_interfaces"
    shipped = {p.relative_to(reference).as_posix() for p in reference.rglob("*.*")
               if p.suffix in (".msg", ".srv", ".action")}
    assert len(shipped) == 38  # 17 msg, 20 srv, 1 action in every release since 1.5
    registry = registry_for(distro)
    for path in shipped:
        kind, file = path.split("/")
        name = f"simulation_interfaces/{kind}/{file.rsplit('.', 1)[0]}"
        assert registry.definition_file(name) == reference / path
        assert type_hash(name, registry).startswith("RIHS01_")
