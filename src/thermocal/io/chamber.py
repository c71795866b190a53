"""Chamber sessions: HDF5 files of blackbody frames with their temperatures.

A **chamber file** (DESIGN.md, "The contract: command line and files") is HDF5 with

=============== ======================= ======================================================
name            type, shape             meaning
=============== ======================= ======================================================
``frames``      uint16 ``(M, H, W)``    raw counts, chunked one frame per chunk
``blackbody_c`` float ``(M,)``          blackbody temperature for each frame, °C
``fpa_c``       float ``(M,)``          FPA temperature reported by the camera, °C
``time_s``      float ``(M,)``          time stamp of each frame, s
``housing_c``   float ``(M,)``          optional: housing temperature, °C
``ambient_c``   float ``(M,)``          optional: chamber (ambient) temperature, °C
=============== ======================= ======================================================

and the file attributes ``format = "thermocal-chamber"``, ``version = 1``, ``bit_depth = 14``,
plus free metadata attributes (``unit``, ``preset``, ``seed``, ...). Series are written as
float64; any float dtype is accepted on reading.

Writers are atomic (a temporary file renamed into place on success); :class:`ChamberWriter`
streams frames to disk so that sessions larger than memory can be written.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from thermocal._validate import (
    ABSOLUTE_ZERO_C,
    as_float_array,
    as_fpa_c,
    as_temperature_c,
    check_length,
    first_frame_outside,
)
from thermocal.errors import FileFormatError, InvalidInputError, ResolutionMismatchError
from thermocal.io.atomic import atomic_path
from thermocal.io.recording import _check_bit_depth, _counts_as_uint16, _series_or_none

__all__ = [
    "CHAMBER_FORMAT",
    "CHAMBER_VERSION",
    "ChamberSession",
    "ChamberWriter",
    "LazyFrames",
    "chamber_problems",
    "damaged_attribute_type",
    "iter_chamber_frames",
    "read_chamber",
    "validate_chamber",
    "write_chamber",
]

CHAMBER_FORMAT = "thermocal-chamber"
CHAMBER_VERSION = 1
REQUIRED_SERIES: tuple[str, ...] = ("blackbody_c", "fpa_c", "time_s")
OPTIONAL_SERIES: tuple[str, ...] = ("housing_c", "ambient_c")
ALL_SERIES = REQUIRED_SERIES + OPTIONAL_SERIES
_SERIES_CHUNK = 4096  # values per HDF5 chunk of a per-frame series
_COPY_CHUNK = 256  # frames per block when copying frames into a file
_HEAP_DAMAGED = ("the chamber file is damaged and cannot be read (a global heap's objects overrun "
                 "it); copy or record it again")

#: What h5py raises on a damaged file (a bad signature, heap, B-tree or object header): each is
#: turned into a :class:`FileFormatError` naming the file.
_H5_ERRORS = (OSError, KeyError, RuntimeError, ValueError, TypeError)


def _damaged(path: Path, exc: BaseException) -> FileFormatError:
    """The one-line error of a chamber file that h5py cannot read."""
    text = " ".join(str(exc).split())[:120]
    return FileFormatError(f"{path}: the chamber file is damaged and cannot be read ({text}); "
                           "copy or record it again")


# --------------------------------------------------------------------------------------------
# attributes
# --------------------------------------------------------------------------------------------


def _check_attr(key: Any, value: Any) -> Any:
    """Return ``value`` in a form HDF5 can store as an attribute, or raise InvalidInputError."""
    if not isinstance(key, str) or not key:
        raise InvalidInputError(f"attrs: attribute names must be non-empty strings, got {key!r}")
    if isinstance(value, str | bool | np.bool_):
        return value
    if isinstance(value, int | np.integer):
        if not -(2**63) <= int(value) < 2**63:
            raise InvalidInputError(f"attrs[{key!r}]: integer {value} does not fit in 64 bits")
        return value
    if isinstance(value, float | np.floating):
        return value
    if isinstance(value, list | tuple | np.ndarray):
        arr = np.asarray(value)
        if arr.dtype.kind in "biuf":
            return arr
        if arr.ndim == 1 and all(isinstance(v, str) for v in arr.tolist()):
            return [str(v) for v in arr.tolist()]  # a list of strings
    raise InvalidInputError(
        f"attrs[{key!r}]: cannot store {type(value).__name__} as an HDF5 attribute; "
        "use a string, a number, a bool, an array of numbers or a list of strings "
        "(json.dumps for nested data)"
    )


def _normalise_attrs(attrs: Mapping[str, Any] | None) -> dict[str, Any]:
    """Validate free attributes; check and drop ``format``/``version``; fill ``bit_depth``."""
    if attrs is None:
        attrs = {}
    if not isinstance(attrs, Mapping):
        raise InvalidInputError(f"attrs: expected a dict, got {type(attrs).__name__}")
    out = {key: _check_attr(key, value) for key, value in attrs.items()}
    if "format" in out and out.pop("format") != CHAMBER_FORMAT:
        raise InvalidInputError(f"attrs['format']: must be {CHAMBER_FORMAT!r} if given")
    if "version" in out and out.pop("version") != CHAMBER_VERSION:
        raise InvalidInputError(f"attrs['version']: must be {CHAMBER_VERSION} if given")
    out["bit_depth"] = _check_bit_depth(out.get("bit_depth", 14), "attrs['bit_depth']")
    return out


def _to_h5_attr(value: Any) -> Any:
    """A checked attribute value in the form h5py writes (lists of str: variable-length UTF-8)."""
    if isinstance(value, list):
        return np.array(value, dtype=h5py.string_dtype())
    return value


def _attr_to_python(value: Any) -> Any:
    """Turn an attribute as h5py returns it into a plain Python value (arrays stay arrays)."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray) and value.dtype.kind == "O":
        return [_attr_to_python(v) for v in value.tolist()]
    return value


