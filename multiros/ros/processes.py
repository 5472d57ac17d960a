"""Processes an owner starts: private graphs, the environment a child joins with, stop by PID,
and the child's watch on its owner.

Shared by everything that starts ROS nodes in child processes (the simulation node's ``process``
mode, ``uniros-fake-robot``, tests): every child is registered and stopped by PID at interpreter
exit, and a child given ``--owner-pid`` exits within about a second of its owner's death, whatever
ended the owner (``SIGKILL`` included).
"""

from __future__ import annotations

import argparse
import atexit
import logging
import os
import signal
import socket
import subprocess
import threading
import weakref
from collections.abc import Mapping

from multiros.ros.context import Context
from multiros.ros.exceptions import TransportError

__all__ = [
    "OWNER_POLL_SEC",
    "SHARED_GRAPH_PREFIXES",
    "add_child_options",
    "child_environment",
    "free_loopback_endpoint",
    "private_context",
    "private_environment",
    "start_child_program",
    "stop_event",
    "stop_process",
    "track_child",
    "untrack_child",
    "watch_owner",
]

_logger = logging.getLogger(__name__)

#: Prefixes of the environment variables that point a Zenoh context at a shared graph (router,
#: session files, overrides, endpoints, credentials); a private context and its child ignore them all.
SHARED_GRAPH_PREFIXES = ("ZENOH_", "UNIROS_ZENOH_")
#: How often a child checks that its owner is alive (seconds).
OWNER_POLL_SEC = 0.2

_children: weakref.WeakSet[subprocess.Popen] = weakref.WeakSet()


def track_child(proc: subprocess.Popen) -> subprocess.Popen:
    """Register a child so that it is stopped by PID at interpreter exit; returns it."""
    _children.add(proc)
    return proc


def untrack_child(proc: subprocess.Popen) -> None:
    """Forget a child (after stopping it)."""
    _children.discard(proc)


def _stop_children_at_exit() -> None:
    for proc in list(_children):
        stop_process(proc, timeout=2.0)


atexit.register(_stop_children_at_exit)


def stop_process(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    """Stop one child by PID: SIGINT, then SIGTERM, then SIGKILL, each with a bounded wait."""
    if proc.poll() is not None:
        return
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        try:
            proc.send_signal(sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=timeout)
            return
        except subprocess.TimeoutExpired:
            continue


def free_loopback_endpoint() -> str:
    """A Zenoh TCP endpoint on a port of 127.0.0.1 that is free right now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


def private_environment(env: Mapping[str, str] | None = None) -> dict[str, str]:
    """``env`` (default: this process's) without any setting that points at a shared Zenoh graph."""
    source = os.environ if env is None else env
    return {k: v for k, v in source.items() if not k.startswith(SHARED_GRAPH_PREFIXES)}


def private_context(attempts: int = 5) -> Context:
    """A Zenoh context with its own router on a free loopback port, deaf to the shared graph.

    The ``ZENOH_*`` and ``UNIROS_ZENOH_*`` variables are ignored, so a user's multi-host set-up
    never leaks into it. A port taken between probing and binding is retried on another port.

    Raises:
        TransportError: no router could be started in ``attempts`` tries.
    """
    env = private_environment()
    last: Exception | None = None
    for _ in range(max(1, attempts)):
        ctx = Context(transport="zenoh", env=env, router="embedded", router_endpoint=free_loopback_endpoint())
        try:
            return ctx.init()
        except TransportError as exc:  # port taken meanwhile: another port
            last = exc
    raise TransportError(f"could not start a private Zenoh router on loopback after {attempts} tries: {last}")


def child_environment(ctx: Context) -> dict[str, str]:
    """Environment variables that make a child process join ``ctx``'s ROS graph."""
    env = {"ROS_DOMAIN_ID": str(ctx.domain_id), "UNIROS_TRANSPORT": ctx.transport_name}
    if ctx.transport_name != "zenoh":
        return env
    endpoint = ctx.transport_options.get("router_endpoint") or ctx.env.get("UNIROS_ZENOH_ROUTER")
    if endpoint:
        env["UNIROS_ZENOH_ROUTER"] = str(endpoint)
    return env


def add_child_options(parser: argparse.ArgumentParser) -> None:
    """The options every program an owner may start shares: ``--owner-pid`` and ``--log-level``
    (read back by :func:`start_child_program`)."""
    parser.add_argument("--owner-pid", type=int, default=None,
                        help="exit when this process is gone (set by the env or test that starts this program)")
    parser.add_argument("--log-level", default="INFO")


def start_child_program(opts: argparse.Namespace) -> threading.Event:
    """Configure logging from ``--log-level`` and return the :func:`stop_event` for ``--owner-pid``
    (call from the main thread, after parsing the options of :func:`add_child_options`)."""
    logging.basicConfig(level=opts.log_level.upper(), format="[%(levelname)s] [%(name)s]: %(message)s")
    return stop_event(opts.owner_pid)


def stop_event(owner_pid: int | None = None) -> threading.Event:
    """An event set by SIGINT, SIGTERM, or (with ``owner_pid``) the owner's death: a program's
    main loop waits on it (call from the main thread: Python installs signal handlers only there)."""
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    if owner_pid is not None:
        watch_owner(owner_pid, stop)
    return stop


def watch_owner(owner_pid: int, stop: threading.Event) -> threading.Thread:
    """Set ``stop`` once the owner process is gone (or this process was re-parented away from it)."""
    watch_parent = os.getppid() == owner_pid  # started by the owner itself: re-parenting means it died

    def alive() -> bool:
        if watch_parent and os.getppid() != owner_pid:
            return False
        try:
            os.kill(owner_pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True

    def watch() -> None:
        while not stop.wait(OWNER_POLL_SEC):
            if not alive():
                _logger.warning("owner process %d is gone: shutting down", owner_pid)
                stop.set()
                return

    thread = threading.Thread(target=watch, name="owner-watch", daemon=True)
    thread.start()
    return thread
