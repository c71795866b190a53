"""How many CPU cores this process may use (no import but ``os`` and thermocal's errors)."""

from __future__ import annotations

import os

from thermocal.errors import InvalidInputError

__all__ = ["MAX_PER_CORE", "available_cores", "check_per_core"]

#: Threads or worker processes per core an option may ask for: beyond, each gets so little of
#: a core that the count is a slip (``--threads 1000000`` allocated 4 GB before failing).
MAX_PER_CORE = 4


def available_cores() -> int:
    """The CPU cores this process may run on: its affinity where the OS has one, else
    ``os.cpu_count()`` (at least 1)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def check_per_core(count: int, option: str) -> int:
    """``count`` (of ``option``'s threads or workers on this machine); :class:`InvalidInputError`
    beyond :data:`MAX_PER_CORE` per core this process may use."""
    cores = available_cores()
    if count > MAX_PER_CORE * cores:
        raise InvalidInputError(
            f"{option} {count}: more than {MAX_PER_CORE} per CPU core this process may use "
            f"({cores}); give at most {MAX_PER_CORE * cores}")
    return count
