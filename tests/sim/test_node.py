"""The simulation node's services over the in-process transport, one test per service behaviour."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from multiros.ros import Context, Node
from multiros.ros.executors import SingleThreadedExecutor
from multiros.ros.interfaces import get_message, get_service
from multiros.sim.client import SimulationClient, SimulationServiceError
from multiros.sim.node import SimulationNode
from multiros.sim.world import World, WorldOptions

DATA = Path(__file__).parent / "data"
ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
BALL = "package://test_arm_description/urdf/ball.xml"

Result = get_message("simulation_interfaces/msg/Result")
SimulationState = get_message("simulation_interfaces/msg/SimulationState")
SpawnEntity = get_service("simulation_interfaces/srv/SpawnEntity")
StepRobot = get_service("uniros_interfaces/srv/StepRobot")
ARM_JOINTS = ("joint1", "joint2", "joint3")
YAML = str(DATA / "test_arm_description" / "config" / "arm_controllers.yaml")
ARM_URI = f"{ARM_XACRO}?__controllers=joint_state_broadcaster,arm_position_controller"


@pytest.fixture
def sim(index, tmp_path):
    """A composed simulation node, an env-side node and a client, all on one inproc context."""
    ctx = Context(transport="inproc").init()
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    node = SimulationNode("mujoco_sim", world=world, context=ctx)
    user = Node("tester", context=ctx)
    client = SimulationClient(user, "/mujoco_sim", timeout_sec=5.0)
    yield node, client, user
    client.close()
    ctx.try_shutdown()


def _spawn_arm(client: SimulationClient, name: str = "arm", **kwargs) -> str:
    return client.spawn_entity(name, uri=ARM_URI, namespace=f"/{name}", **kwargs)


def _wait_for_command(node: SimulationNode, robot: str, timeout: float = 5.0) -> None:
    """Wait until the node's topic thread has taken every queued message (bounded)."""
    deadline = time.monotonic() + timeout
    while any(sub._queue for sub in node.subscriptions) and time.monotonic() < deadline:
        time.sleep(0.001)
    assert not any(sub._queue for sub in node.subscriptions), "the node did not take its messages"
    # The executor runs a taken message's callback under the node's callback lock: once we hold
    # it, the callback has finished.
    with node._callback_lock:
        pass


def _raw(client: SimulationClient, service: str, request):
    return client._client(service).call(request, timeout_sec=5.0)


def test_features_are_truthful(sim):
    node, client, _ = sim
    features = set(int(f) for f in client.get_simulator_features().features)
    Features = get_message("simulation_interfaces/msg/SimulatorFeatures")
    expected = {Features.SPAWNING, Features.DELETING, Features.STEP_SIMULATION_MULTIPLE,
                Features.SIMULATION_RESET_SPAWNED}
    assert expected <= features
    # Advertised services exist; unsupported ones are not advertised.
    assert Features.NAMED_POSES not in features and Features.WORLD_LOADING not in features


def test_spawn_returns_name_and_robot_gets_state(sim):
    node, client, _ = sim
    assert _spawn_arm(client) == "arm"
    assert client.get_entities() == ["arm"]
    state = client.step_robot("arm", steps=0)
    assert set(ARM_JOINTS) <= set(state.names)
    assert state.position.shape == (len(state.names),)


@pytest.mark.parametrize(
    ("request_fields", "resource", "code_name"),
    [
        ({"name": "bad name"}, {"uri": ARM_URI}, "NAME_INVALID"),
        ({"name": ""}, {"uri": ARM_URI}, "NAME_INVALID"),
        ({"name": "x"}, {}, "NO_RESOURCE"),
        ({"name": "x"}, {"resource_string": "<robot name='x'><link name='a'></robot"}, "RESOURCE_PARSE_ERROR"),
        ({"name": "x"}, {"uri": "package://test_arm_description/urdf/missing.urdf"}, "MISSING_ASSETS"),
        ({"name": "x"}, {"uri": "package://no_such_package/robot.urdf"}, "MISSING_ASSETS"),
        ({"name": "x", "entity_namespace": "1bad/ns"}, {"uri": ARM_URI}, "NAMESPACE_INVALID"),
    ],
)
def test_spawn_refuses_bad_input_with_the_standard_code(sim, request_fields, resource, code_name):
    node, client, _ = sim
    req = SpawnEntity.Request(**request_fields)
    for key, value in resource.items():
        setattr(getattr(req, "entity_resource", req), key, value)  # Rolling: Resource; Jazzy: top level
    res = _raw(client, "spawn_entity", req)
    assert res.result.result == getattr(SpawnEntity.Response, code_name), res.result.error_message
    assert res.result.error_message
    assert client.get_entities() == []


