"""Test-session set-up: headless MuJoCo, and a graph of the suite's own.

The machine is shared: other programs (other copies of uniros and of this suite among them) may run
Zenoh routers on the default port 7447 and ROS nodes on domain 0. Before anything opens a context,
the session points every default at a private place: ``UNIROS_ZENOH_ROUTER`` at a free loopback port
and ``ROS_DOMAIN_ID`` at a non-zero domain, and drops the other ``ZENOH_*`` and ``UNIROS_ZENOH_*``
variables a user's shell may set. Child processes the tests start inherit these. ``test_isolation.py`` checks they hold.

Stable-Baselines3 makes a fresh ``SB3-<date>`` folder in the system's temporary directory for every
``learn()`` of a model without a logger of its own; ``SB3_LOGDIR`` sends them to one folder of the
session's, removed at its end.

Torch runs one thread (``OMP_NUM_THREADS=1``, inherited by the processes the tests start): the suite's
networks are small, and two threads on a loaded 2-core machine made SB3's updates up to 7x slower
(rl-zoo3's 300-step run: 107 s against 15 s).
"""

import atexit
import hashlib
import os
import shutil
import socket
import tempfile

import pytest

import multiros  # noqa: F401  (sets MUJOCO_GL=egl when there is no display and none was chosen)


def _free_loopback_endpoint() -> str:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


for _key in [k for k in os.environ if k.startswith(("ZENOH_", "UNIROS_ZENOH_"))]:
    os.environ.pop(_key)
os.environ["UNIROS_ZENOH_ROUTER"] = _free_loopback_endpoint()

def _private_domain() -> int:
    """101..200: never 0, within ROS' 0..232. Under pytest-xdist (``-n N``) the workers of one run
    take consecutive domains from one base, so no two of them share a graph."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")  # "gw0", "gw1", ...
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if worker.startswith("gw") and worker[2:].isdigit() and run:
        return 101 + (int(hashlib.sha256(run.encode()).hexdigest(), 16) + int(worker[2:])) % 100
    return 101 + os.getpid() % 100


os.environ["ROS_DOMAIN_ID"] = str(_private_domain())
os.environ["OMP_NUM_THREADS"] = "1"  # before torch is imported: its default thread count reads it

_sb3_logs = tempfile.mkdtemp(prefix="uniros-tests-sb3-")
os.environ["SB3_LOGDIR"] = _sb3_logs
atexit.register(shutil.rmtree, _sb3_logs, ignore_errors=True)
# A user's arm files (UNIROS_ARMS) are not the suite's; a test that registers one
# (uniros.register_arm adds it to the variable for child processes) must not leave it to later tests.
os.environ.pop("UNIROS_ARMS", None)


@pytest.fixture(autouse=True)
def _arm_files_stay_with_their_test():
    before = os.environ.get("UNIROS_ARMS")
    yield
    if before is None:
        os.environ.pop("UNIROS_ARMS", None)
    else:
        os.environ["UNIROS_ARMS"] = before
