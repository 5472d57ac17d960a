"""Hostile requests to the simulation node, sent the way an attacker would: a raw eclipse-zenoh
query with hand-built CDR and the 33-byte attachment, no uniros client code on the peer side.

Each refused request must get the standard result code with a clear message, the node must still
answer a valid call within a second, no file may be written and no process started, and the
entities spawned before must keep a bit-identical state.
"""

from __future__ import annotations

import os
import socket
import struct
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from raw_zenoh import open_peer_session, query_until_answered

from multiros.ros import Context
from multiros.ros.interfaces import dds_type_name, deserialize_message, serialize_message, type_hash
from multiros.sim.distro_adapters import get_service
from multiros.sim.limits import MAX_DESCRIPTION_CHARS, MAX_STEPS_PER_CALL, DescriptionLimits
from multiros.sim.node import SimulationNode
from multiros.sim.packages import PackageIndex
from multiros.sim.world import World, WorldOptions

DATA = Path(__file__).parent / "data"
ARM_URI = ("package://test_arm_description/urdf/arm.urdf.xacro"
           "?__controllers=joint_state_broadcaster,arm_position_controller")
DOMAIN = 23  # a private router on a free port, and not domain 0
OK, FAILED = 1, 4  # simulation_interfaces/msg/Result RESULT_OK, RESULT_OPERATION_FAILED
UNSUPPORTED_FORMAT, RESOURCE_PARSE_ERROR = 103, 106  # SpawnEntity codes
SECRET = "TOPSECRET-7f3a9c"


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def _children_of(pid: int) -> set[int]:
    """PIDs of the direct children of a process (every thread's list)."""
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            out |= {int(p) for p in (task / "children").read_text().split()}
        except OSError:
            continue
    return out


class RawPeer:
    """A foreign rmw_zenoh client: a zenoh session, our CDR serializer, rmw_zenoh's key and attachment."""

    def __init__(self, endpoint: str) -> None:
        self.session = open_peer_session(endpoint)
        self.seq = 0

    def request(self, service: str, **fields):
        return get_service(_TYPES[service]).Request(**fields)

    @staticmethod
    def key(service: str) -> str:
        """The service's key expression, as rmw_zenoh builds it."""
        srv_type = _TYPES[service]
        return f"{DOMAIN}/mujoco_sim/{service}/{dds_type_name(srv_type)}/{type_hash(get_service(srv_type))}"

    def attachment(self) -> bytes:
        """rmw_zenoh's attachment: the next sequence number, the time and the client's GID."""
        self.seq += 1
        return struct.pack("<qqB", self.seq, time.time_ns(), 16) + bytes(range(16))

    def send(self, service: str, request, timeout: float = 5.0):
        """Send one query; return the zenoh replies handler without waiting."""
        return self.session.get(self.key(service), payload=serialize_message(request), attachment=self.attachment(),
                                target=zenoh.QueryTarget.ALL_COMPLETE, consolidation=zenoh.ConsolidationMode.NONE,
                                timeout=timeout)

    def call(self, service: str, request, timeout: float = 5.0):
        replies = list(self.send(service, request, timeout))
        assert len(replies) == 1, f"{service}: {len(replies)} replies within {timeout} s"
        assert replies[0].ok is not None, replies[0].err.payload.to_string()
        return deserialize_message(replies[0].ok.payload.to_bytes(), get_service(_TYPES[service]).Response)

    def wait_for_service(self, timeout: float = 60.0) -> None:
        """Until this session's queries reach the node (a fresh session's routes take a moment, longer
        on a loaded machine: a query sent before they exist gets no reply at all)."""
        payload = serialize_message(self.request("get_entity_state", entity="nobody"))
        if not query_until_answered(self.session, self.key("get_entity_state"), payload=payload, timeout=timeout,
                                    reply_timeout=0.5, attachment=self.attachment):
            raise AssertionError(f"the node's services did not reach this session within {timeout} s")

    def close(self) -> None:
        self.session.close()


_TYPES = {
    "spawn_entity": "simulation_interfaces/srv/SpawnEntity",
    "delete_entity": "simulation_interfaces/srv/DeleteEntity",
    "get_entity_state": "simulation_interfaces/srv/GetEntityState",
    "step_simulation": "simulation_interfaces/srv/StepSimulation",
    "step_robot": "uniros_interfaces/srv/StepRobot",
}