# --------------------------------------------------------------------------------------------
# lazy frames
# --------------------------------------------------------------------------------------------


class LazyFrames:
    """The frames of a chamber file, read only when indexed: a stand-in for an ``(M, H, W)`` array.

    Returned as ``ChamberSession.frames`` by ``read_chamber(path, frames=False)``. It holds the
    path and the shape only, no open file (no h5py object): every access opens the file, reads
    what is asked for and closes it again.

    Parameters
    ----------
    path : str or os.PathLike
        The chamber file.
    shape : tuple of int
        ``(M, H, W)``.

    Notes
    -----
    Indexing accepts an int, a slice, a tuple of ints/slices, or a 1-D integer or boolean index
    array along the frame axis; it returns a fresh uint16 numpy array. ``np.asarray(lazy)``
    reads all frames.
    """

    dtype = np.dtype(np.uint16)
    ndim = 3

    def __init__(self, path: str | os.PathLike[str], shape: tuple[int, int, int]) -> None:
        self.path = Path(path)
        self.shape = tuple(int(s) for s in shape)
        if len(self.shape) != 3:
            raise InvalidInputError(f"LazyFrames: expected an (M, H, W) shape, got {shape}")

    def __len__(self) -> int:
        return self.shape[0]

    def __repr__(self) -> str:
        return f"LazyFrames({str(self.path)!r}, shape={self.shape})"

    @property
    def nbytes(self) -> int:
        """Bytes the frames take once read."""
        return int(np.prod(self.shape, dtype=np.int64)) * 2

    def __getitem__(self, key: Any) -> np.ndarray:
        return self._with_frames(lambda dset: self._read(dset, key))

    def read_rows(self, index: Any, rows: Any) -> np.ndarray:
        """Frames ``index`` (1-D integers), only their ``rows`` (1-D integers, increasing),
        uint16 ``(k, R, W)``: a sample of rows costs the rows' bytes, not the frames'."""
        idx = np.asarray(index, dtype=np.intp).reshape(-1)
        r = np.asarray(rows, dtype=np.intp).reshape(-1)
        if r.size and (r.min() < 0 or r.max() >= self.shape[1] or np.any(np.diff(r) <= 0)):
            raise IndexError(f"rows must increase within 0..{self.shape[1] - 1}")

        def read(dset: h5py.Dataset) -> np.ndarray:
            offsets = self._offsets(dset)
            if offsets is None or idx.size == 0:
                return self._read(dset, idx)[:, r]
            width = self.shape[2]
            runs = np.split(r, np.flatnonzero(np.diff(r) != 1) + 1)
            return _pread_frames(self.path, offsets, idx, (r.size, width), parts=[
                (2 * width * int(run[0]), 2 * width * run.size) for run in runs if run.size])

        return self._with_frames(read)

    def _with_frames(self, read: Any) -> np.ndarray:
        """``read(dset)`` on the file's ``frames`` dataset, a damaged file named."""
        with _open_chamber(self.path) as f:
            try:
                dset = f["frames"]
            except _H5_ERRORS as exc:
                raise _damaged(self.path, exc) from None
            try:
                return read(dset)
            except (OSError, RuntimeError) as exc:  # a damaged chunk, not a bad index
                raise _damaged(self.path, exc) from None

    def _offsets(self, dset: h5py.Dataset) -> np.ndarray | None:
        """Where each frame's bytes lie in the file (:func:`frame_offsets`), found once per
        version of the file (its size and modification time)."""
        st = self.path.stat()
        stamp = (st.st_size, st.st_mtime_ns)
        cached = getattr(self, "_offset_cache", None)
        if cached is None or cached[0] != stamp:
            try:
                offsets = frame_offsets(dset, st.st_size)
            except _H5_ERRORS:  # a damaged chunk index: h5py's own read says what is wrong
                offsets = None
            cached = (stamp, offsets)
            self._offset_cache = cached
        return cached[1]

    def _read(self, dset: h5py.Dataset, key: Any) -> np.ndarray:
        """The frames of ``key`` from the open ``frames`` dataset ``dset``."""
        if isinstance(key, list | np.ndarray):
            idx = np.asarray(key)
            if idx.dtype == bool:
                if idx.shape != (self.shape[0],):
                    raise IndexError(f"boolean index of shape {idx.shape} for {self.shape}")
                idx = np.flatnonzero(idx)
            if idx.ndim != 1 or idx.dtype.kind not in "iu":
                raise IndexError("only 1-D integer or boolean index arrays are supported")
            idx = np.where(idx < 0, idx + self.shape[0], idx).astype(np.intp)
            if idx.size and (idx.min() < 0 or idx.max() >= self.shape[0]):
                raise IndexError(f"frame index out of range 0..{self.shape[0] - 1}")
            offsets = self._offsets(dset)
            if offsets is not None:  # any order: each frame read where it lies
                return _pread_frames(self.path, offsets, idx, dset.shape[1:])
            if idx.size < 2 or bool(np.all(np.diff(idx) > 0)):  # increasing: as it is
                return _read_runs(dset, idx)
            uniq, inverse = np.unique(idx, return_inverse=True)
            return _read_runs(dset, uniq)[inverse]
        if isinstance(key, slice) and (offsets := self._offsets(dset)) is not None:
            idx = np.arange(self.shape[0])[key]
            return _pread_frames(self.path, offsets, idx, dset.shape[1:])
        return np.asarray(dset[key])

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        arr = self[()]
        return arr if dtype is None else arr.astype(dtype)

    def iter_chunks(self, chunk: int = _COPY_CHUNK) -> Iterator[tuple[slice, np.ndarray]]:
        """Yield ``(slice, frames)`` blocks of at most ``chunk`` frames, in order."""
        with _open_chamber(self.path) as f:
            try:
                dset = f["frames"]
            except _H5_ERRORS as exc:
                raise _damaged(self.path, exc) from None
            for start in range(0, self.shape[0], chunk):
                sl = slice(start, min(start + chunk, self.shape[0]))
                try:
                    block = self._read(dset, sl)
                except (OSError, RuntimeError) as exc:  # a damaged chunk
                    raise _damaged(self.path, exc) from None
                yield sl, block


