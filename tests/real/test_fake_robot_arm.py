"""``uniros-fake-robot --arm PATH``: the fake robot of an arm file, named as the arm's vendor driver names
things (the file's ``real:`` section), so a Real twin runs against it with its defaults.

For each shipped arm file with a Real twin to try (VX300S, UR5e, NED2, IRB120) the fake robot runs in a
child process (on a private router, stopped by PID) and the Real twins reset and step against it with
the simulated twins' spaces: reach, and push where the fake robot serves the driver's gripper interface
(a trajectory controller for the VX300S, a GripperCommand action for the UR5e; the NED2's tool
commander is not served, so its push twin runs with ``gripper_interface='none'``; the IRB120 has no
gripper: reach only). A bad arm file is one line on stderr and exit code 2.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import uniros
from multiros.hardware import FakeHardware
from multiros.hardware.process import FakeRobotProcess
from multiros.ros import Context, Node
from multiros.ros.controller_manager import ControllerManagerClient
from multiros.ros.interfaces import get_message
from multiros.ros.processes import private_context
from rl_environments.arm_file import ArmFile
from rl_environments.arm_registry import registered_arms
from uniros.fake_robot import ArmRobotError, arm_robot_spec, vendor_controllers

from .conftest import TopicRecorder, Tracker, make_real

JTC = "joint_trajectory_controller/JointTrajectoryController"
FORWARD = "position_controllers/JointGroupPositionController"
BROADCASTER = "joint_state_broadcaster/JointStateBroadcaster"
ARMS = ("VX300S", "UR5e", "NED2", "IRB120")
#: The gripper controller each arm's fake robot serves: (name, type, joint), or None.
GRIPPERS = {"VX300S": ("gripper_controller", JTC, "left_finger"),
            "UR5e": ("robotiq_gripper_controller", FORWARD, "left_finger_joint"),  # + gripper_cmd (GripperCommand)
            "NED2": None,  # Niryo's tool commander: not served
            "IRB120": None}  # no gripper: reach only
_CWD = tempfile.gettempdir()
JointState = get_message("sensor_msgs/msg/JointState")


def _arm(name: str) -> ArmFile:
    return registered_arms()[name]


def _params(spec: Any, controller: str) -> dict[str, Any]:
    return spec.controllers[controller]["ros__parameters"]


# ------------------------------------------------------------------------------ in-process units
@pytest.mark.parametrize("name", ARMS)
def test_the_spec_serves_the_real_sections_names_from_the_home_pose(name: str) -> None:
    arm = _arm(name)
    spec = arm_robot_spec(arm)
    assert spec.namespace == ("/" + arm.real.namespace.strip("/") if arm.real.namespace.strip("/") else "")
    cm = spec.controllers["controller_manager"]["ros__parameters"]
    served = {k: v["type"] for k, v in cm.items() if isinstance(v, dict)}
    gripper = GRIPPERS[name]
    expected = {"joint_state_broadcaster": BROADCASTER, arm.real.arm_controller: JTC}
    if gripper is not None:
        expected[gripper[0]] = gripper[1]
    assert served == expected
    assert _params(spec, arm.real.arm_controller)["joints"] == list(arm.joints)
    if gripper is not None:
        assert _params(spec, gripper[0])["joints"] == [gripper[2]]
    start = {j.name: j.initial for j in spec.joints}
    np.testing.assert_allclose([start[j] for j in arm.joints], arm.home, atol=1e-12)
    hardware = FakeHardware(spec)
    assert sorted(hardware.start_controllers()) == sorted(expected)  # every one active, none clashing


def test_start_init_namespace_and_initial_overrides() -> None:
    arm = _arm("VX300S")
    spec = arm_robot_spec(arm, start="init", namespace="other", initial_positions={"waist": 0.25})
    start = {j.name: j.initial for j in spec.joints}
    expected = [0.25, *arm.reach["init_joint_pos"][1:]]
    np.testing.assert_allclose([start[j] for j in arm.joints], expected, atol=1e-12)
    assert spec.namespace == "/other"
    # The description's controllers YAML lends the parameters of a controller it defines by that name.
    assert _params(spec, "arm_controller")["constraints"]["goal_time"] == 1.0
    with pytest.raises(ArmRobotError, match="'home' or 'init'"):
        arm_robot_spec(arm, start="nope")
    with pytest.raises(ArmRobotError, match="--initial: .*unknown joints"):
        arm_robot_spec(arm, initial_positions={"nope": 0.0})


def test_real_controllers_are_served_and_names_must_differ() -> None:
    arm = _arm("UR5e")
    real = dataclasses.replace(arm.real, controllers=("forward_position_controller", "io_and_status_controller"))
    config = vendor_controllers(dataclasses.replace(arm, real=real))
    cm = config["controller_manager"]["ros__parameters"]
    # The YAML defines forward_position_controller (as itself); the other is a placeholder claiming no joint.
    assert cm["forward_position_controller"]["type"] == FORWARD
    assert config["forward_position_controller"]["ros__parameters"]["joints"][0] == "shoulder_pan_joint"
    assert cm["io_and_status_controller"]["type"] == BROADCASTER
    clash = dataclasses.replace(arm.real, gripper_controller=arm.real.arm_controller)
    with pytest.raises(ArmRobotError, match="names controller 'scaled_joint_trajectory_controller' twice"):
        vendor_controllers(dataclasses.replace(arm, real=clash))


def _write_arm(tmp_path: Path, name: str, edit: Any) -> Path:
    """A copy of a shipped arm file with ``edit`` applied to its data (URIs stay package://)."""
    data = yaml.safe_load(_arm(name).path.read_text())
    edit(data)
    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uniros.fake_robot", "--router", "none", *args],
                          capture_output=True, text=True, timeout=120, cwd=_CWD)