class Rig:
    """A node with one robot (``arm``) on a private router, a raw peer, and the attack's witnesses."""

    def __init__(self, root: Path, **node_kwargs) -> None:
        self.root = root
        self.outside = root / "outside"
        self.trusted = root / "trusted"
        self.outside.mkdir()
        self.trusted.mkdir()
        (self.outside / "secret.urdf").write_text(f"<robot name='x'><link name='{SECRET}'/></robot>")
        (self.outside / "secret.stl").write_text(f"solid {SECRET}\nendsolid\n")
        (self.outside / "secret.xml").write_text(f"<mujoco><worldbody><body name='{SECRET}'/></worldbody></mujoco>")
        (self.outside / "secret.yaml").write_text(f"{SECRET}: 1\n")
        self.endpoint = endpoint = _free_endpoint()
        self.ctx = Context(transport="zenoh", env={}, domain_id=DOMAIN, router_endpoint=endpoint).init()
        index = PackageIndex([DATA], use_entry_points=False, environ={})
        world = World(WorldOptions(), package_index=index, mesh_cache=root / "meshes")
        self.node = SimulationNode("mujoco_sim", world=world, context=self.ctx, spin_topics=False,
                                   trusted_paths=[self.trusted], **node_kwargs)
        self.peer = RawPeer(endpoint)
        self.peer.wait_for_service()
        req = self.peer.request("spawn_entity", name="arm")
        req.entity_resource.uri = ARM_URI
        res = self.peer.call("spawn_entity", req)
        assert res.result.result == OK, res.result.error_message
        self.peer.call("step_robot", self.peer.request("step_robot", entity="arm", steps=50))

    def snapshot(self) -> tuple:
        with self.node.lock:
            d = self.node.world.data
            return (self.node.world.entity_names(), d.time, d.qpos.tobytes(), d.qvel.tobytes(), d.ctrl.tobytes())

    def assert_alive(self) -> None:
        """A valid call over the wire is answered within a second."""
        t0 = time.monotonic()
        res = self.peer.call("get_entity_state", self.peer.request("get_entity_state", entity="arm"), timeout=1.0)
        assert res.result.result == OK and time.monotonic() - t0 < 1.0

    def spawn(self, *, uri: str = "", text: str = "", name: str = "intruder", position=(0.0, 0.0, 0.0)):
        req = self.peer.request("spawn_entity", name=name)
        req.entity_resource.uri = uri
        req.entity_resource.resource_string = text
        p = req.initial_pose.pose.position
        p.x, p.y, p.z = (float(v) for v in position)
        return self.peer.call("spawn_entity", req, timeout=20.0)

    def spawn_after_cool_down(self, **kwargs: Any) -> Any:
        """:meth:`spawn`, again while the node holds this peer back: the world refused its spawns several
        times in a row (the refusal tests do that on purpose), so it waits out a cool-down (node_quota)."""
        deadline = time.monotonic() + 90.0
        res = self.spawn(**kwargs)
        while "spawns in a row refused by the world" in res.result.error_message:
            assert time.monotonic() < deadline, res.result.error_message
            time.sleep(0.05)
            res = self.spawn(**kwargs)
        return res

    def refused(self, code: int, *, uri: str = "", text: str = "", expect: tuple[str, ...] = (),
                position=(0.0, 0.0, 0.0)) -> str:
        """Send a spawn that must be refused with ``code``; check the node and the world; return the message."""
        before, children = self.snapshot(), _children_of(os.getpid())
        res = self.spawn_after_cool_down(uri=uri, text=text, position=position)
        message = res.result.error_message
        assert res.result.result == code, message
        assert message and SECRET not in message
        for part in expect:
            assert part in message, message
        assert self.snapshot() == before
        assert _children_of(os.getpid()) <= children
        self.assert_alive()
        return message

    def close(self) -> None:
        self.peer.close()
        self.node.destroy_node()
        self.ctx.try_shutdown()


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    r = Rig(tmp_path_factory.mktemp("hostile"))
    yield r
    r.close()


