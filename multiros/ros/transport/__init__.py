"""Transports behind one seam (``base.Transport``): ``inproc`` (default) and ``zenoh``."""

from __future__ import annotations

from typing import TYPE_CHECKING

from multiros.ros.exceptions import TransportError
from multiros.ros.transport.base import Transport

if TYPE_CHECKING:
    from multiros.ros.context import Context

__all__ = ["Transport", "make_transport", "TRANSPORTS"]

TRANSPORTS = ("inproc", "zenoh")


def make_transport(name: str, context: Context) -> Transport:
    """The transport called ``name`` for ``context`` (imported lazily).

    Raises:
        TransportError: unknown name.
    """
    if name == "inproc":
        from multiros.ros.transport.inproc import InprocTransport

        return InprocTransport(context)
    if name == "zenoh":
        from multiros.ros.transport.zenoh import ZenohTransport

        return ZenohTransport(context)
    raise TransportError(
        f"unknown transport {name!r}: use one of {', '.join(TRANSPORTS)} "
        "(argument transport=... or environment variable UNIROS_TRANSPORT)"
    )
