"""``uniros-sim --transport rclpy`` as a good citizen of a DDS graph, seen by plain rclpy peers (no uniros
import in what they call): a quick request answered while another client's long step runs, a burst of
200 calls of one client all answered, the node's settings as ROS parameters (read-only ones refused
with the reason) and the memory of large parameter requests given back, a quota of entities per
client (each DDS client by its request writer's GUID), the rest of the controller manager's services,
and no hidden node of uniros' own.
"""

from __future__ import annotations

import importlib.util
import threading

import pytest

_NEEDED = ("rclpy", "simulation_interfaces", "controller_manager_msgs", "rcl_interfaces", "uniros_interfaces")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy and the interface packages .ci/rclpy builds (run by .ci/rclpy)", allow_module_level=True)

from controller_manager_msgs.srv import ListControllerTypes, ListHardwareComponents, ListHardwareInterfaces  # noqa: E402
from plain_ros import PlainPeer, wait_until  # noqa: E402
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy_harness import Program, uniros_script  # noqa: E402
from simulation_interfaces.msg import Result  # noqa: E402
from simulation_interfaces.srv import (  # noqa: E402
    DeleteEntity,
    GetEntities,
    GetSimulationState,
    SpawnEntity,
    StepSimulation,
)

pytestmark = pytest.mark.slow

RX200 = "rx200=package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
SIM = "/mujoco_sim"
ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """One ``uniros-sim`` with an RX200 for the module (stopped by PID at its end)."""
    log = tmp_path_factory.mktemp("citizen") / "uniros-sim.log"
    prog = Program([uniros_script("uniros-sim"), "--transport", "rclpy", "--robot", RX200, "--max-robots", "4",
                    "--max-entities-per-client", "2"],
                   str(log))
    try:
        prog.wait_ready("simulation node /mujoco_sim ready")
        yield prog
    finally:
        prog.stop()


def _answered(peer: PlainPeer, srv_type, name: str):
    client = peer.node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=30.0), f"service {name} not available"
    return client


def test_a_quick_request_is_answered_while_another_client_s_long_step_runs(sim) -> None:
    """Each client's request runs on a worker of its own and the node's lock gives turns: another
    client's GetEntities is answered before a StepSimulation(100000) (seconds of physics) ends. The
    long step is checked still running when the answer came, which a serial receive loop never allows."""
    with PlainPeer("flooder") as flooder, PlainPeer("quick_one") as quick:
        step = _answered(flooder, StepSimulation, f"{SIM}/step_simulation")
        entities = _answered(quick, GetEntities, f"{SIM}/get_entities")
        for _attempt in range(3):  # a loaded machine may deliver the quick request late: try a fresh step
            long_call = step.call_async(StepSimulation.Request(steps=100000))
            answer = entities.call_async(GetEntities.Request())
            wait_until(lambda: answer.done() or long_call.done(), 120, "either answer")  # noqa: B023
            overtaken = answer.done() and not long_call.done()
            wait_until(lambda: answer.done() and long_call.done(), 120, "both answers")  # noqa: B023
            assert list(answer.result().entities) == ["rx200"]
            assert long_call.result().result.result == Result.RESULT_OK, long_call.result().result.error_message
            if overtaken:
                return
        raise AssertionError("GetEntities was never answered during another client's StepSimulation(100000)")


def test_a_burst_of_200_calls_of_one_client_is_queued_not_dropped(sim) -> None:
    """The node keeps every request (KEEP_ALL) and answers a client's burst in order. The client here
    keeps every answer too (KEEP_ALL): with rclpy's default KEEP_LAST 10 a client drops the answers it
    has not taken yet beyond 10, which a loaded machine can make happen whatever the server does (the
    node paces bursts for such clients: benchmarks/bench_rclpy_fairness.py measures them)."""
    with PlainPeer("burst") as peer:
        qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
        client = peer.node.create_client(GetSimulationState, f"{SIM}/get_simulation_state", qos_profile=qos)
        assert client.wait_for_service(timeout_sec=30.0)
        lock, answered = threading.Lock(), [0]

        def count(_future) -> None:
            with lock:
                answered[0] += 1

        futures = [client.call_async(GetSimulationState.Request()) for _ in range(200)]
        for future in futures:
            future.add_done_callback(count)
        wait_until(lambda: answered[0] == 200, 60, f"200 answers (got {answered[0]})")
        assert all(f.result().result.result == Result.RESULT_OK for f in futures)


