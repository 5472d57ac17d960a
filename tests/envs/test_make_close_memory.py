"""Making and closing envs in a loop keeps no memory: nothing per env outlives its ``close()``.

Each env used to leave about 17 KB behind (its node's ``logging`` logger, kept by ``logging`` for
good, and the documents of every xacro run); a training script that makes an env per evaluation
grew without end. Measured with ``tracemalloc`` after a warm-up, leaving out NumPy's cache of
small array buffers and ``importlib.metadata``'s lookups; what is left still includes CPython's
free lists (up to 2,000 tuples of each size, for instance), which fill over many cycles: about 1-2
KB per cycle here, with no object left behind (``gc.get_objects()`` counts stay flat).
"""

from __future__ import annotations

import gc
import logging
import tracemalloc

import numpy as np
import pytest
import xacro

import uniros

ENV = "RX200ReacherGoalSim-v0"
WARM_UP, CYCLES = 8, 16
MAX_BYTES_PER_CYCLE = 4096  # free lists settling: 1-2 KB; the leak was ~17 KB
_BOUNDED_CACHES = [tracemalloc.DomainFilter(False, np.lib.tracemalloc_domain),
                   tracemalloc.Filter(False, "*/importlib/metadata/*", all_frames=True),
                   tracemalloc.Filter(False, tracemalloc.__file__)]  # the first snapshot itself


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
    tracemalloc.start(4)
    try:
        before = tracemalloc.take_snapshot().filter_traces(_BOUNDED_CACHES)
        for _ in range(CYCLES):
            _cycle()
        gc.collect()
        after = tracemalloc.take_snapshot().filter_traces(_BOUNDED_CACHES)
    finally:
        tracemalloc.stop()
    growth = sum(stat.size_diff for stat in after.compare_to(before, "filename")) / CYCLES
    assert len(logging.Logger.manager.loggerDict) == loggers  # no logger per env node
    assert len(xacro.all_includes) == includes  # xacro's global list of included files
    assert growth < MAX_BYTES_PER_CYCLE, f"{growth:.0f} bytes kept per make/close"