def _urdf(**over: str) -> str:
    v = {"xyz": "0 0 0.1", "box": "0.1 0.1 0.1", "mass": "1", "ixx": "0.01", "lower": "-1", "upper": "1",
         "effort": "10", "damping": "0.1", "mesh": ""}
    v.update(over)
    geometry = f'<mesh filename="{v["mesh"]}"/>' if v["mesh"] else f'<box size="{v["box"]}"/>'
    return (f'<robot name="r"><link name="base"/><link name="l1"><inertial><mass value="{v["mass"]}"/>'
            f'<inertia ixx="{v["ixx"]}" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
            f'<visual><geometry>{geometry}</geometry></visual></link>'
            f'<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="{v["xyz"]}"/>'
            f'<axis xyz="0 0 1"/><limit lower="{v["lower"]}" upper="{v["upper"]}" effort="{v["effort"]}" '
            f'velocity="1"/><dynamics damping="{v["damping"]}"/></joint></robot>')


def _mjcf(body: str = '<geom type="sphere" size="0.05"/>', head: str = "", pos: str = "0 0 0") -> str:
    return f'<mujoco model="m">{head}<worldbody><body name="b" pos="{pos}">{body}</body></worldbody></mujoco>'


# -- code execution --------------------------------------------------------------------------
def test_xacro_expressions_in_a_resource_string_are_never_evaluated(rig, tmp_path):
    marker, touched = tmp_path / "written", tmp_path / "touched"
    payload = (f'<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro">'
               f'<xacro:property name="a" value="${{open(\'{marker}\', \'w\').write(\'pwned\')}}"/>'
               f'<link name="${{__import__(\'subprocess\').Popen([\'touch\', \'{touched}\'])}}"/></robot>')
    message = rig.refused(UNSUPPORTED_FORMAT, text=payload, expect=("xacro",))
    assert "allow_xacro_strings" in message
    assert not marker.exists() and not touched.exists()


@pytest.mark.parametrize("value", ["$(find test_arm_description)", "${__import__('os').getpid()}", "a\nb"])
def test_substitutions_in_uri_xacro_arguments_are_refused(rig, value):
    from urllib.parse import quote

    rig.refused(RESOURCE_PARSE_ERROR, uri=f"package://test_arm_description/urdf/arm.urdf.xacro?x={quote(value)}",
                expect=("xacro argument 'x'",))


def test_too_many_or_too_long_xacro_arguments_are_refused(rig):
    base = "package://test_arm_description/urdf/arm.urdf.xacro"
    rig.refused(RESOURCE_PARSE_ERROR, uri=base + "?" + "&".join(f"a{i}=1" for i in range(100)), expect=("at most",))
    rig.refused(RESOURCE_PARSE_ERROR, uri=f"{base}?a={'x' * 5000}", expect=("at most",))


# -- files outside the roots -----------------------------------------------------------------
def test_description_uris_outside_the_roots_are_refused(rig):
    secret = rig.outside / "secret.urdf"
    for uri in (f"file://{secret}", str(secret), os.path.relpath(secret), "/etc/hostname",
                "package://test_arm_description/../../../../../../etc/hostname", "package://../etc/hostname",
                f"{rig.trusted}/../outside/secret.urdf"):
        rig.refused(RESOURCE_PARSE_ERROR, uri=uri, expect=("package",))


def test_a_symlink_in_a_trusted_directory_cannot_point_outside(rig):
    link = rig.trusted / "link.urdf"
    link.symlink_to(rig.outside / "secret.urdf")
    try:
        rig.refused(RESOURCE_PARSE_ERROR, uri=str(link), expect=("outside",))
    finally:
        link.unlink()


def test_a_file_in_a_trusted_directory_is_accepted(rig):
    own = rig.trusted / "own.urdf"
    own.write_text(_urdf())
    res = rig.spawn(uri=f"file://{own}", name="own")
    assert res.result.result == OK, res.result.error_message
    assert rig.peer.call("delete_entity", rig.peer.request("delete_entity", entity="own")).result.result == OK


def test_mesh_files_outside_the_roots_are_refused(rig):
    secret = rig.outside / "secret.stl"
    for mesh in (f"file://{secret}", str(secret), "../../../../../../../../etc/hostname",
                 "package://test_arm_description/../../../../../etc/hostname"):
        rig.refused(RESOURCE_PARSE_ERROR, text=_urdf(mesh=mesh), expect=("mesh",))