def test_the_node_s_settings_are_ros_parameters(sim) -> None:
    """What ``ros2 param list/get/describe/set`` calls."""
    with PlainPeer("param_user") as peer:
        names = peer.call(ListParameters, f"{SIM}/list_parameters", ListParameters.Request()).result.names
        assert {"max_steps_per_call", "max_robots", "max_entities", "max_entities_per_client",
                "use_sim_time"} <= set(names)
        values = peer.call(GetParameters, f"{SIM}/get_parameters",
                           GetParameters.Request(names=["max_robots", "max_steps_per_call"])).values
        assert [(v.type, v.integer_value) for v in values] == [(ParameterType.PARAMETER_INTEGER, 4),
                                                               (ParameterType.PARAMETER_INTEGER, 100000)]
        (desc,) = peer.call(DescribeParameters, f"{SIM}/describe_parameters",
                            DescribeParameters.Request(names=["max_robots"])).descriptors
        assert desc.read_only and desc.description
        bad = Parameter(name="max_robots", value=ParameterValue(type=ParameterType.PARAMETER_INTEGER,
                                                                integer_value=1000))
        (result,) = peer.call(SetParameters, f"{SIM}/set_parameters", SetParameters.Request(parameters=[bad])).results
        assert not result.successful and "read-only" in result.reason


def test_an_oversize_parameter_request_is_refused_without_being_decoded(sim) -> None:
    """Over 256 KiB (``MAX_REQUEST_BYTES``): a set answered with one refused result that gives the size, a
    get with an empty answer, each in well under a second; a request of a usual size is answered after."""
    import time

    with PlainPeer("param_flooder") as peer:
        flood = [Parameter(name=f"flood.p{i}", value=ParameterValue(type=ParameterType.PARAMETER_INTEGER,
                                                                    integer_value=i)) for i in range(10_000)]
        peer.call(GetParameters, f"{SIM}/get_parameters", GetParameters.Request(names=["use_sim_time"]))  # warm
        start = time.monotonic()
        (result,) = peer.call(SetParameters, f"{SIM}/set_parameters", SetParameters.Request(parameters=flood)).results
        assert not result.successful and "bytes; at most 262,144" in result.reason, result.reason
        few_bytes = flood[:1_000]  # ~40 KB: within the bytes, over MAX_NAMES: refused from its length alone
        set_few = SetParameters.Request(parameters=few_bytes)
        (result,) = peer.call(SetParameters, f"{SIM}/set_parameters", set_few).results
        assert result.reason == "refused: a request of 1,000 items; at most 256" and not result.successful
        names = [f"flood.p{i}" for i in range(100_000)]
        assert list(peer.call(GetParameters, f"{SIM}/get_parameters", GetParameters.Request(names=names)).values) == []
        assert time.monotonic() - start < 5.0  # both, with the client's own conversions (~0.2 s)
        (value,) = peer.call(GetParameters, f"{SIM}/get_parameters", GetParameters.Request(names=["max_robots"])).values
        assert value.integer_value == 4


def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024


def test_the_node_gives_back_the_memory_of_large_requests(sim) -> None:
    """Three clients set ``use_sim_time`` to a 1,000,000-integer array (8 MB of CDR, refused over 256 KiB)
    three times each, at once: the node's memory is back within 6 MB of what it was within 10 s (Fast
    DDS's service histories free each request once taken, glibc's malloc in one arena trimmed once large
    requests stop: ``multiros/ros/native_memory.py``). Before, the node kept 55 MB of them; with the malloc
    part alone, 24 MB. On Fast DDS 3.x (Kilted) the histories keep their buffers (the profile is checked
    against 2.x only): the node was back within 24 MB there, and the test is skipped."""
    import time

    from multiros.ros.transport.rclpy.fastdds_profile import profile_refusal

    big = SetParameters.Request(parameters=[Parameter(name="use_sim_time", value=ParameterValue(
        type=ParameterType.PARAMETER_INTEGER_ARRAY, integer_array_value=list(range(1_000_000))))])
    peers = [PlainPeer(f"memory_flooder_{k}") for k in range(3)]
    try:
        for peer in peers:  # warm: every client matched, the node's first answers given
            peer.call(GetParameters, f"{SIM}/get_parameters", GetParameters.Request(names=["use_sim_time"]))
        # The node's Fast DDS is this process's (the same venv), loaded by now: the peers' participants
        why = profile_refusal(env={})
        if why is not None:
            pytest.skip(f"the Fast DDS history profile does not apply here: {why}")
        before = _rss_mb(sim.proc.pid)
        answers: list[str] = []

        def flood(peer: PlainPeer) -> None:
            for _ in range(3):
                (result,) = peer.call(SetParameters, f"{SIM}/set_parameters", big, timeout=30.0).results
                answers.append(result.reason)

        threads = [threading.Thread(target=flood, args=(peer,)) for peer in peers]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
        assert len(answers) == 9 and all("bytes; at most 262,144" in a for a in answers), answers
        peak = _rss_mb(sim.proc.pid)
        deadline = time.monotonic() + 10.0
        while _rss_mb(sim.proc.pid) > before + 6 and time.monotonic() < deadline:
            time.sleep(0.05)
        after = _rss_mb(sim.proc.pid)
        assert after <= before + 6, f"node memory {before:.0f} MB before, {peak:.0f} MB after the requests, " \
                                    f"{after:.0f} MB 10 s later"
    finally:
        for peer in peers:
            peer.close()


