"""The simulation node serves every supported distribution's variant of its services at once.

Foreign peers are raw eclipse-zenoh sessions speaking rmw_zenoh with rosbags CDR built from one
distribution's release definition text, and keys built from rosbags' type hash (``char`` mapped to
uint8 as rosidl does): no multiros code on the peer side. In-process, clients of every variant
reach the node too, each getting its own classes back.
"""

from __future__ import annotations

import socket
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from raw_zenoh import open_peer_session, query_until_answered
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags_types import service_types, store_of

from multiros.ros import Context, Node
from multiros.ros.interfaces import SUPPORTED_DISTROS, registry_for, type_hash
from multiros.ros.interfaces.registry import DEFINITIONS_ROOT, DISTROS_ROOT
from multiros.sim.client import SimulationClient
from multiros.sim.distro_adapters import NATIVE_DISTRO, convert_message, service_variants
from multiros.sim.node import SimulationNode
from multiros.sim.packages import PackageIndex
from multiros.sim.world import World, WorldOptions

DATA = Path(__file__).parent / "data"
ARM_XACRO = "package://test_arm_description/urdf/arm.urdf.xacro"
OK = 1  # simulation_interfaces/msg/Result.RESULT_OK
ARM_URI = f"{ARM_XACRO}?__controllers=joint_state_broadcaster,arm_position_controller"
PEER_SERVICES = {
    "spawn_entity": "simulation_interfaces/srv/SpawnEntity",
    "set_entity_state": "simulation_interfaces/srv/SetEntityState",
    "get_entity_state": "simulation_interfaces/srv/GetEntityState",
    "get_spawnables": "simulation_interfaces/srv/GetSpawnables",
    "list_controllers": "controller_manager_msgs/srv/ListControllers",
    "switch_controller": "controller_manager_msgs/srv/SwitchController",
}


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def _peer_store(distro: str):
    """rosbags' own typestore plus the distribution's release files, read straight from disk."""
    base = get_typestore(Stores.ROS2_JAZZY)
    types = {n: base.fielddefs[n] for n in base.fielddefs}
    for root in (DISTROS_ROOT / distro, DEFINITIONS_ROOT):
        for path in sorted(root.glob("*/msg/*.msg")):
            name = f"{path.parent.parent.name}/msg/{path.stem}"
            if name not in types:
                types.update(get_types_from_msg(path.read_text(), name))
    for srv in PEER_SERVICES.values():
        pkg, _, base_name = srv.split("/")
        types.update(service_types(srv, (DISTROS_ROOT / distro / pkg / "srv" / f"{base_name}.srv").read_text()))
    return store_of(types)


class Peer:
    """A foreign rmw_zenoh service client of one distribution."""

    def __init__(self, distro: str, endpoint: str) -> None:
        self.store = _peer_store(distro)
        self.session = open_peer_session(endpoint)
        self.seq = 0

    def key(self, name: str, srv: str) -> str:
        pkg, _, base = srv.split("/")
        return f"0/{name.strip('/')}/{pkg}::srv::dds_::{base}_/{self.store.hash_rihs01(srv)}"

    def call(self, name: str, srv: str, request, timeout: float = 10.0):
        data = bytes(self.store.serialize_cdr(request, f"{srv}_Request"))
        self.seq += 1
        attachment = struct.pack("<qqB", self.seq, time.time_ns(), 16) + bytes(range(16))
        # until the router has the node's queryable (no reply yet: retry, bounded)
        replies = query_until_answered(self.session, self.key(name, srv), payload=data, timeout=timeout,
                                       attachment=lambda: attachment)
        assert len(replies) == 1, f"{name}: {len(replies)} replies"
        assert replies[0].ok is not None, replies[0].err.payload.to_string()
        return self.store.deserialize_cdr(replies[0].ok.payload.to_bytes(), f"{srv}_Response")

    def default(self, type_name: str, **fields):
        """A rosbags message with every field at its default, ``fields`` overriding."""
        cls = self.store.types[type_name]
        values = {}
        _, field_defs = self.store.fielddefs[type_name]
        for fname, desc in field_defs:
            if fname in fields:
                values[fname] = fields[fname]
            elif desc[0] == Nodetype.NAME:
                values[fname] = self.default(desc[1])
            elif desc[0] == Nodetype.BASE:
                values[fname] = "" if desc[1][0] == "string" else (False if desc[1][0] == "bool" else 0)
            elif desc[0] in (Nodetype.SEQUENCE, Nodetype.ARRAY):
                elem, size = desc[1]
                count = size if desc[0] == Nodetype.ARRAY else 0
                if elem[0] == Nodetype.NAME:
                    values[fname] = [self.default(elem[1]) for _ in range(count)]
                elif elem[1][0] == "string":
                    values[fname] = [""] * count
                else:
                    values[fname] = np.zeros(count, dtype=np.bool_ if elem[1][0] == "bool" else elem[1][0])
        return cls(**values)

    def close(self) -> None:
        self.session.close()


