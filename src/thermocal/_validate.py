"""Input checks shared by every module: one place that turns bad input into clear errors.

Each rule has one home here: numbers and temperatures (:func:`as_float_array`,
:func:`as_temperature_c`), raw frames (:func:`frames_layout`, :func:`as_frames`), saturated and
constant frames (:data:`SATURATED_FRACTION`, :func:`check_not_saturated`, :func:`is_constant`),
frame indices and the pivot (:func:`check_frame_index`, :func:`pivot_index`), output files
(:func:`check_output_file`, :func:`check_suffix`) and the command line's ranges and sizes
(:func:`parse_range`, :func:`parse_size`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ABSOLUTE_ZERO_C
from thermocal.errors import InvalidInputError, ResolutionMismatchError

__all__ = [
    "ABSOLUTE_ZERO_C",
    "SATURATED_FRACTION",
    "TIFF_SUFFIXES",
    "as_float_array",
    "as_frames",
    "as_temperature_c",
    "check_frame_index",
    "check_length",
    "check_ndim",
    "check_not_constant",
    "check_not_saturated",
    "check_output_file",
    "check_rng",
    "check_same_shape",
    "check_suffix",
    "clipped_mask",
    "frames_layout",
    "is_constant",
    "parse_range",
    "parse_size",
    "pivot_index",
    "saturated_fraction",
]


#: A frame of integer counts with more than this fraction of its pixels clipped (at 0 or at the
#: top count) is saturated: refused as input (a calibration's ``apply``, a burst) and left out of
#: a chamber fit. One rule for all three. It was 5 % for calibrations and chamber fits and 2 %
#: (0 and the top counted apart, float frames too) for bursts; 5 % of integer counts is kept
#: because it accepts every frame either rule accepted, so no result computed before changes,
#: while a unit's defects (well under 1 % of a Tau2-class array) still pass and a clipped scene
#: (a blackbody or a sky beyond the range: most of the frame) does not. Float frames are not
#: checked: they are not the ADC's output (registered, filtered or simulated frames), and 0 or
#: the top value in them need not be clipping.
SATURATED_FRACTION = 0.05

#: Relative spread (of the largest magnitude, or of 1) within which a frame is constant: the
#: precision of float32, in which every method works. Integer counts: exactly one value.
CONSTANT_RTOL = 1e-6


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
            f"{name}: {float(arr.min()):.2f} °C is at or below absolute zero "
            f"({ABSOLUTE_ZERO_C} °C)"
        )
    return arr


# --------------------------------------------------------------------------------------------
# raw frames
# --------------------------------------------------------------------------------------------


def frames_layout(
    shape: tuple[int, ...],
    dtype: Any,
    name: str = "frames",
    *,
    ndim: int | tuple[int, ...] = (2, 3),
    min_frames: int = 1,
    min_size: int = 1,
) -> tuple[int, int, int]:
    """Check the dtype and shape of frames without reading them (lazy stacks too).

    Parameters
    ----------
    shape, dtype
        Of the frames: ``(H, W)`` (one frame, where ``ndim`` allows it) or ``(N, H, W)``.
    name : str
        Named in the messages.
    ndim : int or tuple of int
        Accepted numbers of dimensions (2: one frame, 3: a stack).
    min_frames : int
        Fewest frames ``N``.
    min_size : int
        Fewest pixels along each side.

    Returns
    -------
    (N, H, W) : tuple of int

    Raises
    ------
    InvalidInputError
        Not numbers, the wrong dimensions, empty, frames too small, or too few of them.
    """
    if np.dtype(dtype).kind not in "biuf":
        raise InvalidInputError(f"{name}: expected numbers (raw counts), got dtype {dtype}")
    allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
    if len(shape) not in allowed:
        want = " or ".join({2: "one (H, W) frame", 3: "(N, H, W) frames"}[n] for n in allowed)
        raise InvalidInputError(f"{name}: expected {want}, got shape {tuple(shape)}")
    n, h, w = (1, *shape) if len(shape) == 2 else shape
    if 0 in (n, h, w):
        raise InvalidInputError(f"{name}: no frames or empty frames (shape {tuple(shape)})")
    if min(h, w) < min_size:
        raise InvalidInputError(
            f"{name}: frames of {w}x{h} are too small (at least {min_size}x{min_size} pixels)"
        )
    if n < min_frames:
        raise InvalidInputError(f"{name}: needs at least {min_frames} frames, got {n}")
    return int(n), int(h), int(w)


def as_frames(
    x: Any,
    name: str = "frames",
    *,
    min_frames: int = 1,
    min_size: int = 1,
    bit_depth: int | None = 14,
    ndim: int | tuple[int, ...] = (2, 3),
) -> np.ndarray:
    """Return frames as a ``(N, H, W)`` array (one ``(H, W)`` frame becomes ``N = 1``).

    The input is never copied or cast: raw counts stay integers. Float frames must be finite;
    integer counts must lie in ``0 .. 2**bit_depth − 1`` (``bit_depth=None``: any integers).
    Layout rules (``ndim``, ``min_frames``, ``min_size``) as :func:`frames_layout`.

    Raises
    ------
    InvalidInputError
        Frames of mixed sizes, not numbers, a bad layout, NaN or infinity (naming the first
        such frame), or counts out of range.
    """
    try:
        arr = np.asarray(x)
    except ValueError:  # numpy refuses ragged lists of frames
        arr = np.empty(0, dtype=object)
    if arr.dtype == object:
        raise InvalidInputError(f"{name}: frames of mixed sizes; every frame must be H x W alike")
    frames_layout(arr.shape, arr.dtype, name, ndim=ndim, min_frames=min_frames,
                  min_size=min_size)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            k = int(np.flatnonzero(~np.isfinite(arr).reshape(len(arr), -1).all(axis=1))[0])
            raise InvalidInputError(f"{name}: frame {k} contains NaN or infinite values")
    elif bit_depth is not None:
        top = 2**bit_depth - 1
        lo, hi = int(arr.min()), int(arr.max())
        if lo < 0 or hi > top:
            raise InvalidInputError(
                f"{name}: counts outside the {bit_depth}-bit range 0..{top} (min {lo}, max {hi}); "
                "check the bit depth or the file"
            )
    return arr


def clipped_mask(frames: np.ndarray, bit_depth: int = 14, *, registered: bool = False
                 ) -> np.ndarray:
    """Where raw counts are clipped, bool like ``frames``: at 0 or at ``2**bit_depth − 1``.

    In ``registered`` frames 0 marks pixels a frame does not cover: only the top counts.
    """
    clipped = frames >= 2**bit_depth - 1
    if not registered:
        clipped |= frames <= 0
    return clipped


def saturated_fraction(frames: np.ndarray, bit_depth: int = 14, *, registered: bool = False,
                       clipped: np.ndarray | None = None) -> np.ndarray:
    """Fraction of each frame's pixels that are clipped, ``(N,)``; of the covered (non-zero)
    pixels of ``registered`` frames. ``clipped``: the frames' :func:`clipped_mask`, if known."""
    n = len(frames)
    if clipped is None:
        clipped = clipped_mask(frames, bit_depth, registered=registered)
    clipped = np.count_nonzero(clipped.reshape(n, -1), axis=1)
    pixels = (np.count_nonzero(frames.reshape(n, -1) > 0, axis=1) if registered
              else np.full(n, frames[0].size))
    return clipped / np.maximum(pixels, 1)


