"""thermocal.threads: each thread's warnings kept apart."""

from __future__ import annotations

import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

from thermocal.threads import caught_warnings, routed_warnings


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


def test_routed_blocks_of_two_threads_at_once_keep_their_warnings_and_give_the_state_back():
    """Two flights in one process (a Dask worker running two tasks): blocks opened and closed
    out of order; each thread's warnings reach its own list, and the process's filters and
    showwarning are as before once both have closed."""
    before = (warnings.filters[:], warnings.showwarning)
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()

    def flight_a() -> list[str]:
        with routed_warnings():
            a_in.set()
            b_in.wait(5)
            with caught_warnings() as caught:
                warnings.warn("a", UserWarning, stacklevel=1)
        a_out.set()
        return [str(w.message) for w in caught]

    def flight_b() -> list[str]:
        a_in.wait(5)
        with routed_warnings():
            b_in.set()
            a_out.wait(5)  # a's block has closed, b's is open
            with caught_warnings() as caught:
                warnings.warn("b", UserWarning, stacklevel=1)
        return [str(w.message) for w in caught]

    with ThreadPoolExecutor(2) as pool:
        a, b = pool.submit(flight_a), pool.submit(flight_b)
        assert a.result() == ["a"] and b.result() == ["b"]
    assert warnings.filters == before[0] and warnings.showwarning is before[1]
