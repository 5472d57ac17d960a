"""Test-session set-up: headless MuJoCo, and a graph of the suite's own.

The machine is shared: other programs (other copies of uniros and of this suite among them) may run
Zenoh routers on the default port 7447 and ROS nodes on domain 0. Before anything opens a context,
the session points every default at a private place: ``UNIROS_ZENOH_ROUTER`` at a free loopback port
and ``ROS_DOMAIN_ID`` at a non-zero domain, and drops the other ``ZENOH_*`` and ``UNIROS_ZENOH_*``
variables a user's shell may set. Child processes the tests start inherit these. ``test_isolation.py`` checks they hold.
"""

import os
import socket

import multiros  # noqa: F401  (sets MUJOCO_GL=egl when there is no display and none was chosen)


def _free_loopback_endpoint() -> str:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


for _key in [k for k in os.environ if k.startswith(("ZENOH_", "UNIROS_ZENOH_"))]:
    os.environ.pop(_key)
os.environ["UNIROS_ZENOH_ROUTER"] = _free_loopback_endpoint()
os.environ["ROS_DOMAIN_ID"] = str(101 + os.getpid() % 100)  # 101..200: never 0, within ROS' 0..232