def check_not_saturated(frames: np.ndarray, name: str = "frames", *, bit_depth: int = 14,
                        registered: bool = False) -> None:
    """Raise :class:`InvalidInputError` for the first frame of integer counts ``(N, H, W)``
    with more than :data:`SATURATED_FRACTION` of its pixels clipped (:func:`saturated_fraction`);
    float frames pass."""
    if frames.dtype.kind not in "ui":
        return
    fraction = saturated_fraction(frames, bit_depth, registered=registered)
    over = np.flatnonzero(fraction > SATURATED_FRACTION)
    if over.size:
        k = int(over[0])
        top = 2**bit_depth - 1
        where = f"at {top}" if registered else f"at 0 or {top}"
        raise InvalidInputError(
            f"{name}: frame {k} is saturated ({100 * fraction[k]:.0f} % of its pixels {where}); "
            "remove it, or lower the scene temperature or the gain"
        )


def is_constant(frame: np.ndarray) -> bool:
    """Whether a frame (any shape) holds one value, to float32 precision (:data:`CONSTANT_RTOL`
    of its largest magnitude, or of 1); an empty one is constant."""
    if frame.size == 0:
        return True
    return float(np.ptp(frame)) <= CONSTANT_RTOL * max(1.0, float(np.abs(frame).max()))


