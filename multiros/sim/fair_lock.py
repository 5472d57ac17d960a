"""A reentrant lock that grants turns in arrival order, and lets a long holder give way.

The simulation node serialises every access to its world under one lock. Python's locks are not
fair: a thread that releases and takes the lock again at once usually wins, and waiting threads
wake in no particular order, so one client's long ``StepSimulation`` (up to ``max_steps_per_call``
steps, seconds of work) kept every other client waiting for all of it, and four such clients in
a row kept a fifth waiting indefinitely. :class:`FairLock` queues waiting threads first come,
first served and hands the lock to the head of the queue on release; :meth:`FairLock.yield_turn`,
called by a long step call between its chunks, puts the holder at the back of that queue, so
every request that arrived meanwhile gets its turn first (one chunk of the long call, then one
whole short request, and so on).

Requests that arrive over Zenoh are delivered one at a time per connection (a Zenoh session), so
first come, first served between threads is round robin between connected clients.

Uncontended, :meth:`FairLock.acquire` and :meth:`FairLock.release` cost about a microsecond each
(a few attribute operations under an internal lock); ``benchmarks/bench_sim_node.py`` measures the
lockstep path with it.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any

__all__ = ["FairLock"]

_get_ident = threading.get_ident


class _Waiter:
    __slots__ = ("ident", "gate")

    def __init__(self, ident: int) -> None:
        self.ident = ident
        self.gate = threading.Lock()
        self.gate.acquire()


class FairLock:
    """Reentrant lock with first-come-first-served hand-over (see the module docstring).

    Same interface as ``threading.RLock`` for ``acquire``/``release``/``with``, plus
    :meth:`yield_turn` and :attr:`waiting`. A thread that finds the lock free takes it at once; a
    released lock goes to the longest-waiting thread without ever being free in between.
    """

    def __init__(self) -> None:
        self._held = threading.Lock()  # acquired while any thread owns the FairLock
        self._mutex = threading.Lock()  # orders enqueuing against hand-over
        self._owner: int | None = None
        self._depth = 0
        self._queue: deque[_Waiter] = deque()

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        me = _get_ident()
        if self._owner == me:  # only this thread can make that true or false
            self._depth += 1
            return True
        if self._held.acquire(False):
            self._owner, self._depth = me, 1
            return True
        if not blocking:
            return False
        with self._mutex:
            if self._held.acquire(False):  # released meanwhile
                self._owner, self._depth = me, 1
                return True
            waiter = _Waiter(me)
            self._queue.append(waiter)
        try:
            if waiter.gate.acquire(timeout=timeout if timeout is not None and timeout >= 0 else -1):
                return True  # handed over: the releasing thread made us the owner
        except BaseException:  # KeyboardInterrupt while waiting: leave no turn to a thread that gave up
            with self._mutex:
                if self._owner == me:
                    self._depth = 1
                    self._release_turn()
                else:
                    self._queue.remove(waiter)
            raise
        with self._mutex:
            if self._owner == me:  # handed over between the timeout and here
                return True
            self._queue.remove(waiter)
            return False

    def release(self) -> None:
        if self._owner != _get_ident():
            raise RuntimeError("cannot release a FairLock this thread does not hold")
        self._depth -= 1
        if self._depth:
            return
        with self._mutex:
            self._release_turn()

    def _release_turn(self) -> None:
        """The owner is done (``_mutex`` held): hand over to the first waiter, or free the lock."""
        if self._queue:
            self._hand_over()
        else:
            self._owner = None
            self._held.release()

    def _hand_over(self) -> None:
        """Make the first waiter the owner (``_mutex`` held, queue not empty; ``_held`` stays held)."""
        waiter = self._queue.popleft()
        self._owner, self._depth = waiter.ident, 1
        waiter.gate.release()

    @property
    def waiting(self) -> int:
        """Threads waiting for the lock now (a snapshot)."""
        return len(self._queue)

    def yield_turn(self) -> bool:
        """Let every thread waiting now have its turn, then take the lock back (same depth).

        Call it while holding the lock, at a point where others may use what it guards. A no-op
        (False) when nobody waits or the calling thread does not hold the lock (work done on
        another thread's behalf, which keeps its turn).
        """
        if not self._queue or self._owner != _get_ident():
            return False
        with self._mutex:
            if not self._queue:
                return False
            depth = self._depth
            waiter = _Waiter(self._owner)
            self._queue.append(waiter)
            self._hand_over()
        interrupted: BaseException | None = None
        while True:  # the caller holds the lock again when this returns or raises: it will release it
            try:
                waiter.gate.acquire()
                break
            except BaseException as exc:  # KeyboardInterrupt: raise it once our turn is back
                interrupted = exc
        self._depth = depth  # the hand-over made us the owner at depth 1
        if interrupted is not None:
            raise interrupted
        return True

    def locked(self) -> bool:
        """Whether some thread holds the lock."""
        return self._owner is not None

    def __enter__(self) -> FairLock:
        self.acquire()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()