def test_mjcf_includes_and_asset_files_outside_the_roots_are_refused(rig):
    secret_xml, secret_stl = rig.outside / "secret.xml", rig.outside / "secret.stl"
    attacks = [
        _mjcf(head=f'<include file="{secret_xml}"/>'),
        _mjcf(head=f'<include file="{os.path.relpath(secret_xml)}"/>'),
        _mjcf('<geom type="mesh" mesh="m"/>', head=f'<asset><mesh name="m" file="{secret_stl}"/></asset>'),
        _mjcf('<geom type="mesh" mesh="m"/>',
              head=f'<compiler meshdir="{rig.outside}"/><asset><mesh name="m" file="secret.stl"/></asset>'),
        _mjcf(head=f'<asset><texture name="t" type="2d" file="{rig.outside}/secret.png"/></asset>'),
        _mjcf(head=f'<asset><hfield name="h" size="1 1 1 1" file="{rig.outside}/secret.png"/></asset>'),
    ]
    for text in attacks:
        rig.refused(RESOURCE_PARSE_ERROR, text=text, expect=("outside",))


def test_mjcf_generators_plugins_and_huge_generated_data_are_refused(rig):
    rig.refused(RESOURCE_PARSE_ERROR, text=_mjcf('<replicate count="100000" offset="0 0 1"><geom size="1"/>'
                                                 '</replicate>'), expect=("replicate",))
    rig.refused(RESOURCE_PARSE_ERROR, text=_mjcf(head='<asset><texture name="t" type="2d" builtin="checker" '
                                                      'width="100000" height="100000"/></asset>'), expect=("pixels",))
    rig.refused(RESOURCE_PARSE_ERROR, text=_mjcf(head='<size memory="500G"/>'), expect=("memory",))


def test_a_controllers_file_outside_the_roots_is_refused(rig):
    uri = f"package://test_arm_description/urdf/arm.urdf.xacro?__controllers_file={rig.outside / 'secret.yaml'}"
    rig.refused(RESOURCE_PARSE_ERROR, uri=uri, expect=("controllers file",))


def test_doctype_entities_are_refused(rig):
    text = '<!DOCTYPE r [<!ENTITY e SYSTEM "file:///etc/hostname">]><robot name="r"><link name="&e;"/></robot>'
    rig.refused(RESOURCE_PARSE_ERROR, text=text, expect=("DOCTYPE",))


# -- numbers ----------------------------------------------------------------------------------
@pytest.mark.parametrize(("override", "expect"), [
    ({"xyz": "nan nan inf"}, ("j1", "origin xyz")),
    ({"box": "1e30 1 1"}, ("l1", "box size")),
    ({"mass": "-1"}, ("l1", "mass")),
    ({"mass": "1e30"}, ("l1", "mass")),
    ({"ixx": "nan"}, ("l1", "inertia")),
    ({"lower": "2", "upper": "1"}, ("j1", "ordered")),
    ({"upper": "inf"}, ("j1", "upper")),
    ({"effort": "1e30"}, ("j1", "effort")),
    ({"damping": "1e300"}, ("j1", "damping")),
    ({"xyz": "1e30 0 0"}, ("j1", "origin xyz")),
])
def test_bad_urdf_numbers_are_refused_naming_the_element(rig, override, expect):
    rig.refused(RESOURCE_PARSE_ERROR, text=_urdf(**override), expect=expect)


@pytest.mark.parametrize(("text", "expect"), [
    (_mjcf(pos="nan 0 0"), ("body 'b'",)),
    (_mjcf('<geom type="box" size="1e30 1 1"/>'), ("geom", "size")),
    (_mjcf('<geom type="sphere" size="0.1" mass="1e30"/>'), ("body 'b'", "mass")),
    (_mjcf('<geom size="0.1"/><joint name="hj" damping="-3"/>'), ("joint 'hj'", "damping")),
])
def test_bad_mjcf_numbers_are_refused_naming_the_element(rig, text, expect):
    rig.refused(RESOURCE_PARSE_ERROR, text=text, expect=expect)


# -- sizes -------------------------------------------------------------------------------------
def _chain(n: int) -> str:
    links = "".join(f'<link name="l{i}"/>' for i in range(n))
    joints = "".join(f'<joint name="j{i}" type="fixed"><parent link="l{i}"/><child link="l{i + 1}"/></joint>'
                     for i in range(n - 1))
    return f'<robot name="chain">{links}{joints}</robot>'


def test_a_2000_link_chain_is_refused_with_the_standard_code(rig):
    rig.refused(RESOURCE_PARSE_ERROR, text=_chain(2000), expect=("too many links",))