def _real(data: dict, **keys: Any) -> None:
    data["real"].update(keys)


@pytest.mark.parametrize(("edit", "match"), [
    (None, "arm file not found"),
    (lambda d: _real(d, namespce="/x"), r"key 'real.namespce' is not a key of real; did you mean 'namespace'\?"),
    (lambda d: _real(d, gripper_interface="trajectory", gripper_controller="g", gripper_joint="nope"),
     r"key 'real.gripper_joint': 'nope' is not a commandable joint of the description"),
    (lambda d: d["description"].update(uri="package://no_such_description/urdf/x.urdf"), r"key 'description.uri'"),
], ids=["missing", "unknown-key", "gripper-joint", "description"])
def test_a_bad_arm_file_is_one_line_and_exit_code_2(tmp_path: Path, edit: Any, match: str) -> None:
    path = tmp_path / "missing.yaml" if edit is None else _write_arm(tmp_path, "UR5e", edit)
    out = _run("--arm", str(path))
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("uniros-fake-robot: "), out.stderr
    assert str(path) in lines[0] or "arm file not found" in lines[0]
    assert re.search(match, lines[0]), lines[0]


def test_robot_names_a_shipped_arm_files_robot_as_arm() -> None:
    from uniros.fake_robot import _shipped_arm_as_arm

    ur5e = str(_arm("UR5e").path)
    assert _shipped_arm_as_arm(["--robot", "ur5e", "--rate", "50"]) == ["--arm", ur5e, "--rate", "50"]
    assert _shipped_arm_as_arm(["--rate", "50", "--robot=ur5e"]) == ["--rate", "50", "--arm", ur5e]
    for kept in (["--robot", "rx200"], ["--robot", "nope"], ["--arm", ur5e, "--robot", "ur5e"]):
        assert _shipped_arm_as_arm(kept) == kept
    # main rewrites the program's own arguments, after the ROS sections are split off (ros2 run's form)
    from multiros.ros.names import split_ros_arguments

    own, ros = split_ros_arguments(["--ros-args", "-r", "__ns:=/a", "--", "--robot", "ur5e"])
    assert _shipped_arm_as_arm(own) == ["--arm", ur5e] and ros == ["--ros-args", "-r", "__ns:=/a"]


def test_the_arm_file_replaces_the_description_options() -> None:
    out = _run("--arm", str(_arm("UR5e").path), "--robot", "rx200")
    assert out.returncode == 2 and "--robot: the arm file names the description" in out.stderr
    out = _run("--robot", "rx200", "--start", "init")
    assert out.returncode == 2 and "--start needs --arm" in out.stderr


# ------------------------------------------------------------------------------ over the wire
@functools.cache
def _sim_spaces(env_id: str) -> tuple[Any, Any]:
    env = uniros.make(env_id)
    try:
        return env.observation_space, env.action_space
    finally:
        env.close()


