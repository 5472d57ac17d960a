"""Several hosts: a simulation node on one host, an env on another, over Zenoh.

The two hosts are two network namespaces the test creates (a veth pair, 10.231.x.0/24 inside
them only, the node's embedded router in the first). Where namespaces are not permitted, the same
is shown across two routers on loopback (router A with the node, router B connected to A with the
env). Also: a client with the wrong password cannot reach a node whose router demands one.
"""

from __future__ import annotations

import contextlib
import os
import random
import shutil
import subprocess
import sys
import tempfile
import textwrap
from collections.abc import Iterator

import pytest

from multiros import ros
from multiros.ros.processes import stop_process
from multiros.sim.client import SimulationClient
from multiros.sim.launch import free_loopback_endpoint

pytestmark = [pytest.mark.slow, pytest.mark.multiprocess]

_CWD = tempfile.gettempdir()  # children import the installed package, not the working tree
RX200 = "package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
DOMAIN = "57"  # never domain 0's graph

_ENV_SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    import uniros
    env = uniros.make("RX200ReacherGoalSim-v0", sim_mode="existing", sim_node_name=sys.argv[1], timeout_sec=30.0)
    try:
        obs, _ = env.reset(seed=3)
        for _ in range(5):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert all(np.all(np.isfinite(v)) for v in obs.values())
        print("ENV_OK", float(reward), flush=True)
    finally:
        env.close()
""")


def _clean_env(**extra: str) -> dict[str, str]:
    """This process's environment without any Zenoh/ROS graph settings, plus ``extra``."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("ZENOH_", "UNIROS_ZENOH_")) and k not in ("ROS_DOMAIN_ID", "UNIROS_TRANSPORT")}
    env.update(ROS_DOMAIN_ID=DOMAIN, UNIROS_TRANSPORT="zenoh", **extra)
    return env


def _stop(proc: subprocess.Popen) -> str:
    stop_process(proc)  # SIGINT, SIGTERM, SIGKILL: bounded waits
    return proc.stdout.read() if proc.stdout else ""


def _run(cmd: list[str]) -> None:
    subprocess.run(cmd, check=True, capture_output=True, timeout=20)


def _netns_permitted() -> str:
    """Empty if this machine lets us create network namespaces and veth pairs, else why not."""
    if shutil.which("ip") is None:
        return "the 'ip' command is missing"
    if os.geteuid() != 0:
        return "network namespaces need root"
    name = f"urprobe{os.getpid()}"
    try:
        _run(["ip", "netns", "add", name])
    except (subprocess.CalledProcessError, OSError) as exc:
        return f"'ip netns add' failed: {exc}"
    try:
        _run(["ip", "netns", "del", name])
    except (subprocess.CalledProcessError, OSError):
        pass
    return ""


@contextlib.contextmanager
def _two_hosts() -> Iterator[tuple[list[str], list[str], str, str]]:
    """Two namespaces joined by a veth pair: (prefix A, prefix B, address A, address B)."""
    tag = f"{os.getpid() % 10000}{random.randrange(100)}"
    net = random.randrange(1, 250)
    ns_a, ns_b, va, vb = f"urhA{tag}", f"urhB{tag}", f"urva{tag}", f"urvb{tag}"
    addr_a, addr_b = f"10.231.{net}.1", f"10.231.{net}.2"
    created = []
    try:
        for ns in (ns_a, ns_b):
            _run(["ip", "netns", "add", ns])
            created.append(ns)
        _run(["ip", "link", "add", va, "type", "veth", "peer", "name", vb])
        _run(["ip", "link", "set", va, "netns", ns_a])
        _run(["ip", "link", "set", vb, "netns", ns_b])
        for ns, dev, addr in ((ns_a, va, addr_a), (ns_b, vb, addr_b)):
            _run(["ip", "-n", ns, "addr", "add", f"{addr}/24", "dev", dev])
            _run(["ip", "-n", ns, "link", "set", dev, "up"])
            _run(["ip", "-n", ns, "link", "set", "lo", "up"])
        yield ["ip", "netns", "exec", ns_a], ["ip", "netns", "exec", ns_b], addr_a, addr_b
    finally:
        for ns in created:  # deleting a namespace deletes its end of the veth pair, and so the pair
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=20)


