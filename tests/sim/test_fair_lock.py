"""FairLock: reentrant, first come first served, and a holder that yields lets every waiter go first."""

from __future__ import annotations

import threading

import pytest

from multiros.sim.fair_lock import FairLock


def _wait_until(predicate, timeout: float = 10.0) -> None:
    done = threading.Event()
    deadline = threading.Timer(timeout, done.set)
    deadline.start()
    try:
        while not predicate():
            if done.wait(0.001):
                raise AssertionError("condition not met in time")
    finally:
        deadline.cancel()


def test_reentrant_and_owned() -> None:
    lock = FairLock()
    with lock:
        with lock:
            assert lock.locked()
        assert lock.locked()
    assert not lock.locked()
    with pytest.raises(RuntimeError, match="does not hold"):
        lock.release()
    assert lock.acquire(blocking=False)
    other = []
    t = threading.Thread(target=lambda: other.append(lock.acquire(timeout=0.05)))
    t.start()
    t.join()
    assert other == [False] and lock.waiting == 0  # a timed-out waiter leaves the queue
    lock.release()


def test_waiters_get_the_lock_in_arrival_order_and_a_yield_lets_them_all_go_first() -> None:
    lock = FairLock()
    order: list[str] = []
    lock.acquire()
    threads = []
    for name in "abc":
        t = threading.Thread(target=lambda n=name: (lock.acquire(), order.append(n), lock.release()))
        t.start()
        threads.append(t)
        queued = len(threads)
        _wait_until(lambda q=queued: lock.waiting == q)  # queued in this order
    assert lock.yield_turn()
    order.append("holder")
    assert order == ["a", "b", "c", "holder"]
    assert not lock.yield_turn()  # nobody waits: a no-op
    lock.release()
    for t in threads:
        t.join(timeout=10)
    assert not lock.locked()


def test_yield_keeps_the_holders_depth_and_many_threads_stay_exclusive() -> None:
    lock = FairLock()
    inside: list[int] = []
    errors: list[str] = []
    counter = [0]

    def check() -> None:
        if len(inside) != 1:
            errors.append(f"{len(inside)} threads inside")

    def work() -> None:
        for _ in range(200):
            with lock:
                with lock:
                    inside.append(1)
                    check()
                    counter[0] += 1
                    inside.pop()
                    lock.yield_turn()  # from depth 2: back at depth 2 afterwards
                    inside.append(1)
                    check()
                    inside.pop()
                if inside:
                    errors.append("left inside")

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not errors and counter[0] == 800 and not lock.locked()


def test_yield_from_a_thread_that_does_not_hold_the_lock_is_a_no_op() -> None:
    lock = FairLock()
    lock.acquire()
    waiter = threading.Thread(target=lambda: (lock.acquire(), lock.release()))
    waiter.start()
    _wait_until(lambda: lock.waiting == 1)
    result = []
    t = threading.Thread(target=lambda: result.append(lock.yield_turn()))
    t.start()
    t.join(timeout=10)
    assert result == [False] and lock.waiting == 1
    lock.release()
    waiter.join(timeout=10)
