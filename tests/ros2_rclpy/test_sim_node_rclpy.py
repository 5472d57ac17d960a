"""A plain rclpy client (tests/ros2_rclpy/plain_ros.py, no uniros import) drives ``uniros-sim --transport rclpy``
in another process over Fast DDS: discovery, /clock, joint_states, the simulation_interfaces services
(pause, step while paused, spawn/delete, reset), list/switch controllers, and a FollowJointTrajectory
goal with feedback and result."""

from __future__ import annotations

import importlib.util

import pytest

_NEEDED = ("rclpy", "simulation_interfaces", "control_msgs", "controller_manager_msgs", "uniros_interfaces")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy and the interface packages .ci/rclpy builds (run by .ci/rclpy)", allow_module_level=True)

from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from controller_manager_msgs.srv import ListControllers, SwitchController  # noqa: E402
from plain_ros import PlainPeer, wait_until  # noqa: E402
from rclpy_harness import uniros_script  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from simulation_interfaces.msg import Result, SimulationState  # noqa: E402
from simulation_interfaces.srv import (  # noqa: E402
    DeleteEntity,
    GetEntities,
    GetSimulationState,
    ResetSimulation,
    SetSimulationState,
    SpawnEntity,
    StepSimulation,
)
from trajectory_msgs.msg import JointTrajectoryPoint  # noqa: E402

pytestmark = pytest.mark.slow

RX200 = "rx200=package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
SIM = "/mujoco_sim"
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]
BOX = ('<robot name="box"><link name="box"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" '
       'izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry><box size="0.05 0.05 0.05"/>'
       '</geometry></collision></link></robot>')


def _ok(response) -> None:
    assert response.result.result == Result.RESULT_OK, response.result.error_message


def _clock_sec(msg) -> float:
    return msg.clock.sec + msg.clock.nanosec * 1e-9


def test_plain_rclpy_client_drives_uniros_sim(program) -> None:
    sim = program([uniros_script("uniros-sim"), "--transport", "rclpy", "--robot", RX200, "--log-level", "INFO"],
                  "uniros-sim")
    with PlainPeer("plain_ros_user") as peer:
        sim.wait_ready("simulation node /mujoco_sim ready")
        peer.wait_for_node(SIM)
        state = peer.call(GetSimulationState, f"{SIM}/get_simulation_state", GetSimulationState.Request())
        _ok(state)
        assert state.state.state == SimulationState.STATE_PAUSED

        clocks, _ = peer.collect(Clock, "/clock", best_effort=True)
        states, _ = peer.collect(JointState, "/rx200/joint_states")
        # The node publishes only while someone listens: wait until it has matched both readers.
        wait_until(lambda: peer.node.get_publishers_info_by_topic("/clock")
                   and peer.node.get_publishers_info_by_topic("/rx200/joint_states"), 20, "the node's publishers")

        # Step while paused: time advances by exactly the steps asked, and the topics follow.
        step = StepSimulation.Request(steps=20)
        for _ in range(3):  # a reader matched moments ago may miss the first publication
            _ok(peer.call(StepSimulation, f"{SIM}/step_simulation", step))
        wait_until(lambda: clocks and states, 20, "/clock and /rx200/joint_states after stepping")
        first = _clock_sec(clocks[-1])
        _ok(peer.call(StepSimulation, f"{SIM}/step_simulation", step))
        wait_until(lambda: _clock_sec(clocks[-1]) > first, 10, "the clock after one more step")
        assert 0 < _clock_sec(clocks[-1]) - first <= 0.2
        assert set(ARM) <= set(states[-1].name)
        paused = peer.call(GetSimulationState, f"{SIM}/get_simulation_state", GetSimulationState.Request())
        assert paused.state.state == SimulationState.STATE_PAUSED

        # Spawn and delete an entity.
        spawn = SpawnEntity.Request(name="box", resource_string=BOX, allow_renaming=False)
        spawn.initial_pose.pose.position.x = 0.4
        _ok(peer.call(SpawnEntity, f"{SIM}/spawn_entity", spawn))
        names = peer.call(GetEntities, f"{SIM}/get_entities", GetEntities.Request()).entities
        assert "box" in names and "rx200" in names
        _ok(peer.call(DeleteEntity, f"{SIM}/delete_entity", DeleteEntity.Request(entity="box")))
        assert "box" not in peer.call(GetEntities, f"{SIM}/get_entities", GetEntities.Request()).entities

        # Reset: time back to zero, the robot still there.
        _ok(peer.call(ResetSimulation, f"{SIM}/reset_simulation", ResetSimulation.Request()))
        assert peer.call(GetEntities, f"{SIM}/get_entities", GetEntities.Request()).entities == ["rx200"]

        # Controllers: list, switch one off and on again.
        cm = "/rx200/controller_manager"
        listed = {c.name: c.state for c in peer.call(ListControllers, f"{cm}/list_controllers",
                                                     ListControllers.Request()).controller}
        assert listed["arm_controller"] == "active"
        assert listed["arm_position_controller"] == "inactive"
        off = SwitchController.Request(deactivate_controllers=["gripper_controller"],
                                       strictness=SwitchController.Request.STRICT)
        assert peer.call(SwitchController, f"{cm}/switch_controller", off).ok
        listed = {c.name: c.state for c in peer.call(ListControllers, f"{cm}/list_controllers",
                                                     ListControllers.Request()).controller}
        assert listed["gripper_controller"] == "inactive"
        on = SwitchController.Request(activate_controllers=["gripper_controller"],
                                      strictness=SwitchController.Request.STRICT)
        assert peer.call(SwitchController, f"{cm}/switch_controller", on).ok

        # A trajectory goal while playing: accepted, feedback, result SUCCEEDED.
        play = SetSimulationState.Request(state=SimulationState(state=SimulationState.STATE_PLAYING))
        _ok(peer.call(SetSimulationState, f"{SIM}/set_simulation_state", play))
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = ARM
        goal.trajectory.points = [JointTrajectoryPoint(positions=[0.3, 0.0, 0.0, 0.0, 0.0],
                                                       time_from_start=Duration(sec=1))]
        handle, feedback, result = peer.send_goal(
            FollowJointTrajectory, "/rx200/arm_controller/follow_joint_trajectory", goal, timeout=30.0)
        assert handle.accepted
        assert result is not None and result.status == 4, result  # action_msgs/GoalStatus.STATUS_SUCCEEDED
        assert result.result.error_code == FollowJointTrajectory.Result.SUCCESSFUL
        assert feedback, "no feedback arrived"
        assert list(feedback[-1].feedback.joint_names) == ARM
        wait_until(lambda: abs(states[-1].position[list(states[-1].name).index("waist")] - 0.3) < 0.1, 10,
                   "the waist at the goal in joint_states")
