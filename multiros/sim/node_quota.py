"""Per-client quotas on the simulation node's entities: who spawned what, and what each may still spawn.

Every entity in a shared world costs every owner's physics steps, so one client must not fill the
world. Each entity spawned through SpawnEntity records the client that asked for it
(:func:`multiros.ros.service.current_caller`), and SpawnEntity refuses, with one line naming the
limit, the count and the fix:

* any entity beyond ``max_entities`` in the node (robots and objects, every client together);
* a robot beyond ``max_robots`` in the node;
* an entity beyond the caller's quota: ``max_entities_per_client`` plus
  :data:`~multiros.sim.limits.ENTITIES_PER_ROBOT` for each robot the caller holds (a robot brings
  its scene: a vector env of N pick-and-place robots on one client fits whatever N).

The quotas and ``max_entities`` are checked before the description is loaded, ``max_robots`` once it
is (robot or object known), and all of them again under the node's lock just before the newcomer
is compiled and at its commit: a spawn refused by a quota costs a few dictionary lookups, not a load
or a compile.
Deleting an entity (or a reset removing it) frees its owner's quota.

A spawn the world itself refuses (a model that does not compile, an admission refusal: overlap,
landing, divergence, bad controllers) costs a compile and a trial on the cores every owner steps on
(beside the node's lock: :mod:`multiros.sim.world_prepare`).
So such refusals are counted per client: after :data:`REFUSALS_BEFORE_BACKOFF` in a row, that client's
next spawns are refused before any load or lock for a cool-down (1 s, doubling with each further
refusal, at most 60 s), with one warning in the node's log per cool-down; an admitted spawn ends the
streak. A loop of refused spawns then costs the others a compile every few seconds, not back to back.

The caller's identity comes from the wire and serves accounting only: a peer that names itself anew
per request escapes its per-client quota, not ``max_entities``. Callers a transport cannot name
(``None``) share one quota. Entities the node's owner spawned itself (its command line, a world
given at construction) belong to no client and count only towards the node's limits.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Collection
from dataclasses import dataclass

from multiros.sim.limits import ENTITIES_PER_ROBOT

__all__ = ["BACKOFF_FIRST_S", "BACKOFF_MAX_S", "REFUSALS_BEFORE_BACKOFF", "EntityQuota", "describe_caller"]

#: Spawns the world may refuse in a row for one client before it must wait.
REFUSALS_BEFORE_BACKOFF = 3
#: The first cool-down; each further refusal after one doubles it, up to :data:`BACKOFF_MAX_S`.
BACKOFF_FIRST_S = 1.0
BACKOFF_MAX_S = 60.0
_MAX_TRACKED = 1024  # clients whose refusal streaks are remembered (the oldest forgotten first)


@dataclass
class _Streak:
    refused: int = 0
    until: float = 0.0  # monotonic time the cool-down ends
    length: float = 0.0  # the last cool-down's length
    last: str = ""  # the last refusal's reason


def describe_caller(caller: str | None) -> str:
    """How a caller is named in a refusal (``None``: the callers whose identity is unknown)."""
    return "callers of unknown identity (one shared quota)" if caller is None else f"client {caller!r}"


class EntityQuota:
    """The owners of a node's entities and the node's entity limits.

    Args:
        max_entities: most entities in the node.
        max_entities_per_client: entities one client may hold besides :data:`ENTITIES_PER_ROBOT` per robot
            (at least 1: a client's first robot must fit).
        max_robots: most robots in the node.
    """

    def __init__(self, max_entities: int, max_entities_per_client: int, max_robots: int, *,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.max_entities = int(max_entities)
        self.max_entities_per_client = int(max_entities_per_client)
        self.max_robots = int(max_robots)
        self._owners: dict[str, tuple[str | None, bool]] = {}  # entity -> (caller, is a robot)
        self._streaks: OrderedDict[str | None, _Streak] = OrderedDict()
        self._clock = clock
        self._mutex = threading.Lock()

    def cooling_down(self, caller: str | None) -> str | None:
        """Why ``caller`` may not spawn now (its spawns were refused by the world too often), or ``None``."""
        with self._mutex:
            streak = self._streaks.get(caller)
            left = streak.until - self._clock() if streak is not None else 0.0
            if streak is None or left <= 0:
                return None
            return (f"SpawnEntity refused: {describe_caller(caller)} had {streak.refused} spawns in a row refused "
                    f"by the world (the last: {streak.last}); each costs every owner of this node a compile "
                    f"and a trial on its cores, so it may spawn again in {left:.1f} s. Fix the description first")

    def note_refused(self, caller: str | None, reason: str) -> float | None:
        """The world refused a spawn by ``caller`` (``reason``: its one line). Returns the cool-down it
        starts, in seconds, or ``None`` (no cool-down yet)."""
        with self._mutex:
            streak = self._streaks.pop(caller, None) or _Streak()
            self._streaks[caller] = streak  # most recent last
            while len(self._streaks) > _MAX_TRACKED:
                self._streaks.popitem(last=False)
            streak.refused += 1
            streak.last = reason.splitlines()[0][:200] if reason else "no reason given"
            if streak.refused < REFUSALS_BEFORE_BACKOFF:
                return None
            streak.length = min(BACKOFF_MAX_S, streak.length * 2 if streak.length else BACKOFF_FIRST_S)
            streak.until = self._clock() + streak.length
            return streak.length

    def refusals(self, caller: str | None) -> int:
        """Spawns by ``caller`` the world refused in a row (0 after an admitted one)."""
        with self._mutex:
            streak = self._streaks.get(caller)
        return 0 if streak is None else streak.refused

    def note_admitted(self, caller: str | None) -> None:
        """The world took a spawn by ``caller``: its streak of refusals ends."""
        with self._mutex:
            self._streaks.pop(caller, None)

    def held(self, caller: str | None, present: Collection[str]) -> tuple[int, int]:
        """``(entities, robots)`` that ``caller`` spawned and that are among ``present``."""
        with self._mutex:
            mine = [robot for name, (owner, robot) in self._owners.items() if owner == caller and name in present]
        return len(mine), sum(mine)

    def allowance(self, robots: int) -> int:
        """Entities a client holding ``robots`` robots may hold."""
        return self.max_entities_per_client + ENTITIES_PER_ROBOT * robots

    def refusal(self, caller: str | None, robot: bool | None, present: Collection[str], robots: int) -> str | None:
        """Why a spawn by ``caller`` must be refused, or ``None``.

        Args:
            caller: who asks (``current_caller()``).
            robot: whether the newcomer is a robot; ``None`` before its description is loaded (then
                ``max_robots`` is not checked yet; everything else is).
            present: names of the entities in the world now.
            robots: robots in the node now.
        """
        if len(present) >= self.max_entities:
            return (f"SpawnEntity refused: this node holds {len(present)} entities, max_entities="
                    f"{self.max_entities}; delete some (DeleteEntity), spawn on another node, or start this "
                    f"one with a larger max_entities (uniros-sim --max-entities N)")
        if robot and robots >= self.max_robots:
            return (f"this node already holds max_robots={self.max_robots} robots; spawn it on another node, "
                    f"or start this one with a larger max_robots (uniros-sim --max-robots)")
        # Robot or object alike (known before loading): a robot spawned within the quota raises it by
        # ENTITIES_PER_ROBOT, room for itself and its scene.
        held, own_robots = self.held(caller, present)
        allowance = self.allowance(own_robots)
        if held < allowance:
            return None
        return (f"SpawnEntity refused: {describe_caller(caller)} holds {held} entities on this node, its quota "
                f"is {allowance} (max_entities_per_client={self.max_entities_per_client} + {ENTITIES_PER_ROBOT} "
                f"per robot it holds x {own_robots}); delete some of them (DeleteEntity), spawn on another node, "
                f"or start this one with a larger quota (uniros-sim --max-entities-per-client N)")

    def record(self, name: str, caller: str | None, robot: bool) -> None:
        """``caller`` spawned ``name`` (call under the node's lock, after the world took it)."""
        with self._mutex:
            self._owners[name] = (caller, bool(robot))

    def prune(self, present: Collection[str]) -> None:
        """Forget the owners of entities no longer in the world (deleted, reset away, removed as
        unstable): their quota is free again. Call under the node's lock."""
        with self._mutex:
            for name in [n for n in self._owners if n not in present]:
                del self._owners[name]

    def owner(self, name: str) -> str | None:
        """The client that spawned ``name`` (``None``: unknown, or the node's owner)."""
        with self._mutex:
            entry = self._owners.get(name)
        return None if entry is None else entry[0]

    def counts(self, present: Collection[str]) -> dict[str | None, int]:
        """Entities per client among ``present`` (the node's own are not listed)."""
        out: dict[str | None, int] = {}
        with self._mutex:
            for name, (owner, _robot) in self._owners.items():
                if name in present:
                    out[owner] = out.get(owner, 0) + 1
        return out
