"""ServiceLanes (the rclpy transport's request workers): one client's requests in order, other
clients' beside a long one, bounds that refuse, and a stop that drops what waits."""

from __future__ import annotations

import threading
import time

import pytest

from multiros.ros.transport.rclpy.lanes import ServiceLanes

WAIT = 10.0


@pytest.fixture
def lanes():
    pool = ServiceLanes(max_workers=4, max_per_lane=3, max_queued=5, idle_sec=0.5)
    yield pool
    pool.stop()


def test_a_lane_runs_in_order_one_at_a_time(lanes) -> None:
    seen: list[int] = []
    running = []
    done = threading.Event()

    def job(i: int) -> None:
        running.append(i)
        assert len(running) == 1, "two jobs of one lane ran at once"
        seen.append(i)
        running.pop()
        if i == 2:
            done.set()

    for i in range(3):
        assert lanes.submit("client-a", lambda i=i: job(i))
    assert done.wait(WAIT)
    assert seen == [0, 1, 2]


def test_another_client_is_served_while_one_request_runs_long(lanes) -> None:
    release, quick = threading.Event(), threading.Event()
    started = threading.Event()

    def long_job() -> None:
        started.set()
        release.wait(WAIT)

    assert lanes.submit("flooder", long_job)
    assert started.wait(WAIT)
    assert lanes.submit("flooder", lambda: None)  # queued behind the long one, in its lane
    assert lanes.submit("third", quick.set)
    assert quick.wait(WAIT), "a second client waited for the first one's long request"
    release.set()


def test_a_burst_is_paced_while_other_clients_run() -> None:
    """A lane with ``backlog`` requests waiting pauses ``backlog_interval`` after each answer (so a client
    with rclpy's KEEP_LAST 10 response history takes every answer); the lane keeps its order, every
    request is answered, and another client's request runs while the burst's worker pauses."""
    pauses: list[float] = []
    paused, release = threading.Event(), threading.Event()

    def pause(seconds: float) -> None:
        pauses.append(seconds)
        paused.set()
        assert release.wait(WAIT)

    pool = ServiceLanes(max_workers=2, backlog=3, backlog_interval=0.002, idle_sec=0.5, pause=pause)
    try:
        seen: list[int] = []
        gate = threading.Event()
        pool.submit("burst", lambda: gate.wait(WAIT))  # holds the lane while the burst queues behind it
        for i in range(6):
            assert pool.submit("burst", lambda i=i: seen.append(i))
        gate.set()
        assert paused.wait(WAIT), "a backlog of 6 was not paced"
        other = threading.Event()
        assert pool.submit("other", other.set)
        assert other.wait(WAIT), "another client waited for the burst's pause"
        release.set()
        _wait(lambda: seen == list(range(6)))
        # Paced after each answer while 3 or more waited: after the gate (6 waiting) and answers 0..3.
        assert pauses == [0.002] * 4
    finally:
        release.set()
        pool.stop()


def _wait(predicate) -> None:
    deadline = time.monotonic() + WAIT
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.001)


def test_bounds_refuse_with_a_warning(lanes, caplog) -> None:
    release, started = threading.Event(), threading.Event()
    assert lanes.submit("a", lambda: (started.set(), release.wait(WAIT)))
    assert started.wait(WAIT)
    assert all(lanes.submit("a", lambda: None) for _ in range(3))
    assert not lanes.submit("a", lambda: None, "a request of service '/x'")  # 3 waiting in lane a
    b_started = threading.Event()
    assert lanes.submit("b", lambda: (b_started.set(), release.wait(WAIT)))
    assert b_started.wait(WAIT)
    assert lanes.submit("b", lambda: None) and lanes.submit("b", lambda: None)
    assert not lanes.submit("c", lambda: None)  # 5 waiting in all
    assert "a request of service '/x' dropped" in caplog.text
    release.set()


def test_workers_are_bounded_and_a_failing_job_does_not_end_them(lanes) -> None:
    release = threading.Event()
    gate = threading.Barrier(5, timeout=WAIT)

    def block() -> None:
        gate.wait()
        release.wait(WAIT)

    lanes.max_queued = 100
    for name in "abcd":
        assert lanes.submit(name, block)
    gate.wait()  # four workers run at once
    assert lanes.workers == 4
    ran = threading.Event()
    assert lanes.submit("e", ran.set)  # waits for a worker
    assert not ran.wait(0.05) or lanes.workers == 4
    release.set()
    assert ran.wait(WAIT)
    assert lanes.submit("f", lambda: 1 / 0)
    after = threading.Event()
    assert lanes.submit("f", after.set)
    assert after.wait(WAIT)


def test_stop_drops_what_waits_and_refuses_more() -> None:
    pool = ServiceLanes(max_workers=1)
    release, started = threading.Event(), threading.Event()
    ran = []
    pool.submit("a", lambda: (started.set(), release.wait(WAIT)))
    assert started.wait(WAIT)
    pool.submit("a", lambda: ran.append(1))
    threading.Timer(0.1, release.set).start()
    pool.stop(timeout=WAIT)
    assert ran == [] and not pool.submit("a", lambda: None)


def test_bad_bounds_are_refused() -> None:
    with pytest.raises(ValueError):
        ServiceLanes(max_workers=0)
