"""Start or reach a simulation node: composed in this process, in a child process, or already running.

* :func:`compose` builds a :class:`~multiros.sim.node.SimulationNode` in the calling process.
* :func:`connect` returns a :class:`SimulationConnection` (an env-side node plus a
  :class:`~multiros.sim.client.SimulationClient`) for one of three modes: ``"composed"`` (own
  context, in-process transport: the fast, isolated default), ``"process"`` (a child process over
  Zenoh, stopped by PID on close) or ``"existing"`` (a node someone else runs).
* :func:`main` is the ``uniros-sim`` command (also ``python -m multiros.sim.launch``).

Readiness is signalled, never slept for: a child process is ready when its services answer.
"""

from __future__ import annotations

import argparse
import atexit
import itertools
import logging
import os
import signal
import subprocess
import sys
import threading
import time
import weakref
from collections.abc import Mapping, Sequence
from typing import Any
from urllib.parse import urlencode

from multiros.ros import Context, Node
from multiros.sim.client import DEFAULT_NODE_NAME, SimulationClient, SimulationNodeError

_logger = logging.getLogger(__name__)
_env_ids = itertools.count()
_children: weakref.WeakSet[subprocess.Popen] = weakref.WeakSet()


def _stop_children_at_exit() -> None:
    for proc in list(_children):
        _stop_process(proc, timeout=2.0)


atexit.register(_stop_children_at_exit)


def _stop_process(proc: subprocess.Popen, timeout: float = 5.0) -> None:
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


def compose(
    node_name: str = DEFAULT_NODE_NAME,
    *,
    context: Context | None = None,
    transport: str | None = None,
    paused: bool = True,
    real_time_factor: float = 1.0,
    timestep: float | None = None,
    gui: bool = False,
    **node_kwargs: Any,
) -> Any:
    """Create a simulation node in this process and return it.

    Args:
        node_name: the node's name.
        context: the ROS context to join (a new one with ``transport`` when omitted).
        transport: ``"inproc"`` or ``"zenoh"`` for a new context.
        paused: start paused (lockstep) instead of playing in real time.
        real_time_factor: playing speed (1.0 = wall clock, <= 0 = as fast as possible).
        timestep: physics time step in seconds.
        gui: open the interactive viewer (needs a display).
    """
    from multiros.sim.node import SimulationNode
    from multiros.sim.world import WorldOptions

    if context is None:
        context = Context(transport=transport).init()
    options = WorldOptions() if timestep is None else WorldOptions(timestep=timestep)
    node = SimulationNode(
        node_name, options=options, paused=paused, real_time_factor=real_time_factor, context=context, **node_kwargs
    )
    if gui:
        node.open_viewer()
    return node