def frame_offsets(dset: h5py.Dataset, file_size: int) -> np.ndarray | None:
    """The byte offset in the file of each frame of a ``frames`` dataset ``(M, H, W)`` stored as
    :class:`ChamberWriter` writes it — one frame per chunk, no filter, little-endian uint16 — or
    of a contiguous one; ``(M,)`` int64, or None for any other layout, a chunk not written, or a
    frame that would lie beyond the file's ``file_size`` bytes (then h5py reads it, and says
    what is wrong)."""
    m, h, w = dset.shape
    nbytes = h * w * 2
    if dset.dtype != np.dtype("<u2") or m == 0:
        return None
    plist = dset.id.get_create_plist()
    if plist.get_nfilters():
        return None
    if dset.chunks is None:  # contiguous: one run of bytes
        start = dset.id.get_offset()
        offsets = None if start is None else start + nbytes * np.arange(m, dtype=np.int64)
    elif tuple(dset.chunks) == (1, h, w):
        offsets = np.full(m, -1, dtype=np.int64)

        def note(info: Any) -> None:
            if info.filter_mask == 0 and info.size == nbytes:
                offsets[info.chunk_offset[0]] = info.byte_offset

        dset.id.chunk_iter(note)
    else:
        return None
    if offsets is None or offsets.min() < 0 or offsets.max() + nbytes > file_size:
        return None
    return offsets


def _pread_frames(path: Path, offsets: np.ndarray, idx: np.ndarray, shape: tuple[int, ...],
                  *, parts: list[tuple[int, int]] | None = None,
                  out: np.ndarray | None = None) -> np.ndarray:
    """Frames ``idx`` read where :func:`frame_offsets` says they lie, each straight into the
    result (``os.preadv``, one call per frame).

    Written by hand because h5py reads a chunked dataset through HDF5's chunk cache and type
    conversion, chunk by chunk: 0.6 GB/s for one frame per chunk on this project's machine,
    against 5 GB/s for the same bytes read into place (``benchmarks/RESULTS.md``, chamber
    reads). Used only for the uncompressed layout :class:`ChamberWriter` writes; a short read
    (a file cut since its layout was read) is an error. ``parts``: ``(start, length)`` byte
    ranges of each frame to read, one after the other into ``shape`` (default: the whole
    frame). ``out``: a little-endian uint16 ``(len(idx), *shape)`` array to read into.
    """
    if out is None:
        out = np.empty((idx.size, *shape), dtype="<u2")
    fd = os.open(path, os.O_RDONLY)
    try:
        for k, i in enumerate(idx):
            view = memoryview(out[k]).cast("B")
            at = 0
            for start, length in parts or [(0, view.nbytes)]:
                got = os.preadv(fd, [view[at:at + length]], int(offsets[i]) + start)
                if got != length:
                    raise OSError(f"frame {int(i)} is cut short")
                at += length
    finally:
        os.close(fd)
    return out.astype(np.uint16, copy=False)