@pytest.fixture(scope="module", params=ARMS)
def fake(request: pytest.FixtureRequest, graph: Context) -> Iterator[tuple[ArmFile, FakeRobotProcess]]:
    """``uniros-fake-robot --arm <file>`` in a child process; nothing else tells it a name."""
    arm = _arm(request.param)
    robot = FakeRobotProcess(None, context=graph, args=["--arm", str(arm.path), "--log-level", "WARNING"],
                             namespace=arm.real.namespace, timeout_sec=90.0, cwd=_CWD, module="uniros.fake_robot")
    tracker = Tracker(graph, arm.base_link)  # the push twin's object pose, from a stand-in tracker
    try:
        yield arm, robot
    finally:
        tracker.stop()
        robot.stop()


def _make(graph: Context, env_id: str, **kwargs: Any) -> Any:
    return make_real(graph, env_id, startup_timeout=20.0, **kwargs)


@pytest.mark.multiprocess
@pytest.mark.slow
def test_the_reach_twin_resets_and_steps_against_the_fake_robot(graph: Context, fake: Any) -> None:
    arm, robot = fake
    env = _make(graph, f"{arm.name}ReacherGoalReal-v0")  # the twin's defaults: the real: section's names
    try:
        u = env.unwrapped
        obs_space, act_space = _sim_spaces(f"{arm.name}ReacherGoalSim-v0")
        assert env.observation_space == obs_space and env.action_space == act_space
        assert u.robot_driver.startswith(f"{robot.namespace}/controller_manager")
        # The task's joint range tightened the description's in the safety rules.
        assert np.all(u.safety.lower >= u.task.min_joint_pos) and np.all(u.safety.upper <= u.task.max_joint_pos)
        obs, _ = env.reset(seed=0)
        assert obs_space.contains(obs)
        # The fake robot started at arm.home; the reset moved it to the task's start pose.
        np.testing.assert_allclose(u.arm_positions(), arm.reach["init_joint_pos"], atol=0.05)
        for _ in range(3):
            obs, _, _, _, info = env.step(env.action_space.sample())
            assert obs_space.contains(obs) and info["safety"]["refused"] is False
    finally:
        env.close()
    node = Node(f"probe_{time.monotonic_ns()}", context=graph)
    try:
        states = ControllerManagerClient(node, robot.namespace).states()
    finally:
        node.destroy_node()
    gripper = GRIPPERS[arm.name]
    assert states == {"joint_state_broadcaster": "active", arm.real.arm_controller: "active",
                      **({gripper[0]: "active"} if gripper else {})}


@pytest.mark.multiprocess
@pytest.mark.slow
def test_the_push_twin_drives_the_gripper_through_the_drivers_interface(graph: Context, fake: Any) -> None:
    arm, robot = fake
    if arm.gripper is None:
        pytest.skip(f"the {arm.name} has no gripper: no push twin")
    served = GRIPPERS[arm.name]
    kwargs = {} if served is not None else {"gripper_interface": "none"}
    env = _make(graph, f"{arm.name}PushGoalReal-v0", **kwargs)
    topic = arm.real.joint_states_topic or f"{robot.namespace}/joint_states"
    recorder = TopicRecorder(graph, JointState, topic)
    try:
        u = env.unwrapped
        obs_space, act_space = _sim_spaces(f"{arm.name}PushGoalSim-v0")
        assert env.observation_space == obs_space and env.action_space == act_space
        obs, _ = env.reset(seed=0)
        assert obs_space.contains(obs)
        obs, _, _, _, info = env.step(np.array([0.0, 0.0, 0.0, 0.0], np.float32))  # fingers half open
        assert obs_space.contains(obs) and info["safety"]["refused"] is False
        if served is None:
            return
        lo, hi = u.task.gripper_range
        joint = served[2]

        def finger() -> float | None:
            if not recorder.messages:
                return None
            last = recorder.messages[-1]
            return float(last.position[list(last.name).index(joint)])

        # Half open through the driver's units (the UR5e's GripperCommand: 0.4 of 0..0.8) lands on the
        # finger joint's half-open position, not on a limit.
        assert u.context.wait_for(lambda: finger() is not None and abs(finger() - (lo + hi) / 2) < 1e-3, 15.0), \
            f"the finger joint {joint} is at {finger()}, not {(lo + hi) / 2}"
    finally:
        recorder.close()
        env.close()


