"""Warnings kept per thread, for work that runs on several threads at once.

:class:`warnings.catch_warnings` changes the process's state and is not thread-safe (two threads
inside it at once lose or swap each other's warnings). Instead, :func:`routed_warnings` sets
the state once around the parallel work (several such blocks may be open at once, from any
threads: the first sets it, the last gives the earlier state back), and each thread collects
what it raises with :func:`caught_warnings`. By hand: Python adds per-context warnings only in
3.14.
"""

from __future__ import annotations

import contextlib
import threading
import warnings
from collections.abc import Iterator
from typing import Any

__all__ = ["caught_warnings", "routed_warnings"]

_sinks = threading.local()
_lock = threading.Lock()
#: How many :func:`routed_warnings` blocks are open, and the state the first one replaced.
_open = 0
_saved: tuple[warnings.catch_warnings, Any] | None = None


def _show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
          file: Any = None, line: str | None = None) -> None:
    """``warnings.showwarning`` inside :func:`routed_warnings`: to the raising thread's list of
    :func:`caught_warnings`, or as the state before showed it."""
    sink = getattr(_sinks, "sink", None)
    if sink is not None:
        sink.append(warnings.WarningMessage(message, category, filename, lineno, file, line))
    elif _saved is not None:
        _saved[1](message, category, filename, lineno, file, line)


@contextlib.contextmanager
def routed_warnings() -> Iterator[None]:
    """Within: every warning is shown (``"always"``), to the list of :func:`caught_warnings` of
    the thread that raised it; a thread outside one should catch its own (the ``"always"``
    filter is the process's while any block is open)."""
    global _open, _saved
    with _lock:
        if _open == 0:
            state = warnings.catch_warnings()  # saves the filters and showwarning, gives back
            state.__enter__()
            _saved = (state, warnings.showwarning)
            warnings.simplefilter("always")
            warnings.showwarning = _show
        _open += 1
    try:
        yield
    finally:
        with _lock:
            _open -= 1
            if _open == 0 and _saved is not None:
                _saved[0].__exit__(None, None, None)
                _saved = None


@contextlib.contextmanager
def caught_warnings() -> Iterator[list[warnings.WarningMessage]]:
    """The warnings this thread raises within, as :class:`warnings.catch_warnings`
    ``(record=True)`` with the ``"always"`` filter lists them: apart from other threads' inside
    :func:`routed_warnings` (nested ones too: the inner list takes what is raised within it);
    elsewhere through :class:`warnings.catch_warnings` itself, which changes the process's state
    for every thread while it lasts."""
    if not _open:
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