def _read_runs(dset: h5py.Dataset, frames: np.ndarray) -> np.ndarray:
    """The frames at the increasing indices ``frames`` of ``dset``, each run of consecutive
    indices read as one slice: h5py reads a list of indices a frame at a time (a selection per
    element), over ten times slower than the same frames as slices."""
    out = np.empty((frames.size, *dset.shape[1:]), dtype=dset.dtype)
    if not frames.size:
        return out
    starts = np.flatnonzero(np.diff(frames) != 1) + 1
    for a, z in zip(np.r_[0, starts], np.r_[starts, frames.size], strict=True):
        dset.read_direct(out, np.s_[frames[a] : frames[z - 1] + 1], np.s_[a:z])
    return out


# --------------------------------------------------------------------------------------------
# ChamberSession
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ChamberSession:
    """A chamber session: blackbody frames and, for each frame, its temperatures and time.

    Parameters
    ----------
    frames : numpy.ndarray, shape (M, H, W), or LazyFrames
        Raw counts, an integer dtype within ``0 .. 2**bit_depth - 1``; stored as uint16 (a 2-D
        frame becomes M = 1). A :class:`LazyFrames` (from ``read_chamber(..., frames=False)``)
        is kept as it is; its counts are not checked.
    blackbody_c : numpy.ndarray, shape (M,)
        Blackbody temperature, °C.
    fpa_c : numpy.ndarray, shape (M,)
        FPA temperature reported by the camera, °C.
    time_s : numpy.ndarray, shape (M,)
        Time of each frame, s.
    housing_c, ambient_c : numpy.ndarray or None, shape (M,)
        Optional housing and chamber (ambient) temperatures, °C.
    attrs : dict, optional
        Free metadata (``unit``, ``preset``, ``seed``, ...): strings, numbers, bools, numeric
        arrays or lists of strings (read back as lists). ``bit_depth`` (default 14) lives
        here; ``format``/``version`` belong to the file and are dropped (they must match if
        given).

    Raises
    ------
    InvalidInputError
        On counts outside the bit depth, series that are not finite, not 1-D or not of length M,
        temperatures at or below absolute zero, or attributes HDF5 cannot store.

    Notes
    -----
    Arrays are kept as read-only views (no copy when already uint16/float64). Series are
    float64.
    """

    frames: np.ndarray | LazyFrames
    blackbody_c: np.ndarray
    fpa_c: np.ndarray
    time_s: np.ndarray
    housing_c: np.ndarray | None = None
    ambient_c: np.ndarray | None = None
    attrs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        attrs = _normalise_attrs(self.attrs)
        object.__setattr__(self, "attrs", attrs)
        if isinstance(self.frames, LazyFrames):
            n = len(self.frames)
        else:
            frames = _counts_as_uint16(self.frames, attrs["bit_depth"])
            frames = frames.view()
            frames.flags.writeable = False
            object.__setattr__(self, "frames", frames)
            n = frames.shape[0]
        for key in ALL_SERIES:
            value = getattr(self, key)
            if value is None and key in REQUIRED_SERIES:
                raise InvalidInputError(f"{key}: required, one value per frame")
            object.__setattr__(self, key, _series_or_none(value, n, key))

    @property
    def n_frames(self) -> int:
        """Number of frames M."""
        return int(self.frames.shape[0])

    @property
    def frame_shape(self) -> tuple[int, int]:
        """Frame size ``(H, W)`` in pixels."""
        return int(self.frames.shape[1]), int(self.frames.shape[2])

    @property
    def bit_depth(self) -> int:
        """Bits of the raw counts."""
        return int(self.attrs["bit_depth"])


# --------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------


def _chunk_series(values: Any, k: int, name: str) -> np.ndarray:
    """A per-frame series for ``k`` new frames; a scalar is repeated ``k`` times."""
    arr = np.asarray(values)
    if arr.ndim == 0 and arr.dtype.kind in "biuf":
        arr = np.full(k, arr, dtype=np.float64)
    if name == "fpa_c":
        check = as_fpa_c
    else:
        check = as_temperature_c if name.endswith("_c") else as_float_array
    arr = check(arr, name, ndim=1)
    check_length(arr, k, name)
    return arr.astype(np.float64, copy=False)


