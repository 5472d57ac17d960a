"""Native memory that a long-lived node gives back: glibc's malloc in one arena, trimmed after large requests.

A node process (``uniros-sim``) serves strangers for weeks, and some requests are large: a
``SetParameters`` of 10,000 names, a 100,000-name ``GetParameters`` or a 1,000,000-integer array are
megabytes of C message, CDR and Python bytes, even when the answer is a refusal. After the flood of
``benchmarks/bench_hostile_neighbour.py --attacks params_rclpy`` the node's memory stayed near the
flood's peak: 124-126 MB before, +70 to +92 MB after (six runs), and a ``malloc_trim(0)`` called from
gdb afterwards gave back only 8 MB of it. Two things held it:

* Fast DDS's service request histories, which keep every payload buffer they ever grew (about 60 MB
  live: ``multiros.ros.transport.rclpy.fastdds_profile`` has them free each request once taken);
* glibc, which keeps what a process frees for its next allocations. With the histories freeing, the
  node still kept +47 to +57 MB, free, at the top of the arenas of the threads that took the requests
  (rcl's and Fast DDS's threads each get an arena of their own, up to 8 per core). ``malloc_trim`` gives
  back the free pages inside every arena but never the top of a thread's arena (glibc trims only the
  main arena's top: 3-5 MB came back), and a thread's arena trims its own top only on a large free
  while the top exceeds the trim threshold, which glibc raises to twice the largest mapped buffer it
  freed (up to 64 MB).

What was tried on the flood (two shared cores, other work beside), with the histories freeing:

* fixed thresholds (``M_MMAP_THRESHOLD`` 256 KiB, ``M_TRIM_THRESHOLD`` 128 KiB): back within 8 MB,
  but every large buffer is mapped and unmapped per request and every page of it faulted again: the
  neighbour's ``StepRobot`` p95 went from 16-22 ms to 61-75 ms, and a 1,000-name set waited 1.4 s;
* one arena (``M_ARENA_MAX`` 1) and ``malloc_trim(0)`` once the large requests stop: buffers are
  reused during the flood (``StepRobot`` p95 14-23 ms, as before) and the trim gives back all but
  4-5 MB (seven runs). The trim itself took 2 ms.

So :func:`configure_node_process` sets one arena (first thing in the node's program, before its
threads allocate: a thread keeps the arena it first got) and turns on :func:`release_soon`, which the
rclpy transport calls after each request of :data:`LARGE_BYTES` or more: one ``malloc_trim(0)``, on a
thread of its own, once no large request came for :data:`QUIET_SEC`, and at least every
:data:`LONGEST_SEC` during an endless stream. Other processes (a learner composing a node in its own
process) keep glibc's defaults: :func:`release_soon` does nothing there. Where the C library is not
glibc nothing changes. Over Zenoh the node takes no parameter requests; one arena did not change its
latencies there (``--attacks params``).
"""

from __future__ import annotations

import ctypes
import logging
import threading
import time
from collections.abc import Callable

__all__ = ["LARGE_BYTES", "LONGEST_SEC", "QUIET_SEC", "configure_node_process", "release_soon", "trim"]

_log = logging.getLogger(__name__)

LARGE_BYTES = 256 * 1024  # a request this large is worth a trim once such requests stop
QUIET_SEC = 0.5  # the trim waits this long after the last large request
LONGEST_SEC = 5.0  # ... but no longer than this after the first one it gives back
_M_ARENA_MAX = -8  # glibc's malloc.h


def _glibc() -> ctypes.CDLL | None:
    """This process's C library if it is glibc (it has ``gnu_get_libc_version``), else None."""
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # noqa: B018 - the check itself
    except (OSError, AttributeError):
        return None
    libc.mallopt.restype, libc.mallopt.argtypes = ctypes.c_int, [ctypes.c_int, ctypes.c_int]
    libc.malloc_trim.restype, libc.malloc_trim.argtypes = ctypes.c_int, [ctypes.c_size_t]
    return libc


def trim() -> bool:
    """``malloc_trim(0)``: give the system back the free pages of every arena (and the main arena's top).
    False where the C library is not glibc or there was nothing to give back."""
    libc = _glibc()
    return bool(libc is not None and libc.malloc_trim(0))


class _Trimmer:
    """Calls ``trim_fn`` on a daemon thread of its own once :meth:`note` stops being called for ``quiet``
    seconds, or ``longest`` seconds after the first note it has not yet answered."""

    def __init__(self, trim_fn: Callable[[], object], quiet: float = QUIET_SEC, longest: float = LONGEST_SEC) -> None:
        self._trim = trim_fn
        self._quiet = quiet
        self._longest = longest
        self._cond = threading.Condition()
        self._first: float | None = None  # the first note not yet answered by a trim
        self._last = 0.0
        self._thread: threading.Thread | None = None
        self.trims = 0

    def note(self) -> None:
        with self._cond:
            now = time.monotonic()
            if self._first is None:
                self._first = now
            self._last = now
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="uniros-malloc-trim", daemon=True)
                self._thread.start()
            self._cond.notify()

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._first is None:
                    self._cond.wait()
                while True:
                    due = min(self._last + self._quiet, self._first + self._longest)
                    left = due - time.monotonic()
                    if left <= 0:
                        break
                    self._cond.wait(left)
                self._first = None
            start = time.perf_counter()
            try:
                self._trim()
            except Exception:  # noqa: BLE001 - never end the thread: the next note trims again
                _log.debug("malloc_trim failed", exc_info=True)
            with self._cond:
                self.trims += 1
            _log.debug("gave freed memory back after large requests (%.1f ms)", (time.perf_counter() - start) * 1e3)


_trimmer: list[_Trimmer] = []  # [] until configure_node_process() ran in this process
_lock = threading.Lock()


def configure_node_process() -> bool:
    """glibc's malloc for a long-lived node process: one arena (``M_ARENA_MAX`` 1), and :func:`release_soon`
    turned on. Call it first thing in the node's program, before threads allocate. True where applied
    (glibc); calling it again changes nothing."""
    libc = _glibc()
    if libc is None:
        return False
    with _lock:
        if not _trimmer:
            if not libc.mallopt(_M_ARENA_MAX, 1):
                _log.debug("mallopt(M_ARENA_MAX, 1) refused: glibc's arenas kept")
            _trimmer.append(_Trimmer(trim))
    return True


def release_soon() -> None:
    """A large request was handled: give freed memory back once such requests stop (see the module's
    docstring). Nothing unless :func:`configure_node_process` ran in this process."""
    if _trimmer:
        _trimmer[0].note()