def _start_node(prefix: list[str], name: str, env: dict[str, str], *robots: str) -> subprocess.Popen:
    """``uniros-sim`` (empty: the env spawns its own robot) in a child process, under ``prefix``."""
    spawn = [a for r in robots for a in ("--robot", r)]
    return subprocess.Popen(
        [*prefix, sys.executable, "-m", "multiros.sim.program", "--name", name, *spawn, "--log-level", "WARNING"],
        env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=_CWD,
    )


def _run_env(prefix: list[str], name: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([*prefix, sys.executable, "-c", _ENV_SCRIPT, name], env=env, stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=180, cwd=_CWD)


@pytest.mark.parametrize("topology", ["router_per_host", "one_router"])
def test_node_and_env_on_two_hosts_network_namespaces(topology: str) -> None:
    reason = _netns_permitted()
    if reason:
        pytest.skip(f"network namespaces not permitted here ({reason}); "
                    "test_node_and_env_across_two_routers_on_loopback covers the two-router set-up")
    with _two_hosts() as (host_a, host_b, addr_a, addr_b):
        port_a, port_b = random.sample(range(20000, 60000), 2)
        if topology == "router_per_host":
            # As rmw_zenoh recommends: a router per host, sessions on loopback, routers connected.
            node_env = _clean_env(UNIROS_ZENOH_ROUTER=f"tcp/127.0.0.1:{port_a}",
                                  UNIROS_ZENOH_ROUTER_LISTEN=f"tcp/{addr_a}:{port_a}")
            env_env = _clean_env(UNIROS_ZENOH_ROUTER=f"tcp/127.0.0.1:{port_b}",
                                 UNIROS_ZENOH_ROUTER_CONNECT=f"tcp/{addr_a}:{port_a}")
        else:
            # One router on host A; host B's session connects to it and listens where A can reach it.
            router = f"tcp/{addr_a}:{port_a}"
            node_env = _clean_env(UNIROS_ZENOH_ROUTER=router)
            env_env = _clean_env(UNIROS_ZENOH_ROUTER=router, UNIROS_ZENOH_LISTEN=f"tcp/{addr_b}:0",
                                 ZENOH_ROUTER_CHECK_ATTEMPTS="60")  # wait for A's router, 1 s apart
        node = _start_node(host_a, "sim_on_a", node_env)
        try:
            result = _run_env(host_b, "sim_on_a", env_env)
            assert "ENV_OK" in result.stdout, (result.stdout, result.stderr[-3000:], _stop(node))
        finally:
            _stop(node)


def test_node_and_env_across_two_routers_on_loopback() -> None:
    router_a, router_b = free_loopback_endpoint(), free_loopback_endpoint()
    node = _start_node([], "sim_behind_a", _clean_env(UNIROS_ZENOH_ROUTER=router_a))
    try:
        # The env's context starts router B (nothing listens there yet), which connects to A.
        env = _clean_env(UNIROS_ZENOH_ROUTER=router_b, UNIROS_ZENOH_ROUTER_CONNECT=router_a)
        result = _run_env([], "sim_behind_a", env)
        assert "ENV_OK" in result.stdout, (result.stdout, result.stderr, _stop(node))
    finally:
        _stop(node)


def test_wrong_password_cannot_reach_the_node(tmp_path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("sim:correct horse\n")
    router = free_loopback_endpoint()
    secured = {"UNIROS_ZENOH_USER": "sim", "UNIROS_ZENOH_PASSWORD": "correct horse",
               "UNIROS_ZENOH_AUTH_DICTIONARY": str(users)}
    node = _start_node([], "guarded", _clean_env(UNIROS_ZENOH_ROUTER=router, **secured), f"rx200={RX200}")
    try:
        good = {k: v for k, v in secured.items() if k != "UNIROS_ZENOH_AUTH_DICTIONARY"}
        # Probe until the node's router listens (1 s apart), as rmw_zenoh's ZENOH_ROUTER_CHECK_ATTEMPTS.
        with ros.Context(transport="zenoh", env={"ROS_DOMAIN_ID": DOMAIN, "ZENOH_ROUTER_CHECK_ATTEMPTS": "60", **good},
                         router_endpoint=router) as ctx:
            client = SimulationClient(ros.Node("good", context=ctx), "/guarded", timeout_sec=10.0)
            client.wait_until_ready(timeout_sec=60.0)
            assert client.get_entities() == ["rx200"]
        bad = ros.Context(transport="zenoh", router_endpoint=router, router_wait_sec=2.0,
                          env={"ROS_DOMAIN_ID": DOMAIN, "UNIROS_ZENOH_USER": "sim", "UNIROS_ZENOH_PASSWORD": "guess"})
        with pytest.raises(ros.TransportError, match="user and password"):
            bad.init()
    finally:
        _stop(node)


_ACL = """{
  enabled: true,
  default_permission: "deny",
  rules: [
    { id: "operate", permission: "allow", flows: ["ingress", "egress"], key_exprs: ["**"],
      messages: ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
                 "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"] },
    { id: "watch", permission: "allow", flows: ["ingress", "egress"], key_exprs: ["**"],
      messages: ["put", "declare_subscriber", "liveliness_token", "liveliness_query",
                 "declare_liveliness_subscriber"] },
  ],
  subjects: [ { id: "operators", usernames: ["sim", "trainer"] }, { id: "viewers", usernames: ["viewer"] } ],
  policies: [ { rules: ["operate"], subjects: ["operators"] }, { rules: ["watch"], subjects: ["viewers"] } ],
}"""


def test_a_shared_node_with_access_control_serves_operators_only(tmp_path) -> None:
    """A shared ``uniros-sim`` with user/password authentication and Zenoh access control (as the
    docs set it up): an operator's GetEntities is answered; a viewer, authenticated but only allowed
    to watch, gets no answer to any service call (queries are not among its messages); someone
    without a password gets no connection. The peers are plain Zenoh sessions, as rmw_zenoh opens them."""
    import zenoh
    from raw_calls import raw_get_entities
    from raw_zenoh import open_peer_session

    users = tmp_path / "users.txt"
    users.write_text("sim:node-secret\ntrainer:train-secret\nviewer:view-secret\n")
    acl = tmp_path / "acl.json5"
    acl.write_text(_ACL)
    router = free_loopback_endpoint()
    node = _start_node([], "mujoco_sim", _clean_env(
        UNIROS_ZENOH_ROUTER=router, UNIROS_ZENOH_USER="sim", UNIROS_ZENOH_PASSWORD="node-secret",
        UNIROS_ZENOH_AUTH_DICTIONARY=str(users), UNIROS_ZENOH_ACCESS_CONTROL=str(acl)), f"rx200={RX200}")
    try:
        operator = viewer = None
        try:
            operator = open_peer_session(router, credentials={"user": "trainer", "password": "train-secret"},
                                         connect_timeout_ms=60000)  # until the node's router listens
            assert raw_get_entities(operator, int(DOMAIN), timeout=60.0) == ["rx200"]
            viewer = open_peer_session(router, credentials={"user": "viewer", "password": "view-secret"},
                                       connect_timeout_ms=10000)
            with pytest.raises(AssertionError, match="no answer"):
                raw_get_entities(viewer, int(DOMAIN), timeout=3.0)
            with pytest.raises(zenoh.ZError):
                open_peer_session(router, connect_timeout_ms=1000)
            assert raw_get_entities(operator, int(DOMAIN)) == ["rx200"]
        finally:
            for session in (operator, viewer):
                if session is not None:
                    session.close()
    finally:
        _stop(node)