class ChamberWriter:
    """Stream a chamber session to an HDF5 file, frames appended in blocks.

    The data go into resizable datasets of a temporary file beside ``path``; the file is renamed
    onto ``path`` only when the ``with`` block ends without an error (and at least one frame was
    appended). On error the temporary file is removed and an existing ``path`` is untouched.
    Memory use is bounded by the block passed to :meth:`append`.

    Parameters
    ----------
    path : str or os.PathLike
        The output chamber file (``.h5``); its directory must exist.
    frame_shape : tuple of int
        ``(H, W)`` of every frame, pixels.
    attrs : dict, optional
        Free metadata attributes (see :class:`ChamberSession`); ``bit_depth`` defaults to 14.
    compression : {None, "gzip", "lzf"}, optional
        HDF5 compression of the frames (default None: fastest).

    Examples
    --------
    >>> with ChamberWriter("chamber.h5", (256, 336), attrs={"seed": 1}) as w:  # doctest: +SKIP
    ...     for block, bb, fpa, t in blocks:
    ...         w.append(block, blackbody_c=bb, fpa_c=fpa, time_s=t)
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        frame_shape: tuple[int, int],
        *,
        attrs: Mapping[str, Any] | None = None,
        compression: str | None = None,
    ) -> None:
        try:
            h, w = (int(s) for s in frame_shape)
        except (TypeError, ValueError):
            raise InvalidInputError(f"frame_shape: expected (H, W), got {frame_shape!r}") from None
        if h < 1 or w < 1:
            raise InvalidInputError(f"frame_shape: must be positive, got {(h, w)}")
        if compression not in (None, "gzip", "lzf"):
            raise InvalidInputError(
                f"compression: expected None, 'gzip' or 'lzf', not {compression!r}"
            )
        self.path = Path(path)
        self.frame_shape = (h, w)
        self.attrs = _normalise_attrs(attrs)
        self._compression = compression
        self._stack: contextlib.ExitStack | None = None
        self._file: h5py.File | None = None
        self._n = 0
        self._optional: dict[str, bool] = {}

    @property
    def n_frames(self) -> int:
        """Frames appended so far."""
        return self._n

    def __enter__(self) -> ChamberWriter:
        if self._stack is not None:
            raise RuntimeError("ChamberWriter: already open")
        stack = contextlib.ExitStack()
        try:
            tmp = stack.enter_context(atomic_path(self.path))
            f = h5py.File(tmp, "w")
            stack.callback(f.close)  # closes before atomic_path renames or removes the file
            h, w = self.frame_shape
            f.create_dataset(
                "frames",
                shape=(0, h, w),
                maxshape=(None, h, w),
                dtype=np.uint16,
                chunks=(1, h, w),
                compression=self._compression,
            )
            for key in REQUIRED_SERIES:
                self._create_series(f, key)
            f.attrs["format"] = CHAMBER_FORMAT
            f.attrs["version"] = np.int64(CHAMBER_VERSION)
            for key, value in self.attrs.items():
                f.attrs[key] = _to_h5_attr(value)
        except BaseException:
            stack.close()
            raise
        self._stack, self._file = stack, f
        return self

    @staticmethod
    def _create_series(f: h5py.File, key: str) -> None:
        f.create_dataset(
            key, shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(_SERIES_CHUNK,)
        )

    def append(
        self,
        frames: Any,
        blackbody_c: Any,
        fpa_c: Any,
        time_s: Any,
        housing_c: Any = None,
        ambient_c: Any = None,
    ) -> None:
        """Append ``k`` frames and their per-frame values.

        Parameters
        ----------
        frames : array_like, shape (k, H, W) or (H, W)
            Raw counts (integers within the bit depth).
        blackbody_c, fpa_c : array_like, shape (k,) or scalar
            Blackbody and FPA temperatures, °C; a scalar applies to all k frames.
        time_s : array_like, shape (k,) or scalar
            Time of each frame, s.
        housing_c, ambient_c : array_like or None, shape (k,) or scalar
            Optional temperatures, °C. Whether each is given must be the same in every call.

        Raises
        ------
        InvalidInputError
            On bad counts or series, or an optional series given in some calls but not others.
            Nothing is appended then.
        ResolutionMismatchError
            If the frames are not ``frame_shape``.
        """
        if self._file is None:
            raise RuntimeError("ChamberWriter.append: use the writer in a `with` block")
        block = _counts_as_uint16(frames, self.attrs["bit_depth"])
        if block.shape[1:] != self.frame_shape:
            h, w = self.frame_shape
            raise ResolutionMismatchError(
                f"frames are {block.shape[2]}x{block.shape[1]} but this chamber file is {w}x{h}"
            )
        k = block.shape[0]
        given = {
            "blackbody_c": blackbody_c,
            "fpa_c": fpa_c,
            "time_s": time_s,
            "housing_c": housing_c,
            "ambient_c": ambient_c,
        }
        series: dict[str, np.ndarray] = {}
        for key in ALL_SERIES:
            value = given[key]
            if key in OPTIONAL_SERIES:
                present = value is not None
                if self._optional.setdefault(key, present) != present:
                    raise InvalidInputError(
                        f"{key}: given in some append() calls but not in others; "
                        "give it for every frame or never"
                    )
                if not present:
                    continue
            series[key] = _chunk_series(value, k, key)
        f = self._file
        n0, n1 = self._n, self._n + k
        for key, values in series.items():
            if key not in f:
                self._create_series(f, key)
            f[key].resize((n1,))
            f[key][n0:n1] = values
        dset = f["frames"]
        dset.resize((n1, *self.frame_shape))
        dset[n0:n1] = block
        self._n = n1

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> bool:
        stack, self._stack, self._file = self._stack, None, None
        if stack is None:
            return False
        if exc_type is None and self._n == 0:
            try:
                raise InvalidInputError(f"{self.path}: no frames were appended; nothing written")
            except InvalidInputError as err:
                stack.__exit__(type(err), err, err.__traceback__)
                raise
        return bool(stack.__exit__(exc_type, exc, tb))


def write_chamber(
    path: str | os.PathLike[str], session: ChamberSession, *, compression: str | None = None
) -> Path:
    """Write a chamber session to an HDF5 chamber file, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The output file; its directory must exist. It may be the file ``session`` was lazily
        read from: the new file replaces it only once complete.
    session : ChamberSession
        The session; lazy frames are copied block by block.
    compression : {None, "gzip", "lzf"}, optional
        HDF5 compression of the frames.

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.
    """
    if not isinstance(session, ChamberSession):
        raise InvalidInputError(f"session: expected a ChamberSession, got {type(session).__name__}")
    with ChamberWriter(
        path, session.frame_shape, attrs=session.attrs, compression=compression
    ) as writer:
        if isinstance(session.frames, LazyFrames):
            blocks: Iterator[tuple[slice, np.ndarray]] = session.frames.iter_chunks(_COPY_CHUNK)
        else:
            frames = session.frames
            blocks = (
                (slice(s, s + _COPY_CHUNK), frames[s : s + _COPY_CHUNK])
                for s in range(0, session.n_frames, _COPY_CHUNK)
            )
        for sl, block in blocks:
            writer.append(
                block,
                blackbody_c=session.blackbody_c[sl],
                fpa_c=session.fpa_c[sl],
                time_s=session.time_s[sl],
                housing_c=None if session.housing_c is None else session.housing_c[sl],
                ambient_c=None if session.ambient_c is None else session.ambient_c[sl],
            )
    return Path(path)


# --------------------------------------------------------------------------------------------
# reading and validation
# --------------------------------------------------------------------------------------------


def _global_heap_damaged(path: Path, head: int = 1 << 20) -> bool:
    """Whether a global heap collection (``GCOL``, where HDF5 keeps variable-length strings) in
    the first ``head`` bytes is inconsistent: libhdf5 loops for ever reading a string from a
    collection whose object sizes overrun it. Each collection is walked object by object; its
    last (free-space, index 0) object must end where the collection does."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(head)
    except OSError:  # h5py reports it
        return False
    pos = data.find(b"GCOL")
    while pos >= 0 and pos + 16 <= len(data):
        end = pos + int.from_bytes(data[pos + 8:pos + 16], "little")
        obj = pos + 16
        while True:
            if obj + 16 > min(end, len(data)):
                # the free-space object is left out when fewer than 16 bytes remain
                if obj > end and end <= len(data):
                    return True
                break
            index = int.from_bytes(data[obj:obj + 2], "little")
            size = int.from_bytes(data[obj + 8:obj + 16], "little")
            if index == 0:
                if size != end - obj:
                    return True
                break
            obj += 16 + (size + 7) // 8 * 8
        pos = data.find(b"GCOL", pos + 4)
    return False


