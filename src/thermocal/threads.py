"""Work on threads, in order: results in the order of the work, warnings kept per thread.

- :func:`ordered_map` runs a function over items on a thread pool, a few items ahead of the
  consumer, and yields the results in the items' order (a consumer that stops early leaves no
  queued work running: the items not started are cancelled).
- :func:`routed_warnings` and :func:`caught_warnings` catch each thread's warnings apart:
  :class:`warnings.catch_warnings` changes the process's state and is not thread-safe (two
  threads inside it at once lose or swap each other's warnings), so the state is set once around
  the parallel work and each thread collects what it raises. By hand: Python adds per-context
  warnings only in 3.14.
"""

from __future__ import annotations

import contextlib
import threading
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, Future
from typing import Any, TypeVar

__all__ = ["caught_warnings", "ordered_map", "routed_warnings"]

T = TypeVar("T")
R = TypeVar("R")

_sinks = threading.local()
#: How many :func:`routed_warnings` blocks are open.
_routed = 0


def ordered_map(pool: Executor | None, fn: Callable[[T], R], items: Iterable[T], *,
                ahead: int) -> Iterator[R]:
    """``fn(item)`` for each of ``items``, in their order, run on ``pool`` (None: here, one at a
    time) with at most ``ahead`` (>= 1) items submitted and not yet yielded. An exception of
    ``fn`` is raised here, at its item's place; closing the generator early cancels the items
    not started (those running finish)."""
    if pool is None:
        for item in items:
            yield fn(item)
        return
    if ahead < 1:
        raise ValueError(f"ahead must be >= 1, got {ahead}")
    pending: deque[Future[R]] = deque()
    it = iter(items)
    try:
        for item in it:
            pending.append(pool.submit(fn, item))
            if len(pending) >= ahead:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        for future in pending:
            future.cancel()


@contextlib.contextmanager
def routed_warnings() -> Iterator[None]:
    """Within (entered by one thread, around the work of several): every warning is shown
    (``"always"``), to the list of :func:`caught_warnings` of the thread that raised it, or as
    usual in a thread outside one."""
    global _routed
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        shown = warnings.showwarning

        def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                 file: Any = None, line: str | None = None) -> None:
            sink = getattr(_sinks, "sink", None)
            if sink is None:
                shown(message, category, filename, lineno, file, line)
            else:
                sink.append(warnings.WarningMessage(message, category, filename, lineno, file,
                                                    line))

        warnings.showwarning = show
        _routed += 1
        try:
            yield
        finally:
            _routed -= 1


@contextlib.contextmanager
def caught_warnings() -> Iterator[list[warnings.WarningMessage]]:
    """The warnings this thread raises within, as :class:`warnings.catch_warnings`
    ``(record=True)`` with the ``"always"`` filter lists them: apart from other threads' inside
    :func:`routed_warnings` (nested ones too: the inner list takes what is raised within it);
    elsewhere through :class:`warnings.catch_warnings` itself, which changes the process's state
    for every thread while it lasts."""
    if not _routed:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield caught
        return
    caught: list[warnings.WarningMessage] = []
    outer = getattr(_sinks, "sink", None)
    _sinks.sink = caught
    try:
        yield caught
    finally:
        _sinks.sink = outer
