"""Making and closing envs in a loop keeps no memory: nothing per env outlives its ``close()``.

Each env used to leave about 17 KB behind (its node's ``logging`` logger, kept by ``logging`` for
good, and the documents of every xacro run); a training script that makes an env per evaluation
grew without end.
"""

from __future__ import annotations

import gc
import logging
import tracemalloc

import pytest
import xacro

import uniros

ENV = "RX200ReacherGoalSim-v0"
WARM_UP, CYCLES = 6, 24
MAX_BYTES_PER_CYCLE = 2048  # caches still settling (importlib's, MuJoCo's); a leak per env was ~17 KB


def _cycle() -> None:
    env = uniros.make(ENV)
    env.reset(seed=0)
    env.close()


@pytest.mark.slow
def test_make_close_cycles_keep_no_memory() -> None:
    for _ in range(WARM_UP):
        _cycle()
    gc.collect()
    loggers, includes = len(logging.Logger.manager.loggerDict), len(xacro.all_includes)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(CYCLES):
            _cycle()
        gc.collect()
        growth = (tracemalloc.get_traced_memory()[0] - before) / CYCLES
    finally:
        tracemalloc.stop()
    assert len(logging.Logger.manager.loggerDict) == loggers  # no logger per env node
    assert len(xacro.all_includes) == includes  # xacro's global list of included files
    assert growth < MAX_BYTES_PER_CYCLE, f"{growth:.0f} bytes kept per make/close"
