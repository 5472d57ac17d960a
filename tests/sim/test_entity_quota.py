"""Per-client quotas and the node-wide entity limit of the simulation node (multiros.sim.node_quota).

A client (one ``Client`` in the same process, one GID over Zenoh) may hold ``max_entities_per_client``
entities plus 4 per robot it holds; the node holds at most ``max_entities``. A refused spawn never
reaches the world's compiler, one client's refusal leaves the others alone, and deleting an entity
frees its owner's quota. Over Zenoh the peers are raw eclipse-zenoh sessions with hand-made
attachments, each naming its own GID.
"""

from __future__ import annotations

import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from raw_zenoh import open_peer_session, query_until_answered

from multiros.ros import Context, Node
from multiros.ros.interfaces import dds_type_name, deserialize_message, serialize_message, type_hash
from multiros.sim import node_quota, node_spawn
from multiros.sim.client import SimulationClient, SimulationServiceError
from multiros.sim.distro_adapters import get_service
from multiros.sim.limits import ENTITIES_PER_ROBOT, MAX_ENTITIES_PER_CLIENT, MAX_ROBOTS, default_max_entities
from multiros.sim.node import SimulationNode
from multiros.sim.node_quota import BACKOFF_FIRST_S, BACKOFF_MAX_S, REFUSALS_BEFORE_BACKOFF, EntityQuota
from multiros.sim.packages import PackageIndex
from multiros.sim.world import World, WorldOptions

DATA = Path(__file__).parent / "data"
ARM = "package://test_arm_description/urdf/arm.urdf.xacro?__controllers=joint_state_broadcaster"
BOX = """<mujoco><worldbody><body name="box"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/>
</body></worldbody></mujoco>"""
DOMAIN = 29  # a private router on a free port, never domain 0
OK, FAILED = 1, 4  # simulation_interfaces/msg/Result


def _node(ctx: Context, tmp_path: Path, **kwargs) -> SimulationNode:
    index = PackageIndex([DATA], use_entry_points=False, environ={})
    world = World(WorldOptions(), package_index=index, mesh_cache=tmp_path / "meshes")
    return SimulationNode("mujoco_sim", world=world, context=ctx, spin_topics=False, **kwargs)


