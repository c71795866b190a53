"""Input checks shared by every module: one place that turns bad arrays into clear errors."""

from __future__ import annotations

from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError, ResolutionMismatchError

ABSOLUTE_ZERO_C = -273.15
MAX_COUNTS_14BIT = 16383


def as_float_array(x: Any, name: str, *, ndim: int | tuple[int, ...] | None = None) -> np.ndarray:
    """Return ``x`` as a finite float array (float32 kept, anything else to float64).

    Raises :class:`InvalidInputError` naming ``name`` when it is not numeric, has the wrong number
    of dimensions, or holds NaN or infinity. The input is never modified.
    """
    try:
        arr = np.asarray(x)
    except Exception as exc:  # pragma: no cover - numpy raises many types here
        raise InvalidInputError(f"{name}: not an array ({exc})") from None
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"{name}: expected numbers, got dtype {arr.dtype}")
    if arr.dtype != np.float32:
        arr = arr.astype(np.float64)
    check_ndim(arr, name, ndim)
    if arr.size and not np.all(np.isfinite(arr)):
        n_bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise InvalidInputError(f"{name}: {n_bad} value(s) are NaN or infinite")
    return arr


def check_ndim(arr: np.ndarray, name: str, ndim: int | tuple[int, ...] | None) -> None:
    """Raise :class:`InvalidInputError` unless ``arr.ndim`` is ``ndim`` (or one of them)."""
    if ndim is None:
        return
    allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
    if arr.ndim not in allowed:
        want = " or ".join(f"{n}-D" for n in allowed)
        raise InvalidInputError(f"{name}: expected a {want} array, got shape {arr.shape}")


def as_temperature_c(x: Any, name: str, *, ndim: int | tuple[int, ...] | None = None) -> np.ndarray:
    """Like :func:`as_float_array`, and also reject temperatures at or below absolute zero (°C)."""
    arr = as_float_array(x, name, ndim=ndim)
    if arr.size and float(arr.min()) <= ABSOLUTE_ZERO_C:
        raise InvalidInputError(
            f"{name}: {float(arr.min()):.2f} °C is at or below absolute zero (-273.15 °C)"
        )
    return arr


def as_frames(x: Any, name: str = "frames", *, min_frames: int = 1) -> np.ndarray:
    """Return raw counts as a ``(N, H, W)`` array; a single ``(H, W)`` frame becomes ``N = 1``.

    Integer input must lie within 14 bits; float input must be finite. Fewer than ``min_frames``
    frames, or empty frames, raise :class:`InvalidInputError`.
    """
    arr = np.asarray(x)
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"{name}: expected raw counts, got dtype {arr.dtype}")
    check_ndim(arr, name, (2, 3))
    if arr.ndim == 2:
        arr = arr[None]
    if arr.shape[1] == 0 or arr.shape[2] == 0:
        raise InvalidInputError(f"{name}: frames are empty (shape {arr.shape})")
    if arr.shape[0] < min_frames:
        raise InvalidInputError(f"{name}: needs at least {min_frames} frames, got {arr.shape[0]}")
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"{name}: frames contain NaN or infinite values")
    elif arr.size and (int(arr.min()) < 0 or int(arr.max()) > MAX_COUNTS_14BIT):
        raise InvalidInputError(
            f"{name}: counts outside the 14-bit range 0..{MAX_COUNTS_14BIT} "
            f"(min {int(arr.min())}, max {int(arr.max())})"
        )
    return arr


def check_same_shape(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str) -> None:
    """Raise :class:`ResolutionMismatchError` unless the last two axes of ``a`` and ``b`` agree."""
    if a.shape[-2:] != b.shape[-2:]:
        raise ResolutionMismatchError(
            f"{name_a} is {a.shape[-1]}x{a.shape[-2]} but {name_b} is {b.shape[-1]}x{b.shape[-2]}"
        )


def check_length(values: np.ndarray, n: int, name: str) -> None:
    """Raise :class:`InvalidInputError` unless ``values`` has exactly ``n`` entries (first axis)."""
    if values.shape[:1] != (n,):
        raise InvalidInputError(f"{name}: expected {n} values (one per frame), got {values.shape}")


def check_rng(rng: Any) -> np.random.Generator:
    """Return ``rng`` if it is a :class:`numpy.random.Generator`, else raise InvalidInputError."""
    if not isinstance(rng, np.random.Generator):
        raise InvalidInputError(
            f"rng: expected a numpy.random.Generator (np.random.default_rng(seed)), got "
            f"{type(rng).__name__}"
        )
    return rng


def parse_size(text: str) -> tuple[int, int]:
    """Parse ``"WxH"`` into ``(width, height)``; both must be between 8 and 8192 pixels."""
    parts = text.lower().split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise InvalidInputError(f"size {text!r}: expected WIDTHxHEIGHT, e.g. 336x256") from None
    if not (8 <= w <= 8192 and 8 <= h <= 8192):
        raise InvalidInputError(f"size {text!r}: width and height must be between 8 and 8192")
    return w, h
