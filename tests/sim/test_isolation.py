"""Isolation: process-mode nodes are private to their owner, die with it, and never meet another graph.

Every process a test starts is stopped by PID in a ``finally``; every router listens on a free
loopback port. The "shared graph" of these tests is the one the suite's conftest set up (a private
port and a non-zero domain), standing in for a user's default router and domain.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh
from raw_calls import raw_get_entities
from raw_zenoh import open_peer_session

from multiros import ros
from multiros.ros.processes import PRIVATE_GRAPH_OVERRIDE, private_graph_credentials, write_session_config
from multiros.sim.client import SimulationClient
from multiros.sim.launch import connect, free_loopback_endpoint, local_description_dirs, private_context

pytestmark = [pytest.mark.multiprocess]

RX200 = "package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"
# Children run outside the checkout so they import the installed package, as a user's scripts do.
_CWD = tempfile.gettempdir()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _wait_gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while _alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
    proc.wait(timeout=10)


@contextlib.contextmanager
def _uniros_sim(*args: str, endpoint: str) -> Iterator[subprocess.Popen]:
    """``uniros-sim`` in a child process with a router of its own at ``endpoint``."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "multiros.sim.program", "--router", endpoint, "--log-level", "WARNING", *args],
        stdin=subprocess.DEVNULL, cwd=_CWD,
    )
    try:
        yield proc
    finally:
        _stop(proc)


@contextlib.contextmanager
def _client_on(endpoint: str, node_name: str = "mujoco_sim") -> Iterator[SimulationClient]:
    env = {"ROS_DOMAIN_ID": os.environ["ROS_DOMAIN_ID"]}  # the domain uniros-sim inherited
    with ros.Context(transport="zenoh", env=env, router="none", router_endpoint=endpoint) as ctx:
        node = ros.Node("isolation_probe", context=ctx)
        client = SimulationClient(node, "/" + node_name, timeout_sec=10.0)
        try:
            yield client
        finally:
            client.close()
            node.destroy_node()


def test_the_suite_never_uses_the_default_router_or_domain():
    endpoint = os.environ["UNIROS_ZENOH_ROUTER"]
    assert not endpoint.endswith(":7447")
    assert int(os.environ["ROS_DOMAIN_ID"]) != 0
    ctx = ros.Context(transport="zenoh")
    assert ctx.domain_id != 0


def test_private_context_has_its_own_router_and_ignores_shared_settings(monkeypatch):
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", "connect/endpoints=[\"tcp/127.0.0.1:7447\"]")
    monkeypatch.setenv("UNIROS_ZENOH_CONNECT", "tcp/127.0.0.1:7447")
    ctx = private_context()
    try:
        endpoint = ctx.transport_options["router_endpoint"]
        assert endpoint.startswith("tcp/127.0.0.1:") and endpoint != os.environ["UNIROS_ZENOH_ROUTER"]
        assert [k for k in ctx.env if "ZENOH" in k] == ["ZENOH_CONFIG_OVERRIDE"]  # ours, not the user's
        assert ctx.env["ZENOH_CONFIG_OVERRIDE"] == PRIVATE_GRAPH_OVERRIDE
    finally:
        ctx.try_shutdown()


def test_local_description_dirs_names_folders_of_local_files_only(tmp_path):
    urdf = tmp_path / "robot.urdf"
    urdf.write_text("<robot name='r'/>")
    assert local_description_dirs(str(urdf), None) == [str(tmp_path.resolve())]
    assert local_description_dirs(f"file://{urdf}?a=b") == [str(tmp_path.resolve())]
    assert local_description_dirs("package://rx200_description/urdf/rx200.urdf.xacro", "<robot/>", None) == []
    assert local_description_dirs(str(tmp_path / "missing.urdf")) == []


