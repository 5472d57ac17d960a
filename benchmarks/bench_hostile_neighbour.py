"""What a hostile (or careless) neighbour can do to a victim robot on one simulation node, measured.

Each attack runs against a victim RX200 holding its initial pose and prints what the victim sees:

* ``stiff``: an MJCF hinge with stiffness=1000, springref=0.5 on a 1 g capsule, 2 m away (inside
  every description limit): is it refused at spawn, and do the victim's steps still succeed, advance
  time, and cost what they cost before?
* ``stiff_late``: the same hinge on a node whose spawn trial is off (``trial_steps=0``), standing in
  for an entity whose physics fails only later: what the victim's steps see then.
* ``overlap``: a 100 kg box spawned through the victim's forearm: refused, or how far is the arm thrown?
* ``drop``: a 100 t box spawned 1 m above the victim: refused, or how far is the arm thrown?
* ``flood``: 4 attackers, each its own Zenoh session, sending ``StepSimulation`` with the node's
  maximum step count back to back while the victim calls ``StepRobot`` (10 steps): the victim's
  latency (median, 95th percentile) against the same calls alone.
* ``boxes``: a neighbour (a raw Zenoh peer with a GID of its own) tries to spawn 200 small boxes
  (``--boxes N``) beside a victim RX200 whose client is another Zenoh session, while the victim calls
  ``StepRobot`` (10 steps): how many boxes the node admits (its per-client quota), and the victim's
  median / p95 latency alone, while the neighbour spawns, and after, with the ratios to alone.
  ``--unlimited-too`` runs it again on a node without quotas (the behaviour before them).
* ``refused``: the same neighbour spawns a 100 kg box through the victim's forearm in a loop for
  ``--seconds`` (each one compiled and tried beside the node's lock, then refused at admission): how
  many spawns the world refused, how many the node's cool-down refused before loading them
  (``multiros.sim.node_quota``), and the victim's latency alone and meanwhile. ``--unlimited-too``
  runs it again with the cool-down off.
* ``cameras``: a neighbour (its own Zenoh session) spawns a rig of 8 camera sensors of 1920 x 1080 (the
  node's pixel limit, ``MAX_CAMERA_PIXELS``) above the victim and subscribes to every image topic: the
  victim's ``StepRobot(10)`` latency alone and while the images are rendered and sent, and how many
  images a second the neighbour gets (the node renders on a thread of its own, at a capped rate, holding
  its lock only to copy each camera's scene). Needs a GL backend (``MUJOCO_GL=egl``).
* ``intruder``: an owner's ``sim_mode="process"`` node; another local process finds the private
  router's port (and every port the owner and its child listen on, as ``ss -ltnp`` shows them)
  and, as a raw Zenoh peer without the owner's secret, sends ``GetEntities`` and
  ``DeleteEntity(rx200)``: answered or refused?
* ``params`` / ``params_rclpy``: the node a ``uniros-sim`` process (over Zenoh; over rclpy, which needs
  the venv ``.ci/rclpy`` makes: ``.venv-rclpy/bin/python``), a neighbour (a process of its own, four
  callers and 50 more) floods its parameter services for 8 s: SetParameters of 10,000, 1,000 and 256
  undeclared names, Get/Describe/GetParameterTypes of 100,000 names, ListParameters with 100,000
  prefixes, ``use_sim_time`` set to a 1,000,000-integer array, and 50 SetParameters of 1,000 names at
  once, while the victim calls ``StepRobot(10)`` and ``list_controllers`` in turn: their median / p95 /
  max alone, during and after the flood, each kind of request's slowest answer (the goal: answered or
  refused within 1 s), and the node's RSS before, at its peak and after. Over Zenoh the node serves no
  parameters (``Transport.serves_parameters``): the requests find no service.

    python benchmarks/bench_hostile_neighbour.py [--attacks stiff overlap drop flood boxes cameras intruder params]
                                                 [--boxes 200] [--seconds 10] [--unlimited-too]
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import zenoh

from multiros.ros import Context, Node
from multiros.ros.interfaces import dds_type_name, deserialize_message, serialize_message, type_hash
from multiros.sim.client import SimulationClient, SimulationServiceError
from multiros.sim.distro_adapters import get_service
from multiros.sim.launch import compose, connect, free_loopback_endpoint
from multiros.sim.limits import DescriptionLimits

RX200 = ("package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
         "&__controllers=joint_state_broadcaster,arm_position_controller")
ARM = "arm_position_controller"
HOLD = [0.0, 0.0, 0.0, 0.0, 0.0]
STIFF = """<mujoco><worldbody><body name="b"><joint name="hinge" type="hinge" axis="0 1 0" stiffness="1000"
 springref="0.5"/><geom type="capsule" size="0.01 0.05" mass="0.001"/></body></worldbody></mujoco>"""
BOX = """<mujoco><worldbody><body name="box"><freejoint/><geom type="box" size="{h} {h} {h}" mass="{m}"/>
</body></worldbody></mujoco>"""
DOMAIN = 57


def _victim(ctx: Context, client_ctx: Context | None = None, timeout: float = 60.0,
            **node_kwargs: object) -> tuple[Any, SimulationClient]:
    """A node composed on ``ctx`` and the victim's client (on ``client_ctx``, a session of its own, or
    ``ctx``), its RX200 spawned and settled at its initial pose."""
    sim = compose("mujoco_sim", context=ctx, spin_topics=False, **node_kwargs)
    client = SimulationClient(Node("victim", context=client_ctx or ctx), "/mujoco_sim", timeout_sec=timeout)
    client.wait_until_ready(20.0)
    client.spawn_entity("rx200", uri=RX200)
    client.step_robot("rx200", {ARM: HOLD}, 200)
    return sim, client


def _victim_latencies(client: SimulationClient, until: Callable[[], bool]) -> np.ndarray:
    """Seconds per victim ``StepRobot(10)`` call (the arm held), called back to back until ``until()``."""
    lat = []
    while not until():
        t = time.perf_counter()
        client.step_robot("rx200", {ARM: HOLD}, 10)
        lat.append(time.perf_counter() - t)
    return np.array(lat)


def _for_seconds(duration: float) -> Callable[[], bool]:
    """``until`` for :func:`_victim_latencies`: true ``duration`` seconds from now."""
    end = time.monotonic() + duration
    return lambda: time.monotonic() >= end


def _session(endpoint: str) -> Context:
    """Another Zenoh session (a client process of its own) on the private router at ``endpoint``."""
    return Context(transport="zenoh", env={}, domain_id=DOMAIN, router="none", router_endpoint=endpoint).init()


def _spawn(client: SimulationClient, name: str, text: str, position: tuple[float, float, float]) -> str:
    try:
        client.spawn_entity(name, resource_string=text, position=position)
        return "spawned"
    except SimulationServiceError as exc:
        return f"REFUSED ({exc.message[:160]})"


def attack_stiff(late: bool = False) -> None:
    ctx = Context(transport="inproc").init()
    try:
        _, client = _victim(ctx, **({"description_limits": DescriptionLimits(trial_steps=0)} if late else {}))
        t0 = time.perf_counter()
        for _ in range(50):
            client.step_robot("rx200", {ARM: HOLD}, 10)
        alone = (time.perf_counter() - t0) / 50
        outcome = _spawn(client, "hostile", STIFF, (2.0, 0.0, 0.5))
        failed, start_time = 0, None
        t0 = time.perf_counter()
        for i in range(50):
            if i == 25:
                client.reset_simulation(3)  # TIME | STATE: what an env's reset does
            try:
                state = client.step_robot("rx200", {ARM: HOLD}, 10)
                start_time = state.sim_time if start_time is None else start_time
            except SimulationServiceError:
                failed += 1
        per_call = (time.perf_counter() - t0) / 50
        sim_time = client.step_robot("rx200", {ARM: HOLD}, 0).sim_time
        entities = client.get_entities()
        what = "stiff hinge (no spawn trial)" if late else "stiff hinge"
        print(f"{what}: spawn {outcome}; victim steps failed {failed}/50 (one reset after 25); "
              f"sim time after {sim_time:.3f} s; {per_call * 1e3:.2f} ms per call vs {alone * 1e3:.2f} ms alone "
              f"({per_call / alone:.1f}x); entities {entities}")
    finally:
        ctx.try_shutdown()


def _thrown(name: str, text: str, position: tuple[float, float, float]) -> None:
    ctx = Context(transport="inproc").init()
    try:
        _, client = _victim(ctx)
        before = np.array(client.step_robot("rx200", {ARM: HOLD}, 0).position[:5])
        outcome = _spawn(client, name, text, position)
        worst = 0.0
        for _ in range(100):  # 0.2 s held at the initial pose
            state = client.step_robot("rx200", {ARM: HOLD}, 10)
            worst = max(worst, float(np.max(np.abs(np.array(state.position[:5]) - before))))
        print(f"{name}: spawn {outcome}; victim arm thrown up to {worst:.3f} rad from its held pose in 2 s")
    finally:
        ctx.try_shutdown()


def attack_overlap() -> None:
    _thrown("overlap_box", BOX.format(h=0.05, m=100.0), (0.2, 0.0, 0.3))


def attack_drop() -> None:
    _thrown("heavy_box", BOX.format(h=0.1, m=1e5), (0.2, 0.0, 1.3))


class _RawPeer:
    """A foreign rmw_zenoh client: a plain zenoh session, hand-made keys and attachments."""

    def __init__(self, endpoint: str, domain: int, user: str | None = None, password: str | None = None) -> None:
        config = zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("connect/endpoints", json.dumps([endpoint]))
        config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
        config.insert_json5("scouting/multicast/enabled", "false")
        if user is not None:
            config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
            config.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
        self.session = zenoh.open(config)
        self.domain = domain
        self.seq = 0
        self._payloads: dict[int, bytes] = {}

    def call(self, node: str, service: str, type_name: str, timeout: float = 5.0, **fields: object) -> object:
        srv = get_service(type_name)
        key = f"{self.domain}/{node}/{service}/{dds_type_name(type_name)}/{type_hash(srv)}"
        self.seq += 1
        attachment = struct.pack("<qqB", self.seq, time.time_ns(), 16) + bytes(range(16))
        replies = list(self.session.get(key, payload=serialize_message(srv.Request(**fields)), attachment=attachment,
                                        target=zenoh.QueryTarget.ALL_COMPLETE, timeout=timeout))
        if not replies or replies[0].ok is None:
            return None
        return deserialize_message(replies[0].ok.payload.to_bytes(), srv.Response)

    def call_request(self, node: str, service: str, type_name: str, request: Any, timeout: float = 5.0) -> bool:
        """Send ``request`` (serialized once per request object) and wait: whether a reply came."""
        payload = self._payloads.get(id(request))
        if payload is None:
            payload = self._payloads[id(request)] = serialize_message(request)
        key = f"{self.domain}/{node}/{service}/{dds_type_name(type_name)}/{type_hash(get_service(type_name))}"
        self.seq += 1
        attachment = struct.pack("<qqB", self.seq, time.time_ns(), 16) + bytes(range(16))
        replies = list(self.session.get(key, payload=payload, attachment=attachment,
                                        target=zenoh.QueryTarget.ALL_COMPLETE, timeout=timeout))
        return bool(replies) and replies[0].ok is not None

    def close(self) -> None:
        self.session.close()


def attack_flood(attackers: int = 4, seconds: float = 4.0) -> None:
    endpoint = free_loopback_endpoint()
    ctx = Context(transport="zenoh", env={}, domain_id=DOMAIN, router="embedded", router_endpoint=endpoint).init()
    peers: list[_RawPeer] = []
    stop = threading.Event()
    try:
        sim = compose("mujoco_sim", context=ctx, spin_topics=False)
        victim_ctx = _session(endpoint)
        client = SimulationClient(Node("victim", context=victim_ctx), "/mujoco_sim", timeout_sec=120.0)
        client.wait_until_ready(20.0)
        client.spawn_entity("rx200", uri=RX200)

        alone = _victim_latencies(client, _for_seconds(1.0))
        peers = [_RawPeer(endpoint, DOMAIN) for _ in range(attackers)]
        answered = [0] * attackers

        def attack(i: int) -> None:
            while not stop.is_set():
                if peers[i].call("mujoco_sim", "step_simulation", "simulation_interfaces/srv/StepSimulation",
                                 timeout=60.0, steps=sim.max_steps_per_call) is not None:
                    answered[i] += 1

        threads = [threading.Thread(target=attack, args=(i,), daemon=True) for i in range(attackers)]
        for t in threads:
            t.start()
        time.sleep(0.5)  # the attackers' first calls are in
        busy = _victim_latencies(client, _for_seconds(seconds))
        stop.set()
        for t in threads:
            t.join(timeout=120)
        print(f"flood: {attackers} attackers x StepSimulation({sim.max_steps_per_call}); victim StepRobot(10) "
              f"median {np.median(busy) * 1e3:.2f} ms, p95 {np.percentile(busy, 95) * 1e3:.2f} ms, "
              f"{len(busy)} calls in {seconds:g} s (alone: median {np.median(alone) * 1e3:.2f} ms); attackers' "
              f"calls answered {sum(answered)}")
        client.close()
        victim_ctx.try_shutdown()
    finally:
        stop.set()
        for p in peers:
            p.close()
        ctx.try_shutdown()


SMALL_BOX = BOX.format(h=0.02, m=0.05)
HEAVY_BOX = BOX.format(h=0.05, m=100.0)


def attack_boxes(boxes: int = 200, unlimited: bool = False, seconds: float = 2.0,
                 refused_for: float | None = None) -> None:
    """``boxes``, or with ``refused_for`` the ``refused`` attack for that many seconds."""
    from multiros.sim import node_quota

    threshold = node_quota.REFUSALS_BEFORE_BACKOFF
    if refused_for is not None and unlimited:
        node_quota.REFUSALS_BEFORE_BACKOFF = 10**9  # the behaviour before the cool-down, for this run only
    try:
        _attack_boxes(boxes, unlimited, seconds, refused_for)
    finally:
        node_quota.REFUSALS_BEFORE_BACKOFF = threshold


def _attack_boxes(boxes: int, unlimited: bool, seconds: float, refused_for: float | None) -> None:
    endpoint = free_loopback_endpoint()
    ctx = Context(transport="zenoh", env={}, domain_id=DOMAIN, router="embedded", router_endpoint=endpoint).init()
    peer: _RawPeer | None = None
    victim_ctx = None
    try:
        limits = {"max_entities": 10**6, "max_entities_per_client": 10**6} if unlimited else {}
        victim_ctx = _session(endpoint)
        sim, client = _victim(ctx, victim_ctx, timeout=120.0, **limits)

        alone = _victim_latencies(client, _for_seconds(seconds))
        peer = neighbour_peer = _RawPeer(endpoint, DOMAIN)
        deadline = time.monotonic() + 20.0  # the neighbour's session reaches the node's services first
        while peer.call("mujoco_sim", "get_entities", "simulation_interfaces/srv/GetEntities", timeout=0.5) is None:
            if time.monotonic() > deadline:
                raise RuntimeError("the neighbour's session did not reach the node within 20 s")
        outcomes: list[int] = []
        refusals: list[str] = []
        cooled: list[bool] = []  # per refusal: by the node's cool-down (True) or by the world
        done = threading.Event()
        spawn = get_service("simulation_interfaces/srv/SpawnEntity")

        def neighbour() -> None:
            end = time.monotonic() + (refused_for or 0.0)
            try:
                for i in range(boxes if refused_for is None else 10**9):
                    if refused_for is not None and time.monotonic() >= end:
                        break
                    req = spawn.Request(name=f"box{i}")
                    req.entity_resource.resource_string = SMALL_BOX if refused_for is None else HEAVY_BOX
                    p = req.initial_pose.pose.position
                    p.x, p.y, p.z = ((1.0 + 0.1 * (i % 20), -1.0 + 0.1 * (i // 20), 0.02) if refused_for is None
                                     else (0.03, 0.0, 0.25))
                    res: Any = neighbour_peer.call(
                        "mujoco_sim", "spawn_entity", "simulation_interfaces/srv/SpawnEntity", timeout=60.0,
                        name=req.name, entity_resource=req.entity_resource, initial_pose=req.initial_pose)
                    code = -1 if res is None else int(res.result.result)
                    outcomes.append(code)
                    if code != 1:
                        message = "no answer" if res is None else res.result.error_message
                        cooled.append("refused by the world" in message)
                        if not refusals or (cooled[-1] and len(refusals) == 1):
                            refusals.append(message)
            finally:
                done.set()

        thread = threading.Thread(target=neighbour, daemon=True)
        t0 = time.monotonic()
        thread.start()
        during = _victim_latencies(client, done.is_set)
        spawn_sec = time.monotonic() - t0
        thread.join(timeout=600)
        after = _victim_latencies(client, _for_seconds(seconds))
        admitted = outcomes.count(1)
        base = float(np.median(alone))

        def figures(lat: np.ndarray) -> str:
            if not len(lat):
                return "no calls"
            med, p95 = float(np.median(lat)), float(np.percentile(lat, 95))
            return f"median {med * 1e3:.2f} ms ({med / base:.1f}x), p95 {p95 * 1e3:.2f} ms, {len(lat)} calls"

        if refused_for is not None:
            print(f"refused ({'no cool-down' if unlimited else 'cool-down on'}): the neighbour sent {len(outcomes)} "
                  f"spawns into the arm in {spawn_sec:.1f} s: {cooled.count(False)} refused by the world (a compile "
                  f"and trial each, beside the node's lock), {cooled.count(True)} by the cool-down before loading; "
                  f"victim "
                  f"StepRobot(10) alone: median {base * 1e3:.2f} ms, p95 {np.percentile(alone, 95) * 1e3:.2f} ms; "
                  f"meanwhile: {figures(during)}")
            for message in refusals:
                print(f"  a refusal: {message}")
            client.close()
            return
        what = "no quotas" if unlimited else (f"max_entities_per_client={sim.max_entities_per_client}, "
                                              f"max_entities={sim.max_entities}")
        print(f"boxes ({what}): neighbour asked for {boxes} boxes in {spawn_sec:.1f} s, {admitted} admitted, "
              f"{len(outcomes) - admitted} refused; victim StepRobot(10) alone: median {base * 1e3:.2f} ms, "
              f"p95 {np.percentile(alone, 95) * 1e3:.2f} ms; while spawning: {figures(during)}; "
              f"after, beside the admitted boxes: {figures(after)}")
        if refusals:
            print(f"  the neighbour's first refusal: {refusals[0]}")
        client.close()
    finally:
        if peer is not None:
            peer.close()
        if victim_ctx is not None:
            victim_ctx.try_shutdown()
        ctx.try_shutdown()


def _listening_ports(pid: int) -> set[int]:
    """Loopback TCP ports a process listens on, as ``ss -ltnp`` shows them to anyone on the machine."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[len("socket:["):-1])
    with open("/proc/net/tcp") as f:
        rows = [line.split() for line in f.readlines()[1:]]
    return {int(r[1].split(":")[1], 16) for r in rows if r[3] == "0A" and r[9] in inodes}


def attack_intruder() -> None:
    conn = connect("process", timeout_sec=60.0)
    try:
        conn.client.spawn_entity("rx200", uri=RX200)
        domain = conn.context.domain_id
        assert conn.pid is not None
        ports = sorted(_listening_ports(conn.pid) | _listening_ports(os.getpid()))
        outcomes = []
        for port in ports:
            intruder = None
            try:
                intruder = _RawPeer(f"tcp/127.0.0.1:{port}", domain)
                listed, deadline = None, time.monotonic() + 3.0
                while listed is None and time.monotonic() < deadline:  # the node's services reach it in ms, if ever
                    listed = intruder.call("mujoco_sim", "get_entities", "simulation_interfaces/srv/GetEntities",
                                           timeout=0.5)
                deleted = intruder.call("mujoco_sim", "delete_entity", "simulation_interfaces/srv/DeleteEntity",
                                        timeout=2.0, entity="rx200")
                seen = "no answer" if listed is None else f"answered {list(listed.entities)}"
                done = "no answer" if deleted is None else f"result {deleted.result.result}"
            except Exception as exc:  # noqa: BLE001 - a refused session is the defence
                seen = done = f"session refused ({type(exc).__name__})"
            finally:
                if intruder is not None:
                    intruder.close()
            outcomes.append(f"port {port}: GetEntities {seen}, DeleteEntity(rx200) {done}")
        owner = conn.client.get_entities()
        print(f"intruder without the secret at the {len(ports)} listening ports of the owner and its child: "
              f"{'; '.join(outcomes)}; the owner sees {owner}")
    finally:
        conn.close()


def _camera_rig(sensors: int, width: int, height: int) -> str:
    """A fixed mount with ``sensors`` camera sensors of ``width`` x ``height``, looking down at the floor."""
    cams = "".join(
        f'<sensor type="camera" name="cam{i}"><pose>0 0 0 0 1.5708 0</pose><camera><horizontal_fov>1.2'
        f"</horizontal_fov><image><width>{width}</width><height>{height}</height></image></camera></sensor>"
        for i in range(sensors))
    return ('<robot name="rig"><link name="world"/><link name="mount"/><joint name="fix" type="fixed">'
            '<parent link="world"/><child link="mount"/><origin xyz="0 0 1.5"/></joint>'
            f'<gazebo reference="mount">{cams}</gazebo></robot>')


def attack_cameras(sensors: int = 8, width: int = 1920, height: int = 1080, seconds: float = 4.0) -> None:
    """A neighbour (its own Zenoh session) spawns a rig of ``sensors`` 1080p cameras above the victim
    and subscribes to every image topic: the victim's StepRobot(10) alone and while they are served."""
    from multiros.ros.executors import SingleThreadedExecutor
    from multiros.ros.interfaces import get_message

    endpoint = free_loopback_endpoint()
    ctx = Context(transport="zenoh", env={}, domain_id=DOMAIN, router="embedded", router_endpoint=endpoint).init()
    others: list[Context] = []
    try:
        others += [_session(endpoint), _session(endpoint)]
        victim_ctx, neighbour_ctx = others
        sim, client = _victim(ctx, victim_ctx, timeout=120.0)
        alone = _victim_latencies(client, _for_seconds(seconds))
        neighbour = Node("neighbour", context=neighbour_ctx)
        SimulationClient(neighbour, "/mujoco_sim", timeout_sec=120.0).spawn_entity(
            "rig", resource_string=_camera_rig(sensors, width, height), position=(0.0, 0.0, 0.0))
        published = {spec.camera for spec in sim.cameras.specs()}  # within the node's pixel limit
        served = [i for i in range(sensors) if f"rig/cam{i}" in published]
        image = get_message("sensor_msgs/msg/Image")
        frames = [0] * sensors

        def count(i: int) -> Callable[[Any], None]:
            def received(_msg: Any) -> None:
                frames[i] += 1
            return received

        subs = [neighbour.create_subscription(image, f"/rig/cam{i}/image_raw", count(i), 1) for i in range(sensors)]
        executor = SingleThreadedExecutor(context=neighbour_ctx)
        executor.add_node(neighbour)
        stop = threading.Event()

        def spin() -> None:  # the neighbour takes its images as they come
            while not stop.is_set():
                executor.spin_once(timeout_sec=0.1)

        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        deadline = time.monotonic() + 180.0
        while min(frames[i] for i in served) == 0:  # every published camera delivered (the victim steps)
            if time.monotonic() > deadline:
                raise RuntimeError(f"not every camera delivered an image within 180 s: {frames}")
            client.step_robot("rx200", {ARM: HOLD}, 10)
        start = sum(frames)
        busy = _victim_latencies(client, _for_seconds(seconds))
        rate = (sum(frames) - start) / seconds
        stop.set()
        spinner.join(10.0)
        executor.remove_node(neighbour)
        for sub in subs:
            neighbour.destroy_subscription(sub)
        a, b = np.median(alone), np.median(busy)
        print(f"cameras: {sensors} subscribed {width}x{height} sensors of a neighbour's rig, {len(served)} published "
              f"(MAX_CAMERA_PIXELS counts the victim's cameras too), {rate:.1f} images/s delivered in all; "
              f"victim StepRobot(10) alone: median {a * 1e3:.2f} ms, p95 "
              f"{np.percentile(alone, 95) * 1e3:.2f} ms; while they are served: median {b * 1e3:.2f} ms "
              f"({b / a:.1f}x), p95 {np.percentile(busy, 95) * 1e3:.2f} ms, {len(busy)} calls")
        client.close()
    finally:
        for other in others:
            other.try_shutdown()
        ctx.try_shutdown()


# -- the parameter flood ----------------------------------------------------------------------------
#: Each request of the flood: (what, service, its requests' count of names, values); see _param_payloads.
PARAM_KINDS = ("set 10,000 undeclared", "set 1,000 undeclared", "set 256 undeclared", "get 100,000",
               "describe 100,000", "types 100,000", "list 100,000 prefixes", "use_sim_time := 1,000,000 ints",
               "get 256", "list")
PARAM_TYPES = {"set": "rcl_interfaces/srv/SetParameters", "get": "rcl_interfaces/srv/GetParameters",
               "describe": "rcl_interfaces/srv/DescribeParameters", "types": "rcl_interfaces/srv/GetParameterTypes",
               "list": "rcl_interfaces/srv/ListParameters"}
PARAM_SERVICES = {"set": "set_parameters", "get": "get_parameters", "describe": "describe_parameters",
                  "types": "get_parameter_types", "list": "list_parameters"}


def _param_requests(get_srv: Callable[[str], Any], get_msg: Callable[[str], Any]) -> dict[str, tuple[str, Any]]:
    """Each kind of :data:`PARAM_KINDS`: (its service's short name, its request), built with ``get_srv`` and
    ``get_msg`` (multiros' types for a raw Zenoh peer, rclpy's for an rclpy client)."""
    param, value = get_msg("rcl_interfaces/msg/Parameter"), get_msg("rcl_interfaces/msg/ParameterValue")

    def setting(n: int) -> Any:
        return get_srv(PARAM_TYPES["set"]).Request(parameters=[
            param(name=f"flood.p{i}", value=value(type=2, integer_value=i)) for i in range(n)])

    names = [f"flood.p{i}" for i in range(100_000)]
    big = get_srv(PARAM_TYPES["set"]).Request(parameters=[param(name="use_sim_time", value=value(
        type=7, integer_array_value=list(range(1_000_000))))])
    return {
        "set 10,000 undeclared": ("set", setting(10_000)), "set 1,000 undeclared": ("set", setting(1_000)),
        "set 256 undeclared": ("set", setting(256)),
        "get 100,000": ("get", get_srv(PARAM_TYPES["get"]).Request(names=names)),
        "describe 100,000": ("describe", get_srv(PARAM_TYPES["describe"]).Request(names=names)),
        "types 100,000": ("types", get_srv(PARAM_TYPES["types"]).Request(names=names)),
        "list 100,000 prefixes": ("list", get_srv(PARAM_TYPES["list"]).Request(prefixes=names)),
        "use_sim_time := 1,000,000 ints": ("set", big),
        "get 256": ("get", get_srv(PARAM_TYPES["get"]).Request(names=names[:256])),
        "list": ("list", get_srv(PARAM_TYPES["list"]).Request()),
    }


def param_flooder(transport: str, where: str, seconds: float, out: str) -> None:
    """Child mode of the ``params`` attack: the neighbour. Four callers each send every kind of
    request in turn for ``seconds``, and once, 50 requests of 1,000 names at the same time; writes one
    JSON object to the file ``out``: kind -> list of [seconds, answered] per request."""
    flooders, in_flight = 4, 50
    if transport == "zenoh":
        from multiros.ros.interfaces import get_message as get_msg

        peers = [_RawPeer(where, DOMAIN) for _ in range(flooders + in_flight)]

        def caller(k: int) -> Callable[[str, str, Any], bool]:
            def call(service: str, type_name: str, request: Any) -> bool:
                return peers[k].call_request("mujoco_sim", service, type_name, request, timeout=60.0)
            return call

        requests = _param_requests(get_service, get_msg)
        close: Callable[[], None] = lambda: [p.close() for p in peers]  # noqa: E731
    else:
        import importlib

        from bench_rclpy_fairness import Peer  # a plain rclpy node (benchmarks/ is on sys.path)

        def rtype(name: str) -> Any:
            pkg, kind, cls = name.split("/")
            return getattr(importlib.import_module(f"{pkg}.{kind}"), cls)

        peers = [Peer(f"param_flooder_{k}") for k in range(flooders + 1)]  # the last: the 50 in flight
        clients: dict[tuple[int, str], Any] = {}
        for k, peer in enumerate(peers):
            for short, service in PARAM_SERVICES.items():
                clients[k, short] = peer.client(rtype(PARAM_TYPES[short]), f"/mujoco_sim/{service}", keep_all=True)

        def caller(k: int) -> Callable[[str, str, Any], bool]:
            k = min(k, flooders)
            def call(service: str, type_name: str, request: Any) -> bool:
                short = next(s for s, n in PARAM_SERVICES.items() if n == service)
                return peers[k].call(clients[k, short], request, timeout=60.0) is not None
            return call

        requests = _param_requests(rtype, rtype)
        close = lambda: [p.close() for p in peers]  # noqa: E731
    times: dict[str, list[list[float]]] = {kind: [] for kind in PARAM_KINDS}
    lock = threading.Lock()

    def timed(k: int, kind: str) -> None:
        short, request = requests[kind]
        t = time.perf_counter()
        answered = caller(k)(PARAM_SERVICES[short], PARAM_TYPES[short], request)
        with lock:
            times[kind].append([time.perf_counter() - t, float(answered)])

    print("flooding", flush=True)
    end = time.monotonic() + seconds

    def flood(k: int) -> None:
        i = k
        while time.monotonic() < end:
            timed(k, PARAM_KINDS[i % len(PARAM_KINDS)])
            i += 1

    threads = [threading.Thread(target=flood, args=(k,)) for k in range(flooders)]
    burst = [threading.Thread(target=timed, args=(flooders + j, "set 1,000 undeclared")) for j in range(in_flight)]
    for t in threads + burst:
        t.start()
    for t in threads + burst:
        t.join(seconds + 120)
    with open(out, "w") as f:
        json.dump(times, f)
    close()


def _read(path: str) -> str:
    with open(path) as f:
        return f.read()


def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024


def attack_params(transport: str = "zenoh", seconds: float = 8.0) -> None:
    """A neighbour floods the node's parameter services (:func:`param_flooder`, a process of its own) while
    the victim calls ``StepRobot(10)`` and ``list_controllers`` in turn: their latencies alone and meanwhile,
    each parameter request's answer time, and the node's memory (a ``uniros-sim`` process) before and after."""
    env = dict(os.environ)
    endpoint = ""
    ctx = None
    if transport == "zenoh":
        endpoint = free_loopback_endpoint()
        ctx = Context(transport="zenoh", env={}, domain_id=DOMAIN, router="embedded", router_endpoint=endpoint).init()
        env.update(ROS_DOMAIN_ID=str(DOMAIN), UNIROS_TRANSPORT="zenoh")
        node_args = ["--transport", "zenoh", "--router", endpoint]
    else:
        env.update(ROS_DOMAIN_ID=str(DOMAIN), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        env.pop("RMW_IMPLEMENTATION", None)
        os.environ.update(ROS_DOMAIN_ID=str(DOMAIN), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        node_args = ["--transport", "rclpy"]
    bindir = os.path.dirname(sys.executable)
    log = tempfile.NamedTemporaryFile("w+", prefix="uniros-sim-", suffix=".log", delete=False)  # noqa: SIM115
    node = subprocess.Popen([os.path.join(bindir, "uniros-sim"), *node_args, "--robot", f"rx200={RX200}",
                             "--owner-pid", str(os.getpid())], env=env, stdout=log, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL)
    flooder: subprocess.Popen | None = None
    victim_ctx = None
    try:
        deadline = time.monotonic() + 120
        while "ready" not in _read(log.name):
            if node.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"uniros-sim did not start:\n{_read(log.name)[-2000:]}")
            time.sleep(0.1)
        victim_ctx = (_session(endpoint) if transport == "zenoh"
                      else Context(transport="rclpy", domain_id=DOMAIN).init())
        client = SimulationClient(Node("victim", context=victim_ctx), "/mujoco_sim", timeout_sec=120.0)
        client.wait_until_ready(60.0)
        client.step_robot("rx200", {ARM: HOLD}, 200)

        def victim(until: Callable[[], bool]) -> tuple[np.ndarray, np.ndarray]:
            steps, lists = [], []
            while not until():
                t = time.perf_counter()
                client.step_robot("rx200", {ARM: HOLD}, 10)
                steps.append(time.perf_counter() - t)
                t = time.perf_counter()
                client.list_controllers("rx200")
                lists.append(time.perf_counter() - t)
            return np.array(steps), np.array(lists)

        victim(_for_seconds(1.0))  # warm-up
        alone = victim(_for_seconds(2.0))
        before = _rss_mb(node.pid)
        flooder = subprocess.Popen([sys.executable, __file__, "--param-flooder", transport, endpoint, str(seconds),
                                    f"{log.name}.json"], stdout=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL,
                                   env=env)
        assert flooder.stdout is not None
        if flooder.stdout.readline().strip() != "flooding":
            raise RuntimeError("the parameter flooder did not start")
        peak, done = [before], threading.Event()

        def sample() -> None:
            while not done.wait(0.1):
                peak[0] = max(peak[0], _rss_mb(node.pid))

        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        during = victim(lambda: flooder.poll() is not None)  # until it printed its figures and exited
        done.set()
        flooder.wait(60)
        with open(f"{log.name}.json") as f:
            times = json.load(f)
        after_lat = victim(_for_seconds(2.0))
        after = _rss_mb(node.pid)

        def figures(lat: np.ndarray) -> str:
            if not len(lat):
                return "no calls"
            return (f"median {np.median(lat) * 1e3:.1f} ms, p95 {np.percentile(lat, 95) * 1e3:.1f} ms, "
                    f"max {lat.max() * 1e3:.1f} ms, {len(lat)} calls")

        served = "served" if transport == "rclpy" else "not served on Zenoh (Transport.serves_parameters)"
        print(f"params over {transport} (parameter services {served}): victim StepRobot(10) alone {figures(alone[0])}; "
              f"during the flood {figures(during[0])}; after {figures(after_lat[0])}")
        print(f"  victim list_controllers alone {figures(alone[1])}; during {figures(during[1])}")
        for kind in PARAM_KINDS:
            rows = np.array(times[kind]) if times[kind] else np.zeros((0, 2))
            if len(rows):
                print(f"  {kind}: {len(rows)} requests, {int(rows[:, 1].sum())} answered, slowest "
                      f"{rows[:, 0].max() * 1e3:.0f} ms, median {np.median(rows[:, 0]) * 1e3:.0f} ms")
        print(f"  node memory (uniros-sim RSS): {before:.0f} MB before, peak {peak[0]:.0f} MB, {after:.0f} MB after "
              f"({after - before:+.0f} MB)")
        client.close()
    finally:
        for proc in (flooder, node):
            if proc is not None and proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(10)
        if victim_ctx is not None:
            victim_ctx.try_shutdown()
        if ctx is not None:
            ctx.try_shutdown()
        log.close()
        for path in (log.name, f"{log.name}.json"):
            if os.path.exists(path):
                os.unlink(path)


ATTACKS = {"stiff": attack_stiff, "stiff_late": lambda: attack_stiff(late=True), "overlap": attack_overlap,
           "drop": attack_drop, "flood": attack_flood, "boxes": attack_boxes,
           "refused": lambda: attack_boxes(refused_for=10.0), "intruder": attack_intruder, "cameras": attack_cameras,
           "params": attack_params, "params_rclpy": lambda: attack_params("rclpy")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--attacks", nargs="+", choices=sorted(ATTACKS),
                        default=[a for a in ATTACKS if a != "params_rclpy"])
    parser.add_argument("--boxes", type=int, default=200, help="boxes the neighbour of the 'boxes' attack asks for")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long the 'refused' attack's neighbour loops")
    parser.add_argument("--unlimited-too", action="store_true",
                        help="run the 'boxes' attack also on a node without quotas, for comparison")
    parser.add_argument("--param-flooder", nargs=4, metavar=("TRANSPORT", "ENDPOINT", "SECONDS", "OUT"),
                        help=argparse.SUPPRESS)  # child mode: the neighbour of the 'params' attacks
    args = parser.parse_args()
    if args.param_flooder:
        transport, endpoint, seconds, out = args.param_flooder
        param_flooder(transport, endpoint, float(seconds), out)
        return
    for name in args.attacks:
        if name in ("boxes", "refused"):
            refused_for = args.seconds if name == "refused" else None
            attack_boxes(args.boxes, refused_for=refused_for)
            if args.unlimited_too:
                attack_boxes(args.boxes, unlimited=True, refused_for=refused_for)
        else:
            ATTACKS[name]()


if __name__ == "__main__":
    main()