def test_spawn_refuses_zero_quaternion(sim):
    node, client, _ = sim
    req = SpawnEntity.Request(name="arm")
    getattr(req, "entity_resource", req).uri = ARM_URI
    q = req.initial_pose.pose.orientation
    q.x = q.y = q.z = q.w = 0.0
    res = _raw(client, "spawn_entity", req)
    assert res.result.result == SpawnEntity.Response.INVALID_POSE
    assert "zero" in res.result.error_message


def test_spawn_name_taken_and_renaming(sim):
    node, client, _ = sim
    _spawn_arm(client)
    with pytest.raises(SimulationServiceError) as err:
        _spawn_arm(client)
    assert err.value.code == SpawnEntity.Response.NAME_NOT_UNIQUE
    renamed = client.spawn_entity("arm", uri=ARM_URI, namespace="/arm2", allow_renaming=True)
    assert renamed != "arm" and renamed.startswith("arm")
    assert sorted(client.get_entities()) == sorted(["arm", renamed])


def test_entity_state_get_set_and_not_found(sim):
    node, client, _ = sim
    client.spawn_entity("ball", uri=BALL, position=(0.5, 0.0, 1.0))
    state = client.get_entity_state("ball")
    assert state.pose.position.x == pytest.approx(0.5)
    assert state.header.frame_id == "world"
    client.set_entity_pose("ball", (0.1, 0.2, 0.3), (0.0, 0.0, 0.0, 1.0))
    state = client.get_entity_state("ball")
    assert (state.pose.position.x, state.pose.position.y, state.pose.position.z) == pytest.approx((0.1, 0.2, 0.3))
    assert abs(state.pose.orientation.z) == pytest.approx(1.0)
    with pytest.raises(SimulationServiceError) as err:
        client.get_entity_state("nobody")
    assert err.value.code == Result.RESULT_NOT_FOUND


def test_get_entities_filters_by_regex_and_category(sim):
    node, client, _ = sim
    _spawn_arm(client, "arm_a")
    client.spawn_entity("ball", uri=BALL, position=(0.5, 0.0, 1.0))
    assert client.get_entities("^arm") == ["arm_a"]
    Req = get_service("simulation_interfaces/srv/GetEntities").Request
    Category = get_message("simulation_interfaces/msg/EntityCategory")
    req = Req()
    req.filters.categories = [Category(category=Category.CATEGORY_ROBOT)]
    assert list(_raw(client, "get_entities", req).entities) == ["arm_a"]
    req = Req()
    req.filters.filter = "(unclosed"
    assert _raw(client, "get_entities", req).result.result == Result.RESULT_OPERATION_FAILED


def test_step_robot_moves_joints_toward_the_command(sim):
    node, client, _ = sim
    _spawn_arm(client)
    target = np.array([0.5, -0.4, 0.3])
    state = client.step_robot("arm", {"arm_position_controller": target}, steps=500, frames=["ee_link"])
    q = state.position[[state.names.index(j) for j in ARM_JOINTS]]
    assert np.max(np.abs(q - target)) < 0.02
    assert state.sim_time == pytest.approx(500 * node.world.timestep)
    assert state.frame_positions.shape == (1, 3)
    assert np.linalg.norm(state.frame_orientations[0]) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("command", "code_name"),
    [
        ({"arm_position_controller": [np.nan, 0.0, 0.0]}, "BAD_COMMAND"),
        ({"arm_position_controller": [0.0, 0.0]}, "BAD_COMMAND"),
        ({"no_such_controller": [0.0, 0.0, 0.0]}, "UNKNOWN_CONTROLLER"),
    ],
)
def test_step_robot_refuses_bad_commands_and_keeps_state(sim, command, code_name):
    node, client, _ = sim
    _spawn_arm(client)
    before = client.step_robot("arm", steps=0)
    with pytest.raises(SimulationServiceError) as err:
        client.step_robot("arm", command, steps=10)
    assert err.value.code == getattr(StepRobot.Response, code_name)
    after = client.step_robot("arm", steps=0)
    assert after.sim_time == before.sim_time
    np.testing.assert_array_equal(after.position, before.position)