def _box_at(i: int) -> tuple[float, float, float]:
    return (3.0 + 0.2 * (i % 10), 0.2 * (i // 10), 0.03)  # apart on the floor, away from the arms


def _client(ctx: Context, name: str) -> SimulationClient:
    return SimulationClient(Node(name, context=ctx), "/mujoco_sim", timeout_sec=30.0)


def _spawn_box(client: SimulationClient, name: str, i: int) -> str:
    return client.spawn_entity(name, resource_string=BOX, position=_box_at(i))


def _count_loads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """A list that grows by one at each description the node loads from now on."""
    loaded: list[str] = []
    load = node_spawn.load_description
    monkeypatch.setattr(node_spawn, "load_description", lambda *args, **kw: loaded.append("x") or load(*args, **kw))
    return loaded


def test_defaults_fit_every_robot_with_its_scene() -> None:
    """Every robot the node accepts fits with a table, an object and a camera mount, on one client."""
    assert default_max_entities(MAX_ROBOTS) >= ENTITIES_PER_ROBOT * MAX_ROBOTS
    assert ENTITIES_PER_ROBOT >= 4 and MAX_ENTITIES_PER_CLIENT >= 1


def test_quota_per_in_process_client(tmp_path, monkeypatch) -> None:
    """Two clients of one process: each gets its own quota; a refusal names the limit, the count and
    the fix and is decided before the description is even loaded; a deletion frees the quota; a
    robot raises its holder's quota by ENTITIES_PER_ROBOT."""
    ctx = Context(transport="inproc").init()
    try:
        node = _node(ctx, tmp_path, max_entities_per_client=3)
        a, b = _client(ctx, "a"), _client(ctx, "b")
        for i in range(3):
            _spawn_box(a, f"a{i}", i)
        loaded = _count_loads(monkeypatch)
        with pytest.raises(SimulationServiceError) as refused:
            _spawn_box(a, "a3", 3)
        message = refused.value.message
        assert "holds 3 entities" in message and "max_entities_per_client=3" in message
        assert "DeleteEntity" in message and "uniros-sim --max-entities-per-client" in message
        assert "\n" not in message and loaded == []
        with pytest.raises(SimulationServiceError, match="holds 3 entities"):  # a robot too: delete first
            a.spawn_entity("arm", uri=ARM)
        assert loaded == []
        for i in range(3):  # the other client is not affected
            _spawn_box(b, f"b{i}", 10 + i)
        with pytest.raises(SimulationServiceError, match="holds 3 entities"):
            _spawn_box(b, "b3", 13)
        b.delete_entity("a0")  # whoever deletes it, the owner's quota is freed
        a.spawn_entity("arm", uri=ARM)  # a robot: its owner may hold ENTITIES_PER_ROBOT more
        for i in range(ENTITIES_PER_ROBOT):
            _spawn_box(a, f"scene{i}", 20 + i)
        with pytest.raises(SimulationServiceError, match=f"holds {3 + ENTITIES_PER_ROBOT} entities"):
            _spawn_box(a, "one_too_many", 30)
        assert sorted(node.entity_quota.counts(set(node.world.entity_names())).values()) == [3, 3 + ENTITIES_PER_ROBOT]
        a.reset_simulation(255)  # a reset that removes spawned entities frees their quota too
        assert a.get_entities() == []
        for i in range(3):
            _spawn_box(a, f"again{i}", i)
    finally:
        ctx.try_shutdown()


def test_refusal_streak_backoff_with_a_clock() -> None:
    """Refused by the world REFUSALS_BEFORE_BACKOFF times in a row: a cool-down of BACKOFF_FIRST_S,
    doubling with each further refusal up to BACKOFF_MAX_S; an admitted spawn ends the streak."""
    now = [100.0]
    quota = EntityQuota(10, 5, 4, clock=lambda: now[0])
    for _ in range(REFUSALS_BEFORE_BACKOFF - 1):
        assert quota.note_refused("x", "overlaps 'y'") is None and quota.cooling_down("x") is None
    assert quota.note_refused("x", "overlaps 'y'\nmore") == BACKOFF_FIRST_S
    waiting = quota.cooling_down("x")
    assert waiting is not None and f"had {REFUSALS_BEFORE_BACKOFF} spawns in a row" in waiting
    assert "(the last: overlaps 'y')" in waiting and "again in 1.0 s" in waiting and "\n" not in waiting
    assert quota.cooling_down("z") is None and quota.cooling_down(None) is None  # others unaffected
    now[0] += BACKOFF_FIRST_S
    assert quota.cooling_down("x") is None
    lengths = [quota.note_refused("x", "again") for _ in range(10)]
    assert lengths[:3] == [2 * BACKOFF_FIRST_S, 4 * BACKOFF_FIRST_S, 8 * BACKOFF_FIRST_S]
    assert lengths[-1] == BACKOFF_MAX_S and quota.refusals("x") == REFUSALS_BEFORE_BACKOFF + 10
    quota.note_admitted("x")
    assert quota.cooling_down("x") is None and quota.refusals("x") == 0
    for i in range(5000):  # forged identities: the memory of streaks stays bounded
        quota.note_refused(f"forged{i}", "r")
    assert quota.refusals("forged0") == 0 and quota.refusals("forged4999") == 1


def test_spawns_the_world_keeps_refusing_wait_before_loading(tmp_path, monkeypatch) -> None:
    """Boxes spawned into another entity (refused at admission, after a compile and a trial):
    after REFUSALS_BEFORE_BACKOFF of them the client's next spawn is refused before it is loaded, with
    one warning in the node's log; another client spawns on; after the cool-down the client may
    spawn again."""
    monkeypatch.setattr(node_quota, "BACKOFF_FIRST_S", 0.3)
    ctx = Context(transport="inproc").init()
    try:
        node = _node(ctx, tmp_path)
        warnings: list[str] = []
        logger = node.get_logger()
        monkeypatch.setattr(logger, "warning", lambda fmt, *args: warnings.append(fmt % args))
        a, b = _client(ctx, "a"), _client(ctx, "b")
        _spawn_box(b, "target", 0)
        for i in range(REFUSALS_BEFORE_BACKOFF):
            with pytest.raises(SimulationServiceError, match="reaches .* into entity .target."):
                _spawn_box(a, f"into{i}", 0)
        assert len(warnings) == 1 and warnings[0].startswith("client '"), warnings
        assert f"{REFUSALS_BEFORE_BACKOFF} spawns refused by the world in a row" in warnings[0]
        loaded = _count_loads(monkeypatch)
        with pytest.raises(SimulationServiceError, match="spawns in a row refused by the world") as refused:
            _spawn_box(a, "elsewhere", 5)
        assert loaded == [] and "\n" not in refused.value.message
        _spawn_box(b, "b_elsewhere", 6)  # the other client is not held back
        deadline = time.monotonic() + 30.0
        while True:
            try:
                _spawn_box(a, "elsewhere", 5)
                break
            except SimulationServiceError as exc:
                assert "refused by the world" in exc.message and time.monotonic() < deadline, exc.message
                time.sleep(0.05)
        caller = node.entity_quota.owner("elsewhere")
        assert caller is not None and caller != node.entity_quota.owner("target")
        assert node.entity_quota.refusals(caller) == 0 and len(warnings) == 1  # admitted: the streak ended
    finally:
        ctx.try_shutdown()


def test_node_wide_limits_refuse_before_loading(tmp_path, monkeypatch) -> None:
    """``max_entities`` (every client together) and ``max_robots`` refuse before the description is
    loaded; parameters and properties show the limits."""
    ctx = Context(transport="inproc").init()
    try:
        node = _node(ctx, tmp_path, max_entities=3, max_entities_per_client=2, max_robots=1)
        assert node.get_parameter("max_entities").value == 3 == node.max_entities
        assert node.get_parameter("max_entities_per_client").value == 2 == node.max_entities_per_client
        a, b = _client(ctx, "a"), _client(ctx, "b")
        a.spawn_entity("arm", uri=ARM)
        _spawn_box(a, "a0", 0)
        _spawn_box(b, "b0", 1)
        loaded = _count_loads(monkeypatch)
        with pytest.raises(SimulationServiceError) as refused:
            _spawn_box(b, "b1", 2)
        message = refused.value.message
        assert "holds 3 entities, max_entities=3" in message and "uniros-sim --max-entities N" in message
        assert loaded == [] and "\n" not in message
        b.delete_entity("b0")
        with pytest.raises(SimulationServiceError, match="max_robots=1"):
            b.spawn_entity("arm2", uri=ARM, position=(1.0, 0.0, 0.0))
        assert a.get_entities() == ["arm", "a0"]
        with pytest.raises(ValueError, match="max_entities must be"):
            SimulationNode("bad", context=ctx, spin_topics=False, max_entities=0)
        with pytest.raises(ValueError, match="max_entities_per_client must be"):
            SimulationNode("bad2", context=ctx, spin_topics=False, max_entities_per_client=0)
    finally:
        ctx.try_shutdown()


def test_default_max_entities_follows_max_robots(tmp_path) -> None:
    ctx = Context(transport="inproc").init()
    try:
        node = _node(ctx, tmp_path, max_robots=8)
        assert node.max_entities == default_max_entities(8) == ENTITIES_PER_ROBOT * 8 + 64
        assert node.max_entities_per_client == MAX_ENTITIES_PER_CLIENT
    finally:
        ctx.try_shutdown()


def test_a_batch_of_pick_and_place_robots_fits_on_one_client(tmp_path) -> None:
    """One client (a vector env's) spawns max_robots robots, each with a table, a cube and a camera
    mount: none is refused at the default quotas."""
    ctx = Context(transport="inproc").init()
    try:
        node = _node(ctx, tmp_path, max_robots=3, max_entities_per_client=1)
        client = _client(ctx, "vec")
        for r in range(3):
            client.spawn_entity(f"arm{r}", uri=ARM, position=(4.0 * r, 0.0, 0.0))
            for k in range(ENTITIES_PER_ROBOT - 1):
                client.spawn_entity(f"obj{r}_{k}", resource_string=BOX, position=(4.0 * r + 1.0, 0.3 * k, 0.03))
        assert len(node.world.entity_names()) == 3 * ENTITIES_PER_ROBOT <= node.max_entities
    finally:
        ctx.try_shutdown()


# -- over Zenoh: raw peers, each its own GID ------------------------------------------------------
def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


_TYPES = {"spawn_entity": "simulation_interfaces/srv/SpawnEntity",
          "delete_entity": "simulation_interfaces/srv/DeleteEntity",
          "get_entities": "simulation_interfaces/srv/GetEntities"}


class _Peer:
    """A foreign rmw_zenoh client naming itself with ``gid`` in every request's attachment."""

    def __init__(self, endpoint: str, gid: bytes) -> None:
        self.session = open_peer_session(endpoint)
        self.gid = gid
        self.seq = 0

    def call(self, service: str, timeout: float = 20.0, **fields):
        srv = get_service(_TYPES[service])
        key = f"{DOMAIN}/mujoco_sim/{service}/{dds_type_name(_TYPES[service])}/{type_hash(srv)}"
        # the first calls may come before the node's services reached this session
        replies = query_until_answered(self.session, key, payload=serialize_message(srv.Request(**fields)),
                                       attachment=self._attachment, timeout=timeout, reply_timeout=min(timeout, 2.0))
        assert replies and replies[0].ok is not None, f"{service}: no answer within {timeout} s"
        return deserialize_message(replies[0].ok.payload.to_bytes(), srv.Response)

    def _attachment(self) -> bytes:
        self.seq += 1
        return struct.pack("<qqB", self.seq, time.time_ns(), 16) + self.gid

    def spawn_box(self, name: str, i: int):
        req = get_service(_TYPES["spawn_entity"]).Request(name=name)
        req.entity_resource.resource_string = BOX
        p = req.initial_pose.pose.position
        p.x, p.y, p.z = _box_at(i)
        return self.call("spawn_entity", entity_resource=req.entity_resource, initial_pose=req.initial_pose,
                         name=name)

    def close(self) -> None:
        self.session.close()


def test_quota_per_zenoh_client(tmp_path) -> None:
    """Two wire clients (two GIDs): one's refusal does not affect the other; deleting frees quota;
    the node-wide cap holds whatever GID a peer claims."""
    endpoint = _free_endpoint()
    ctx = Context(transport="zenoh", env={}, domain_id=DOMAIN, router_endpoint=endpoint).init()
    peers: list[_Peer] = []
    try:
        node = _node(ctx, tmp_path, max_entities_per_client=2, max_entities=5)
        a, b = _Peer(endpoint, bytes(range(16))), _Peer(endpoint, bytes(range(16, 32)))
        peers += [a, b]
        assert [a.spawn_box(f"a{i}", i).result.result for i in range(2)] == [OK, OK]
        res = a.spawn_box("a2", 2)
        assert res.result.result == FAILED
        assert f"client 'zenoh:{bytes(range(16)).hex()}' holds 2 entities" in res.result.error_message
        assert [b.spawn_box(f"b{i}", 10 + i).result.result for i in range(2)] == [OK, OK]
        assert b.spawn_box("b2", 12).result.result == FAILED
        assert a.call("delete_entity", entity="a0").result.result == OK
        assert a.spawn_box("a2", 2).result.result == OK
        owner = node.entity_quota.owner
        assert owner("a2") == "zenoh:" + bytes(range(16)).hex() and owner("b1") == "zenoh:" + bytes(range(16, 32)).hex()
        forger = _Peer(endpoint, bytes(range(32, 48)))  # a new identity escapes its quota, not the node's
        peers.append(forger)
        assert forger.spawn_box("f0", 20).result.result == OK
        res = forger.spawn_box("f1", 21)
        assert res.result.result == FAILED and "max_entities=5" in res.result.error_message
        assert sorted(b.call("get_entities").entities) == ["a1", "a2", "b0", "b1", "f0"]
    finally:
        for p in peers:
            p.close()
        ctx.try_shutdown()


@pytest.mark.parametrize(("option", "value"), [("--max-entities", "0"), ("--max-entities-per-client", "0")])
def test_uniros_sim_refuses_bad_entity_limits(option: str, value: str) -> None:
    """``uniros-sim --max-entities N --max-entities-per-client N``: bad values are a usage error."""
    run = subprocess.run([sys.executable, "-m", "multiros.sim.program", "--transport", "inproc", option, value],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and f"{option} must be" in run.stderr


def test_uniros_sim_gui_without_a_display_is_a_usage_error() -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    run = subprocess.run([sys.executable, "-m", "multiros.sim.program", "--transport", "inproc", "--gui"],
                         capture_output=True, text=True, timeout=120, env=env)
    assert run.returncode == 2 and "needs a display" in run.stderr and "drop --gui" in run.stderr
    assert "Traceback" not in run.stderr


def test_uniros_sim_on_inproc_warns_that_no_other_process_reaches_it(tmp_path) -> None:
    """``uniros-sim --transport inproc`` starts, says nobody else can reach it, and exits with its owner."""
    log = tmp_path / "node.log"
    owner = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    with open(log, "w") as err:
        node = subprocess.Popen([sys.executable, "-m", "multiros.sim.program", "--transport", "inproc",
                                 "--owner-pid", str(owner.pid)], stderr=err)
    try:
        deadline = time.monotonic() + 60
        while "ready" not in log.read_text() and node.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # polled with a deadline: the node's log line is the event
        assert "ready" in log.read_text(), log.read_text()
        owner.stdin.close()  # type: ignore[union-attr]
        owner.wait(timeout=30)  # reaped: a zombie would still count as alive
        assert node.wait(timeout=60) == 0
        assert "transport inproc: no other process can reach this node" in log.read_text()
    finally:
        for proc in (node, owner):
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=30)