def damaged_attribute_type(f: h5py.File) -> str | None:
    """The name of the first attribute of an HDF5 file's root whose datatype is a variable-length
    sequence (a damaged variable-length string's type bits: libhdf5 crashes, SIGSEGV, when it
    reads one, which nothing can catch); None when there is none. Only types are looked at."""
    for index in range(h5py.h5a.get_num_attrs(f.id)):
        attr = h5py.h5a.open(f.id, index=index)
        if isinstance(attr.get_type(), h5py.h5t.TypeVlenID):
            return attr.get_name().decode("utf-8", "replace")
    return None


@contextlib.contextmanager
def _open_chamber(path: Path) -> Iterator[h5py.File]:
    """Open an HDF5 file for reading, turning failures into FileFormatError."""
    if not path.is_file():
        raise FileFormatError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except _H5_ERRORS as exc:
        raise FileFormatError(f"{path}: {_open_problem(exc)}") from None
    try:
        yield f
    finally:
        f.close()


def _open_problem(exc: BaseException) -> str:
    text = str(exc)
    if "truncated" in text:
        return "the HDF5 file is truncated; write it again"
    return f"not a readable HDF5 file ({text[:120]})"


def chamber_problems(path: str | os.PathLike[str]) -> list[str]:
    """List every problem that keeps ``path`` from being a valid chamber file.

    Checks the attributes (``format``, ``version``, ``bit_depth``), the presence, dtype and shape
    of every dataset, that the series have one value per frame, and that they are finite (and,
    for temperatures, above absolute zero). The counts in ``frames`` are not read.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    list of str
        One line per problem; empty for a valid file.
    """
    p = Path(path)
    if not p.is_file():
        return ["no such file"]
    if _global_heap_damaged(p):
        return [_HEAP_DAMAGED]
    try:
        f = h5py.File(p, "r")
    except _H5_ERRORS as exc:
        return [_open_problem(exc)]
    problems: list[str] = []
    with f:
        try:
            damaged = damaged_attribute_type(f)
            if damaged is not None:
                return [f"the chamber file is damaged and cannot be read (attribute {damaged!r} "
                        "has a damaged type); copy or record it again"]
            _file_problems(f, problems)
        except _H5_ERRORS as exc:  # a damaged header, heap or B-tree
            text = " ".join(str(exc).split())[:120]
            problems.append(f"the chamber file is damaged and cannot be read ({text}); copy or "
                            "record it again")
    return problems


