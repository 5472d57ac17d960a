"""Transports behind one seam (``base.Transport``): ``inproc`` (default), ``zenoh`` and ``rclpy``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import TYPE_CHECKING

from multiros.ros.exceptions import TransportError
from multiros.ros.transport.base import Transport

if TYPE_CHECKING:
    from multiros.ros.context import Context

__all__ = ["Transport", "make_transport", "wire_transport", "TRANSPORTS", "WIRE_TRANSPORTS"]

TRANSPORTS = ("inproc", "zenoh", "rclpy")
#: Transports that reach other processes.
WIRE_TRANSPORTS = ("zenoh", "rclpy")


def wire_transport(explicit: str | None = None, *, prefer_rclpy: bool = True,
                   env: Mapping[str, str] | None = None) -> str:
    """The transport of a program that other processes must reach (``uniros-sim``, a Real env, ...).

    An explicit choice wins, then ``$UNIROS_TRANSPORT``; without either, ``rclpy`` when rclpy can be
    imported and ``prefer_rclpy`` (a ROS user's own graph, on their default middleware), else
    ``zenoh``. Finding rclpy loads nothing, so this never trips rcl's ``RMW_IMPLEMENTATION`` check.
    """
    source = os.environ if env is None else env
    chosen = (explicit or source.get("UNIROS_TRANSPORT") or "").strip().lower()
    if chosen:
        return chosen
    if prefer_rclpy:
        from multiros.ros.transport.rclpy.loader import rclpy_available

        if rclpy_available():
            return "rclpy"
    return "zenoh"


def make_transport(name: str, context: Context) -> Transport:
    """The transport called ``name`` for ``context`` (imported lazily).

    Raises:
        TransportError: unknown name.
        UnsupportedDistroError: a transport that reaches peers (zenoh, rclpy) while ``ROS_DISTRO``
            names a distribution uniros cannot speak to (Humble).
    """
    if name == "inproc":
        from multiros.ros.transport.inproc import InprocTransport

        return InprocTransport(context)
    if name in WIRE_TRANSPORTS:
        from multiros.ros.interfaces import require_peer_distro

        require_peer_distro(f"the {name} transport reaches other ROS 2 programs with ROS_DISTRO's interfaces")
    if name == "zenoh":
        from multiros.ros.transport.zenoh import ZenohTransport

        return ZenohTransport(context)
    if name == "rclpy":
        from multiros.ros.transport.rclpy import RclpyTransport

        return RclpyTransport(context)
    raise TransportError(
        f"unknown transport {name!r}: use one of {', '.join(TRANSPORTS)} "
        "(argument transport=... or environment variable UNIROS_TRANSPORT)"
    )