@pytest.mark.multiprocess
@pytest.mark.slow
def test_the_gripper_command_action_answers_in_the_drivers_units(graph: Context, fake: Any) -> None:
    from multiros.ros.action import STATUS_SUCCEEDED, ActionClient
    from multiros.ros.executors import SingleThreadedExecutor
    from multiros.ros.interfaces import get_action

    arm, robot = fake
    if arm.real.gripper_interface != "gripper_action":
        pytest.skip(f"{arm.name}'s driver takes no GripperCommand ({arm.real.gripper_interface})")
    assert arm.gripper is not None and arm.real.gripper_range is not None
    gripper_command = get_action("control_msgs/action/GripperCommand")
    node = Node(f"gripper_probe_{time.monotonic_ns()}", context=graph)
    executor = SingleThreadedExecutor(context=graph)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    client = ActionClient(node, gripper_command, f"{robot.namespace}/{arm.real.gripper_controller}/gripper_cmd")
    try:
        assert client.wait_for_server(10.0)
        rlo, rhi = arm.real.gripper_range
        goal = gripper_command.Goal()
        goal.command.position = rlo + 0.25 * (rhi - rlo)  # a quarter open, in the driver's units
        sent = client.send_goal_async(goal)
        assert sent.wait(5.0) and sent.result().accepted
        response = sent.result().get_result(timeout_sec=15.0)
        assert response.status == STATUS_SUCCEEDED and response.result.reached_goal
        assert response.result.position == pytest.approx(goal.command.position, abs=0.03 * abs(rhi - rlo))
        goal.command.position = float("nan")
        sent = client.send_goal_async(goal)
        assert sent.wait(5.0) and not sent.result().accepted
    finally:
        client.destroy()
        executor.shutdown()
        thread.join(timeout=5.0)
        node.destroy_node()


@pytest.mark.multiprocess
@pytest.mark.slow
def test_an_arm_file_of_your_own_with_its_own_driver_names(graph: Context, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """A user's arm file (a NED2 copy) whose driver has another namespace, joint_states topic, arm
    controller, command interface and an extra controller that must be active: the twin's defaults
    find them all on ``uniros-fake-robot --arm``."""
    from rl_environments.arm_registry import register_arm, unregister_arm

    def edit(data: dict) -> None:
        data["name"] = "NED2Mine"
        _real(data, namespace="/mine", joint_states_topic="robot/joint_states", arm_controller="my_arm",
              command_interface="topic", check_controllers=True, controllers=["io_and_status_controller"])

    path = _write_arm(tmp_path, "NED2", edit)
    monkeypatch.setenv("UNIROS_ARMS", "")  # register_arm adds the file for child processes; restored after
    register_arm(path)
    robot = FakeRobotProcess(None, context=graph, args=["--arm", str(path), "--log-level", "WARNING"],
                             namespace="/mine", timeout_sec=90.0, cwd=_CWD, module="uniros.fake_robot")
    try:
        env = _make(graph, "NED2MineReacherGoalReal-v0")
        try:
            u = env.unwrapped
            assert u.link.joint_states_topic == "/mine/robot/joint_states"
            assert env.observation_space == _sim_spaces("NED2ReacherGoalSim-v0")[0]
            obs, _ = env.reset(seed=0)
            obs, _, _, _, info = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs) and info["safety"]["refused"] is False
            assert u.commands_sent >= 2  # on /mine/my_arm/joint_trajectory, which only the fake robot serves
        finally:
            env.close()
    finally:
        robot.stop()
        unregister_arm("NED2Mine")


def _both_fingers_follow(graph: Context, env: Any, arm: ArmFile) -> None:
    """Two independently driven fingers: one finger action moves both, the second at its multiplier."""
    assert arm.gripper is not None
    lead, other = arm.gripper.joints
    recorder = TopicRecorder(graph, JointState, arm.real.joint_states_topic or "/joint_states")
    try:
        env.step(np.array([0.0, 0.0, 0.0, 0.0], np.float32))  # fingers half open: both joints mid-stroke
        half = (arm.gripper.closed + arm.gripper.open) / 2

        def at_half() -> bool:
            if not recorder.messages:
                return False
            last = recorder.messages[-1]
            where = dict(zip(last.name, last.position))
            return abs(where[lead] - half) < 1e-3 and abs(where[other] - arm.gripper.mimic * half) < 1e-3

        assert env.unwrapped.context.wait_for(at_half, 15.0), recorder.messages[-1:]
    finally:
        recorder.close()


