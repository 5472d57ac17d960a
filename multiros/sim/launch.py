"""Start or reach a simulation node: composed in this process, in a child process, or already running.

* :func:`compose` builds a :class:`~multiros.sim.node.SimulationNode` in the calling process.
* :func:`connect` returns a :class:`SimulationConnection` (an env-side node plus a
  :class:`~multiros.sim.client.SimulationClient`) for one of three modes: ``"composed"`` (own
  context, in-process transport: the fast, isolated default), ``"process"`` (a child process over
  Zenoh, stopped by PID on close) or ``"existing"`` (a node someone else runs).
* The ``uniros-sim`` command that runs a node standalone is :mod:`multiros.sim.program`.

Readiness is signalled, never slept for: a child process is ready when its services answer.

Isolation (``process`` mode): the env's context starts a **private Zenoh router** on a free
loopback port and the child node joins only that router, so several owners on one machine (scripts,
vector envs, SB3's ``SubprocVecEnv`` workers, test suites) never see each other's nodes, whatever
router or ``ROS_DOMAIN_ID`` the user's shell points at. Over rclpy (DDS: no router, no
authentication without SROS2) the env's context and the child take a **domain of their own**, one no
participant on this machine uses, with discovery on this machine only, and the child node a name of
its own (``<node_name>_<owner pid>_<n>``): strangers on the user's domain or on other hosts never
see it, and two owners never share or clash (``multiros.ros.processes.private_dds_context``). The
child watches its owner and exits within about a second of the owner's death, whatever signal ended
it. ``isolated=False`` joins the user's graph instead (router and domain from the environment), for
a child that ROS tools should see. ``existing`` mode and ``uniros-sim`` keep the ROS conventions: a
named node on the user's domain (``uniros-sim`` with discovery on this machine only unless
``ROS_AUTOMATIC_DISCOVERY_RANGE`` says otherwise).
"""

from __future__ import annotations

import gc
import itertools
import logging
import os
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any
from urllib.parse import urlencode

from multiros.ros import Context, Node
from multiros.ros.processes import (
    DISCOVERY_RANGE_ENV,
    STATIC_PEERS_ENV,
    child_environment,
    free_loopback_endpoint,
    owner_log_level,
    private_context,
    private_dds_context,
    private_environment,
    stop_process,
    track_child,
    untrack_child,
)
from multiros.ros.transport import WIRE_TRANSPORTS, wire_transport
from multiros.sim.client import DEFAULT_NODE_NAME, SimulationClient, SimulationNodeError

if TYPE_CHECKING:
    from multiros.sim.stepper import RobotStepper

_logger = logging.getLogger(__name__)
_env_ids = itertools.count()
_private_names = itertools.count()
__all__ = ["SimulationConnection", "compose", "connect", "free_loopback_endpoint", "local_description_dirs",
           "private_context", "robot_resource", "trust_kwargs"]