def test_a_deep_chain_within_the_link_count_is_refused_by_depth(rig):
    rig.refused(RESOURCE_PARSE_ERROR, text=_chain(500), expect=("deeper than",))


def test_deeply_nested_mjcf_is_refused(rig):
    text = '<mujoco><worldbody>' + '<body><geom size="0.01"/>' * 2000 + '</body>' * 2000 + '</worldbody></mujoco>'
    rig.refused(RESOURCE_PARSE_ERROR, text=text, expect=("nested deeper",))


def test_huge_text_is_refused(rig):
    text = "<robot name='x'>" + " " * MAX_DESCRIPTION_CHARS + "</robot>"
    rig.refused(RESOURCE_PARSE_ERROR, text=text, expect=("longer than",))


def test_a_cycle_of_joints_is_refused(rig):
    text = ('<robot name="c"><link name="r"/><link name="a"/><link name="b"/>'
            '<joint name="ra" type="fixed"><parent link="r"/><child link="a"/></joint>'
            '<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>'
            '<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint></robot>')
    rig.refused(RESOURCE_PARSE_ERROR, text=text, expect=("child of joints",))


# -- step counts ---------------------------------------------------------------------------------
@pytest.mark.parametrize("steps", [2**31 - 1, 10**7, MAX_STEPS_PER_CALL + 1])
def test_step_robot_beyond_the_maximum_is_refused_at_once(rig, steps):
    before = rig.snapshot()
    t0 = time.monotonic()
    res = rig.peer.call("step_robot", rig.peer.request("step_robot", entity="arm", steps=steps), timeout=2.0)
    assert time.monotonic() - t0 < 1.0
    assert res.result.result == FAILED and str(MAX_STEPS_PER_CALL) in res.result.error_message
    assert rig.snapshot() == before
    rig.assert_alive()


@pytest.mark.parametrize("steps", [2**40, 2**64 - 1, 10**7])
def test_step_simulation_beyond_the_maximum_is_refused_at_once(rig, steps):
    before = rig.snapshot()
    t0 = time.monotonic()
    res = rig.peer.call("step_simulation", rig.peer.request("step_simulation", steps=steps), timeout=2.0)
    assert time.monotonic() - t0 < 1.0
    assert res.result.result == FAILED and str(MAX_STEPS_PER_CALL) in res.result.error_message
    assert rig.snapshot() == before
    rig.assert_alive()


