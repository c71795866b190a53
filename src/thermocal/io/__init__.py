"""Reading and writing files: recordings (any format a user brings: :func:`open_recording`),
chamber sessions, temperature TIFFs, atomic writes.

``open_recording``, ``RecordingSource`` and ``FrameChunk`` are loaded on first use (their
readers pull in Pillow and imagecodecs, which most commands do not need)."""

from __future__ import annotations

from typing import Any

__all__ = ["FrameChunk", "RecordingSource", "open_recording"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from thermocal.io import open as _open

        return getattr(_open, name)
    raise AttributeError(f"module 'thermocal.io' has no attribute {name!r}")