class SimulationConnection:
    """An env's link to a simulation node: its own ROS context and node, a client, and whatever it
    started (a composed node or a child process), all released by :meth:`close`."""

    def __init__(
        self,
        context: Context,
        node: Node,
        client: SimulationClient,
        *,
        sim_node: Any = None,
        process: subprocess.Popen | None = None,
        owns_context: bool = True,
    ) -> None:
        self.context = context
        self.node = node
        self.client = client
        self.sim_node = sim_node
        self.process = process
        self._owns_context = owns_context
        self._lock = threading.Lock()
        self._closed = False

    @property
    def pid(self) -> int | None:
        """PID of the child process running the node (``process`` mode)."""
        return self.process.pid if self.process is not None else None

    def show_viewer(self) -> None:
        """Open (or refresh) the interactive viewer of a composed node."""
        if self.sim_node is None:
            raise SimulationNodeError("the viewer is only available for a composed node (sim_mode='composed')")
        self.sim_node.open_viewer()

    def close(self) -> None:
        """Destroy the env node and client, the composed node, stop the child process by PID."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        try:
            self.client.close()
            self.node.destroy_node()
            if self.sim_node is not None:
                self.sim_node.destroy_node()
        finally:
            if self.process is not None:
                _stop_process(self.process)
                _children.discard(self.process)
            if self._owns_context:
                self.context.try_shutdown()


def _wait_ready(client: SimulationClient, process: subprocess.Popen | None, timeout_sec: float) -> None:
    deadline = time.monotonic() + timeout_sec
    while True:
        remaining = deadline - time.monotonic()
        if process is not None and process.poll() is not None:
            raise SimulationNodeError(
                f"simulation node process (pid {process.pid}) exited with code {process.returncode} before it was ready"
            )
        if remaining <= 0:
            raise SimulationNodeError(
                f"simulation node {client.sim_node!r} not ready within {timeout_sec:g} s "
                "(for sim_mode='existing': is it running, on the same transport and ROS_DOMAIN_ID?)"
            )
        try:
            client.wait_until_ready(timeout_sec=min(0.5, remaining))
            return
        except SimulationNodeError:
            continue


def connect(
    mode: str = "composed",
    *,
    node_name: str = DEFAULT_NODE_NAME,
    transport: str | None = None,
    gui: bool = False,
    timeout_sec: float = 10.0,
    paused: bool = True,
    real_time_factor: float = 1.0,
    timestep: float | None = None,
    context: Context | None = None,
) -> SimulationConnection:
    """Reach a simulation node and return a :class:`SimulationConnection`.

    Args:
        mode: ``"composed"``, ``"process"`` or ``"existing"``.
        node_name: the simulation node's name (``/`` prefix optional).
        transport: ``"inproc"`` (composed only) or ``"zenoh"``; default inproc when composed,
            zenoh otherwise.
        gui: open the viewer (composed and process modes).
        timeout_sec: how long to wait for the node to become ready.
        paused, real_time_factor, timestep: start-up options of a node this call starts.
        context: join this context instead of creating one (the caller then owns its shutdown).
    """
    if mode not in ("composed", "process", "existing"):
        raise ValueError(f"sim_mode {mode!r} is not one of 'composed', 'process', 'existing'")
    if mode != "composed" and transport == "inproc":
        raise ValueError(f"sim_mode {mode!r} needs a wire transport; use transport='zenoh'")
    transport = transport or ("inproc" if mode == "composed" else "zenoh")
    owns = context is None
    ctx = context if context is not None else Context(transport=transport).init()
    sim_node = None
    process = None
    node = None
    try:
        if mode == "composed":
            sim_node = compose(
                node_name, context=ctx, paused=paused, real_time_factor=real_time_factor, timestep=timestep, gui=gui
            )
        elif mode == "process":
            process = _spawn_child(ctx, node_name, gui=gui, paused=paused, real_time_factor=real_time_factor,
                                   timestep=timestep)
        node = Node(f"uniros_env_{os.getpid()}_{next(_env_ids)}", context=ctx)
        client = SimulationClient(node, "/" + node_name.lstrip("/"), timeout_sec=timeout_sec)
        if mode != "composed":
            _wait_ready(client, process, timeout_sec)
        return SimulationConnection(ctx, node, client, sim_node=sim_node, process=process, owns_context=owns)
    except BaseException:
        if node is not None:
            node.destroy_node()
        if sim_node is not None:
            sim_node.destroy_node()
        if process is not None:
            _stop_process(process)
        if owns:
            ctx.try_shutdown()
        raise


def _spawn_child(
    ctx: Context, node_name: str, *, gui: bool, paused: bool, real_time_factor: float, timestep: float | None
) -> subprocess.Popen:
    argv = [sys.executable, "-m", "multiros.sim.launch", "--name", node_name.lstrip("/"), "--transport", "zenoh",
            "--real-time-factor", str(real_time_factor)]
    if not paused:
        argv.append("--play")
    if gui:
        argv.append("--gui")
    if timestep is not None:
        argv += ["--timestep", str(timestep)]
    env = dict(os.environ)
    env.update(_child_environment(ctx))
    proc = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL)
    _children.add(proc)
    return proc


def _child_environment(ctx: Context) -> dict[str, str]:
    """Environment variables that make a child process join ``ctx``'s ROS graph."""
    env = {"ROS_DOMAIN_ID": str(ctx.domain_id), "UNIROS_TRANSPORT": "zenoh"}
    endpoint = ctx.transport_options.get("router_endpoint")
    if endpoint:
        env["UNIROS_ZENOH_ROUTER"] = str(endpoint)
    return env


