"""ResetSimulation and the launched world: SCOPE_ALL / SCOPE_DEFAULT bring back what was launched,
in its launched state, and remove what requests spawned later; the other scopes keep their meaning."""

from __future__ import annotations

import time

import numpy as np
import pytest

from multiros.ros import Context, Node
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_message
from multiros.sim.client import SimulationClient, SimulationServiceError
from multiros.sim.node import SimulationNode
from multiros.sim.world import ResetScope, World, WorldOptions

ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
ARM_URI = f"{ARM_XACRO}?__controllers=joint_state_broadcaster,arm_position_controller"
FREE_BOX = "package://test_arm_description/urdf/free_box.xml"
LAUNCH_Q = [0.0, 0.3, 0.0]  # the arm's ros2_control initial values
Result = get_message("simulation_interfaces/msg/Result")
SimulationState = get_message("simulation_interfaces/msg/SimulationState")


def _controllers(world: World, name: str) -> dict[str, str]:
    return {c.name: c.state for c in world.controller_manager(name).list_controllers()}


def _rollout(world: World, name: str = "arm") -> bytes:
    rows = []
    for target in ([0.4, -0.3, 0.2], [-0.2, 0.5, -0.3]):
        world.set_command(name, "", target)
        world.step(60)
        js = world.joint_state(name)
        rows.append(np.concatenate([js.position, js.velocity, world.get_entity_state("box").position, [world.time]]))
    return np.array(rows).tobytes()


def _launched_world(make_world) -> World:
    world = make_world()
    world.spawn("arm", ARM_XACRO, pose=([0.1, 0.2, 0.0], [1, 0, 0, 0]), controllers=["arm_position_controller"])
    world.spawn("box", FREE_BOX, pose=([0.4, 0.0, 0.3], [1, 0, 0, 0]))
    assert world.mark_launched() == ("arm", "box")
    return world


def test_reset_all_relaunches_the_launched_world(make_world):
    world = _launched_world(make_world)
    assert world.launched_entities() == ("arm", "box") and world.entity("arm").initial
    launch_controllers = _controllers(world, "arm")
    first = _rollout(world)
    # Change everything a session can change, then spawn more.
    world.switch_controllers("arm", activate=["arm_controller"], deactivate=["arm_position_controller"])
    world.set_entity_state("arm", position=[1, 1, 0])
    world.set_joint_positions("arm", ["joint1"], [1.0])
    world.spawn("later", ARM_XACRO, pose=([-1, 0, 0], [1, 0, 0, 0]))
    world.spawn("ball", FREE_BOX, pose=([0, 1, 0.5], [1, 0, 0, 0]))
    world.delete("box")  # a launched entity deleted by request comes back too
    world.step(30)
    respawned = world.reset(ResetScope.ALL)
    assert respawned == ("arm", "box") and world.entity_names() == ("arm", "box")
    assert world.time == 0.0
    np.testing.assert_allclose(world.get_entity_state("arm").position, [0.1, 0.2, 0.0])
    np.testing.assert_allclose(world.get_entity_state("box").position, [0.4, 0.0, 0.3])
    np.testing.assert_array_equal(world.joint_state("arm").position, LAUNCH_Q)
    assert _controllers(world, "arm") == launch_controllers
    assert _rollout(world) == first  # bit for bit as after the launch
    world.spawn("later", ARM_XACRO)
    world.reset(ResetScope.DEFAULT)  # scope 0 is SCOPE_ALL
    assert world.entity_names() == ("arm", "box") and world.time == 0.0


def test_reset_all_without_a_launched_world_empties_it(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO)
    world.step(10)
    assert world.reset(ResetScope.ALL) == ()
    assert world.entity_names() == () and world.time == 0.0
    world.spawn("arm", ARM_XACRO)  # the world works on
    world.step(10)