def check_not_constant(frames: np.ndarray, name: str = "frames", *, registered: bool = False
                       ) -> None:
    """Raise :class:`InvalidInputError` for the first constant frame of ``(N, H, W)``
    (:func:`is_constant`; of its covered, non-zero pixels when ``registered``)."""
    for k, frame in enumerate(frames):
        if is_constant(frame[frame > 0] if registered else frame):
            raise InvalidInputError(f"{name}: frame {k} is constant (a dead or blank frame)")


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


# --------------------------------------------------------------------------------------------
# frame indices
# --------------------------------------------------------------------------------------------


def check_frame_index(index: Any, n: int, name: str = "pivot", *, within: str = "the burst"
                      ) -> int:
    """``index`` as an int that names one of ``n`` frames (``0 .. n − 1``).

    Raises :class:`InvalidInputError` naming ``name`` for a non-integer (a bool included) or an
    index outside ``within``.
    """
    if isinstance(index, bool) or not isinstance(index, int | np.integer):
        raise InvalidInputError(f"{name}: expected a frame index (an integer), got {index!r}")
    if not 0 <= int(index) < n:
        raise InvalidInputError(f"{name} {index} is outside {within} (frames 0..{n - 1})")
    return int(index)


def pivot_index(pivot: Any, n: int) -> int:
    """The pivot frame of ``n``: ``pivot`` checked (:func:`check_frame_index`), or the middle
    frame ``n // 2`` when None."""
    return n // 2 if pivot is None else check_frame_index(pivot, n)


# --------------------------------------------------------------------------------------------
# output files
# --------------------------------------------------------------------------------------------

#: Names a TIFF output may end in (any case).
TIFF_SUFFIXES = (".tif", ".tiff")


def check_suffix(path: str | Path, suffixes: tuple[str, ...], what: str = "the output") -> Path:
    """``path`` as a Path; :class:`InvalidInputError` unless it ends in one of ``suffixes``
    (any case)."""
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise InvalidInputError(f"{p}: {what} must end in {' or '.join(suffixes)}")
    return p


def check_output_file(path: str | Path, suffixes: tuple[str, ...] | None = None) -> Path:
    """Check an output file before any work: a file name (not a folder) in an existing folder,
    ending in one of ``suffixes`` when given. Returns it as a Path.

    Raises
    ------
    InvalidInputError
        ``path`` is a folder, its folder does not exist, or it has another suffix.
    """
    p = Path(path)
    if p.is_dir():
        raise InvalidInputError(f"{p}: is a directory, expected a file name")
    if not p.parent.is_dir():
        raise InvalidInputError(f"{p.parent}: output folder does not exist")
    return p if suffixes is None else check_suffix(p, suffixes)


# --------------------------------------------------------------------------------------------
# command-line values
# --------------------------------------------------------------------------------------------


def parse_range(text: str, name: str, *, step: bool = False, increasing: bool = False
                ) -> tuple[float, ...]:
    """Parse a range of temperatures, °C: ``A:B``, or ``A:B:STEP`` with ``step``.

    ``A:B:STEP`` needs ``A <= B`` and ``STEP > 0``; ``A:B`` needs ``A < B`` only when
    ``increasing`` (else a falling range is allowed). Raises :class:`InvalidInputError` naming
    ``name`` (the option) otherwise.
    """
    want, example = ("A:B:STEP", "10:70:10") if step else ("A:B", "10:50")
    try:
        values = tuple(float(v) for v in text.split(":"))
    except ValueError:
        values = ()
    if len(values) != (3 if step else 2):
        raise InvalidInputError(f"{name} {text!r}: expected {want} in °C, e.g. {example}")
    if step and (values[2] <= 0 or values[1] < values[0]):
        raise InvalidInputError(
            f"{name} {text!r}: expected {want} with A <= B and STEP > 0, e.g. {example}"
        )
    if increasing and not values[0] < values[1]:
        raise InvalidInputError(f"{name} {text!r}: A must be below B")
    return values


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


def parse_units(text: str) -> tuple[int, ...]:
    """``"0-23"``, ``"3"`` or ``"0,2,5-7"`` → unit numbers."""
    units: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                a, b = (int(x) for x in part.split("-"))
                units.extend(range(a, b + 1))
            elif part:
                units.append(int(part))
    except ValueError:
        raise InvalidInputError(f"units {text!r}: expected e.g. 0-23 or 0,2,5-7") from None
    if not units or min(units) < 0:
        raise InvalidInputError(f"units {text!r}: give unit numbers >= 0")
    return tuple(dict.fromkeys(units))
