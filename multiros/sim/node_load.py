"""The simulation node's load: physics steps per second, busy time, memory; served as ``~/get_node_load``.

A node serves robots of several clients at once; a client sizing a batch (or an operator watching
a shared node) asks ``uniros_interfaces/srv/GetNodeLoad`` how many robots the node holds, how many
it accepts (``max_robots``), how fast its physics runs and how much memory it uses.
"""

from __future__ import annotations

import collections
import os
import time
from typing import TYPE_CHECKING, Any

from multiros.sim.node_results import ok

if TYPE_CHECKING:
    from multiros.sim.node import SimulationNode

_WINDOW_SEC = 5.0  # physics rate and busy fraction are measured over this many recent seconds
_MAX_EVENTS = 4096  # bound on the recorded step calls inside the window


class LoadMeter:
    """Physics steps and time spent stepping, over a sliding window of recent step calls."""

    def __init__(self, window_sec: float = _WINDOW_SEC) -> None:
        self.window_sec = float(window_sec)
        self.total_steps = 0
        self._events: collections.deque[tuple[float, int, float]] = collections.deque(maxlen=_MAX_EVENTS)

    def record(self, steps: int, busy_sec: float) -> None:
        """One step call: ``steps`` physics steps that took ``busy_sec`` seconds."""
        self.total_steps += int(steps)
        self._events.append((time.monotonic(), int(steps), float(busy_sec)))

    def rates(self) -> tuple[float, float]:
        """``(physics steps per second, busy fraction)`` over the window (0 when idle)."""
        now = time.monotonic()
        recent = [e for e in self._events if now - e[0] <= self.window_sec]
        if not recent:
            return 0.0, 0.0
        span = max(now - recent[0][0] + recent[0][2], 1e-3)
        steps = sum(e[1] for e in recent)
        busy = sum(e[2] for e in recent)
        return steps / span, min(1.0, busy / span)


def process_rss_bytes() -> int:
    """Resident memory of this process in bytes (0 where ``/proc`` is not available)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def get_node_load(node: SimulationNode, request: Any, response: Any) -> Any:
    """``uniros_interfaces/srv/GetNodeLoad``."""
    with node.lock:
        world = node.world
        response.robots = len(node._robots)
        response.entities = len(world.entity_names())
        response.model_bytes = int(world.model.nbuffer + world.data.nbuffer + world.data.narena)
    response.max_robots = node.max_robots
    response.physics_steps = node.load.total_steps
    response.physics_steps_per_sec, response.busy_fraction = node.load.rates()
    response.process_rss_bytes = process_rss_bytes()
    ok(response.result)
    return response