@pytest.mark.slow
def test_process_mode_nodes_of_one_owner_never_meet_and_ignore_a_shared_node():
    """Two process-mode nodes at once plus a node on the shared graph: each spawn of 'rx200'
    lands in its own world (this collided with 'an entity named rx200 exists' before)."""
    shared = os.environ["UNIROS_ZENOH_ROUTER"]
    with _uniros_sim("--robot", f"rx200={RX200}", endpoint=shared) as decoy:
        a = connect("process", timeout_sec=30.0)
        b = connect("process", timeout_sec=30.0)
        try:
            assert {a.pid, b.pid, decoy.pid} == {a.pid, b.pid, decoy.pid} and len({a.pid, b.pid}) == 2
            for conn in (a, b):
                assert conn.context.transport_options["router_endpoint"] != shared
                assert conn.client.get_entities() == []
                assert conn.client.spawn_entity("rx200", uri=RX200) == "rx200"
            a.client.reset_simulation()
            assert b.client.get_entities() == ["rx200"]
        finally:
            a.close()
            b.close()
        with _client_on(shared) as client:
            client.wait_until_ready(timeout_sec=20.0)
            assert client.get_entities() == ["rx200"]  # the decoy saw none of it


_OWNER = textwrap.dedent("""
    import sys
    from multiros.sim.launch import connect
    conn = connect("process", timeout_sec=30.0)
    print(conn.pid, flush=True)
    sys.stdin.read()  # until the test kills us
""")


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_child_node_dies_with_its_owner_whatever_the_signal(sig):
    owner = subprocess.Popen([sys.executable, "-c", _OWNER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True, cwd=_CWD)
    child_pid = None
    try:
        line = owner.stdout.readline()
        assert line.strip().isdigit(), f"owner printed {line!r}"
        child_pid = int(line)
        assert _alive(child_pid)
        owner.send_signal(sig)
        owner.wait(timeout=10)
        assert _wait_gone(child_pid, timeout=5.0), f"child {child_pid} outlived its owner ({sig.name})"
    finally:
        _stop(owner)
        if child_pid is not None and _alive(child_pid):
            os.kill(child_pid, signal.SIGKILL)


@pytest.mark.slow
def test_uniros_sim_answers_only_once_its_robots_are_spawned():
    endpoint = free_loopback_endpoint()
    with _uniros_sim("--robot", f"rx200={RX200}", endpoint=endpoint), _client_on(endpoint) as client:
        client.wait_until_ready(timeout_sec=30.0)
        # The very first answer already knows the robot (it said "no robot 'rx200'" before).
        assert client.get_entities() == ["rx200"]
        # The launched robot is the launched world: SCOPE_ALL (and the default scope 0) bring it back.
        client.spawn_entity("second", uri=RX200.replace("robot_name=rx200", "robot_name=second"))
        for scope in (255, 0):
            client.delete_entity("rx200")
            client.reset_simulation(scope)
            assert client.get_entities() == ["rx200"]


def test_uniros_sim_exits_non_zero_when_a_robot_cannot_be_spawned():
    endpoint = free_loopback_endpoint()
    proc = subprocess.run(
        [sys.executable, "-m", "multiros.sim.program", "--router", endpoint,
         "--robot", "arm=package://no_such_package/robot.urdf"],
        stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60, cwd=_CWD,
    )
    assert proc.returncode == 1
    assert "no_such_package" in proc.stderr


def test_uniros_sim_help_mentions_isolation_options():
    proc = subprocess.run([sys.executable, "-m", "multiros.sim.program", "--help"], capture_output=True, text=True,
                          timeout=60, cwd=_CWD)
    assert proc.returncode == 0
    for flag in ("--router", "--trust-path", "--allow-xacro-strings", "--owner-pid"):
        assert flag in proc.stdout


_WORKER = textwrap.dedent("""
    import sys
    import uniros
    env = uniros.make("RX200ReacherGoalSim-v0", sim_mode="process", timeout_sec=60.0)
    try:
        env.reset(seed=int(sys.argv[1]))
        for _ in range(20):
            env.step(env.action_space.sample())
        print("ok", env.unwrapped.sim_connection.pid, flush=True)
    finally:
        env.close()
""")


@pytest.mark.slow
def test_four_processes_make_process_mode_envs_at_once():
    procs = [subprocess.Popen([sys.executable, "-c", _WORKER, str(i)], stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=_CWD)
             for i in range(4)]
    try:
        outs = [p.communicate(timeout=240) for p in procs]
    finally:
        for p in procs:
            _stop(p)
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err[-2000:]
        assert out.startswith("ok ")
    assert len({out.split()[1] for out, _ in outs}) == 4


@pytest.mark.slow
def test_make_vec_and_subproc_vec_env_with_process_mode():
    import uniros

    vec = uniros.make_vec("RX200ReacherSim-v0", num_envs=2, sim_mode="process",
                          vector_kwargs={"workers": 0})  # the nodes behind their private router
    try:
        vec.reset(seed=0)
        for _ in range(5):
            vec.step(vec.action_space.sample())
    finally:
        vec.close()

    from stable_baselines3.common.vec_env import SubprocVecEnv

    sub = SubprocVecEnv([lambda: uniros.make("RX200ReacherSim-v0", sim_mode="process", timeout_sec=60.0)] * 2)
    try:
        sub.reset()
        for _ in range(5):
            sub.step([sub.action_space.sample() for _ in range(2)])
    finally:
        sub.close()


def test_a_robot_file_directly_in_home_is_not_a_folder_to_trust(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    urdf = tmp_path / "robot.urdf"
    urdf.write_text("<robot name='r'/>")
    with pytest.raises(ValueError, match="folder .* of its own"):
        local_description_dirs(str(urdf))


def _listening_ports(pid: int) -> set[int]:
    """Loopback TCP ports a process listens on, as ``ss -ltnp`` shows them to anyone on the machine."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        with contextlib.suppress(OSError):
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
            if link.startswith("socket:["):
                inodes.add(link[len("socket:["):-1])
    ports = set()
    with open("/proc/net/tcp") as f:
        for line in f.readlines()[1:]:
            fields = line.split()
            local, state, inode = fields[1], fields[3], fields[9]
            if state == "0A" and inode in inodes:  # LISTEN
                ports.add(int(local.split(":")[1], 16))
    return ports


def _intruder_refused(endpoint: str, credentials: dict | None = None) -> bool:
    try:
        session = open_peer_session(endpoint, credentials=credentials, connect_timeout_ms=1000)
    except zenoh.ZError:
        return True
    session.close()
    return False


@pytest.mark.slow
def test_a_private_graph_refuses_intruders_and_serves_its_owner(tmp_path):
    """Another local process finds the owner's ports (the router's and each session's) and connects
    without the secret: refused at every port; the owner, its child and peers given the
    credentials (directly, or through a Zenoh session config file as rmw_zenoh reads it) work."""
    conn = connect("process", timeout_sec=30.0)
    try:
        conn.client.spawn_entity("rx200", uri=RX200)
        router = conn.context.transport_options["router_endpoint"]
        ports = _listening_ports(conn.pid) | _listening_ports(os.getpid())
        assert int(router.rsplit(":", 1)[1]) in ports and len(ports) >= 3  # router, owner session, child session
        for port in sorted(ports):
            assert _intruder_refused(f"tcp/127.0.0.1:{port}"), f"port {port} accepted a peer without the secret"
        wrong = {**private_graph_credentials(conn.context), "password": "guess"}
        wrong.pop("auth_dictionary")
        assert _intruder_refused(router, wrong)
        assert conn.client.get_entities() == ["rx200"]  # nothing reached the node
        conn.client.step_robot("rx200", steps=10)

        config = write_session_config(conn.context, tmp_path / "session.json5")
        assert config.stat().st_mode & 0o777 == 0o600
        credentials = private_graph_credentials(conn.context)
        assert credentials["password"] not in Path(f"/proc/{conn.pid}/cmdline").read_text()  # visible to all users
        for opener in (lambda: open_peer_session(router, credentials=credentials, connect_timeout_ms=5000),
                       lambda: zenoh.open(zenoh.Config.from_file(str(config)))):  # rmw_zenoh's ZENOH_SESSION_CONFIG_URI
            session = opener()
            try:
                assert raw_get_entities(session, conn.context.domain_id) == ["rx200"]
            finally:
                session.close()
    finally:
        folder = os.path.dirname(private_graph_credentials(conn.context)["auth_dictionary"])
        conn.close()
    assert not os.path.exists(folder)  # the secret is gone with the graph