def test_other_scopes_keep_their_meaning(make_world):
    world = _launched_world(make_world)
    world.switch_controllers("arm", activate=["arm_controller"], deactivate=["arm_position_controller"])
    switched = _controllers(world, "arm")
    world.spawn("later", FREE_BOX, pose=([0, 1, 0.5], [1, 0, 0, 0]))
    world.set_joint_positions("arm", ["joint1"], [1.0])
    world.step(50)
    cm = world.controller_manager("arm")
    assert world.reset(ResetScope.STATE) == ()  # poses and joints back, controllers and time as they are
    assert world.time > 0 and world.entity_names() == ("arm", "box", "later")
    np.testing.assert_array_equal(world.joint_state("arm").position, LAUNCH_Q)
    assert _controllers(world, "arm") == switched and world.controller_manager("arm") is cm
    world.reset(ResetScope.TIME)
    assert world.time == 0.0 and world.entity_names() == ("arm", "box", "later")
    world.step(10)
    world.reset(ResetScope.SPAWNED)  # only what was spawned later goes
    assert world.entity_names() == ("arm", "box") and world.time > 0
    assert _controllers(world, "arm") == switched
    world.reset(ResetScope.TIME | ResetScope.STATE | ResetScope.SPAWNED)
    assert world.time == 0.0 and _controllers(world, "arm") == switched
    with pytest.raises(ValueError, match="unknown bits"):
        world.reset(256)


def test_spawn_initial_is_launched(make_world):
    world = make_world()
    world.spawn("arm", ARM_XACRO, initial=True)
    world.spawn("box", FREE_BOX, pose=([0.4, 0, 0.3], [1, 0, 0, 0]))
    world.delete("arm")
    world.reset(ResetScope.SPAWNED)
    assert world.entity_names() == ()  # SPAWNED does not bring back what was deleted
    world.reset(ResetScope.ALL)
    assert world.entity_names() == ("arm",)


# ---------------------------------------------------------------------------------------- over the node
@pytest.fixture
def sim(index, tmp_path):
    """A node with a launched arm (as ``uniros-sim --robot arm=...`` makes it), a client and a user node."""
    ctx = Context(transport="inproc").init()
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    node = SimulationNode("mujoco_sim", world=world, context=ctx)
    node.spawn_from_cli("arm", ARM_URI)
    assert node.mark_launched() == ("arm",)
    user = Node("tester", context=ctx)
    client = SimulationClient(user, "/mujoco_sim", timeout_sec=5.0)
    yield node, client, user
    client.close()
    ctx.try_shutdown()


def _states(client: SimulationClient, ns: str) -> dict[str, str]:
    return {c.name: c.state for c in client.list_controllers(ns)}


def _to_trajectory_controller(client: SimulationClient) -> None:
    """Load, configure and activate the arm's trajectory controller in place of its position one."""
    cm = client.controller_manager("/arm")
    assert cm.load("arm_controller") and cm.configure("arm_controller")
    client.switch_controllers("/arm", activate=["arm_controller"], deactivate=["arm_position_controller"])


def test_node_reset_all_restores_the_launched_robot(sim):
    node, client, user = sim
    launch_controllers = _states(client, "/arm")
    assert launch_controllers["arm_position_controller"] == "active"
    first = client.step_robot("arm", {"arm_position_controller": [0.3, 0.1, -0.1]}, 100, ["ee_link"])
    client.reset_simulation(255)
    _to_trajectory_controller(client)
    client.set_robot_joint_state("arm", ["joint1"], [0.8])
    client.spawn_entity("later", uri=ARM_URI, namespace="/later", position=(1.0, 0, 0))
    client.spawn_entity("box", uri=FREE_BOX, position=(0.4, 0, 0.3))
    client.step_simulation(50)
    client.reset_simulation(255)
    assert client.get_entities() == ["arm"]
    state = client.step_robot("arm", steps=0)
    assert state.sim_time == 0.0
    np.testing.assert_array_equal(state.position, LAUNCH_Q)
    assert _states(client, "/arm") == launch_controllers
    with pytest.raises(SimulationServiceError) as err:
        client.step_robot("later", steps=0)
    assert err.value.code == Result.RESULT_NOT_FOUND
    again = client.step_robot("arm", {"arm_position_controller": [0.3, 0.1, -0.1]}, 100, ["ee_link"])
    assert again.position.tobytes() == first.position.tobytes()
    assert again.frame_positions.tobytes() == first.frame_positions.tobytes()
    # Deleted by request, it comes back with SCOPE_DEFAULT too.
    client.delete_entity("arm")
    client.reset_simulation(0)
    assert client.get_entities() == ["arm"]


