"""Start or reach a simulation node: composed in this process, in a child process, or already running.

* :func:`compose` builds a :class:`~multiros.sim.node.SimulationNode` in the calling process.
* :func:`connect` returns a :class:`SimulationConnection` (an env-side node plus a
  :class:`~multiros.sim.client.SimulationClient`) for one of three modes: ``"composed"`` (own
  context, in-process transport: the fast, isolated default), ``"process"`` (a child process over
  Zenoh, stopped by PID on close) or ``"existing"`` (a node someone else runs).
* :func:`main` is the ``uniros-sim`` command (also ``python -m multiros.sim.launch``).

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

import argparse
import contextlib
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

from multiros.ros import Context, Node, native_memory
from multiros.ros.exceptions import TransportError
from multiros.ros.names import split_ros_arguments
from multiros.ros.processes import (
    DISCOVERY_RANGE_ENV,
    STATIC_PEERS_ENV,
    add_child_options,
    child_environment,
    discovery_environment,
    free_loopback_endpoint,
    owner_log_level,
    private_context,
    private_dds_context,
    private_environment,
    start_child_program,
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
__all__ = ["SimulationConnection", "compose", "connect", "free_loopback_endpoint", "local_description_dirs", "main",
           "private_context", "robot_resource"]
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
                floor_color=floor_color, **_trust_kwargs(trusted_paths),
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


def _trust_kwargs(trusted_paths: Sequence[str | os.PathLike[str]]) -> dict[str, Any]:
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
    argv = [sys.executable, "-m", "multiros.sim.launch", "--name", node_name.lstrip("/"), "--transport",
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


def _parser() -> argparse.ArgumentParser:
    from multiros.sim.world_model import FLOOR_COLORS

    parser = argparse.ArgumentParser(
        prog="uniros-sim",
        description="Run the uniros MuJoCo simulation node. It reports ready (a log line, and its services "
                    "start answering) only once every --robot is spawned.",
        epilog="ROS arguments go to rcl as for any ROS 2 program: --ros-args [--enclave E] [-r from:=to] "
               "[--log-level L] [--]. Over rclpy, DDS discovery stays on this machine unless "
               "ROS_AUTOMATIC_DISCOVERY_RANGE says otherwise (SUBNET: the LAN).",
    )
    parser.add_argument("--name", default=DEFAULT_NODE_NAME, help="node name (default: %(default)s)")
    parser.add_argument("--namespace", default="", help="node namespace")
    parser.add_argument("--transport", default=None, choices=["zenoh", "rclpy", "inproc"],
                        help="ROS transport (default: $UNIROS_TRANSPORT, else rclpy when rclpy can be imported: "
                             "your own ROS 2 graph on its default middleware; else zenoh). inproc: a node no "
                             "other process can reach (to watch with --gui)")
    parser.add_argument("--robot", action="append", default=[],
                        help="spawn a robot at launch: NAME=URI[?xacro_arg=value...] (repeatable); "
                             "ResetSimulation with SCOPE_ALL brings it back")
    parser.add_argument("--play", action="store_true", help="start playing in real time instead of paused")
    parser.add_argument("--real-time-factor", type=float, default=1.0,
                        help="speed when playing: 1.0 = wall clock, <= 0 = as fast as possible")
    parser.add_argument("--timestep", type=float, help="physics time step in seconds")
    parser.add_argument("--gui", action="store_true", help="open the interactive MuJoCo viewer")
    parser.add_argument("--floor-color", default=None, choices=sorted(FLOOR_COLORS),
                        help="the floor's tiles in rendered images (default: light); a pale arm seen from "
                             "pixels stands out on dark")
    parser.add_argument("--router", default=None,
                        help="Zenoh router: 'auto' (default: use the one at $UNIROS_ZENOH_ROUTER or "
                             "tcp/127.0.0.1:7447, start one there if none listens), 'embedded', 'none', "
                             "or an endpoint such as tcp/127.0.0.1:7448")
    parser.add_argument("--trust-path", action="append", default=[], metavar="DIR",
                        help="a directory besides the package roots from which spawn requests may read "
                             "description files (repeatable)")
    parser.add_argument("--allow-xacro-strings", action="store_true",
                        help="run xacro on descriptions that arrive as request strings (xacro evaluates "
                             "Python expressions: only on a trusted network)")
    parser.add_argument("--max-steps-per-call", type=int, default=None, metavar="N",
                        help="largest step count one StepSimulation/StepRobot request may ask for "
                             "(default 100000); larger requests are refused")
    parser.add_argument("--max-robots", type=int, default=None, metavar="N",
                        help="most robots this node holds (default 256); SpawnEntity refuses more")
    parser.add_argument("--max-entities", type=int, default=None, metavar="N",
                        help="most entities (robots and objects, every client together) this node holds "
                             "(default 4 per robot it accepts + 64); SpawnEntity refuses more")
    parser.add_argument("--max-entities-per-client", type=int, default=None, metavar="N",
                        help="entities one client may hold besides 4 per robot it holds (default 12, at least 1); "
                             "SpawnEntity refuses more")
    parser.add_argument("--frame-prefix", default=None, metavar="PREFIX",
                        help="TF frame prefix of every entity's links: '' (default) the URDF's link names as "
                             "robot_state_publisher publishes them, '{entity}/' each entity's name first")
    parser.add_argument("--camera-rate", type=float, default=None, metavar="HZ",
                        help="images per second of each subscribed camera topic whose sensor sets no "
                             "<update_rate> (default 15), rendered beside the physics")
    add_child_options(parser)
    return parser


def _service_history_profile(transport: str) -> contextlib.AbstractContextManager[bool]:
    """Over rclpy on Fast DDS: service requests freed once taken (``transport/rclpy/fastdds_profile.py``)."""
    if transport != "rclpy":
        return contextlib.nullcontext(False)
    from multiros.ros.transport.rclpy.fastdds_profile import service_history_profile

    return service_history_profile()


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros-sim``: run the simulation node standalone until interrupted."""
    native_memory.configure_node_process()  # before the node's threads allocate (multiros/ros/native_memory.py)
    parser = _parser()
    own, ros_args = split_ros_arguments(sys.argv[1:] if argv is None else list(argv))
    opts = parser.parse_args(own)
    robots = []
    for spec in opts.robot:
        name, sep, uri = spec.partition("=")
        if not sep or not name:
            parser.error(f"--robot {spec!r} must look like NAME=URI")
        robots.append((name, uri))

    if opts.gui:
        from multiros.sim.render import display_available

        if not display_available():
            parser.error("--gui opens MuJoCo's viewer, which needs a display (DISPLAY or WAYLAND_DISPLAY is not "
                         "set): drop --gui to run the node headless")
    transport_options: dict[str, Any] = {}
    if opts.router:
        transport_options["router"] = opts.router
    stop = start_child_program(opts)
    opts.transport = wire_transport(opts.transport)
    env = discovery_environment()
    try:
        ctx = Context(transport=opts.transport, env=env,
                      **(transport_options if opts.transport == "zenoh" else {})).init(ros_args)
    except (TransportError, ValueError) as exc:
        parser.exit(2, f"uniros-sim: {exc}\n")
    if opts.transport == "inproc":
        _logger.warning("transport inproc: no other process can reach this node (it serves this program alone: "
                        "watch it with --gui); for clients choose zenoh or rclpy")
    if opts.transport == "rclpy" and not os.environ.get(DISCOVERY_RANGE_ENV, "").strip():
        _logger.info("DDS discovery on this machine only (%s=LOCALHOST); set %s=SUBNET to reach other hosts",
                     DISCOVERY_RANGE_ENV, DISCOVERY_RANGE_ENV)
    node_options: dict[str, Any] = dict(_trust_kwargs(opts.trust_path))
    if opts.allow_xacro_strings:
        node_options["allow_xacro_strings"] = True
    for limit in ("max_steps_per_call", "max_robots", "max_entities", "max_entities_per_client"):
        value = getattr(opts, limit)
        if value is not None:
            if value < 1:
                parser.error(f"--{limit.replace('_', '-')} must be a positive integer")
            node_options[limit] = value
    if opts.frame_prefix is not None:
        from multiros.sim.tf_publisher import check_frame_prefix

        try:
            node_options["frame_prefix"] = check_frame_prefix(opts.frame_prefix)
        except ValueError as exc:
            parser.error(str(exc))
    if opts.camera_rate is not None:
        if not opts.camera_rate > 0 or opts.camera_rate == float("inf"):
            parser.error("--camera-rate must be a positive number of images per second")
        node_options["camera_rate"] = opts.camera_rate
    node = None
    try:
        with _service_history_profile(opts.transport):  # the participant is created with the first node
            node = compose(opts.name, context=ctx, namespace=opts.namespace or None, paused=not opts.play,
                           real_time_factor=opts.real_time_factor, timestep=opts.timestep, gui=opts.gui,
                           floor_color=opts.floor_color, serve=False, **node_options)
        for name, uri in robots:
            node.spawn_from_cli(name, uri)
        node.mark_launched()
        node.start_serving()
        _logger.info("simulation node %s ready (transport %s, robots: %s)", node.get_fully_qualified_name(),
                     opts.transport, ", ".join(n for n, _ in robots) or "none")
        while not stop.wait(0.5):
            pass
    except TransportError as exc:  # e.g. an interface package rclpy lacks: say which and how to get it
        _logger.error("%s", exc)
        return 2
    except RuntimeError as exc:  # a robot could not be spawned: say why, exit non-zero
        _logger.error("%s", exc)
        return 1
    finally:
        if node is not None:
            node.destroy_node()
        ctx.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
