"""Service requests over rclpy served in turns: one lane per client, worker threads off the receive thread.

The rclpy transport's receive thread takes every request of every service (``loop.py``). Running
each request's callback there, inline, let one client's long request (a ``StepSimulation`` of
100,000 steps: seconds) hold up every other client's requests and every topic; two clients
stepping back to back starved a third entirely. The Zenoh transport does not have that problem:
it delivers queries of different connections on different threads, and the simulation node's
:class:`~multiros.sim.fair_lock.FairLock` gives those threads turns (a long step call yields
between chunks of about 2 ms).

:class:`ServiceLanes` gives rclpy the same shape. A taken request goes to the lane of the client
that sent it (its DDS writer GUID): a lane runs its requests in arrival order, one at a time, as a
Zenoh connection does; lanes of different clients run on different worker threads, up to
``max_workers`` at once, lanes waiting for a worker first come, first served. The receive thread
only queues, so it stays free for topics, responses and other clients' requests.

A burst is paced: while a lane has ``backlog`` (8) or more requests waiting, its worker waits
``backlog_interval`` (2 ms) after each answer. A ROS 2 client keeps the answers it has not yet taken
in a history of rclpy's default depth, KEEP_LAST 10, and drops the oldest beyond it: answered as fast
as this node answers (0.5 ms each), 200 calls sent at once by one plain rclpy client got 66-106
answers; paced, 200 of 200 (in about 0.5 s; a plain rclpy server takes about 1.2 s). Other clients'
lanes run on other workers meanwhile, unpaced.

Everything is bounded: workers (started on demand, ended after ``idle_sec`` without work), the
requests queued per lane and in all; a request over a bound is dropped with a (throttled) warning,
as DDS itself would drop it from a full history.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Hashable

from multiros.ros.logging import LogThrottle

__all__ = ["ServiceLanes"]

_log = logging.getLogger(__name__)


class ServiceLanes:
    """Runs jobs on worker threads, in order per lane, lanes in turns (see the module docstring).

    Args:
        max_workers: most jobs running at once (one per lane).
        max_per_lane: most jobs waiting in one lane; more are refused.
        max_queued: most jobs waiting in all lanes together; more are refused.
        idle_sec: a worker without work for this long ends (a new one starts when work comes).
        backlog: a lane with this many requests waiting is paced ...
        backlog_interval: ... by this many seconds after each answer (0: never paced).
        name: prefix of the worker threads' names.
        pause: how a paced worker waits (``time.sleep``).
    """

    def __init__(self, max_workers: int = 16, *, max_per_lane: int = 1024, max_queued: int = 8192,
                 idle_sec: float = 30.0, backlog: int = 8, backlog_interval: float = 0.002,
                 name: str = "uniros-rclpy-service", pause: Callable[[float], None] = time.sleep) -> None:
        if max_workers < 1 or max_per_lane < 1 or max_queued < 1 or backlog < 1 or not idle_sec > 0 \
                or not backlog_interval >= 0:
            raise ValueError("ServiceLanes needs max_workers, max_per_lane, max_queued, backlog >= 1, idle_sec > 0 "
                             "and backlog_interval >= 0")
        self.max_workers = int(max_workers)
        self.max_per_lane = int(max_per_lane)
        self.max_queued = int(max_queued)
        self.idle_sec = float(idle_sec)
        self.backlog = int(backlog)
        self.backlog_interval = float(backlog_interval)
        self._pause = pause
        self._name = name
        self._cond = threading.Condition()
        self._lanes: dict[Hashable, deque[Callable[[], None]]] = {}
        self._ready: deque[Hashable] = deque()  # lanes with work and no worker, in the order they became ready
        self._running: set[Hashable] = set()  # lanes a worker is running a job of
        self._queued = 0
        self._workers = 0
        self._idle = 0
        self._stopped = False
        self._threads: list[threading.Thread] = []
        self._refusals = LogThrottle()

    @property
    def workers(self) -> int:
        """Worker threads alive now (a snapshot)."""
        return self._workers

    def submit(self, lane: Hashable, job: Callable[[], None], what: str = "a request") -> bool:
        """Queue ``job`` on ``lane``; False (and a throttled warning naming ``what``) when refused:
        stopped, or a bound reached."""
        with self._cond:
            if self._stopped:
                return False
            queue = self._lanes.get(lane)
            waiting = len(queue) if queue is not None else 0
            if waiting >= self.max_per_lane or self._queued >= self.max_queued:
                refused = True
            else:
                refused = False
                if queue is None:
                    queue = self._lanes[lane] = deque()
                queue.append(job)
                self._queued += 1
                if not waiting and lane not in self._running:
                    self._ready.append(lane)
                    if self._idle:
                        self._cond.notify()
                    elif self._workers < self.max_workers:
                        self._start_worker()
        if refused:
            self._refusals.log(_log, logging.WARNING, "%s dropped: %d requests of that client (at most %d) and "
                               "%d in all (at most %d) are waiting", what, waiting, self.max_per_lane,
                               self._queued, self.max_queued)
        return not refused

    def _start_worker(self) -> None:
        """One more worker (``_cond`` held)."""
        self._workers += 1
        thread = threading.Thread(target=self._work, name=f"{self._name}-{self._workers}", daemon=True)
        self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        thread.start()

    def _next(self) -> tuple[Hashable, Callable[[], None]] | None:
        """The next lane's next job, waiting for one; None when this worker should end (``_cond`` held)."""
        while not self._ready:
            if self._stopped:
                return None
            self._idle += 1
            try:
                woke = self._cond.wait(self.idle_sec)
            finally:
                self._idle -= 1
            if not woke and not self._ready:
                return None
        lane = self._ready.popleft()
        job = self._lanes[lane].popleft()
        self._queued -= 1
        self._running.add(lane)
        return lane, job

    def _work(self) -> None:
        while True:
            with self._cond:
                got = None if self._stopped else self._next()
                if got is None:
                    self._workers -= 1
                    return
            lane, job = got
            try:
                job()
            except Exception:  # noqa: BLE001 - one bad request must not end the worker
                _log.exception("rclpy transport: serving a request failed")
            with self._cond:
                waiting = len(self._lanes.get(lane) or ())
            if self.backlog_interval > 0 and waiting >= self.backlog:
                self._pause(self.backlog_interval)  # a burst: paced for the client's history (module docstring)
            with self._cond:
                self._running.discard(lane)
                queue = self._lanes.get(lane)
                if queue:
                    self._ready.append(lane)  # behind every lane that became ready meanwhile: turns
                else:
                    self._lanes.pop(lane, None)

    def stop(self, timeout: float = 2.0) -> None:
        """Drop what waits, let running jobs finish (the workers joined for ``timeout`` in all)."""
        with self._cond:
            self._stopped = True
            self._lanes.clear()
            self._ready.clear()
            self._queued = 0
            self._cond.notify_all()
            threads = list(self._threads)
        current = threading.current_thread()
        deadline = time.monotonic() + timeout
        for thread in threads:
            if thread is not current:
                thread.join(max(0.0, deadline - time.monotonic()))