#: Arms written by ``uniros arm add`` from the suite's stand-ins of vendor descriptions: (URI, arguments,
#: the gripper interface the file names): the OMX's from its ros2_control tag (a Dynamixel plugin), the
#: Panda's (no tag) from ros2_control's conventions (a GripperActionController), the two-finger arm's from
#: its package's controllers file (one trajectory controller over both independently driven fingers).
WRITTEN = {
    "OmxWritten": ("package://uniros_test_omx_description/urdf/omx.urdf.xacro", (), "gripper_action"),
    "PandaWritten": ("package://uniros_test_panda_description/urdf/panda.urdf.xacro", ("--xacro-arg", "hand=true"),
                     "gripper_action"),
    "TwoFingerWritten": ("package://uniros_test_twofinger_description/urdf/twofinger_arm.urdf.xacro", (),
                         "trajectory"),
}


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.parametrize("name", list(WRITTEN))
def test_an_arm_written_by_arm_add_runs_its_real_twins_against_its_fake_robot(
        name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    """Arms the project does not ship, from their description packages alone: ``uniros arm add`` of the
    OpenManipulator-X and Panda stand-ins (tests/robots/arm_add_data, found through ``AMENT_PREFIX_PATH``
    as a sourced workspace gives it), then ``uniros-fake-robot --arm`` of the written file serves the
    driver names the file took from the description, and the reach and push twins reset and step against
    it with their simulated twins' spaces, the gripper through the interface the file names."""
    from rl_environments.arm_registry import unregister_arm
    from uniros.cli import main as cli

    monkeypatch.setenv("AMENT_PREFIX_PATH", str(Path(__file__).parents[1] / "robots" / "arm_add_data" / "install"))
    monkeypatch.setenv("UNIROS_ARMS", "")  # arm add registers the file for child processes; restored after
    uri, extra, interface = WRITTEN[name]
    code = cli(["arm", "add", uri, "--name", name, "--output", str(tmp_path), *extra])
    assert code == 0, capsys.readouterr().err
    path = tmp_path / f"{name}.yaml"
    graph = private_context()  # a graph of its own: the module's holds the IRB120's fake robot on /joint_states
    try:
        arm = registered_arms()[name]
        assert arm.real.gripper_interface == interface
        robot = FakeRobotProcess(None, context=graph, args=["--arm", str(path), "--log-level", "WARNING"],
                                 namespace=arm.real.namespace, timeout_sec=90.0, cwd=_CWD, module="uniros.fake_robot")
        tracker = Tracker(graph, arm.base_link)  # the push twin's object pose, from a stand-in tracker
        try:
            for task in ("ReacherGoal", "PushGoal"):
                env = _make(graph, f"{name}{task}Real-v0")
                try:
                    obs_space, act_space = _sim_spaces(f"{name}{task}Sim-v0")
                    assert env.observation_space == obs_space and env.action_space == act_space
                    obs, _ = env.reset(seed=0)
                    assert obs_space.contains(obs)
                    for _ in range(3):
                        obs, _, _, _, info = env.step(env.action_space.sample())
                        assert obs_space.contains(obs) and info["safety"]["refused"] is False
                    assert env.unwrapped.commands_sent >= 3
                    if any(arm.tcp_offset):  # the EE: the link's FK moved by arm.tcp_offset in its frame
                        from rl_environments.arm_registry import chain_of

                        u = env.unwrapped
                        np.testing.assert_allclose(u.ee_position(), chain_of(arm).fk_position(u.arm_positions())
                                                   + u.connection.base_position, atol=1e-9)
                    if task == "PushGoal" and arm.gripper is not None and arm.gripper.independent:
                        _both_fingers_follow(graph, env, arm)
                finally:
                    env.close()
        finally:
            tracker.stop()
            robot.stop()
    finally:
        graph.try_shutdown()
        unregister_arm(name)
