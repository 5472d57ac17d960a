"""Controllers: each type, YAML config, switching, claim conflicts, bad commands, tracking error."""

from __future__ import annotations

import numpy as np
import pytest

from multiros.sim.controller_manager import ControllerManager, load_controller_config
from multiros.sim.controllers import RobotHardware
from multiros.sim.errors import CommandError, ControllerError

ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
JOINTS = ["joint1", "joint2", "joint3"]


def _yaml(**controllers):
    cm = {"update_rate": 500}
    cfg = {"controller_manager": {"ros__parameters": cm}}
    for name, (type_name, params) in controllers.items():
        cm[name] = {"type": type_name}
        cfg[name] = {"ros__parameters": params}
    return cfg


ALL = _yaml(
    jsb=("joint_state_broadcaster/JointStateBroadcaster", {}),
    pos=("position_controllers/JointGroupPositionController", {"joints": JOINTS}),
    vel=("velocity_controllers/JointGroupVelocityController", {"joints": JOINTS}),
    eff=("effort_controllers/JointGroupEffortController", {"joints": JOINTS}),
    fwd=("forward_command_controller/ForwardCommandController", {"joints": ["joint3"], "interface_name": "position"}),
    jtc=("joint_trajectory_controller/JointTrajectoryController",
         {"joints": JOINTS, "command_interfaces": ["position"], "interpolation_method": "splines"}),
)


@pytest.fixture
def world(make_world):
    w = make_world()
    w.spawn("arm", ARM_XACRO, controllers_yaml=ALL, controllers=["jsb", "pos"], initial=True)
    return w


def test_yaml_parsing():
    cfg = load_controller_config(ALL)
    assert cfg["update_rate"] == 500 and cfg["types"]["vel"].startswith("velocity_controllers")
    assert cfg["params"]["fwd"]["interface_name"] == "position"
    with pytest.raises(ControllerError, match="cannot be read"):
        load_controller_config("/nonexistent/controllers.yaml")