def test_step_robot_unknown_frame_and_robot(sim):
    node, client, _ = sim
    _spawn_arm(client)
    with pytest.raises(SimulationServiceError) as err:
        client.step_robot("arm", steps=1, frames=["no_such_link"])
    assert err.value.code == StepRobot.Response.UNKNOWN_FRAME
    with pytest.raises(SimulationServiceError) as err:
        client.step_robot("ghost", steps=1)
    assert err.value.code == Result.RESULT_NOT_FOUND


def test_lockstep_is_deterministic_bit_for_bit(index, tmp_path):
    def run() -> np.ndarray:
        ctx = Context(transport="inproc").init()
        try:
            world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
            SimulationNode("mujoco_sim", world=world, context=ctx)
            client = SimulationClient(Node("t", context=ctx), "/mujoco_sim")
            _spawn_arm(client)
            rng = np.random.default_rng(3)
            rows = []
            for _ in range(20):
                state = client.step_robot("arm", {"arm_position_controller": rng.uniform(-1, 1, 3)}, 20, ["ee_link"])
                rows.append(np.concatenate([state.position, state.velocity, state.frame_positions.ravel()]))
            return np.array(rows)
        finally:
            ctx.try_shutdown()

    a, b = run(), run()
    assert a.tobytes() == b.tobytes()


def test_reset_scopes(sim):
    node, client, _ = sim
    _spawn_arm(client)
    client.step_robot("arm", {"arm_position_controller": [0.5, 0.5, 0.5]}, steps=200)
    client.spawn_entity("ball", uri=BALL, position=(0.5, 0.0, 1.0))
    client.reset_simulation(scope=2)  # state only: time keeps going
    state = client.step_robot("arm", steps=0)
    assert state.sim_time > 0
    assert np.max(np.abs(state.position[[state.names.index(j) for j in ARM_JOINTS]] - [0.0, 0.3, 0.0])) < 1e-9
    client.reset_simulation(scope=1)  # time only
    assert client.step_robot("arm", steps=0).sim_time == 0.0
    client.reset_simulation(scope=4)  # spawned entities removed
    assert client.get_entities() == []


def test_delete_keeps_the_other_robot_state(sim):
    node, client, _ = sim
    _spawn_arm(client, "a")
    _spawn_arm(client, "b", position=(1.0, 0.0, 0.0))
    client.step_robot("a", {"arm_position_controller": [0.4, 0.2, -0.2]}, steps=300)
    before = client.step_robot("a", steps=0)
    client.delete_entity("b")
    after = client.step_robot("a", steps=0)
    np.testing.assert_array_equal(after.position, before.position)
    assert after.sim_time == before.sim_time
    with pytest.raises(SimulationServiceError) as err:
        client.delete_entity("b")
    assert err.value.code == Result.RESULT_NOT_FOUND


def test_simulation_state_transitions(sim):
    node, client, _ = sim
    assert client.get_simulation_state() == SimulationState.STATE_PAUSED
    client.step_simulation(5)
    client.unpause()
    assert client.get_simulation_state() == SimulationState.STATE_PLAYING
    with pytest.raises(SimulationServiceError) as err:
        client.step_simulation(1)
    assert err.value.code == Result.RESULT_OPERATION_FAILED
    client.unpause()  # already playing: not an error for the client
    client.set_simulation_state(SimulationState.STATE_STOPPED)
    assert client.get_simulation_state() == SimulationState.STATE_STOPPED


