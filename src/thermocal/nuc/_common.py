"""Input checks and helpers shared by the NUC methods, and the writer of their output."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import TIFF_SUFFIXES, as_float_array, as_frames, check_suffix
from thermocal.errors import InvalidInputError, ResolutionMismatchError

#: Physical range of a detector's gain relative to the array's mean gain, ``(low, high)``. A
#: microbolometer array's gains spread by a few per cent (pixels, columns) and its lens's
#: vignetting dims the corners by up to a few tens of per cent; a per-pixel spread statistic that
#: puts a detector beyond a factor 1.5 of the mean is the scene's, not the detector's: the
#: constant-statistics (or constant-range) assumption failed at that pixel (on a slow walk over a
#: uniform patch the pixel saw only its temporal noise). Dividing by such a "gain" multiplies
#: every later scene change at that pixel by up to ``1/low``; with the former floor of 5 % of the
#: mean that was 20x, which made torres-kalman diverge on 40-frame walks and UAV passes (issue 18,
#: item 5). Harris1999, Pezoa2004, TorresKalman and hardie2000 keep their gains in this range.
GAIN_RANGE = (2.0 / 3.0, 1.5)


def as_nuc_frames(frames: Any, *, min_frames: int = 1, name: str = "frames") -> np.ndarray:
    """Frames as float32 ``(N, H, W)`` (a copy never shares memory with the input when cast).

    The checks are :func:`thermocal._validate.as_frames` (any numbers, frames of at least 4x4
    pixels); fewer than ``min_frames`` frames (a multi-frame method given one frame) raise
    :class:`InvalidInputError` naming the single-frame method.
    """
    arr = as_frames(frames, name, min_size=4, bit_depth=None)
    if arr.shape[0] < min_frames:
        one = "; use a single-frame method (admire or he2018) for one frame"
        raise InvalidInputError(
            f"{name}: this method needs at least {min_frames} frames, got {arr.shape[0]}"
            + (one if arr.shape[0] == 1 else ""))
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


def write_counts_tiff(
    path: str | os.PathLike[str], frames: Any, *, extra: dict[str, Any] | None = None
) -> Path:
    """Write counts-like frames (a NUC's output: not temperatures) as a float32 TIFF, atomically.

    The TIFF's description (tifffile's JSON metadata) says ``"units": "counts"`` and
    ``"radiometric": false``, with the entries of ``extra``. No temperature rule applies: counts
    may be any finite number.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``.tiff``/``.tif``; its directory must exist.
    frames : array_like, shape (H, W) or (N, H, W)
        Counts-like values.
    extra : dict, optional
        Further JSON-serialisable description entries (e.g. ``{"method": "ecr"}``).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InvalidInputError
        A wrong suffix, frames not 2-D or 3-D, empty, NaN or infinite, or beyond float32.
        Nothing is written then.
    """
    import tifffile

    from thermocal.io.atomic import atomic_path

    out = check_suffix(path, TIFF_SUFFIXES, "a TIFF output")
    arr = as_float_array(frames, "frames", ndim=(2, 3))
    if 0 in arr.shape:
        raise InvalidInputError(f"frames: empty image (shape {arr.shape})")
    f32 = _as_float32(arr, "frames")
    metadata = {"units": "counts", "radiometric": False, **(extra or {})}
    with atomic_path(out) as tmp:
        tifffile.imwrite(tmp, f32, photometric="minisblack", metadata=metadata,
                         bigtiff=f32.nbytes > 2**31)
    return out
