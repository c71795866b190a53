"""Input checks shared by every module: one place that turns bad input into clear errors.

Each rule has one home here: numbers and temperatures (:func:`as_float_array`,
:func:`as_temperature_c`), raw frames (:func:`frames_layout`, :func:`as_frames`), saturated and
constant frames (:data:`SATURATED_FRACTION`, :func:`check_not_saturated`, :func:`is_constant`),
FPA temperatures (:data:`FPA_RANGE_C`, :func:`as_fpa_c`, :func:`check_fpa_c`), frame indices and
the pivot (:func:`check_frame_index`, :func:`pivot_index`), output files and folders
(:func:`check_output_file`, :func:`check_output_dir`, :func:`check_suffix`,
:func:`check_not_input`), the amount of data a command may make (:func:`check_data_size`) and the
command line's numbers, ranges and sizes (:func:`check_number`, :func:`parse_range`,
:func:`parse_size`).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ABSOLUTE_ZERO_C
from thermocal.errors import InvalidInputError, ResolutionMismatchError

__all__ = [
    "ABSOLUTE_ZERO_C",
    "FPA_RANGE_C",
    "HDF5_SUFFIXES",
    "MAX_DATA_FRAMES",
    "MAX_DATA_PIXELS",
    "SATURATED_FRACTION",
    "TIFF_SUFFIXES",
    "as_float_array",
    "as_fpa_c",
    "as_frames",
    "as_temperature_c",
    "check_data_size",
    "check_fpa_c",
    "check_frame_index",
    "check_length",
    "check_ndim",
    "check_not_constant",
    "check_not_input",
    "check_not_saturated",
    "check_number",
    "check_output_dir",
    "check_output_file",
    "check_rng",
    "check_same_shape",
    "check_suffix",
    "clipped_mask",
    "surely_unclipped",
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


#: FPA temperatures a microbolometer core can report, °C (``(low, high)``): a Tau2-class core
#: is specified for −40…80 °C ambient and its FPA runs a few °C above it; outside −60…120 °C a
#: reading is a wrong unit (1/100 °C, kelvin), a damaged file or a typing error, and would give
#: temperature maps off by hundreds of °C. One range for every FPA temperature that enters
#: thermocal: ``--fpa-c`` and ``--fpa-ref-c``, a sidecar's ``fpa_c``, a chamber file's ``fpa_c``.
FPA_RANGE_C: tuple[float, float] = (-60.0, 120.0)


def _fpa_range_text() -> str:
    lo, hi = FPA_RANGE_C
    return f"{lo:g}…{hi:g} °C"


def check_fpa_c(value: Any, name: str = "fpa_c") -> float:
    """One FPA temperature, °C, as a float: a finite number within :data:`FPA_RANGE_C`.

    Raises :class:`InvalidInputError` naming ``name`` otherwise (``bool`` is not a number).
    """
    if isinstance(value, bool | np.bool_):
        raise InvalidInputError(f"{name}: expected an FPA temperature in °C, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(
            f"{name}: expected an FPA temperature in °C, got {value!r}"[:200]
        ) from None
    lo, hi = FPA_RANGE_C
    if not lo <= v <= hi:  # NaN fails too
        raise InvalidInputError(f"{name}: {_implausible_fpa(v)}")
    return v


def _implausible_fpa(value: float) -> str:
    below = " is at or below absolute zero and" if value <= ABSOLUTE_ZERO_C else ""
    return (f"{value:g} °C{below} is not a plausible FPA temperature (a microbolometer core "
            f"reports {_fpa_range_text()})")


def as_fpa_c(x: Any, name: str = "fpa_c", *, ndim: int | tuple[int, ...] | None = None
             ) -> np.ndarray:
    """Like :func:`as_float_array`, and also reject FPA temperatures outside
    :data:`FPA_RANGE_C` (naming the first such value)."""
    arr = as_float_array(x, name, ndim=ndim)
    lo, hi = FPA_RANGE_C
    bad = (arr < lo) | (arr > hi)
    if bad.any():
        k = int(np.flatnonzero(bad.ravel())[0])
        where = f"value {k}: " if arr.size > 1 else ""
        raise InvalidInputError(f"{name}: {where}{_implausible_fpa(float(arr.ravel()[k]))}")
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
        k = first_frame_outside(arr, top)
        if k is not None:
            lo, hi = int(arr.min()), int(arr.max())
            raise InvalidInputError(
                f"{name}: counts outside the {bit_depth}-bit range 0..{top} from frame {k} on "
                f"(min {lo}, max {hi}); check the bit depth (a sidecar's bit_depth) or the file, "
                "or whether it comes from the camera the model was made for"
            )
    return arr


def clipped_mask(frames: np.ndarray, bit_depth: int = 14, *, registered: bool = False
                 ) -> np.ndarray:
    """Where raw counts are clipped, bool like ``frames``: at 0 or at ``2**bit_depth − 1``.

    In ``registered`` frames 0 marks pixels a frame does not cover: only the top counts.
    """
    top = 2**bit_depth - 1
    if not registered and frames.dtype.kind == "u" and np.iinfo(frames.dtype).max >= top:
        # one pass: an unsigned count − 1 wraps 0 round to the type's top
        return np.subtract(frames, 1, dtype=frames.dtype) >= top - 1
    clipped = frames >= top
    if not registered:
        clipped |= frames <= 0
    return clipped


def surely_unclipped(frames: np.ndarray, bit_depth: int = 14) -> bool:
    """Whether unsigned raw ``frames`` hold no clipped count (:func:`clipped_mask` nowhere
    True), from their minimum and maximum alone: two reductions, 3.5× faster than the mask on a
    block of 640×512 frames. False for other types and where a count is at 0 or at the top."""
    top = 2**bit_depth - 1
    return frames.dtype.kind == "u" and 0 < int(frames.min()) and int(frames.max()) < top


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
    an all-zero frame is called dead, not saturated; float frames pass."""
    if frames.dtype.kind not in "ui":
        return
    fraction = saturated_fraction(frames, bit_depth, registered=registered)
    over = np.flatnonzero(fraction > SATURATED_FRACTION)
    if over.size:
        k = int(over[0])
        if not registered and not frames[k].any():
            raise InvalidInputError(
                f"{name}: frame {k} is all zero (a dead frame: no signal from the camera); "
                "remove it"
            )
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