def test_an_unexpected_error_in_a_handler_becomes_operation_failed(rig, monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("kaboom")

    monkeypatch.setattr(rig.node.world, "step", boom)
    res = rig.peer.call("step_simulation", rig.peer.request("step_simulation", steps=3), timeout=2.0)
    assert res.result.result == FAILED and "kaboom" in res.result.error_message
    monkeypatch.undo()
    rig.assert_alive()


def test_shutdown_interrupts_a_long_allowed_step(tmp_path):
    rig = Rig(tmp_path, max_steps_per_call=10**8)
    destroyed = False
    try:
        start_time = rig.node.world.time
        pending = rig.peer.send("step_simulation", rig.peer.request("step_simulation", steps=10**8), timeout=30.0)
        drained = threading.Thread(target=lambda: list(pending), daemon=True)
        drained.start()
        deadline = time.monotonic() + 10.0
        while rig.node.world.time == start_time and time.monotonic() < deadline:
            time.sleep(0.005)
        assert rig.node.world.time > start_time, "the step never started"
        t0 = time.monotonic()
        rig.node.destroy_node()
        destroyed = True
        assert time.monotonic() - t0 < 2.0
        with rig.node.lock:  # the step call has returned: it released the lock
            done = round((rig.node.world.time - start_time) / rig.node.world.timestep)
        assert done < 10**8
    finally:
        rig.peer.close()
        if not destroyed:
            rig.node.destroy_node()
        rig.ctx.try_shutdown()


# -- neighbours: entities within every limit that would harm the others --------------------------------
STIFF_HINGE = ('<mujoco><worldbody><body name="b"><joint name="hinge" type="hinge" axis="0 1 0" stiffness="1000" '
               'springref="0.5"/><geom type="capsule" size="0.01 0.05" mass="0.001"/></body></worldbody></mujoco>')
INVALID_POSE = 109  # SpawnEntity


def _box(mass: float, half: float = 0.05) -> str:
    return (f'<mujoco><worldbody><body name="box"><freejoint/><geom type="box" size="{half} {half} {half}" '
            f'mass="{mass}"/></body></worldbody></mujoco>')


def test_an_entity_that_diverges_on_its_own_is_refused_at_spawn(rig):
    """A 1 g capsule on a hinge of stiffness 1000: inside every limit, it diverged on every step and
    made every other robot's steps fail (sim time stuck at 0, calls 16x slower)."""
    rig.refused(RESOURCE_PARSE_ERROR, text=STIFF_HINGE, position=(2.0, 0.0, 0.5),
                expect=("'intruder'", "diverges within", "stiffness"))


def test_an_entity_overlapping_another_is_refused_at_spawn(rig):
    """A 100 kg box spawned through the arm's second link would be thrown out and throw the arm."""
    rig.refused(INVALID_POSE, text=_box(100.0), position=(0.03, 0.0, 0.25),
                expect=("'intruder'", "into entity 'arm'", "mm"))


def test_a_heavy_object_above_a_lighter_entity_is_refused_at_spawn(rig):
    """A 10 t box 0.5 m above the arm would fall onto it."""
    rig.refused(INVALID_POSE, text=_box(1e4), position=(0.05, 0.0, 1.0),
                expect=("'intruder'", "would fall", "onto entity 'arm'", "kg"))


def test_objects_on_the_floor_and_stacked_on_their_peers_are_accepted(rig):
    """What the checks allow: a box resting on the floor beside the arm, a second one of its mass
    dropped onto it, and a light one above the arm (the contact solver copes with those)."""
    spawned = []
    try:
        for name, mass, position in (("crate", 2.0, (0.5, 0.0, 0.05)), ("stacked", 2.0, (0.5, 0.0, 0.3)),
                                     ("light", 0.5, (0.05, 0.0, 1.0))):
            res = rig.spawn_after_cool_down(text=_box(mass), name=name, position=position)
            assert res.result.result == OK, res.result.error_message
            spawned.append(name)
    finally:
        for name in spawned:
            rig.peer.call("delete_entity", rig.peer.request("delete_entity", entity=name))


def test_an_entity_diverging_at_run_time_is_removed_alone_and_its_owner_told(tmp_path):
    """Admitted without the spawn trial (as an entity whose physics only fails later would be):
    the first step removes it; the arm's step succeeds and time advances; later requests naming it
    say why it is gone."""
    rig = Rig(tmp_path, description_limits=DescriptionLimits(trial_steps=0))
    try:
        assert rig.spawn(text=STIFF_HINGE, name="hostile", position=(2.0, 0.0, 0.5)).result.result == OK
        t0 = rig.node.world.time
        for _ in range(20):
            res = rig.peer.call("step_robot", rig.peer.request("step_robot", entity="arm", steps=10))
            assert res.result.result == OK, res.result.error_message
        assert rig.node.world.time == pytest.approx(t0 + 200 * rig.node.world.timestep)
        assert rig.node.world.entity_names() == ("arm",)
        res = rig.peer.call("step_robot", rig.peer.request("step_robot", entity="hostile", steps=1))
        assert res.result.result == 2  # RESULT_NOT_FOUND
        assert "removed from the world" in res.result.error_message and "stiffness" in res.result.error_message
        rig.assert_alive()
    finally:
        rig.close()


def test_a_long_step_call_gives_way_to_other_clients(tmp_path):
    """Three clients send StepSimulation with many steps at once: a fourth client's StepRobot is
    answered while all three are still in progress (it waits its turn, not for their calls)."""
    rig = Rig(tmp_path)
    attackers = [RawPeer(rig.endpoint) for _ in range(3)]
    try:
        for peer in attackers:  # each has its own connection, as separate processes would
            peer.wait_for_service()
        start = rig.node.world.time
        pending = [peer.send("step_simulation", peer.request("step_simulation", steps=MAX_STEPS_PER_CALL),
                             timeout=120.0) for peer in attackers]
        finished = [threading.Event() for _ in attackers]
        threads = [threading.Thread(target=lambda p=p, f=f: (list(p), f.set()), daemon=True)
                   for p, f in zip(pending, finished)]
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + 30.0
        while rig.node.world.time == start and time.monotonic() < deadline:
            time.sleep(0.005)
        for _ in range(5):
            res = rig.peer.call("step_robot", rig.peer.request("step_robot", entity="arm", steps=10), timeout=60.0)
            assert res.result.result == OK, res.result.error_message
        assert not any(f.is_set() for f in finished), "the short calls waited for a whole long call"
        for thread in threads:
            thread.join(timeout=120.0)
        assert all(f.is_set() for f in finished)
    finally:
        for peer in attackers:
            peer.close()
        rig.close()


# -- world level -----------------------------------------------------------------------------------
def test_chunked_steps_are_bit_identical_to_one_call(make_world):
    a, b = make_world(), make_world()
    for w in (a, b):
        w.spawn("arm", "package://test_arm_description/urdf/arm.urdf.xacro")
        w.set_command("arm", "", [0.5, -0.3, 0.2])
    a.step(4321)
    b.step(4321, should_stop=lambda: False)
    assert a.time == b.time
    assert np.array_equal(a.data.qpos, b.data.qpos) and np.array_equal(a.data.qvel, b.data.qvel)


def test_node_refuses_a_bad_max_steps_per_call():
    ctx = Context(transport="inproc").init()
    try:
        with pytest.raises(ValueError, match="max_steps_per_call"):
            SimulationNode("bad", context=ctx, spin_topics=False, max_steps_per_call=0)
    finally:
        ctx.try_shutdown()


def test_xacro_strings_run_only_with_the_opt_in(tmp_path):
    from multiros.sim.description import SourcePolicy, UnsupportedFormatError, load_description

    index = PackageIndex([DATA], use_entry_points=False, environ={})
    text = ('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="n" value="b"/>'
            '<link name="${n}"/></robot>')
    with pytest.raises(UnsupportedFormatError):
        load_description(text, index=index, policy=SourcePolicy())
    desc = load_description(text, index=index, policy=SourcePolicy(allow_xacro_text=True))
    assert desc.links == ("b",)
    assert load_description(text, index=index).links == ("b",)  # a local caller is trusted


def test_robot_resource_expands_xacro_text_client_side():
    from multiros.sim.launch import robot_resource

    text = ('<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="n" value="b"/>'
            '<link name="${n}"/></robot>')
    uri, out = robot_resource(robot_model_xml=text)
    assert uri == "" and "xacro" not in out and 'name="b"' in out
    uri, out = robot_resource(robot_model_xml=text, controllers_list=["a"])
    assert uri == "string:?__controllers=a" and "xacro" not in out


# -- the pose a robot is spawned at ---------------------------------------------------------------
@pytest.mark.parametrize(("query", "expect"), [
    ("joint1=nan", ("joint1", "not finite")),
    ("joint1=inf", ("joint1", "not finite")),
    ("joint1", ("NAME=NUMBER",)),
    ("joint1=abc", ("NAME=NUMBER",)),
    ("bad name!=1", ("NAME=NUMBER",)),
    (",".join(f"j{i}=0" for i in range(300)), ("at most 256",)),
    ("joint1=99", ("joint1", "outside")),
    ("nosuch=0.1", ("nosuch", "does not have")),
])
def test_bad_spawn_joint_positions_are_refused(rig, query, expect):
    from urllib.parse import quote

    rig.refused(INVALID_POSE, uri=f"{ARM_URI}&__joint_positions={quote(query)}", expect=expect)


def test_a_robot_is_spawned_and_reset_at_the_joint_positions_asked_for(rig):
    """``__joint_positions`` (an env's ``initial_joint_positions``): the spawn pose, and what a reset of the
    world puts the robot back at."""
    res = rig.spawn_after_cool_down(uri=f"{ARM_URI}&__joint_positions=joint1%3D0.5,joint2%3D-0.25", name="placed",
                                    position=(3.0, 0.0, 0.0))
    assert res.result.result == 1, res.result.error_message
    world = rig.node.world

    def placed() -> dict[str, float]:
        with rig.node.lock:
            return dict(zip(world.joint_names("placed"), world.joint_state_arrays("placed")[0].tolist()))

    try:
        state = placed()
        assert state["joint1"] == pytest.approx(0.5) and state["joint2"] == pytest.approx(-0.25)
        with rig.node.lock:
            world.set_joint_positions("placed", ["joint1", "joint2"], [0.0, 0.0])
            world.reset_entity("placed")
        assert placed() == pytest.approx(state)
    finally:
        rig.peer.call("delete_entity", rig.peer.request("delete_entity", entity="placed"), timeout=10.0)