def compose(
    node_name: str = DEFAULT_NODE_NAME,
    *,
    context: Context | None = None,
    transport: str | None = None,
    paused: bool = True,
    real_time_factor: float = 1.0,
    timestep: float | None = None,
    gui: bool = False,
    floor_color: str | None = None,
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
        floor_color: the floor in rendered images, ``"light"`` (default) or ``"dark"``
            (:class:`~multiros.sim.world.WorldOptions`).
    """
    from multiros.sim.node import SimulationNode
    from multiros.sim.world import WorldOptions
    from multiros.sim.world_model import check_floor_color

    if context is None:
        context = Context(transport=transport).init()
    world: dict[str, Any] = {} if timestep is None else {"timestep": timestep}
    if floor_color is not None:
        world["floor_color"] = check_floor_color(floor_color)
    options = WorldOptions(**world)
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

    def stepper(self, timeout_sec: float | None = None) -> RobotStepper:
        """How to step robots on this node: directly when it is composed in this process, else over
        its services (:mod:`multiros.sim.stepper`)."""
        from multiros.sim.stepper import ComposedStepper, ServiceStepper

        if self.sim_node is not None:
            return ComposedStepper(self.sim_node)
        return ServiceStepper(self.client, timeout_sec)

    def trust(self, paths: Sequence[str]) -> None:
        """Let the node read local robot files under ``paths`` (see :meth:`SimulationNode.trust_paths`):
        a composed node only; a node in another process keeps the trusted paths it started with."""
        if self.sim_node is not None and paths:
            self.sim_node.trust_paths(paths)

    def show_viewer(self) -> None:
        """Open (or refresh) the interactive viewer of a composed node."""
        if self.sim_node is None:
            raise SimulationNodeError("the viewer is only available for a composed node (sim_mode='composed')")
        self.sim_node.open_viewer()

    def read_camera(self, camera: str, *, rgb: bool = True, depth: bool = False, width: int | None = None,
                    height: int | None = None) -> Any:
        """A camera's images of the world now, as a :class:`~multiros.sim.cameras.CameraFrame`.

        A composed node hands over the very pixels its camera topics carry (no messages, no copy);
        a node in another process renders them through its ``RenderCamera`` service (the sensor's
        size unless given, else 640 x 480; ``intrinsics`` is then None).

        Raises:
            multiros.sim.errors.RenderError: (composed) an unknown camera, a bad size, or no GL.
            SimulationServiceError: (other modes) the node refused the render.
        """
        if self.sim_node is not None:
            return self.sim_node.read_camera(camera, rgb=rgb, depth=depth, width=width, height=height)
        from multiros.sim.cameras import CameraFrame

        w, h = int(width or 640), int(height or 480)
        color = self.client.render(camera, w, h) if rgb else None
        distance = self.client.render(camera, w, h, depth=True) if depth else None
        return CameraFrame(camera, float("nan"), color, distance, None)

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
                stop_process(self.process)
                untrack_child(self.process)
            if self._owns_context:
                self.context.try_shutdown()
            if self.sim_node is not None:
                # A composed node's world holds MuJoCo's native memory in reference cycles, which Python's
                # collector counts as a few small objects: a process that makes and closes envs grew by
                # ~0.3-0.7 MB a cycle until a full collection ran. Let go of the node and collect once now.
                self.sim_node = None
                gc.collect()


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
    floor_color: str | None = None,
    context: Context | None = None,
    isolated: bool = True,
    trusted_paths: Sequence[str | os.PathLike[str]] = (),
) -> SimulationConnection:
    """Reach a simulation node and return a :class:`SimulationConnection`.

    Args:
        mode: ``"composed"``, ``"process"`` or ``"existing"``.
        node_name: the simulation node's name (``/`` prefix optional).
        transport: ``"inproc"`` (composed only), ``"zenoh"`` or ``"rclpy"``. Default: inproc when
            composed; zenoh for ``process`` (a private router), unless ``$UNIROS_TRANSPORT`` names
            another; for ``existing`` the same choice as ``uniros-sim``'s (``$UNIROS_TRANSPORT``, else
            rclpy when it can be imported, else zenoh).
        gui: open the viewer (composed and process modes).
        timeout_sec: how long to wait for the node to become ready.
        paused, real_time_factor, timestep: start-up options of a node this call starts.
        floor_color: the floor in rendered images of a node this call starts, ``"light"`` or
            ``"dark"`` (ValueError for ``existing``: that node's floor is its own).
        context: join this context instead of creating one (the caller then owns its shutdown).
        isolated: ``process`` mode: give the child a graph of its own (the default). Over Zenoh a
            private router on a free loopback port, closed by a secret, so no other process on the
            machine sees it or is seen by it; over rclpy a free domain id with discovery on this
            machine only, and a node name of its own (``<node_name>_<pid>_<n>``).
            ``False`` joins the graph the environment names (``UNIROS_ZENOH_ROUTER``,
            ``ROS_DOMAIN_ID``, ``ZENOH_*``); pick a ``node_name`` nobody else uses then.
        trusted_paths: directories (besides the package roots) from which a node this call starts
            may read description files, e.g. the folder of your own robot's URDF.
    """
    if mode not in ("composed", "process", "existing"):
        raise ValueError(f"sim_mode {mode!r} is not one of 'composed', 'process', 'existing'")
    if floor_color is not None:
        from multiros.sim.world_model import check_floor_color

        check_floor_color(floor_color)
        if mode == "existing":
            raise ValueError(f"floor_color={floor_color!r} sets the floor of a node this env starts; the existing "
                             "node keeps its own (start it with uniros-sim --floor-color)")
    if mode != "composed" and transport == "inproc":
        raise ValueError(f"sim_mode {mode!r} needs a wire transport; use transport='zenoh' or 'rclpy'")
    if mode == "composed":
        transport = transport or "inproc"
    else:  # a node we start is ours (Zenoh unless asked); one that exists is in the user's graph
        transport = wire_transport(transport, prefer_rclpy=mode == "existing")
        transport = transport if transport in WIRE_TRANSPORTS else "zenoh"
    owns = context is None
    if context is not None:
        ctx = context
    elif mode == "process" and isolated and transport == "zenoh":
        ctx = private_context()
    elif mode == "process" and isolated and transport == "rclpy":
        ctx = private_dds_context()
        node_name = f"{node_name.strip('/')}_{os.getpid()}_{next(_private_names)}"
    else:
        ctx = Context(transport=transport).init()
    sim_node = None
    process = None
    node = None
    try:
        if mode == "composed":
            sim_node = compose(
                node_name, context=ctx, paused=paused, real_time_factor=real_time_factor, timestep=timestep, gui=gui,
                floor_color=floor_color, **trust_kwargs(trusted_paths),
            )
        elif mode == "process":
            process = _spawn_child(ctx, node_name, gui=gui, paused=paused, real_time_factor=real_time_factor,
                                   timestep=timestep, private=isolated and context is None and transport == "zenoh",
                                   trusted_paths=trusted_paths, floor_color=floor_color)
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
            stop_process(process)
        if owns:
            ctx.try_shutdown()
        raise


def trust_kwargs(trusted_paths: Sequence[str | os.PathLike[str]]) -> dict[str, Any]:
    """The node's keyword for the folders ``trusted_paths`` (none when there are none)."""
    return {"trusted_paths": [os.fspath(p) for p in trusted_paths]} if trusted_paths else {}


def local_description_dirs(*locations: str | os.PathLike[str] | None) -> list[str]:
    """Folders of the local files among ``locations`` (not ``package://`` URIs, not XML text).

    A node started for an env may read description files only from package roots and from
    folders it is told to trust: these are the folders of the user's own robot and controller files.
    """
    dirs: list[str] = []
    for location in locations:
        if location is None:
            continue
        text = os.fspath(location).strip()
        if not text or text.startswith("<") or "://" in text and not text.startswith("file://"):
            continue
        path = text[len("file://"):] if text.startswith("file://") else text
        path = path.split("?", 1)[0]
        folder = os.path.dirname(os.path.realpath(path))
        if not os.path.isfile(os.path.realpath(path)) or folder in dirs:
            continue
        if folder in _too_broad_to_trust():
            raise ValueError(
                f"the robot file {path!r} sits directly in {folder!r}; trusting that folder would let spawn "
                "requests read all of it: move the description into a folder (or a ROS package) of its own"
            )
        dirs.append(folder)
    return dirs


def _too_broad_to_trust() -> set[str]:
    """Folders a node must never trust whole (computed per call: ``$HOME`` may change)."""
    return {os.path.realpath(p) for p in ("/", os.path.expanduser("~"), "/tmp", "/home", "/root")}


def _spawn_child(
    ctx: Context, node_name: str, *, gui: bool, paused: bool, real_time_factor: float, timestep: float | None,
    private: bool = False, trusted_paths: Sequence[str | os.PathLike[str]] = (), floor_color: str | None = None,
) -> subprocess.Popen:
    argv = [sys.executable, "-m", "multiros.sim.program", "--name", node_name.lstrip("/"), "--transport",
            ctx.transport_name,
            "--real-time-factor", str(real_time_factor), "--owner-pid", str(os.getpid()),
            "--log-level", owner_log_level()]
    if not paused:
        argv.append("--play")
    if gui:
        argv.append("--gui")
    if timestep is not None:
        argv += ["--timestep", str(timestep)]
    if floor_color is not None:
        argv += ["--floor-color", floor_color]
    for path in trusted_paths:
        argv += ["--trust-path", os.fspath(path)]
    env = private_environment() if private else dict(os.environ)
    if private:
        argv += ["--router", "none"]
    if ctx.transport_name == "rclpy" and ctx.env.get(DISCOVERY_RANGE_ENV) == "LOCALHOST" \
            and STATIC_PEERS_ENV not in ctx.env:
        env.pop(STATIC_PEERS_ENV, None)  # a private DDS graph (private_dds_context): no peers beyond it
    env.update(child_environment(ctx))
    return track_child(subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL))


