"""thermocal.threads: results in order, each thread's warnings kept apart."""

from __future__ import annotations

import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import pytest

from thermocal.threads import caught_warnings, ordered_map, routed_warnings


def _slow_square(x: int) -> int:
    time.sleep(0.002 * (x % 3))  # finish out of order
    return x * x


@pytest.mark.parametrize("workers", [None, 1, 3])
def test_ordered_map_yields_in_the_items_order(workers):
    pool = None if workers is None else ThreadPoolExecutor(workers)
    try:
        assert list(ordered_map(pool, _slow_square, range(20), ahead=4)) == [
            x * x for x in range(20)]
    finally:
        if pool is not None:
            pool.shutdown()


def test_ordered_map_raises_at_the_failing_items_place_and_cancels_the_rest():
    started = []
    lock = threading.Lock()

    def work(x: int) -> int:
        with lock:
            started.append(x)
        if x == 2:
            raise KeyError(x)
        time.sleep(0.01)
        return x

    with ThreadPoolExecutor(2) as pool:
        got = []
        with pytest.raises(KeyError):
            for value in ordered_map(pool, work, range(100), ahead=4):
                got.append(value)
    assert got == [0, 1]
    assert max(started) < 8  # never more than `ahead` past what was yielded


def test_ordered_map_refuses_a_bad_ahead():
    with ThreadPoolExecutor(1) as pool, pytest.raises(ValueError, match="ahead"):
        list(ordered_map(pool, _slow_square, range(3), ahead=0))


def test_each_thread_catches_its_own_warnings():
    barrier = threading.Barrier(4)

    def work(k: int) -> list[str]:
        with caught_warnings() as caught:
            barrier.wait()  # all four inside at once
            for i in range(5):
                warnings.warn(f"task {k} warning {i}", UserWarning, stacklevel=1)
                time.sleep(0.001)
        return [str(w.message) for w in caught]

    with routed_warnings(), ThreadPoolExecutor(4) as pool:
        results = list(pool.map(work, range(4)))
    for k, got in enumerate(results):
        assert got == [f"task {k} warning {i}" for i in range(5)]


def test_a_warning_outside_a_catch_is_shown_as_usual():
    with warnings.catch_warnings(record=True) as outer:
        warnings.simplefilter("always")
        with routed_warnings():
            warnings.warn("shown", UserWarning, stacklevel=1)
            with caught_warnings() as caught:
                warnings.warn("caught", UserWarning, stacklevel=1)
    assert [str(w.message) for w in outer] == ["shown"]
    assert [str(w.message) for w in caught] == ["caught"]


def test_a_nested_catch_keeps_its_own_and_gives_the_outer_back():
    with routed_warnings():
        with caught_warnings() as outer:
            warnings.warn("before", UserWarning, stacklevel=1)
            with caught_warnings() as inner:
                warnings.warn("inner", UserWarning, stacklevel=1)
            warnings.warn("after", UserWarning, stacklevel=1)
    assert [str(w.message) for w in inner] == ["inner"]
    assert [str(w.message) for w in outer] == ["before", "after"]


def test_a_catch_while_another_thread_catches_does_not_silence_it():
    """One thread's catch inside the routed block (as the network's export on a flight's first
    group) leaves another thread's warnings where they belong."""
    inside, go_on = threading.Event(), threading.Event()

    def exporter() -> list[str]:
        with caught_warnings() as caught:
            warnings.warn("tracer", UserWarning, stacklevel=1)
            inside.set()
            go_on.wait(5)
        return [str(w.message) for w in caught]

    def other() -> list[str]:
        inside.wait(5)
        with caught_warnings() as caught:
            warnings.warn("mine", UserWarning, stacklevel=1)
        go_on.set()
        return [str(w.message) for w in caught]

    with routed_warnings(), ThreadPoolExecutor(2) as pool:
        a, b = pool.submit(exporter), pool.submit(other)
        assert a.result() == ["tracer"] and b.result() == ["mine"]


def test_outside_a_routed_block_a_catch_records_as_catch_warnings_does():
    with caught_warnings() as caught:
        warnings.warn("plain", UserWarning, stacklevel=1)
        warnings.warn("plain", UserWarning, stacklevel=1)  # "always": both
    assert [str(w.message) for w in caught] == ["plain", "plain"]