def robot_resource(
    *,
    robot_model_xml: str | None = None,
    urdf_pkg_name: str | None = None,
    urdf_file_name: str | None = None,
    urdf_folder: str = "/urdf",
    xacro_args: Mapping[str, Any] | Sequence[str] | None = None,
    controllers_file: str | None = None,
    controllers_list: Sequence[str] | None = None,
) -> tuple[str, str]:
    """The ``(uri, resource_string)`` pair of a ``SpawnEntity`` request for an env's robot.

    A file or ``package://`` location becomes the URI (xacro arguments as its query, which the
    node passes to xacro); XML text becomes the resource string. ``controllers_file`` and
    ``controllers_list`` travel as the reserved query keys ``__controllers_file`` and
    ``__controllers``.
    """
    if robot_model_xml is None:
        if not (urdf_pkg_name and urdf_file_name):
            raise ValueError(
                "no robot description: give robot_model_xml (a file, package:// URI or XML text), "
                "or urdf_pkg_name and urdf_file_name"
            )
        folder = "/" + urdf_folder.strip("/") if urdf_folder.strip("/") else ""
        robot_model_xml = f"package://{urdf_pkg_name}{folder}/{urdf_file_name}"
    args: dict[str, str] = {}
    if isinstance(xacro_args, Mapping):
        args.update({str(k): str(v) for k, v in xacro_args.items()})
    elif xacro_args:
        for item in xacro_args:
            key, sep, value = str(item).partition(":=")
            if not sep:
                raise ValueError(f"xacro argument {item!r} must look like 'name:=value'")
            args[key] = value
    if controllers_file:
        args["__controllers_file"] = controllers_file
    if controllers_list:
        args["__controllers"] = ",".join(controllers_list)
    if robot_model_xml.lstrip().startswith("<"):
        if args:
            from multiros.sim.description import xacro_to_urdf

            plain = {k: v for k, v in args.items() if not k.startswith("__")}
            text = xacro_to_urdf(robot_model_xml, plain) if plain else robot_model_xml
            reserved = {k: v for k, v in args.items() if k.startswith("__")}
            if reserved:
                return "string:?" + urlencode(reserved), text
            return "", text
        return "", robot_model_xml
    uri = robot_model_xml
    if args:
        uri += ("&" if "?" in uri else "?") + urlencode(args)
    return uri, ""


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros-sim``: run the simulation node standalone until interrupted."""
    parser = argparse.ArgumentParser(prog="uniros-sim", description="Run the uniros MuJoCo simulation node.")
    parser.add_argument("--name", default=DEFAULT_NODE_NAME, help="node name (default: %(default)s)")
    parser.add_argument("--namespace", default="", help="node namespace")
    parser.add_argument("--transport", default="zenoh", choices=["zenoh", "inproc"], help="ROS transport")
    parser.add_argument("--robot", action="append", default=[],
                        help="spawn a robot: NAME=URI[?xacro_arg=value...] (repeatable)")
    parser.add_argument("--play", action="store_true", help="start playing in real time instead of paused")
    parser.add_argument("--real-time-factor", type=float, default=1.0,
                        help="speed when playing: 1.0 = wall clock, <= 0 = as fast as possible")
    parser.add_argument("--timestep", type=float, help="physics time step in seconds")
    parser.add_argument("--gui", action="store_true", help="open the interactive MuJoCo viewer")
    parser.add_argument("--log-level", default="INFO")
    opts = parser.parse_args(argv)
    logging.basicConfig(level=opts.log_level.upper(), format="[%(levelname)s] [%(name)s]: %(message)s")

    ctx = Context(transport=opts.transport).init()
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    node = None
    try:
        node = compose(opts.name, context=ctx, namespace=opts.namespace or None, paused=not opts.play,
                       real_time_factor=opts.real_time_factor, timestep=opts.timestep, gui=opts.gui)
        for spec in opts.robot:
            name, sep, uri = spec.partition("=")
            if not sep:
                parser.error(f"--robot {spec!r} must look like NAME=URI")
            node.spawn_from_cli(name, uri)
        _logger.info("simulation node /%s ready (transport %s)", opts.name, opts.transport)
        while not stop.wait(0.5):
            pass
    finally:
        if node is not None:
            node.destroy_node()
        ctx.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