BOX = """<mujoco><worldbody><body name="box"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/>
</body></worldbody></mujoco>"""


def test_each_dds_client_has_its_own_entity_quota(sim) -> None:
    """``--max-entities-per-client 2``: a third box of one client is refused naming the quota, another
    client still spawns, and a deletion frees the owner's quota."""
    with PlainPeer("owner_a") as a, PlainPeer("owner_b") as b:
        spawn_a, spawn_b = _answered(a, SpawnEntity, f"{SIM}/spawn_entity"), _answered(b, SpawnEntity,
                                                                                      f"{SIM}/spawn_entity")

        def spawn(client, name: str, i: int):
            req = SpawnEntity.Request(name=name, resource_string=BOX)
            req.initial_pose.header.frame_id = "world"
            req.initial_pose.pose.position.x, req.initial_pose.pose.position.y = 3.0 + 0.2 * i, 0.0
            req.initial_pose.pose.position.z = 0.03
            future = client.call_async(req)
            wait_until(future.done, 60, f"the answer to SpawnEntity({name})")
            return future.result().result

        assert [spawn(spawn_a, f"a{i}", i).result for i in range(2)] == [Result.RESULT_OK] * 2
        refused = spawn(spawn_a, "a2", 2)
        assert refused.result == Result.RESULT_OPERATION_FAILED
        assert "holds 2 entities" in refused.error_message and "max_entities_per_client=2" in refused.error_message
        assert refused.error_message.split("'")[1].startswith("dds:")  # named by its GUID, not anonymous
        assert [spawn(spawn_b, f"b{i}", 10 + i).result for i in range(2)] == [Result.RESULT_OK] * 2
        deleted = b.call(DeleteEntity, f"{SIM}/delete_entity", DeleteEntity.Request(entity="a0")).result
        assert deleted.result == Result.RESULT_OK
        assert spawn(spawn_a, "a2", 2).result == Result.RESULT_OK
        for name in ("a1", "a2", "b0", "b1"):
            b.call(DeleteEntity, f"{SIM}/delete_entity", DeleteEntity.Request(entity=name))


def test_ros2_control_s_hardware_and_type_services(sim) -> None:
    with PlainPeer("control_user") as peer:
        cm = "/rx200/controller_manager"
        interfaces = peer.call(ListHardwareInterfaces, f"{cm}/list_hardware_interfaces",
                               ListHardwareInterfaces.Request())
        assert {f"{j}/position" for j in ARM} <= {i.name for i in interfaces.command_interfaces}
        assert any(i.is_claimed for i in interfaces.command_interfaces)
        (component,) = peer.call(ListHardwareComponents, f"{cm}/list_hardware_components",
                                 ListHardwareComponents.Request()).component
        assert component.state.label == "active"
        types = peer.call(ListControllerTypes, f"{cm}/list_controller_types", ListControllerTypes.Request()).types
        assert "joint_state_broadcaster/JointStateBroadcaster" in types


def test_no_hidden_node_of_uniros_in_the_graph(sim) -> None:
    with PlainPeer("graph_user") as peer:
        peer.wait_for_node(SIM)
        assert not [n for n in peer.nodes() if "_uniros_graph_" in n], peer.nodes()
