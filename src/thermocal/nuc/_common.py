"""Input checks and helpers shared by the NUC methods."""

from __future__ import annotations

from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError, ResolutionMismatchError


def as_nuc_frames(frames: Any, *, min_frames: int = 1, name: str = "frames") -> np.ndarray:
    """Frames as float32 ``(N, H, W)`` (a copy never shares memory with the input when cast).

    Raises :class:`InvalidInputError` for non-numeric data, wrong dimensions, NaN or infinity,
    empty frames, or fewer than ``min_frames`` frames (a multi-frame method given one frame).
    """
    try:
        arr = np.asarray(frames)
    except ValueError:  # numpy refuses ragged lists of frames
        arr = np.empty(0, dtype=object)
    if arr.dtype == object:
        raise InvalidInputError(f"{name}: frames of mixed sizes; every frame must be H x W alike")
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"{name}: expected raw counts or floats, got dtype {arr.dtype}")
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3:
        raise InvalidInputError(f"{name}: expected (N, H, W) frames, got shape {arr.shape}")
    if 0 in arr.shape:
        raise InvalidInputError(f"{name}: empty (shape {arr.shape})")
    if min(arr.shape[1:]) < 4:
        raise InvalidInputError(f"{name}: frames of {arr.shape[2]}x{arr.shape[1]} are too small")
    if arr.shape[0] < min_frames:
        raise InvalidInputError(
            f"{name}: this method needs at least {min_frames} frames, got {arr.shape[0]}; "
            "use a single-frame method (admire) for one frame"
        )
    out = arr.astype(np.float32, copy=False)
    if not np.all(np.isfinite(out)):
        raise InvalidInputError(f"{name}: contains NaN or infinite values")
    return out


def as_one_frame(frame: Any, shape: tuple[int, int] | None) -> np.ndarray:
    """One frame as float32 ``(H, W)``, checked against ``shape`` when given."""
    arr = np.asarray(frame)
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"frame: expected raw counts or floats, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise InvalidInputError(f"frame: expected one (H, W) frame, got shape {arr.shape}")
    if shape is not None and arr.shape != shape:
        raise ResolutionMismatchError(
            f"frame is {arr.shape[1]}x{arr.shape[0]} but this corrector was started on "
            f"{shape[1]}x{shape[0]} frames"
        )
    out = arr.astype(np.float32, copy=False)
    if not np.all(np.isfinite(out)):
        raise InvalidInputError("frame: contains NaN or infinite values")
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