def _file_problems(f: h5py.File, problems: list[str]) -> None:
    """Add the problems of the open chamber file ``f`` to ``problems``."""
    attrs = f.attrs
    if "format" in attrs and _attr_to_python(attrs["format"]) == "thermocal-calibration":
        problems.append("a calibration, not a chamber session: give the chamber session "
                        "(frames of a blackbody), which `thermocal calibrate` fits one from")
        return  # the one problem: its other attributes are a calibration's
    if "format" not in attrs:
        problems.append("attribute 'format' is missing (not a thermocal chamber file?)")
    elif _attr_to_python(attrs["format"]) != CHAMBER_FORMAT:
        problems.append(
            f"attribute 'format' is {_attr_to_python(attrs['format'])!r}, "
            f"expected {CHAMBER_FORMAT!r}"
        )
    if "version" not in attrs:
        problems.append("attribute 'version' is missing")
    elif _attr_to_python(attrs["version"]) != CHAMBER_VERSION:
        problems.append(
            f"unsupported version {_attr_to_python(attrs['version'])!r} "
            f"(this thermocal reads version {CHAMBER_VERSION})"
        )
    if "bit_depth" not in attrs:
        problems.append("attribute 'bit_depth' is missing")
    else:
        try:
            _check_bit_depth(_attr_to_python(attrs["bit_depth"]))
        except InvalidInputError as exc:
            problems.append(f"attribute {exc}")
    n_frames = _frames_problems(f, problems)
    for key in ALL_SERIES:
        _series_problems(f, key, n_frames, problems)


def _frames_problems(f: h5py.File, problems: list[str]) -> int | None:
    """Check the ``frames`` dataset; return M, or None if there is no usable frame axis."""
    if "frames" not in f:
        problems.append("dataset 'frames' is missing")
        return None
    dset = f["frames"]
    if not isinstance(dset, h5py.Dataset):
        problems.append("'frames' is not a dataset")
        return None
    if dset.dtype != np.uint16:
        problems.append(f"dataset 'frames' has dtype {dset.dtype}, expected uint16")
    if dset.ndim != 3:
        problems.append(f"dataset 'frames' has shape {dset.shape}, expected (M, H, W)")
        return None
    if 0 in dset.shape:
        problems.append(f"dataset 'frames' is empty (shape {dset.shape})")
    if _declares_too_much(f, dset):
        problems.append(f"dataset 'frames' declares {dset.shape}: more than the file holds")
        return None
    return int(dset.shape[0])


def _declares_too_much(f: h5py.File, dset: h5py.Dataset) -> bool:
    """Whether ``dset`` declares more bytes than the file can hold (a damaged header): reading
    it would allocate them. A compressed dataset may hold up to 1032 times its size (gzip)."""
    nbytes = math.prod(dset.shape) * dset.dtype.itemsize
    size = os.path.getsize(f.filename)
    return nbytes > (size if dset.compression is None else 1032 * size + (1 << 20))


def _series_problems(f: h5py.File, key: str, n_frames: int | None, problems: list[str]) -> None:
    if key not in f:
        if key in REQUIRED_SERIES:
            problems.append(f"dataset {key!r} is missing")
        return
    dset = f[key]
    if not isinstance(dset, h5py.Dataset):
        problems.append(f"{key!r} is not a dataset")
        return
    if dset.dtype.kind != "f":
        problems.append(f"dataset {key!r} has dtype {dset.dtype}, expected float")
    if dset.ndim != 1:
        problems.append(f"dataset {key!r} has shape {dset.shape}, expected (M,)")
        return
    if n_frames is not None and dset.shape[0] != n_frames:
        problems.append(
            f"dataset {key!r} has {dset.shape[0]} values but 'frames' has {n_frames} frames"
        )
    if dset.dtype.kind not in "biuf":
        return
    if _declares_too_much(f, dset):
        problems.append(f"dataset {key!r} declares {dset.shape}: more than the file holds")
        return
    try:
        values = np.asarray(dset[()], dtype=np.float64)
    except OSError as exc:
        problems.append(f"dataset {key!r} cannot be read ({str(exc)[:80]})")
        return
    n_bad = int(np.count_nonzero(~np.isfinite(values)))
    if n_bad:
        problems.append(f"dataset {key!r} holds {n_bad} NaN or infinite value(s)")
    elif key.endswith("_c") and values.size and float(values.min()) <= ABSOLUTE_ZERO_C:
        problems.append(f"dataset {key!r} holds temperatures at or below absolute zero")
    elif key == "fpa_c":
        try:
            as_fpa_c(values, "dataset 'fpa_c'")
        except InvalidInputError as exc:
            problems.append(str(exc))


