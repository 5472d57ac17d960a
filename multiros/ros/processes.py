"""Processes an owner starts: private graphs, the environment a child joins with, stop by PID,
and the child's watch on its owner.

Shared by everything that starts ROS nodes in child processes (the simulation node's ``process``
mode, ``uniros-fake-robot``, tests): every child is registered and stopped by PID at interpreter
exit, and a child given ``--owner-pid`` exits within about a second of its owner's death, whatever
ended the owner (``SIGKILL`` included).

A private graph is closed to everyone but its owner: :func:`private_context` makes a fresh secret
(Zenoh user/password authentication, ``transport/auth/usrpwd``) and writes the one accepted
``user:password`` line to a dictionary file only this user can read (``0600`` in a ``0700``
folder). The router and every session of the graph listen with that dictionary, so a connection
without the secret is refused before it can see a key, to the router's port and to each session's
own port alike; the owner's children get the secret through their environment
(:func:`child_environment`, readable by this user only); :func:`write_session_config` writes it as
a Zenoh session config file for rmw_zenoh (``ZENOH_SESSION_CONFIG_URI``) and Zenoh tools. The
folder is removed when the context shuts down (or at exit). Processes of the same user can read
that file and the owner's memory anyway: the boundary is between users, as for any file.

DDS (the rclpy transport) has no router and no authentication without SROS2, so a private graph
there is what DDS offers: :func:`private_dds_context` takes a domain id nobody on this machine uses
now and discovery on this machine only (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, no static
peers). Other hosts never see it; the owner's own ``ROS_DOMAIN_ID`` (where strangers look) never
holds it; a process of this machine that scans every domain could still find it (only SROS2
closes that; see docs/ros2_system.md). Every program an owner starts also gets localhost-only
discovery unless the owner's environment names a range (:data:`DISCOVERY_RANGE_ENV`).
"""

from __future__ import annotations

import argparse
import atexit
import json
import logging
import os
import secrets
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import weakref
from collections.abc import Mapping
from pathlib import Path

from multiros.ros.context import Context
from multiros.ros.exceptions import TransportError

__all__ = [
    "DISCOVERY_RANGE_ENV",
    "OWNER_POLL_SEC",
    "SHARED_GRAPH_PREFIXES",
    "add_child_options",
    "child_environment",
    "free_loopback_endpoint",
    "discovery_environment",
    "free_dds_domain",
    "private_context",
    "private_dds_context",
    "private_environment",
    "private_graph_credentials",
    "start_child_program",
    "owner_log_level",
    "is_private_graph",
    "OWN_LOGGERS",
    "configure_child_logging",
    "stop_event",
    "stop_process",
    "track_child",
    "untrack_child",
    "watch_owner",
    "write_session_config",
]

_logger = logging.getLogger(__name__)

#: Prefixes of the environment variables that point a Zenoh context at a shared graph (router,
#: session files, overrides, endpoints, credentials); a private context and its child ignore them all.
SHARED_GRAPH_PREFIXES = ("ZENOH_", "UNIROS_ZENOH_")
#: The variable rcl (Jazzy on) reads for how far DDS discovery reaches: LOCALHOST, SUBNET, OFF, SYSTEM_DEFAULT.
DISCOVERY_RANGE_ENV = "ROS_AUTOMATIC_DISCOVERY_RANGE"
#: rcl's list of peers to reach beyond the range (a private graph drops it).
STATIC_PEERS_ENV = "ROS_STATIC_PEERS"
#: Domains a private DDS graph is taken from: 1..100 (0 is everybody's; 101..232 are the test
#: suites' own, and their ports fall into Linux' ephemeral range above 101).
PRIVATE_DOMAINS = range(1, 101)
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


#: The user name of a private graph's credentials (the password is the secret).
PRIVATE_USER = "uniros-owner"
#: Zenoh settings of every session of a private graph (rmw_zenoh's ``ZENOH_CONFIG_OVERRIDE`` syntax).
#: Peers reach each other only over a direct link, which each one found by gossip used to open to
#: the other at the same moment; with both ends authenticating, such a crossing sometimes left no
#: link at all (a child node never seen by its owner, about one start in seven). With
#: ``greater-zid`` only one end of each pair opens it.
PRIVATE_GRAPH_OVERRIDE = 'scouting/gossip/autoconnect_strategy={peer: {to_router: "always", to_peer: "greater-zid"}}'
_AUTOCONNECT = {"peer": {"to_router": "always", "to_peer": "greater-zid"}}
#: Context options and the environment variables that carry them to a child (multiros.ros.transport.zenoh.network).
_CREDENTIAL_VARS = (("user", "UNIROS_ZENOH_USER"), ("password", "UNIROS_ZENOH_PASSWORD"),
                    ("auth_dictionary", "UNIROS_ZENOH_AUTH_DICTIONARY"))


