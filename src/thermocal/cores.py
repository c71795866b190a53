"""How many CPU cores this process may use (numpy only: no import but ``os``)."""

from __future__ import annotations

import os

__all__ = ["available_cores"]


def available_cores() -> int:
    """The CPU cores this process may run on: its affinity where the OS has one, else
    ``os.cpu_count()`` (at least 1)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
