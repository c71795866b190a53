"""Input checks and helpers shared by the NUC methods."""

from __future__ import annotations

from typing import Any

import numpy as np

from thermocal._validate import as_frames
from thermocal.errors import InvalidInputError, ResolutionMismatchError


def as_nuc_frames(frames: Any, *, min_frames: int = 1, name: str = "frames") -> np.ndarray:
    """Frames as float32 ``(N, H, W)`` (a copy never shares memory with the input when cast).

    The checks are :func:`thermocal._validate.as_frames` (any numbers, frames of at least 4x4
    pixels); fewer than ``min_frames`` frames (a multi-frame method given one frame) raise
    :class:`InvalidInputError` naming the single-frame method.
    """
    arr = as_frames(frames, name, min_size=4, bit_depth=None)
    if arr.shape[0] < min_frames:
        raise InvalidInputError(
            f"{name}: this method needs at least {min_frames} frames, got {arr.shape[0]}; "
            "use a single-frame method (admire) for one frame"
        )
    return _as_float32(arr, name)


def as_one_frame(frame: Any, shape: tuple[int, int] | None) -> np.ndarray:
    """One frame as float32 ``(H, W)``, checked against ``shape`` when given."""
    arr = as_frames(frame, "frame", bit_depth=None, ndim=2)[0]
    if shape is not None and arr.shape != shape:
        raise ResolutionMismatchError(
            f"frame is {arr.shape[1]}x{arr.shape[0]} but this corrector was started on "
            f"{shape[1]}x{shape[0]} frames"
        )
    return _as_float32(arr, "frame")


def _as_float32(arr: np.ndarray, name: str) -> np.ndarray:
    """Checked frames as float32; float64 values beyond float32's range are refused."""
    out = arr.astype(np.float32, copy=False)
    if out.dtype != arr.dtype and arr.dtype.kind == "f" and not np.all(np.isfinite(out)):
        raise InvalidInputError(f"{name}: values too large for float32")
    return out


def check_positive(value: Any, name: str, *, upper: float | None = None) -> float:
    """A finite float > 0 (and < ``upper``), else :class:`InvalidInputError`."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0 or (upper is not None and v >= upper):
        bound = f" and < {upper}" if upper is not None else ""
        raise InvalidInputError(f"{name}: expected a value > 0{bound}, got {value!r}")
    return v


def check_int(value: Any, name: str, *, minimum: int = 1) -> int:
    """An int ≥ ``minimum``, else :class:`InvalidInputError`."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise InvalidInputError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)