def test_a_hostile_controllers_file_is_refused_before_it_expands(tmp_path):
    """A controllers file is read within bounds (multiros.bounded_yaml): a "billion laughs" is one
    short error, not an expansion."""
    lol = ",".join(['"lol"'] * 9)
    laughs = tmp_path / "laughs.yaml"
    laughs.write_text(f"a: &a [{lol}]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{','.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8)))
    with pytest.raises(ControllerError, match="cannot be read: expands to more than 50,000 values") as err:
        load_controller_config(laughs)
    assert len(str(err.value)) < 400


def test_default_yaml_from_description(make_world):
    w = make_world()
    w.spawn("arm", ARM_XACRO)  # the <gazebo><parameters> YAML: jsb + JTC active, position ctrl inactive
    states = {c.name: c.state for c in w.controller_manager("arm").list_controllers()}
    assert states == {"joint_state_broadcaster": "active", "arm_controller": "active",
                      "arm_position_controller": "inactive"}


def test_list_controllers_claims(world):
    rows = {c.name: c for c in world.controller_manager("arm").list_controllers()}
    assert rows["pos"].state == "active"
    assert rows["pos"].claimed_interfaces == ("joint1/position", "joint2/position", "joint3/position")
    assert rows["jsb"].claimed_interfaces == ()


def test_position_step_settles(world):
    world.set_command("arm", "pos", [0.6, -0.5, 0.8])
    world.step(150)  # 300 ms
    np.testing.assert_allclose(world.joint_state("arm").position, [0.6, -0.5, 0.8], atol=5e-3)


def test_position_holds_without_command(world):
    q0 = world.joint_state("arm").position.copy()
    world.step(500)
    np.testing.assert_allclose(world.joint_state("arm").position, q0, atol=1e-3)


def test_position_commands_clamped_to_limits(world):
    world.set_command("arm", "pos", [0.0, 5.0, 0.0])
    world.step(300)
    assert world.joint_state("arm").position[1] == pytest.approx(1.8, abs=1e-2)


def test_velocity_controller(world):
    world.switch_controllers("arm", activate=["vel"], deactivate=["pos"])
    world.set_command("arm", "vel", [0.5, 0.0, 0.0])
    world.step(100)
    q0 = world.joint_state("arm").position[0]
    world.step(250)  # 0.5 s at 0.5 rad/s
    assert world.joint_state("arm").velocity[0] == pytest.approx(0.5, abs=0.02)
    assert world.joint_state("arm").position[0] - q0 == pytest.approx(0.25, abs=0.02)


def test_effort_controller_clamps(world):
    world.switch_controllers("arm", activate=["eff"], deactivate=["pos"])
    world.set_command("arm", "eff", [100.0, 0.0, 0.0])  # joint1 effort limit is 20
    world.step(5)
    assert world.joint_state("arm").effort[0] == pytest.approx(20.0)
    assert world.joint_state("arm").velocity[0] > 0


def test_forward_command_controller_subset(world):
    world.switch_controllers("arm", activate=["fwd"], deactivate=["pos"])
    world.set_command("arm", "fwd", [0.7])
    world.step(200)
    assert world.joint_state("arm").position[2] == pytest.approx(0.7, abs=5e-3)


def test_trajectory_followed(world):
    world.switch_controllers("arm", activate=["jtc"], deactivate=["pos"])
    times = np.linspace(0.1, 1.0, 10)
    targets = np.stack([0.5 * np.sin(2 * times), 0.3 + 0.2 * times, -0.4 * times], axis=1)
    vels = np.stack([np.cos(2 * times), 0.2 * np.ones_like(times), -0.4 * np.ones_like(times)], axis=1)
    world.set_trajectory("arm", "jtc", ["joint3", "joint1", "joint2"], targets[:, [2, 0, 1]], times,
                         vels[:, [2, 0, 1]])
    errors = []
    for k in range(1, 11):
        world.step(50)  # 0.1 s
        errors.append(np.abs(world.joint_state("arm").position - targets[k - 1]).max())
    assert max(errors[1:]) < 0.02  # following within 0.02 rad after the first point
    world.step(100)
    np.testing.assert_allclose(world.joint_state("arm").position, targets[-1], atol=3e-3)  # holds the last point


def test_trajectory_linear_interpolation_setpoint(world):
    world.switch_controllers("arm", activate=["jtc"], deactivate=["pos"])
    ctrl = world.controller_manager("arm").get("jtc")
    ctrl.cubic = False
    world.set_trajectory("arm", "jtc", JOINTS, [[1.0, 0.3, 0.0]], [1.0])
    world.step(250)  # halfway: setpoint is the midpoint of the start (0) and the target (1)
    assert world.model.actuator_gainprm is not None
    assert ctrl.hw.command[0] == pytest.approx(0.5, abs=0.01)


def test_bad_trajectories_rejected(world):
    world.switch_controllers("arm", activate=["jtc"], deactivate=["pos"])
    with pytest.raises(CommandError, match="exactly"):
        world.set_trajectory("arm", "jtc", ["joint1"], [[0.1]], [1.0])
    with pytest.raises(CommandError, match="increasing"):
        world.set_trajectory("arm", "jtc", JOINTS, [[0, 0, 0], [0, 0, 0]], [1.0, 0.5])
    with pytest.raises(CommandError, match="NaN"):
        world.set_trajectory("arm", "jtc", JOINTS, [[0, np.nan, 0]], [1.0])


def test_bad_commands_not_applied(world):
    world.set_command("arm", "pos", [0.2, 0.2, 0.2])
    before = world.controller_manager("arm").hw.command.copy()
    for bad in ([0.1, 0.2], [0.1, np.nan, 0.0], [np.inf, 0, 0], ["a", "b", "c"]):
        with pytest.raises(CommandError):
            world.set_command("arm", "pos", bad)
    np.testing.assert_array_equal(world.controller_manager("arm").hw.command, before)
    with pytest.raises(ControllerError, match="not loaded"):
        world.set_command("arm", "nope", [0, 0, 0])
    with pytest.raises(ControllerError, match="takes no command"):
        world.set_command("arm", "jsb", [0, 0, 0])


def test_claim_conflicts_strict_and_best_effort(world):
    cm = world.controller_manager("arm")
    with pytest.raises(ControllerError, match="already claimed"):
        world.switch_controllers("arm", activate=["vel"])
    assert {c.name: c.state for c in cm.list_controllers()}["vel"] == "inactive"
    problems = world.switch_controllers("arm", activate=["fwd", "jsb"], deactivate=["eff"], strict=False)
    assert any("fwd" in p for p in problems) and any("eff" in p for p in problems)
    with pytest.raises(ControllerError, match="not active"):
        world.switch_controllers("arm", deactivate=["eff"])


def test_lifecycle_load_configure_unload(world):
    cm = world.controller_manager("arm")
    with pytest.raises(ControllerError, match="already loaded"):
        cm.load("pos")
    with pytest.raises(ControllerError, match="deactivate it"):
        cm.unload("pos")
    cm.deactivate(["pos"])
    cm.unload("pos")
    assert "pos" not in {c.name for c in cm.list_controllers()}
    with pytest.raises(ControllerError, match="unsupported type"):
        cm.load("x", "pid_controller/PidController")
    with pytest.raises(ControllerError, match="no type"):
        cm.load("undefined")
    cm.load("extra", "position_controllers/JointGroupPositionController", {"joints": ["joint1", "elbow"]})
    with pytest.raises(ControllerError, match="elbow"):
        cm.configure("extra")


def test_manager_without_world():
    hw = RobotHardware(["a", "b"], np.array([-1, -1.0]), np.array([1, 1.0]), np.zeros(2), np.zeros(2),
                       np.ones(2), np.ones(2), np.ones(2))
    cm = ControllerManager(hw, _yaml(p=("position_controllers/JointGroupPositionController", {})))
    assert cm.spawn() == ["p"]
    hw.position[:] = [0.3, -0.2]
    cm.hold()
    np.testing.assert_allclose(hw.command, [0.3, -0.2])
    assert cm.default_command_controller.name == "p"


def test_controllers_yaml_gains(make_world):
    cfg = _yaml(pos=("position_controllers/JointGroupPositionController",
                     {"joints": JOINTS, "gains": {"joint1": {"p": 123.0, "d": 4.0}}}))
    w = make_world()
    w.spawn("arm", ARM_XACRO, controllers_yaml=cfg)
    act = w.model.actuator("arm/joint1").id
    assert w.model.actuator_gainprm[act, 0] == 123.0 and w.model.actuator_biasprm[act, 2] == -4.0


def test_switch_directly_on_manager_reaches_world(world):
    cm = world.controller_manager("arm")
    cm.load("jtc2", "joint_trajectory_controller/JointTrajectoryController", {"joints": JOINTS})
    cm.configure("jtc2")
    cm.switch(activate=["jtc2"], deactivate=["pos"], time=world.time)  # no World call in between
    cm.get("jtc2").set_trajectory(JOINTS, [[0.3, 0.2, 0.1]], [0.2], time=world.time)
    world.step(400)
    np.testing.assert_allclose(world.joint_state("arm").position, [0.3, 0.2, 0.1], atol=5e-3)
