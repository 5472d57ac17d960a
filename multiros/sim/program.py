"""The ``uniros-sim`` program: a simulation node run standalone until interrupted.

Also ``python -m multiros.sim.program`` (the form :func:`multiros.sim.launch.connect` starts its child
nodes with). Its options are the node's own (robots at launch, limits, trust), the child options every
uniros program shares (``--owner-pid``, ``--log-level``: :func:`multiros.ros.processes.add_child_options`)
and ROS arguments after ``--ros-args``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from collections.abc import Sequence
from typing import Any

from multiros.ros import Context, native_memory
from multiros.ros.exceptions import TransportError
from multiros.ros.names import split_ros_arguments
from multiros.ros.processes import DISCOVERY_RANGE_ENV, add_child_options, discovery_environment, start_child_program
from multiros.ros.transport import wire_transport
from multiros.sim.client import DEFAULT_NODE_NAME
from multiros.sim.launch import compose, trust_kwargs

_logger = logging.getLogger(__name__)
__all__ = ["main"]


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
    node_options: dict[str, Any] = dict(trust_kwargs(opts.trust_path))
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