def test_set_robot_joint_state_validates(sim):
    node, client, _ = sim
    _spawn_arm(client)
    client.set_robot_joint_state("arm", ["joint2"], [0.7])
    state = client.step_robot("arm", steps=0)
    assert state.position[state.names.index("joint2")] == pytest.approx(0.7)
    SetJS = get_service("uniros_interfaces/srv/SetRobotJointState").Response
    with pytest.raises(SimulationServiceError) as err:
        client.set_robot_joint_state("arm", ["nope"], [0.0])
    assert err.value.code == SetJS.UNKNOWN_JOINT
    for bad in (np.nan, 10.0):
        with pytest.raises(SimulationServiceError) as err:
            client.set_robot_joint_state("arm", ["joint2"], [bad])
        assert err.value.code == SetJS.BAD_VALUE


def test_physics_properties(sim):
    node, client, _ = sim
    client.set_physics_properties(time_step=0.001, gravity=(0.0, 0.0, -1.0), real_time_factor=2.0)
    props = client.get_physics_properties()
    assert props["time_step"] == pytest.approx(0.001)
    assert props["gravity"] == pytest.approx((0.0, 0.0, -1.0))
    assert props["real_time_factor"] == pytest.approx(2.0)
    with pytest.raises(SimulationServiceError):
        client.set_physics_properties(time_step=-1.0)


def test_controller_manager_services_and_command_topic(sim):
    node, client, user = sim
    _spawn_arm(client)
    states = {c.name: c.state for c in client.list_controllers("/arm")}
    assert states["arm_position_controller"] == "active"
    # The trajectory controller claims the same joints: a strict switch is refused.
    LoadController = get_service("controller_manager_msgs/srv/LoadController")
    load = user.create_client(LoadController, "/arm/controller_manager/load_controller")
    assert load.call(LoadController.Request(name="arm_controller"), timeout_sec=5.0).ok
    Configure = get_service("controller_manager_msgs/srv/ConfigureController")
    configure = user.create_client(Configure, "/arm/controller_manager/configure_controller")
    assert configure.call(Configure.Request(name="arm_controller"), timeout_sec=5.0).ok
    with pytest.raises(SimulationServiceError):
        client.switch_controllers("/arm", activate=["arm_controller"])
    client.switch_controllers("/arm", activate=["arm_controller"], deactivate=["arm_position_controller"])
    # Now command through the ros2_control-style trajectory topic.
    JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
    Point = get_message("trajectory_msgs/msg/JointTrajectoryPoint")
    pub = user.create_publisher(JointTrajectory, "/arm/arm_controller/joint_trajectory", 10)
    point = Point(positions=np.array([0.3, 0.2, 0.1]))
    point.time_from_start.sec = 0
    point.time_from_start.nanosec = 200_000_000
    pub.publish(JointTrajectory(joint_names=list(ARM_JOINTS), points=[point]))
    _wait_for_command(node, "arm")
    state = client.step_robot("arm", steps=400)
    q = state.position[[state.names.index(j) for j in ARM_JOINTS]]
    assert np.max(np.abs(q - [0.3, 0.2, 0.1])) < 0.03


