"""A simulation world's memory over spawn-and-delete cycles, with the world's spec rebuilt every 10 deletions
(``multiros.sim.world._REBUILD_EVERY``, the default) and without (the spec MuJoCo keeps growing).

Each cycle spawns an entity into a world that holds a free box, steps it twice and deletes it; the resident
memory is read after cycle 10 and after the last, and the growth per cycle printed, for an RX200 and for a
499-joint robot (``bench_entity_delete.py``'s). Issue 52 measured the node at ~3.5 MB a cycle for the latter.

    .venv/bin/python benchmarks/bench_spawn_delete_memory.py --cycles 60
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import os
from pathlib import Path

import multiros.sim.world as world_module
from multiros.sim.packages import default_index
from multiros.sim.world import World, WorldOptions

RX200 = "package://rx200_description/urdf/rx200.urdf.xacro"


def _rss_mb() -> float:
    with open(f"/proc/{os.getpid()}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def _wide_urdf(joints: int) -> str:
    path = Path(__file__).with_name("bench_entity_delete.py")
    spec = importlib.util.spec_from_file_location("bench_entity_delete", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.wide_urdf(joints)


def growth(description: str, cycles: int, rebuild: bool, **spawn: object) -> tuple[float, float]:
    """KB of resident memory per cycle over cycles 10 to ``cycles``, and the memory at the end (MB)."""
    world_module._REBUILD_EVERY = 10 if rebuild else 10**9
    world = World(WorldOptions(), package_index=default_index())
    world.spawn("box", "<mujoco><worldbody><body name='b'><freejoint/><geom type='box' size='0.1 0.1 0.1'/>"
                       "</body></worldbody></mujoco>", pose=([2, 0, 0.1], [1, 0, 0, 0]))
    start = 0.0
    for i in range(cycles):
        world.spawn("visitor", description, **spawn)  # type: ignore[arg-type]
        world.step(2)
        world.delete("visitor")
        if i == 10:
            gc.collect()
            start = _rss_mb()
    gc.collect()
    end = _rss_mb()
    world.close()
    return (end - start) / (cycles - 11) * 1000, end


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cycles", type=int, default=60)
    args = parser.parse_args()
    cases = [("RX200", RX200, {"xacro_args": {"robot_name": "visitor"}}), ("499 joints", _wide_urdf(499), {})]
    print(f"{'entity':12} {'spec':10} {'KB/cycle':>9} {'RSS MB':>7}")
    for label, description, spawn in cases:
        for rebuild in (False, True):
            per_cycle, end = growth(description, args.cycles, rebuild, **spawn)
            print(f"{label:12} {'rebuilt' if rebuild else 'kept':10} {per_cycle:9.0f} {end:7.0f}", flush=True)


if __name__ == "__main__":
    main()