class _Secret:
    """A fresh password and its one-line dictionary file in a folder only this user can open."""

    def __init__(self) -> None:
        self.password = secrets.token_urlsafe(32)
        self.folder = tempfile.mkdtemp(prefix="uniros-graph-")  # mode 0700
        self.dictionary = os.path.join(self.folder, "users.txt")
        fd = os.open(self.dictionary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(f"{PRIVATE_USER}:{self.password}\n")
        self._finalizer = weakref.finalize(self, shutil.rmtree, self.folder, True)  # also at exit

    def options(self) -> dict[str, str]:
        return {"user": PRIVATE_USER, "password": self.password, "auth_dictionary": self.dictionary}

    def remove(self) -> None:
        self._finalizer()


def private_context(attempts: int = 5) -> Context:
    """A Zenoh context with its own router on a free loopback port, closed to other users and deaf
    to the shared graph.

    The router and the context's session accept only connections that present this context's
    fresh secret (see the module docstring); :func:`child_environment` hands it to children.
    The ``ZENOH_*`` and ``UNIROS_ZENOH_*`` variables are ignored, so a user's multi-host set-up
    never leaks into it. A port taken between probing and binding is retried on another port.

    Raises:
        TransportError: no router could be started in ``attempts`` tries.
    """
    env = private_environment()
    env["ZENOH_CONFIG_OVERRIDE"] = PRIVATE_GRAPH_OVERRIDE
    last: Exception | None = None
    for _ in range(max(1, attempts)):
        secret = _Secret()
        ctx = Context(transport="zenoh", env=env, router="embedded", router_endpoint=free_loopback_endpoint(),
                      **secret.options())
        try:
            ctx.init()
        except TransportError as exc:  # port taken meanwhile: another port
            secret.remove()
            last = exc
            continue
        ctx.on_shutdown(secret.remove)
        return ctx
    raise TransportError(f"could not start a private Zenoh router on loopback after {attempts} tries: {last}")


def is_private_graph(ctx: Context) -> bool:
    """Whether only its owner's processes can join ``ctx``'s graph: an in-process one, or a private
    Zenoh graph (:func:`private_context`, and the children it starts): no ROS tool looks at it."""
    if ctx.transport_name == "inproc":
        return True
    return (ctx.transport_name == "zenoh" and ctx.env.get("ZENOH_CONFIG_OVERRIDE") == PRIVATE_GRAPH_OVERRIDE
            and bool(private_graph_credentials(ctx)))


def private_graph_credentials(ctx: Context) -> dict[str, str]:
    """The Zenoh credentials ``ctx``'s graph requires (``user``, ``password``, ``auth_dictionary``;
    empty for a graph without authentication)."""
    out = {}
    for option, var in _CREDENTIAL_VARS:
        value = ctx.transport_options.get(option) or ctx.env.get(var)
        if value:
            out[option] = str(value)
    return out


def discovery_environment(env: Mapping[str, str] | None = None) -> dict[str, str]:
    """``env`` (default: this process's) with DDS discovery on this machine only, unless it names a
    range itself (:data:`DISCOVERY_RANGE_ENV`): what every program uniros starts gets."""
    out = dict(os.environ if env is None else env)
    if not out.get(DISCOVERY_RANGE_ENV, "").strip():
        out[DISCOVERY_RANGE_ENV] = "LOCALHOST"
    return out


def _domain_in_use(domain: int) -> bool:
    """Whether a DDS participant of this machine holds ``domain``'s first unicast discovery port
    (RTPS: 7400 + 250 * domain + 10; every participant binds it or the next ones)."""
    port = 7410 + 250 * domain
    for offset in (0, 1):  # the first participant's discovery and user ports
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            try:
                sock.bind(("0.0.0.0", port + offset))
            except OSError:
                return True
    return False


def free_dds_domain(exclude: tuple[int, ...] = ()) -> int:
    """A domain id of :data:`PRIVATE_DOMAINS` that no participant on this machine uses now (picked at
    random, so owners starting at the same moment rarely pick the same one).

    Raises:
        TransportError: every one is in use.
    """
    candidates = [d for d in PRIVATE_DOMAINS if d not in exclude]
    secrets.SystemRandom().shuffle(candidates)
    for domain in candidates:
        if not _domain_in_use(domain):
            return domain
    raise TransportError(f"no free ROS domain id in {PRIVATE_DOMAINS.start}..{PRIVATE_DOMAINS.stop - 1} on this "
                         "machine for a private DDS graph: stop some ROS processes, or use transport='zenoh'")


def private_dds_context() -> Context:
    """An rclpy context on a free domain with discovery on this machine only (see the module
    docstring): a child given :func:`child_environment` of it joins it and nothing else.

    Raises:
        TransportError: rclpy cannot be loaded, or no domain is free.
    """
    env = {k: v for k, v in os.environ.items() if k != STATIC_PEERS_ENV}
    env[DISCOVERY_RANGE_ENV] = "LOCALHOST"
    user_domain = Context(env=os.environ).domain_id
    return Context(transport="rclpy", env=env, domain_id=free_dds_domain((user_domain,))).init()


def child_environment(ctx: Context) -> dict[str, str]:
    """Environment variables that make a child process join ``ctx``'s ROS graph: its domain, its
    router and, for a private graph, its credentials (never on a command line, which every user
    can read; a process's environment is readable by its own user only). DDS discovery: the
    context's range, else this machine only (:func:`discovery_environment`)."""
    env = {"ROS_DOMAIN_ID": str(ctx.domain_id), "UNIROS_TRANSPORT": ctx.transport_name,
           DISCOVERY_RANGE_ENV: discovery_environment(ctx.env)[DISCOVERY_RANGE_ENV]}
    if ctx.transport_name != "zenoh":
        return env
    endpoint = ctx.transport_options.get("router_endpoint") or ctx.env.get("UNIROS_ZENOH_ROUTER")
    if endpoint:
        env["UNIROS_ZENOH_ROUTER"] = str(endpoint)
    credentials = private_graph_credentials(ctx)
    if ctx.env.get("ZENOH_CONFIG_OVERRIDE") == PRIVATE_GRAPH_OVERRIDE:
        env["ZENOH_CONFIG_OVERRIDE"] = PRIVATE_GRAPH_OVERRIDE
    for option, var in _CREDENTIAL_VARS:
        if option in credentials:
            env[var] = credentials[option]
    return env


def write_session_config(ctx: Context, path: str | os.PathLike[str]) -> Path:
    """Write a Zenoh session config (JSON5) that joins ``ctx``'s graph, for rmw_zenoh
    (``ZENOH_SESSION_CONFIG_URI=<path>`` with ``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` and
    ``ROS_DOMAIN_ID`` = ``ctx.domain_id``) or any Zenoh tool: peer mode, the graph's router, loopback,
    no multicast scouting, and the graph's credentials. The file holds the secret: it is created
    with mode ``0600`` (an existing file is refused). Returns the path.

    Raises:
        FileExistsError: ``path`` exists.
    """
    endpoint = ctx.transport_options.get("router_endpoint") or ctx.env.get("UNIROS_ZENOH_ROUTER")
    config: dict = {
        "mode": "peer",
        "connect": {"endpoints": [str(endpoint)] if endpoint else []},
        "listen": {"endpoints": ["tcp/127.0.0.1:0"]},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True}},
    }
    if ctx.env.get("ZENOH_CONFIG_OVERRIDE") == PRIVATE_GRAPH_OVERRIDE:
        config["scouting"]["gossip"]["autoconnect_strategy"] = _AUTOCONNECT
    credentials = private_graph_credentials(ctx)
    if credentials:
        usrpwd = {"user": credentials.get("user"), "password": credentials.get("password")}
        if "auth_dictionary" in credentials:
            usrpwd["dictionary_file"] = credentials["auth_dictionary"]
        config["transport"] = {"auth": {"usrpwd": usrpwd}}
    target = Path(path)
    fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        json.dump(config, f, indent=2)
    return target


