"""Privacy on DDS: a process-mode child over rclpy is out of reach of a stranger on its owner's domain,
two owners get nodes and domains of their own; ``--ros-args`` reach rcl, whose refusal of a secured
node (the PyPI Fast DDS has no security plugins) ends ``uniros-sim`` with one line, not a traceback."""

from __future__ import annotations

import importlib.util
import os
import subprocess

import pytest

_NEEDED = ("rclpy", "simulation_interfaces", "uniros_interfaces")
if any(importlib.util.find_spec(p) is None for p in _NEEDED):
    pytest.skip("needs rclpy and the interface packages .ci/rclpy builds (run by .ci/rclpy)", allow_module_level=True)

from plain_ros import PlainPeer  # noqa: E402
from rclpy_harness import uniros_script  # noqa: E402

pytestmark = pytest.mark.slow


def test_process_mode_children_are_private_and_never_shared() -> None:
    from multiros.sim.launch import connect

    user_domain = int(os.environ["ROS_DOMAIN_ID"])
    first = connect("process", transport="rclpy", timeout_sec=60.0)
    second = None
    try:
        second = connect("process", transport="rclpy", timeout_sec=60.0)
        domains = {first.context.domain_id, second.context.domain_id}
        assert len(domains) == 2 and user_domain not in domains
        assert first.client.sim_node != second.client.sim_node
        assert first.client.sim_node.startswith(f"/mujoco_sim_{os.getpid()}_")
        # Each owner drives its own node: a spawn in one is not in the other.
        first.client.spawn_entity("box", resource_string=_BOX)
        assert first.client.get_entities() == ["box"] and second.client.get_entities() == []
        # A stranger on the owner's domain sees the graph there (a node of its own kind), not the children.
        with PlainPeer("stranger") as stranger, PlainPeer("bystander"):
            stranger.wait_for_node("/bystander")
            assert not [n for n in stranger.nodes() if "mujoco_sim" in n], stranger.nodes()
            services = [name for name, _ in stranger.node.get_service_names_and_types()]
            assert not [s for s in services if "mujoco_sim" in s]
    finally:
        first.close()
        if second is not None:
            second.close()


def test_an_rcl_refusal_of_a_secured_node_is_one_line(tmp_path) -> None:
    """The enclave given after --ros-args reaches rcl (rcl finds that enclave's files in the keystore),
    then Fast DDS refuses: uniros-sim exits non-zero with one line naming it."""
    keystore = tmp_path / "keystore"
    enclave = keystore / "enclaves" / "uniros" / "sim"
    enclave.mkdir(parents=True)
    for name in ("identity_ca.cert.pem", "cert.pem", "key.pem", "permissions_ca.cert.pem", "governance.p7s",
                 "permissions.p7s"):
        (enclave / name).write_text("not a certificate\n")
    env = dict(os.environ, ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce",
               ROS_SECURITY_KEYSTORE=str(keystore))
    proc = subprocess.run([uniros_script("uniros-sim"), "--transport", "rclpy", "--ros-args", "--enclave",
                           "/uniros/sim", "--", "--owner-pid", str(os.getpid())],
                          env=env, capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    output = proc.stdout + proc.stderr
    assert proc.returncode != 0, output
    assert "Traceback" not in output, output
    ours = [line for line in output.splitlines() if "rclpy could not" in line]
    assert len(ours) == 1, output
    # Without the enclave rcl looks for the root enclave "/", which this keystore lacks: another refusal.
    proc = subprocess.run([uniros_script("uniros-sim"), "--transport", "rclpy", "--owner-pid", str(os.getpid())],
                          env=env, capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert proc.returncode != 0 and "Traceback" not in proc.stdout + proc.stderr


_BOX = ('<robot name="box"><link name="box"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" '
        'izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry><box size="0.05 0.05 0.05"/>'
        '</geometry></collision></link></robot>')