def test_forward_command_topic_and_joint_states(sim):
    node, client, user = sim
    _spawn_arm(client)
    Float64MultiArray = get_message("std_msgs/msg/Float64MultiArray")
    JointState = get_message("sensor_msgs/msg/JointState")
    String = get_message("std_msgs/msg/String")
    received, descriptions = [], []
    user.create_subscription(JointState, "/arm/joint_states", received.append, 10)
    from multiros.ros.qos import DurabilityPolicy, QoSProfile

    user.create_subscription(String, "/arm/robot_description", descriptions.append,
                             QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    pub = user.create_publisher(Float64MultiArray, "/arm/arm_position_controller/commands", 10)
    pub.publish(Float64MultiArray(data=np.array([-0.3, 0.1, 0.2])))
    _wait_for_command(node, "arm")
    client.step_simulation(400)
    executor = SingleThreadedExecutor(context=user.context)
    executor.add_node(user)
    deadline = time.monotonic() + 5.0
    while not (received and descriptions) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
    assert received, "joint_states were not published while stepping"
    last = received[-1]
    q = np.array([last.position[list(last.name).index(j)] for j in ARM_JOINTS])
    assert np.max(np.abs(q - [-0.3, 0.1, 0.2])) < 0.03
    assert descriptions and "<robot" in descriptions[-1].data


def test_render_camera(sim):
    node, client, _ = sim
    _spawn_arm(client)
    image = client.render(width=64, height=48)
    assert image.shape == (48, 64, 3) and image.dtype == np.uint8
    assert image.std() > 0
    depth = client.render(width=64, height=48, depth=True)
    assert depth.shape == (48, 64) and np.all(np.isfinite(depth))


def test_the_rest_of_ros2_control_s_controller_manager_services(sim):
    """What `ros2 control list_hardware_interfaces/list_hardware_components/list_controller_types/
    set_hardware_component_state` asks, with the active controller's interfaces claimed."""
    _node, client, user = sim
    _spawn_arm(client)

    def call(type_name: str, /, **fields):
        srv = get_service(f"controller_manager_msgs/srv/{type_name}")
        snake = "".join(f"_{c.lower()}" if c.isupper() else c for c in type_name).lstrip("_")
        cli = user.create_client(srv, f"/arm/controller_manager/{snake}")
        return cli.call(srv.Request(**fields), timeout_sec=5.0)

    interfaces = call("ListHardwareInterfaces")
    claimed = {i.name for i in interfaces.command_interfaces if i.is_claimed}
    assert claimed == {f"{j}/position" for j in ARM_JOINTS}
    assert {i.name for i in interfaces.state_interfaces} == {f"{j}/{k}" for j in ARM_JOINTS
                                                             for k in ("position", "velocity", "effort")}
    (component,) = call("ListHardwareComponents").component
    assert component.name == "arm_system" and component.state.label == "active"
    assert {i.name for i in component.command_interfaces} >= {f"{j}/position" for j in ARM_JOINTS}
    types = call("ListControllerTypes").types
    assert "joint_trajectory_controller/JointTrajectoryController" in types
    State = get_message("lifecycle_msgs/msg/State")
    assert call("SetHardwareComponentState", name="arm_system", target_state=State(id=3, label="active")).ok
    refused = call("SetHardwareComponentState", name="arm_system", target_state=State(id=2, label="inactive"))
    assert not refused.ok and refused.state.label == "active"
    assert not call("SetHardwareComponentState", name="nope", target_state=State(id=3, label="active")).ok


def test_destroying_the_node_releases_the_world_it_made_and_keeps_one_it_was_given(index, tmp_path):
    """The node's objects refer to each other, so garbage collection frees them late; the MuJoCo model,
    data and spec of a world the node made go when it is destroyed. A world passed in stays its owner's."""
    ctx = Context(transport="inproc").init()
    try:
        own = SimulationNode("own_world_sim", context=ctx)
        world = own.world
        assert world.model is not None
        own.destroy_node()
        assert world.model is None and world.data is None and list(world.entity_names()) == []
        given = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
        node = SimulationNode("given_world_sim", world=given, context=ctx)
        node.destroy_node()
        assert given.model is not None
        given.step(1)
    finally:
        ctx.try_shutdown()


def test_a_long_call_gives_way_between_chunks_and_a_short_one_runs_whole(sim, monkeypatch):
    """A step call longer than two turns' work asks between its chunks whether to stop and lets the
    others have their turn; a shorter one runs as one call (chunking it cost a snapshot and every
    robot's actuator writes per chunk, for a wait saved shorter than a turn)."""
    node, client, _ = sim
    _spawn_arm(client)
    client.pause()
    asked: list[float] = []
    real = node._between_chunks
    monkeypatch.setattr(node, "_between_chunks", lambda: asked.append(node.world.time) or real())
    node._step_cost = 1.0  # as if a physics step took a second: the smallest chunk, 10 steps
    dt = node.world.model.opt.timestep
    client.step_simulation(19)
    assert asked == []
    node._step_cost = 1.0
    start = node.world.time
    client.step_simulation(25)  # chunks of 10, 10, 5: asked before each
    assert [round((t - start) / dt) for t in asked] == [0, 10, 20]