def validate_chamber(path: str | os.PathLike[str]) -> None:
    """Raise :class:`FileFormatError` unless ``path`` is a valid chamber file.

    The one-line message names the first problem and counts the others; the full list is on
    the exception's ``problems`` attribute (see :func:`chamber_problems`).

    Raises
    ------
    FileFormatError
        If the file is missing, not HDF5, truncated, or breaks the chamber format.
    """
    problems = chamber_problems(path)
    if problems:
        more = len(problems) - 1
        tail = f" (and {more} other problem{'s' if more > 1 else ''})" if more else ""
        err = FileFormatError(f"{Path(path)}: {problems[0]}{tail}")
        err.problems = problems  # type: ignore[attr-defined]
        raise err


def read_chamber(path: str | os.PathLike[str], *, frames: bool = True) -> ChamberSession:
    """Read a chamber file.

    Parameters
    ----------
    path : str or os.PathLike
        The chamber file.
    frames : bool, optional
        True (default): read all frames into memory (and check their counts against the bit
        depth). False: ``session.frames`` is a :class:`LazyFrames` that reads frames from the
        file on demand and holds no open file, for sessions larger than memory.

    Returns
    -------
    ChamberSession
        Frames ``(M, H, W)`` uint16, series float64 ``(M,)``; every file attribute other than
        ``format`` and ``version`` in ``attrs``.

    Raises
    ------
    FileFormatError
        If the file is not a valid chamber file (see :func:`validate_chamber`) or, with
        ``frames=True``, holds counts above the bit depth.
    """
    p = Path(path)
    validate_chamber(p)
    with _open_chamber(p) as f:
        try:
            attrs = {
                key: _attr_to_python(value)
                for key, value in f.attrs.items()
                if key not in ("format", "version")
            }
            series = {key: np.asarray(f[key][()], dtype=np.float64)
                      for key in ALL_SERIES if key in f}
            dset = f["frames"]
            data: np.ndarray | LazyFrames = dset[()] if frames else LazyFrames(p, dset.shape)
        except _H5_ERRORS as exc:
            raise _damaged(p, exc) from None
    try:
        return ChamberSession(data, attrs=attrs, **series)
    except InvalidInputError as exc:
        raise FileFormatError(f"{p}: {exc}") from None


def iter_chamber_frames(
    path: str | os.PathLike[str], *, chunk: int = 256
) -> Iterator[tuple[slice, np.ndarray]]:
    """Iterate over a chamber file's frames in blocks without loading them all.

    The file is validated when this function is called; the blocks are read lazily.

    Parameters
    ----------
    path : str or os.PathLike
        The chamber file.
    chunk : int, optional
        Frames per block (default 256); the last block may be shorter.

    Yields
    ------
    frames_slice : slice
        The frames of the block (index it into the series, e.g. ``session.fpa_c[frames_slice]``).
    frames : numpy.ndarray, shape (k, H, W), uint16

    Raises
    ------
    InvalidInputError
        If ``chunk`` is not a positive integer.
    FileFormatError
        If the file is not a valid chamber file; counts above the bit depth are found while
        iterating.
    """
    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
        raise InvalidInputError(f"chunk: expected a positive number of frames, got {chunk!r}")
    p = Path(path)
    validate_chamber(p)
    with _open_chamber(p) as f:
        try:
            shape = f["frames"].shape
            bit_depth = int(_attr_to_python(f.attrs["bit_depth"]))
        except _H5_ERRORS as exc:
            raise _damaged(p, exc) from None
    return _iter_frames(p, shape, int(chunk), bit_depth)


def _iter_frames(
    path: Path, shape: tuple[int, ...], chunk: int, bit_depth: int
) -> Iterator[tuple[slice, np.ndarray]]:
    max_count = 2**bit_depth - 1
    for sl, block in LazyFrames(path, shape).iter_chunks(chunk):  # type: ignore[arg-type]
        over = first_frame_outside(block, max_count)
        if over is not None:
            raise FileFormatError(
                f"{path}: frame {sl.start + over} holds counts above the {bit_depth}-bit "
                f"maximum {max_count}: if the camera gives more bits, say so in the file's "
                "bit_depth attribute")
        yield sl, block