@pytest.fixture
def zenoh_node(tmp_path):
    endpoint = _free_endpoint()
    ctx = Context(transport="zenoh", env={}, router_endpoint=endpoint).init()
    index = PackageIndex([DATA], environ={})  # entry points on: GetSpawnables lists the installed robots
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    node = SimulationNode("mujoco_sim", world=world, context=ctx)
    yield node, endpoint
    node.destroy_node()
    ctx.try_shutdown()


def _pose_fields(peer: Peer, xyz) -> object:
    point = peer.default("geometry_msgs/msg/Point", x=xyz[0], y=xyz[1], z=xyz[2])
    quat = peer.default("geometry_msgs/msg/Quaternion", w=1.0)
    return peer.default("geometry_msgs/msg/Pose", position=point, orientation=quat)


@pytest.mark.slow
@pytest.mark.parametrize("distro", SUPPORTED_DISTROS)
def test_foreign_peer_of_each_distribution_reaches_the_node(zenoh_node, distro: str) -> None:
    node, endpoint = zenoh_node
    peer = Peer(distro, endpoint)
    rolling_shape = distro == "rolling"
    srv = PEER_SERVICES
    try:
        # SpawnEntity, in this release's shape.
        resource = {"uri": ARM_URI, "resource_string": ""}
        header = peer.default("std_msgs/msg/Header", frame_id="world")
        pose = peer.default("geometry_msgs/msg/PoseStamped", header=header, pose=_pose_fields(peer, (0.5, 0, 0)))
        if rolling_shape:
            fields = {"entity_resource": peer.default("simulation_interfaces/msg/Resource", **resource)}
        else:
            fields = resource
        req = peer.default("simulation_interfaces/srv/SpawnEntity_Request", name="arm", allow_renaming=False,
                           entity_namespace="/arm", initial_pose=pose, **fields)
        res = peer.call("/mujoco_sim/spawn_entity", srv["spawn_entity"], req)
        assert res.result.result == OK, res.result.error_message
        assert res.entity_name == "arm" and node.world.has_entity("arm")
        assert np.allclose(node.world.get_entity_state("arm").position, [0.5, 0, 0])

        # SetEntityState: Jazzy/Kilted have no flags and mean "set all".
        state = peer.default("simulation_interfaces/msg/EntityState", header=header,
                             pose=_pose_fields(peer, (0.1, 0.2, 0.0)))
        flags = {"set_pose": True} if rolling_shape else {}
        req = peer.default("simulation_interfaces/srv/SetEntityState_Request", entity="arm", state=state, **flags)
        res = peer.call("/mujoco_sim/set_entity_state", srv["set_entity_state"], req)
        assert res.result.result == OK, res.result.error_message
        assert np.allclose(node.world.get_entity_state("arm").position, [0.1, 0.2, 0.0])
        res = peer.call("/mujoco_sim/get_entity_state", srv["get_entity_state"],
                        peer.default("simulation_interfaces/srv/GetEntityState_Request", entity="arm"))
        assert res.result.result == OK and abs(res.state.pose.position.y - 0.2) < 1e-9

        # GetSpawnables: Spawnable.uri (Jazzy/Kilted) or Spawnable.entity_resource.uri (Rolling).
        res = peer.call("/mujoco_sim/get_spawnables", srv["get_spawnables"],
                        peer.default("simulation_interfaces/srv/GetSpawnables_Request"))
        assert res.result.result == OK, res.result.error_message
        uris = [s.entity_resource.uri if rolling_shape else s.uri for s in res.spawnables]
        assert "package://rx200_description/urdf/rx200.urdf.xacro" in uris
        assert all(s.description for s in res.spawnables)

        # The robot's controller manager.
        res = peer.call("/arm/controller_manager/list_controllers", srv["list_controllers"],
                        peer.default("controller_manager_msgs/srv/ListControllers_Request"))
        states = {c.name: c.state for c in res.controller}
        assert states == {"joint_state_broadcaster": "active", "arm_position_controller": "active"}
        req = peer.default("controller_manager_msgs/srv/SwitchController_Request",
                           deactivate_controllers=["arm_position_controller"], strictness=2)
        res = peer.call("/arm/controller_manager/switch_controller", srv["switch_controller"], req)
        assert res.ok
        assert node.world.controller_manager("arm").get("arm_position_controller").state == "inactive"
        req = peer.default("controller_manager_msgs/srv/SwitchController_Request",
                           activate_controllers=["no_such_controller"], strictness=2)
        res = peer.call("/arm/controller_manager/switch_controller", srv["switch_controller"], req)
        assert not res.ok and "no_such_controller" in res.message
    finally:
        peer.close()