def first_frame_outside(block: np.ndarray, top: int) -> int | None:
    """The first frame of ``block`` ``(N, H, W)`` holding a count outside ``0..top`` (its index
    in the block), or None."""
    if not block.size or (int(block.min()) >= 0 and int(block.max()) <= top):
        return None
    flat = block.reshape(len(block), -1)
    return int(np.argmax((flat.min(axis=1) < 0) | (flat.max(axis=1) > top)))


def pivot_index(pivot: Any, n: int) -> int:
    """The pivot frame of ``n``: ``pivot`` checked (:func:`check_frame_index`), or the middle
    frame ``n // 2`` when None."""
    return n // 2 if pivot is None else check_frame_index(pivot, n)


# --------------------------------------------------------------------------------------------
# output files
# --------------------------------------------------------------------------------------------

#: Names a TIFF output may end in (any case).
TIFF_SUFFIXES = (".tif", ".tiff")

#: Names an HDF5 output (a chamber or a calibration file) may end in (any case).
HDF5_SUFFIXES = (".h5", ".hdf5")


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


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name one file or folder: after links (:func:`os.path.samefile`,
    hard links too) where both exist, else by their resolved paths."""
    try:
        if os.path.samefile(a, b):
            return True
    except (OSError, ValueError):
        pass
    try:
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):  # a link loop
        return False


def check_outputs_differ(first: str | os.PathLike[str], second: str | os.PathLike[str] | None,
                         names: tuple[str, str]) -> None:
    """Refuse two outputs of one command that are the same file (after resolving links):
    ``names`` are their options, e.g. ``("--sigma-out", "--out")``."""
    if second is not None and Path(first).resolve() == Path(second).resolve():
        raise InvalidInputError(f"{names[0]} {first} is the {names[1]} file; write it to "
                                "another file")


def check_not_input(out: str | os.PathLike[str] | None,
                    *inputs: str | os.PathLike[str] | None, what: str = "--out") -> None:
    """Refuse an output that is one of the command's inputs (never overwrite an input).

    ``out`` and each input (None: not given) are compared after resolving links, so that a
    link to the input, ``./x`` against ``x`` or a hard link are caught too.

    Raises
    ------
    InvalidInputError
        ``out`` is the same file as an input.
    """
    if out is None:
        return
    target = Path(out)
    for inp in inputs:
        if inp is not None and _same_file(target, Path(inp)):
            same = "" if str(inp) == str(out) else f" (the same file as {inp})"
            raise InvalidInputError(
                f"{what} {out} is an input of this command{same}; write the output to another "
                "file, never over an input"
            )


def check_output_dir(path: str | os.PathLike[str]) -> Path:
    """Check an output folder before any work, creating nothing: an existing, writable folder,
    or a name whose nearest existing parent is a writable folder (it is created later).

    Raises
    ------
    InvalidInputError
        ``path`` (or a parent) exists and is not a folder, or the folder cannot be written.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise InvalidInputError(f"{p}: exists and is a file; give a folder for the output")
    existing = p
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing.exists() and not existing.is_dir():
        raise InvalidInputError(f"{p}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InvalidInputError(f"{p}: {existing} is not writable; choose another output")
    return p


#: Most pixels (frames × height × width) one command may make: 2**33, about 8.6 billion, 17 GB
#: of 16-bit counts (a 10,000-frame chamber session at 640x512 is 3.3 billion; a two-hour flight
#: at 30 Hz and 336x256, 19 billion, is to be simulated in parts). Beyond it a run would fill the
#: disk or take days: a typing error, refused before any work.
MAX_DATA_PIXELS = 2**33

#: Most frames one command may make: ten million (92 hours at 30 Hz).
MAX_DATA_FRAMES = 10**7


def _gib(nbytes: float) -> str:
    return f"{nbytes / 2**30:.1f} GiB"


def _available_memory() -> int | None:
    """Memory the system can give this process without swapping, bytes (None: unknown)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, OSError, ValueError):  # pragma: no cover - not POSIX
        return None


def check_data_size(n_frames: int, frame_shape: tuple[int, int], what: str, *,
                    bytes_per_pixel: float = 2.0, folder: str | os.PathLike[str] | None = None,
                    memory_bytes: float | None = None) -> None:
    """Check, before any work or allocation, that ``n_frames`` frames of ``frame_shape``
    ``(H, W)`` are a sane amount of data to make.

    Parameters
    ----------
    n_frames, frame_shape
        What the command would make.
    what : str
        Named in the message (``"the chamber session"``).
    bytes_per_pixel : float
        Bytes each pixel takes in the outputs (2: uint16 counts).
    folder : path, optional
        Where the outputs go: its free disk space must hold them.
    memory_bytes : float, optional
        Working memory the command needs at once: what the system has available must hold it.

    Raises
    ------
    InvalidInputError
        More than :data:`MAX_DATA_FRAMES` frames or :data:`MAX_DATA_PIXELS` pixels, more than
        the free disk space or more memory than is available.
    """
    h, w = (int(v) for v in frame_shape)
    pixels = int(n_frames) * h * w
    if n_frames > MAX_DATA_FRAMES:
        raise InvalidInputError(
            f"{what}: {n_frames} frames are more than thermocal makes in one run "
            f"({MAX_DATA_FRAMES:.3g}); use fewer frames"
        )
    if pixels > MAX_DATA_PIXELS:
        raise InvalidInputError(
            f"{what}: {n_frames} frames of {w}x{h} are {pixels:.3g} pixels, more than thermocal "
            f"makes in one run ({MAX_DATA_PIXELS:.3g}); use fewer frames or smaller frames"
        )
    if folder is not None:
        import shutil

        need = pixels * bytes_per_pixel
        existing = Path(folder)
        while not existing.exists() and existing.parent != existing:
            existing = existing.parent
        try:
            free = shutil.disk_usage(existing).free
        except OSError:
            free = None
        if free is not None and need > free:
            raise InvalidInputError(
                f"{what}: {n_frames} frames of {w}x{h} need {_gib(need)} of disk, {existing} has "
                f"{_gib(free)} free; use fewer frames or smaller frames"
            )
    if memory_bytes is not None:
        available = _available_memory()
        if available is not None and memory_bytes > available:
            raise InvalidInputError(
                f"{what}: frames of {w}x{h} need about {_gib(memory_bytes)} of memory, this "
                f"machine has {_gib(available)} available; use smaller frames (--size)"
            )


# --------------------------------------------------------------------------------------------
# command-line values
# --------------------------------------------------------------------------------------------


def parse_range(text: str, name: str, *, step: bool = False, increasing: bool = False
                ) -> tuple[float, ...]:
    """Parse a range of temperatures, °C: ``A:B``, or ``A:B:STEP`` with ``step``.

    ``A:B:STEP`` needs ``STEP > 0`` (``A > B``: a falling range, from A down to B); ``A:B``
    needs ``A < B`` only when ``increasing`` (else a falling range is allowed). Raises
    :class:`InvalidInputError` naming ``name`` (the option) otherwise.
    """
    want, example = ("A:B:STEP", "10:70:10") if step else ("A:B", "10:50")
    try:
        values = tuple(float(v) for v in text.split(":"))
    except ValueError:
        values = ()
    if len(values) != (3 if step else 2):
        raise InvalidInputError(f"{name} {text!r}: expected {want} in °C, e.g. {example}")
    if not all(math.isfinite(v) for v in values):
        raise InvalidInputError(f"{name} {text!r}: expected finite numbers (no NaN or inf), "
                                f"e.g. {example}")
    if step and values[2] <= 0:
        raise InvalidInputError(
            f"{name} {text!r}: expected {want} with STEP > 0 (A > B: from A down to B), "
            f"e.g. {example}"
        )
    if increasing and not values[0] < values[1]:
        raise InvalidInputError(f"{name} {text!r}: A must be below B")
    return values


def check_number(value: Any, name: str, *, low: float | None = None,
                 high: float | None = None, low_open: bool = False) -> float:
    """A command-line number as a finite float within ``[low, high]`` (``(low, high]`` with
    ``low_open``; None: no bound). Raises :class:`InvalidInputError` naming ``name`` (the
    option) otherwise: NaN and infinity included."""
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v):
        raise InvalidInputError(f"{name}: expected a finite number, got {value!r}")
    if low is not None and (v <= low if low_open else v < low):
        raise InvalidInputError(f"{name} must be {'>' if low_open else '>='} {low:g}, got {v:g}")
    if high is not None and v > high:
        raise InvalidInputError(f"{name} must be <= {high:g}, got {v:g}")
    return v


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