def test_node_interfaces_of_the_respawned_robot_work(sim):
    node, client, user = sim
    client.reset_simulation(255)
    # Controller-manager services answer for the new robot, and switching acts on it.
    _to_trajectory_controller(client)
    assert _states(client, "/arm")["arm_controller"] == "active"
    assert node.world.controller_manager("arm").get("arm_controller").state == "active"
    client.reset_simulation(255)
    assert _states(client, "/arm") == {"joint_state_broadcaster": "active", "arm_position_controller": "active"}
    # The command topic and joint_states of the new robot work.
    Float64MultiArray = get_message("std_msgs/msg/Float64MultiArray")
    JointState = get_message("sensor_msgs/msg/JointState")
    received = []
    user.create_subscription(JointState, "/arm/joint_states", received.append, 10)
    pub = user.create_publisher(Float64MultiArray, "/arm/arm_position_controller/commands", 10)
    pub.publish(Float64MultiArray(data=np.array([-0.3, 0.1, 0.2])))
    deadline = time.monotonic() + 5.0
    while any(sub._queue for sub in node.subscriptions) and time.monotonic() < deadline:
        time.sleep(0.001)
    with node._callback_lock:  # the executor has finished the command callback
        pass
    client.step_simulation(400)
    executor = SingleThreadedExecutor(context=user.context)
    executor.add_node(user)
    deadline = time.monotonic() + 5.0
    while not received and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert received, "joint_states were not published after the reset"
    last = received[-1]
    np.testing.assert_allclose(last.position, [-0.3, 0.1, 0.2], atol=0.03)


def test_node_other_scopes_keep_spawned_robots(sim):
    node, client, _ = sim
    client.spawn_entity("later", uri=ARM_URI, namespace="/later", position=(1.0, 0, 0))
    _to_trajectory_controller(client)
    client.step_simulation(20)
    client.reset_simulation(2 | 1)
    assert client.get_entities() == ["arm", "later"]
    assert _states(client, "/arm")["arm_controller"] == "active"
    assert client.step_robot("later", steps=0).sim_time == 0.0
    client.reset_simulation(4)
    assert client.get_entities() == ["arm"]
    assert _states(client, "/arm")["arm_controller"] == "active"


def test_node_stopped_state_relaunches(sim):
    node, client, _ = sim
    client.spawn_entity("box", uri=FREE_BOX, position=(0.4, 0, 0.3))
    client.step_simulation(20)
    client.set_simulation_state(SimulationState.STATE_STOPPED)
    assert client.get_entities() == ["arm"]
    assert client.step_robot("arm", steps=0).sim_time == 0.0


@pytest.mark.slow
def test_over_zenoh_the_respawned_robot_answers(index, tmp_path):
    """Two Zenoh sessions on a private router: after SCOPE_ALL the peer reaches the re-created
    controller-manager services and receives the re-created joint_states."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{s.getsockname()[1]}"
    with Context(transport="zenoh", env={}, router_endpoint=endpoint) as node_ctx, \
            Context(transport="zenoh", env={}, router="none", router_endpoint=endpoint) as peer_ctx:
        world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
        node = SimulationNode("mujoco_sim", world=world, context=node_ctx)
        node.spawn_from_cli("arm", ARM_URI)
        node.mark_launched()
        user = Node("tester", context=peer_ctx)
        client = SimulationClient(user, "/mujoco_sim", timeout_sec=5.0)
        client.wait_until_ready(timeout_sec=10.0)
        client.spawn_entity("later", uri=FREE_BOX, position=(0.4, 0, 0.3))
        _to_trajectory_controller(client)
        client.reset_simulation(255)
        assert client.get_entities() == ["arm"]
        assert _states(client, "/arm") == {"joint_state_broadcaster": "active", "arm_position_controller": "active"}
        _to_trajectory_controller(client)
        assert node.world.controller_manager("arm").get("arm_controller").state == "active"
        JointState = get_message("sensor_msgs/msg/JointState")
        received = []
        user.create_subscription(JointState, "/arm/joint_states", received.append, 10)
        executor = SingleThreadedExecutor(context=peer_ctx)
        executor.add_node(user)
        deadline = time.monotonic() + 10.0
        while not received and time.monotonic() < deadline:
            client.step_simulation(10)
            executor.spin_once(timeout_sec=0.05)
        assert received, "joint_states of the respawned robot did not arrive over Zenoh"
        client.close()
        node.destroy_node()
