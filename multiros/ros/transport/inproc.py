"""``inproc``: nodes composed in one process, no network at all.

Everything is done by the context's ``LocalRegistry``; this transport only reports the
registry as the graph.
"""

from __future__ import annotations

from multiros.ros.graph import Endpoint
from multiros.ros.transport.base import Transport

__all__ = ["InprocTransport"]


class InprocTransport(Transport):
    """The no-network transport (default)."""

    name = "inproc"

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def endpoints(self) -> list[Endpoint]:
        return self.context.registry.endpoints()

    def count(self, kind: str, name: str) -> int:
        return self.context.registry.count(kind, name)

    def graph_version(self) -> int | None:
        return self.context.registry.version