def robot_resource(
    *,
    robot_model_xml: str | None = None,
    urdf_pkg_name: str | None = None,
    urdf_file_name: str | None = None,
    urdf_folder: str = "/urdf",
    xacro_args: Mapping[str, Any] | Sequence[str] | None = None,
    controllers_file: str | None = None,
    controllers_list: Sequence[str] | None = None,
    joint_positions: Mapping[str, float] | None = None,
) -> tuple[str, str]:
    """The ``(uri, resource_string)`` pair of a ``SpawnEntity`` request for an env's robot.

    A file or ``package://`` location becomes the URI (xacro arguments as its query, which the
    node passes to xacro); XML text becomes the resource string, xacro text expanded here first (the
    node does not run xacro on request text). ``controllers_file`` and
    ``controllers_list`` travel as the reserved query keys ``__controllers_file`` and
    ``__controllers``; ``joint_positions`` (the pose the robot is spawned and reset at, instead of
    the description's ``initial_value`` or zeros) as ``__joint_positions``.
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
    if joint_positions:
        args["__joint_positions"] = ",".join(f"{name}={float(value)!r}" for name, value in joint_positions.items())
    if robot_model_xml.lstrip().startswith("<"):
        # xacro text runs here, in the user's own (trusted) process: the node refuses to run xacro
        # on a request's text, since xacro evaluates Python.
        plain = {k: v for k, v in args.items() if not k.startswith("__")}
        text = robot_model_xml
        if plain or "http://www.ros.org/wiki/xacro" in text:
            from multiros.sim.description import xacro_to_urdf

            text = xacro_to_urdf(robot_model_xml, plain)
        reserved = {k: v for k, v in args.items() if k.startswith("__")}
        if reserved:
            return "string:?" + urlencode(reserved), text
        return "", text
    uri = robot_model_xml
    if args:
        uri += ("&" if "?" in uri else "?") + urlencode(args)
    return uri, ""