def add_child_options(parser: argparse.ArgumentParser) -> None:
    """The options every program an owner may start shares: ``--owner-pid`` and ``--log-level``
    (read back by :func:`start_child_program`)."""
    parser.add_argument("--owner-pid", type=int, default=None,
                        help="exit when this process is gone (set by the env or test that starts this program)")
    parser.add_argument("--log-level", default="INFO",
                        help="level of uniros' own log lines (other libraries': warnings and errors)")


#: The loggers of uniros' own code (``ros.<node>`` are the nodes'; the upper layers' packages by name
#: only, nothing imported): a program's ``--log-level``
#: sets theirs; other libraries log warnings and errors only (PyOpenGL's INFO lines are no news).
OWN_LOGGERS = ("__main__", "ros", "multiros", "uniros", "rl_environments")


def start_child_program(opts: argparse.Namespace) -> threading.Event:
    """Configure logging from ``--log-level`` (:data:`OWN_LOGGERS`) and return the :func:`stop_event`
    for ``--owner-pid`` (call from the main thread, after parsing the options of
    :func:`add_child_options`)."""
    configure_child_logging(opts.log_level)
    return stop_event(opts.owner_pid)


def configure_child_logging(level: str) -> None:
    """A child process's logging: ``level`` (a standard name) for uniros' own loggers
    (:data:`OWN_LOGGERS`), warnings and errors of other libraries, one line a record on stderr.

    Raises:
        ValueError: an unknown level.
    """
    name = level.upper()
    if not isinstance(logging.getLevelName(name), int):
        raise ValueError(f"unknown --log-level {level!r}; levels: DEBUG, INFO, WARNING, ERROR, CRITICAL")
    logging.basicConfig(level=logging.WARNING, format="[%(levelname)s] [%(name)s]: %(message)s")
    for logger in OWN_LOGGERS:
        logging.getLogger(logger).setLevel(name)


def owner_log_level() -> str:
    """The ``--log-level`` of a child an owner starts for itself (a node of its env): what the owner's
    own node loggers would show (``logging.getLogger("ros")``; WARNING where nothing is configured), as
    the standard level at or below it (a custom level 15 shows what DEBUG shows; the child knows no
    custom names)."""
    level = logging.getLogger("ros").getEffectiveLevel()
    standard = [lvl for lvl in (logging.DEBUG, logging.INFO, logging.WARNING, logging.ERROR, logging.CRITICAL)
                if lvl <= level]
    return logging.getLevelName(standard[-1] if standard else logging.DEBUG)


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
