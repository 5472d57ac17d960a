"""Process memory (RSS) left behind per make/reset/close cycle, after a warm-up: issue 38's probe.

Three loops in one process, each after a warm-up of its own: ``uniros.make_vec(ID, 4)`` (worker
processes, the default), a composed env with a camera observation (64 x 64 RGB), and a composed env.
RSS includes native memory (MuJoCo, the GL driver) that ``tracemalloc`` does not see
(``tests/envs/test_make_close_memory.py`` checks the Python side); the allocator may keep freed memory
for a while, so compare loops of the same length, and try ``MALLOC_ARENA_MAX=1`` to see steady growth.

    MUJOCO_GL=egl python benchmarks/bench_make_close_memory.py [--cycles 40] [--warm-up 5] [--loops camera]

The camera env's RSS climbs for the first 20-30 cycles (the software GL driver's and the allocator's
pools) and then stays: measure it after a longer warm-up too (``--loops camera --warm-up 30 --cycles 60``).
"""

from __future__ import annotations

import argparse
import gc
import os
import time
from collections.abc import Callable

import uniros

ENV = "RX200ReacherGoalSim-v0"


def rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def vector_cycle() -> None:
    env = uniros.make_vec(ENV, 4)
    env.reset(seed=0)
    env.close()


def camera_cycle() -> None:
    env = uniros.make("RX200ReacherSim-v0", rgb_obs_only=True, image_width=64, image_height=64)
    env.reset(seed=0)
    env.close()


def plain_cycle() -> None:
    env = uniros.make(ENV)
    env.reset(seed=0)
    env.close()


def measure(cycle: Callable[[], None], warm_up: int, cycles: int) -> tuple[float, float]:
    """KB of RSS per cycle and the seconds the cycles took."""
    for _ in range(warm_up):
        cycle()
    gc.collect()
    before, t0 = rss(), time.perf_counter()
    for _ in range(cycles):
        cycle()
    gc.collect()
    return (rss() - before) / cycles / 1024, time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cycles", type=int, default=40)
    parser.add_argument("--warm-up", type=int, default=5,
                        help="cycles before measuring (the camera env's RSS climbs for 20-30 cycles, then stays)")
    parser.add_argument("--loops", nargs="+", choices=("vector", "camera", "plain"),
                        default=["vector", "camera", "plain"])
    opts = parser.parse_args()
    loops = {"vector": (f"make_vec({ENV}, 4)", vector_cycle), "camera": ("camera env (64 x 64 RGB)", camera_cycle),
             "plain": (f"composed {ENV}", plain_cycle)}
    for name, cycle in (loops[k] for k in opts.loops):
        per_cycle, seconds = measure(cycle, opts.warm_up, opts.cycles)
        print(f"{name}: {per_cycle:.1f} KB RSS per make/close over {opts.cycles} cycles ({seconds:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