# -- which variants the node creates ---------------------------------------------------------------
def test_only_variants_with_another_hash_get_a_service() -> None:
    spawn = service_variants("simulation_interfaces/srv/SpawnEntity")
    assert [d for d, _ in spawn] == [NATIVE_DISTRO, "jazzy"]  # Kilted's hashes like Jazzy's
    assert type_hash(spawn[1][1]) == type_hash("simulation_interfaces/srv/SpawnEntity", registry_for("kilted"))
    assert [d for d, _ in service_variants("simulation_interfaces/srv/DeleteEntity")] == [NATIVE_DISTRO]
    assert [d for d, _ in service_variants("controller_manager_msgs/srv/SwitchController")] == [NATIVE_DISTRO]
    assert [d for d, _ in service_variants("uniros_interfaces/srv/StepRobot")] == [NATIVE_DISTRO]


def test_converter_adapts_the_fields_whose_meaning_differs() -> None:
    jazzy, rolling = registry_for("jazzy"), registry_for("rolling")
    spawn_j = jazzy.service_class("simulation_interfaces/srv/SpawnEntity").Request(
        name="a", uri="package://p/r.urdf", resource_string="<robot/>")
    spawn_j.initial_pose.pose.position.x = 2.0
    spawn_r = convert_message(spawn_j, rolling.service_class("simulation_interfaces/srv/SpawnEntity").Request)
    assert (spawn_r.name, spawn_r.entity_resource.uri, spawn_r.entity_resource.resource_string) == (
        "a", "package://p/r.urdf", "<robot/>")
    assert spawn_r.initial_pose.pose.position.x == 2.0
    back = convert_message(spawn_r, type(spawn_j))
    assert back == spawn_j
    set_j = jazzy.service_class("simulation_interfaces/srv/SetEntityState").Request(entity="e")
    set_r = convert_message(set_j, rolling.service_class("simulation_interfaces/srv/SetEntityState").Request)
    assert set_r.set_pose and set_r.set_twist and set_r.set_acceleration
    spawnable = rolling.message_class("simulation_interfaces/msg/Spawnable")(description="d")
    spawnable.entity_resource.uri = "package://p/x.urdf"
    old = convert_message(spawnable, jazzy.message_class("simulation_interfaces/msg/Spawnable"))
    assert (old.uri, old.description) == ("package://p/x.urdf", "d")
    load_j = jazzy.service_class("simulation_interfaces/srv/LoadWorld").Request(resource_string="<world/>")
    load_r = convert_message(load_j, rolling.service_class("simulation_interfaces/srv/LoadWorld").Request)
    assert load_r.world_resource.resource_string == "<world/>"


# -- in-process: clients of every variant, matched on the type hash --------------------------------
def test_inproc_clients_of_every_distribution_reach_their_variant(index, tmp_path) -> None:
    ctx = Context(transport="inproc").init()
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    node = SimulationNode("mujoco_sim", world=world, context=ctx)
    user = Node("tester", context=ctx)
    try:
        for i, distro in enumerate(SUPPORTED_DISTROS):
            spawn = registry_for(distro).service_class("simulation_interfaces/srv/SpawnEntity")
            cli = user.create_client(spawn, "/mujoco_sim/spawn_entity")
            assert cli.service_is_ready()
            req = spawn.Request(name=f"arm_{distro}", entity_namespace=f"/arm_{distro}")
            getattr(req, "entity_resource", req).uri = ARM_URI
            req.initial_pose.pose.position.y = float(i)
            res = cli.call(req, timeout_sec=5.0)
            assert type(res) is spawn.Response and res.result.result == OK, res.result.error_message
            setter = registry_for(distro).service_class("simulation_interfaces/srv/SetEntityState")
            req = setter.Request(entity=f"arm_{distro}")
            req.state.pose.position.x = 1.0 + i
            if hasattr(req, "set_pose"):
                req.set_pose = True
            res = user.create_client(setter, "/mujoco_sim/set_entity_state").call(req, timeout_sec=5.0)
            assert type(res) is setter.Response and res.result.result == OK, res.result.error_message
            assert np.allclose(world.get_entity_state(f"arm_{distro}").position, [1.0 + i, 0.0, 0.0])
        # a type no variant has: no server, even with the right name
        other = registry_for("humble").service_class("controller_manager_msgs/srv/ListControllers")
        assert not user.create_client(other, "/arm_jazzy/controller_manager/list_controllers").service_is_ready()
        ours = registry_for("jazzy").service_class("controller_manager_msgs/srv/ListControllers")
        assert user.create_client(ours, "/arm_jazzy/controller_manager/list_controllers").service_is_ready()
        # our own client, on the default distribution's types
        client = SimulationClient(user, "/mujoco_sim", timeout_sec=5.0)
        client.set_entity_pose("arm_jazzy", (0.0, 3.0, 0.0))
        assert np.allclose(world.get_entity_state("arm_jazzy").position, [0.0, 3.0, 0.0])
        assert client.spawn_entity("arm2", uri=ARM_URI, namespace="/arm2") == "arm2"
        client.close()
    finally:
        node.destroy_node()
        ctx.try_shutdown()
