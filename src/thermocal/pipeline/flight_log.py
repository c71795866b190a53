"""The log of a processed flight, ``OUT/log.jsonl``: one JSON object per try of a pivot.

Each line is an object with an integer ``frame`` (the pivot) and what came of it (``time_s``,
``fpa_c``, ``mean_c``, σ statistics, ``registration_correlation``, ``warnings``, ``error``);
a rerun appends, so the latest line of a pivot is its outcome. Read by the flight itself (to
resume), its mosaic and its report.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = ["read_log"]


def read_log(log_path: Path) -> list[dict[str, Any]]:
    """The latest entry of each pivot in the log, by pivot; lines that are not a JSON object
    with an integer ``frame`` of 0 or more (cut by an interruption, edited) are ignored."""
    entries: dict[int, dict[str, Any]] = {}
    try:
        data = log_path.read_bytes()
    except FileNotFoundError:
        return []
    for line in data.splitlines():
        try:
            entry = json.loads(line)
        except (ValueError, RecursionError):  # a line cut short, not UTF-8, not JSON
            continue
        if not isinstance(entry, dict):
            continue
        frame = entry.get("frame")
        if isinstance(frame, bool) or not isinstance(frame, int) or frame < 0:
            continue
        entries[frame] = entry  # the latest try of each pivot
    return [entries[k] for k in sorted(entries)]
