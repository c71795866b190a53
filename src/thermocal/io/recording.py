"""Recordings of raw frames (``NAME.tiff`` + sidecar ``NAME.json``) and temperature TIFFs.

A **recording** (DESIGN.md, "The contract: command line and files") is a multi-page uint16 TIFF
``NAME.tiff`` holding ``(N, H, W)`` raw counts, one page per frame, with an optional sidecar
``NAME.json``::

    {"fpa_c": [...], "time_s": [...], "housing_c": [...], "ambient_c": [...], "bit_depth": 14,
     ...free keys such as "pivot"...}

where each list has one value per frame. Absent series are simply left out. A command-line
``--fpa-c`` replaces the FPA series by a constant (``read_recording(path, fpa_c=...)``).

Temperature outputs are float32 TIFFs in °C, ``(H, W)`` or ``(N, H, W)``.

Every writer here is atomic (:mod:`thermocal.io.atomic`); every reader turns a missing, truncated
or mistyped file into :class:`~thermocal.errors.FileFormatError` with a one-line message.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import tifffile

from thermocal._validate import (
    TIFF_SUFFIXES,
    as_float_array,
    as_fpa_c,
    as_frames,
    as_temperature_c,
    check_fpa_c,
    check_length,
    check_suffix,
    first_frame_outside,
)
from thermocal.errors import FileFormatError, InvalidInputError, ThermocalError
from thermocal.io.atomic import atomic_path

if TYPE_CHECKING:
    from thermocal.io.geotag import MapTags

__all__ = [
    "SERIES_KEYS",
    "Recording",
    "RecordingHeader",
    "RecordingWriter",
    "check_time_order",
    "iter_recording",
    "read_recording_header",
    "read_recording",
    "read_temperature_tiff",
    "sidecar_path",
    "write_recording",
    "write_temperature_tiff",
]

#: Per-frame series a recording may carry, in sidecar order.
SERIES_KEYS: tuple[str, ...] = ("fpa_c", "time_s", "housing_c", "ambient_c")
_RESERVED_KEYS = frozenset((*SERIES_KEYS, "bit_depth"))


# --------------------------------------------------------------------------------------------
# shared validation helpers (also used by thermocal.io.chamber)
# --------------------------------------------------------------------------------------------


def _check_bit_depth(bit_depth: Any, name: str = "bit_depth") -> int:
    """Return ``bit_depth`` as an int in 1..16 or raise :class:`InvalidInputError`."""
    if isinstance(bit_depth, bool) or not isinstance(bit_depth, int | np.integer):
        raise InvalidInputError(f"{name}: expected an integer number of bits, got {bit_depth!r}")
    if not 1 <= int(bit_depth) <= 16:
        raise InvalidInputError(f"{name}: must be between 1 and 16 bits, got {int(bit_depth)}")
    return int(bit_depth)


def _counts_as_uint16(frames: Any, bit_depth: int, name: str = "frames") -> np.ndarray:
    """Validate raw counts and return them as a ``(N, H, W)`` uint16 array (no copy if possible).

    Integer dtypes only; values must lie in ``0 .. 2**bit_depth - 1``
    (:func:`thermocal._validate.as_frames`); a 2-D frame becomes N = 1.
    """
    arr = np.asarray(frames)
    if arr.dtype.kind not in "ui":
        raise InvalidInputError(
            f"{name}: raw counts must be integers (uint16), got dtype {arr.dtype}"
        )
    return as_frames(arr, name, bit_depth=bit_depth).astype(np.uint16, copy=False)


def _read_only(arr: np.ndarray) -> np.ndarray:
    """A read-only view of ``arr`` (the caller's array keeps its own flags)."""
    view = arr.view()
    view.flags.writeable = False
    return view


def _series_or_none(values: Any, n: int, name: str) -> np.ndarray | None:
    """Validate an optional per-frame series: finite, 1-D, length ``n``, float64, read-only.

    Names ending in ``_c`` are temperatures and must lie above absolute zero; ``fpa_c`` must
    lie within :data:`thermocal._validate.FPA_RANGE_C`.
    """
    if values is None:
        return None
    if name == "fpa_c":
        check = as_fpa_c
    else:
        check = as_temperature_c if name.endswith("_c") else as_float_array
    arr = check(values, name, ndim=1)
    check_length(arr, n, name)
    return _read_only(arr.astype(np.float64, copy=False))


# --------------------------------------------------------------------------------------------
# Recording
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Recording:
    """Raw frames of one recording with their per-frame metadata.

    Parameters
    ----------
    frames : numpy.ndarray, shape (N, H, W) or (H, W)
        Raw counts, an integer dtype within ``0 .. 2**bit_depth - 1``; stored as uint16. A single
        ``(H, W)`` frame becomes ``N = 1``.
    fpa_c : numpy.ndarray or None, shape (N,)
        FPA temperature reported by the camera for each frame, °C.
    time_s : numpy.ndarray or None, shape (N,)
        Time stamp of each frame, s.
    housing_c : numpy.ndarray or None, shape (N,)
        Housing temperature for each frame, °C.
    ambient_c : numpy.ndarray or None, shape (N,)
        Ambient temperature for each frame, °C.
    bit_depth : int, optional
        Bits of the raw counts, 1..16 (default 14, a Tau2).
    extra : dict, optional
        Further JSON-serialisable sidecar entries (for example ``"pivot"``); must not reuse the
        keys ``fpa_c``, ``time_s``, ``housing_c``, ``ambient_c``, ``bit_depth``.

    Raises
    ------
    InvalidInputError
        If the frames are not integer counts within the bit depth, a series is not finite, not
        1-D or not of length N, a temperature is at or below absolute zero, or ``extra`` reuses a
        reserved key.

    Notes
    -----
    The arrays are stored as read-only views: they are not copied when already uint16/float64,
    and a Recording never changes them. Series are float64.
    """

    frames: np.ndarray
    fpa_c: np.ndarray | None = None
    time_s: np.ndarray | None = None
    housing_c: np.ndarray | None = None
    ambient_c: np.ndarray | None = None
    bit_depth: int = 14
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        bit_depth = _check_bit_depth(self.bit_depth)
        frames = _read_only(_counts_as_uint16(self.frames, bit_depth))
        n = frames.shape[0]
        object.__setattr__(self, "bit_depth", bit_depth)
        object.__setattr__(self, "frames", frames)
        for key in SERIES_KEYS:
            object.__setattr__(self, key, _series_or_none(getattr(self, key), n, key))
        if not isinstance(self.extra, dict):
            raise InvalidInputError(f"extra: expected a dict, got {type(self.extra).__name__}")
        bad = sorted(k for k in self.extra if not isinstance(k, str) or k in _RESERVED_KEYS)
        if bad:
            raise InvalidInputError(
                f"extra: keys {bad} are reserved or not strings; pass series as fields"
            )
        object.__setattr__(self, "extra", dict(self.extra))

    @property
    def n_frames(self) -> int:
        """Number of frames N."""
        return int(self.frames.shape[0])

    @property
    def frame_shape(self) -> tuple[int, int]:
        """Frame size ``(H, W)`` in pixels."""
        return int(self.frames.shape[1]), int(self.frames.shape[2])

    def sidecar(self) -> dict[str, Any]:
        """The sidecar JSON content: present series as lists, ``bit_depth``, then ``extra``."""
        out: dict[str, Any] = {}
        for key in SERIES_KEYS:
            values = getattr(self, key)
            if values is not None:
                out[key] = values.tolist()
        out["bit_depth"] = self.bit_depth
        out.update(self.extra)
        return out


def sidecar_path(path: str | os.PathLike[str]) -> Path:
    """The sidecar of a recording: ``NAME.tiff`` → ``NAME.json``."""
    return Path(path).with_suffix(".json")


def _check_tiff_name(path: str | os.PathLike[str]) -> Path:
    """Return ``path`` as a Path, raising InvalidInputError unless it ends in .tif/.tiff."""
    return check_suffix(path, TIFF_SUFFIXES, "a TIFF output")


def _sidecar_text(sidecar: dict[str, Any], json_path: Path) -> str:
    """The sidecar as JSON text: one key per line, each list on one line (readable, compact)."""
    try:
        lines = [
            f"  {json.dumps(key)}: {json.dumps(value, allow_nan=False)}"
            for key, value in sidecar.items()
        ]
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(
            f"{json_path}: extra metadata is not JSON-serialisable ({exc})"
        ) from None
    return "{\n" + ",\n".join(lines) + "\n}\n"


class RecordingWriter:
    """Stream a recording to ``NAME.tiff`` + ``NAME.json`` chunk by chunk (bounded memory).

    Use as a context manager; :meth:`append` validates each chunk like :class:`Recording` does.
    A series (``fpa_c``, ``time_s``, ...) must be given with every chunk or with none. Both files
    appear, complete, only when the block ends without an error; otherwise nothing is written
    and an existing recording of that name is left untouched.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``NAME.tiff`` (or ``.tif``); its directory must exist.
    bit_depth : int
        Bits of the raw counts (default 14).
    extra : dict, optional
        Further JSON-serialisable sidecar entries (not the reserved series keys).
    """

    def __init__(
        self, path: str | os.PathLike[str], *, bit_depth: int = 14, extra: dict | None = None
    ) -> None:
        self.tiff_path = _check_tiff_name(path)
        self.json_path = sidecar_path(self.tiff_path)
        # validates bit depth and extra keys once, up front
        self._template = Recording(np.zeros((1, 1, 1), np.uint16), bit_depth=bit_depth,
                                   extra=dict(extra or {}))
        self._series: dict[str, list[float]] | None = None
        self._shape: tuple[int, int] | None = None
        self.n_frames = 0
        self._stack: contextlib.ExitStack | None = None

    def __enter__(self) -> RecordingWriter:
        stack = contextlib.ExitStack()
        try:
            self._tiff_tmp = stack.enter_context(atomic_path(self.tiff_path))
            self._json_tmp = stack.enter_context(atomic_path(self.json_path))
            self._writer = stack.enter_context(tifffile.TiffWriter(self._tiff_tmp, bigtiff=True))
        except BaseException:
            stack.close()
            raise
        self._stack = stack
        return self

    def append(
        self,
        frames: Any,
        *,
        fpa_c: Any = None,
        time_s: Any = None,
        housing_c: Any = None,
        ambient_c: Any = None,
    ) -> None:
        """Add ``(k, H, W)`` frames (or one ``(H, W)``) with their per-frame series."""
        if self._stack is None:
            raise InvalidInputError("RecordingWriter.append: use the writer in a with-block")
        chunk = Recording(frames, fpa_c=fpa_c, time_s=time_s, housing_c=housing_c,
                          ambient_c=ambient_c, bit_depth=self._template.bit_depth)
        present = {k: getattr(chunk, k) for k in SERIES_KEYS if getattr(chunk, k) is not None}
        if self._series is None:
            self._series = {k: [] for k in present}
            self._shape = chunk.frame_shape
        if set(present) != set(self._series):
            raise InvalidInputError(
                f"{self.tiff_path}: every chunk must carry the same series "
                f"({sorted(self._series)}), got {sorted(present)}"
            )
        if chunk.frame_shape != self._shape:
            raise InvalidInputError(
                f"{self.tiff_path}: frames of {chunk.frame_shape} after frames of {self._shape}"
            )
        # no shape metadata: the pages of all chunks then read back as one (N, H, W) series
        self._writer.write(
            chunk.frames, photometric="minisblack", contiguous=True, metadata=None
        )
        for key, values in present.items():
            self._series[key].extend(values.tolist())
        self.n_frames += chunk.n_frames

    def __exit__(self, exc_type, exc, tb) -> bool:
        stack, self._stack = self._stack, None
        assert stack is not None
        if exc_type is not None:
            stack.__exit__(exc_type, exc, tb)  # removes both temporary files
            return False
        try:
            if self.n_frames == 0:
                raise InvalidInputError(f"{self.tiff_path}: no frames were written")
            sidecar = dict(self._series or {})
            sidecar["bit_depth"] = self._template.bit_depth
            sidecar.update(self._template.extra)
            self._writer.close()
            self._json_tmp.write_text(_sidecar_text(sidecar, self.json_path), encoding="utf-8")
        except BaseException as err:
            stack.__exit__(type(err), err, err.__traceback__)
            raise
        stack.__exit__(None, None, None)  # renames both into place
        return False


def write_recording(path: str | os.PathLike[str], rec: Recording) -> tuple[Path, Path]:
    """Write a recording as ``NAME.tiff`` (uint16, one page per frame) and ``NAME.json``.

    Both files are written to temporary files first and renamed into place only when both are
    complete, so a failed write leaves any previous recording untouched. The sidecar is always
    written (it carries at least ``bit_depth``), which replaces a stale one.

    Returns ``(tiff_path, json_path)``. Raises InvalidInputError if ``path`` is not a TIFF
    name, ``rec`` is not a Recording, or ``rec.extra`` cannot be written as JSON (nothing is
    written then).
    """
    if not isinstance(rec, Recording):
        raise InvalidInputError(f"rec: expected a Recording, got {type(rec).__name__}")
    json_path = sidecar_path(_check_tiff_name(path))
    _sidecar_text(rec.sidecar(), json_path)  # fail early, before any file is created
    with RecordingWriter(path, bit_depth=rec.bit_depth, extra=rec.extra) as writer:
        writer.append(rec.frames, **{k: getattr(rec, k) for k in SERIES_KEYS})
    return writer.tiff_path, writer.json_path


# --------------------------------------------------------------------------------------------
# TIFF reading
# --------------------------------------------------------------------------------------------


class _ErrorRecords(logging.Handler):
    """Collects tifffile's ERROR log records (it logs, not raises, on bad page offsets)."""

    def __init__(self) -> None:
        super().__init__(level=logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


_QUIET = {"depth": 0, "propagate": True, "null": logging.NullHandler()}
_QUIET_LOCK = threading.Lock()


@contextlib.contextmanager
def quiet_tifffile() -> Iterator[None]:
    """Keep tifffile's log messages off stderr while a TIFF that may be corrupt is read: the
    reader says what is wrong in one line (an error, or a file redone), where tifffile would
    also log each bad tag. Its logger stops passing records up (a null handler in place of
    Python's last resort) while any read is inside (threads may overlap: counted, the logger
    restored when the last leaves); handlers on that logger itself (the readers'
    :func:`_tiff_errors`) still get them."""
    logger = logging.getLogger("tifffile")
    with _QUIET_LOCK:
        if _QUIET["depth"] == 0:
            _QUIET["propagate"] = logger.propagate
            logger.addHandler(_QUIET["null"])
            logger.propagate = False
        _QUIET["depth"] += 1
    try:
        yield
    finally:
        with _QUIET_LOCK:
            _QUIET["depth"] -= 1
            if _QUIET["depth"] == 0:
                logger.propagate = _QUIET["propagate"]
                logger.removeHandler(_QUIET["null"])


@contextlib.contextmanager
def _tiff_errors() -> Iterator[_ErrorRecords]:
    """Capture tifffile's logged errors while a TIFF is indexed."""
    handler = _ErrorRecords()
    logger = logging.getLogger("tifffile")
    logger.addHandler(handler)
    try:
        yield handler
    finally:
        logger.removeHandler(handler)


@dataclass(frozen=True)
class _StackInfo:
    """Where a TIFF keeps its image stack."""

    n: int
    height: int
    width: int
    dtype: np.dtype
    dataoffset: int | None  # contiguous uncompressed data (memory-mappable) or None


def _stack_info(tif: tifffile.TiffFile, path: Path, errors: _ErrorRecords) -> _StackInfo:
    """Validate that ``tif`` holds exactly one complete stack of grey images and describe it."""
    series_list = tif.series
    if errors.messages:
        raise FileFormatError(
            f"{path}: the TIFF is truncated or corrupt ({errors.messages[0]}); write it again"
        )
    if not series_list:
        raise FileFormatError(f"{path}: the TIFF holds no image")
    if len(series_list) > 1:
        shapes = ", ".join(str(s.shape) for s in series_list[:3])
        raise FileFormatError(
            f"{path}: the TIFF holds {len(series_list)} image series ({shapes}); "
            "expected one stack of equally sized frames"
        )
    series = series_list[0]
    axes = series.axes
    if "S" in axes and series.shape[axes.index("S")] > 1:
        raise FileFormatError(f"{path}: colour (RGB) images are not thermal frames")
    shape = tuple(s for s, a in zip(series.shape, axes, strict=True) if a != "S")
    if len(shape) < 2 or 0 in shape:
        raise FileFormatError(f"{path}: image series of shape {series.shape} is not an image")
    height, width = shape[-2:]
    n = int(np.prod(shape[:-2], dtype=np.int64)) if len(shape) > 2 else 1
    size = tif.filehandle.size
    offset = series.dataoffset
    if offset is not None:
        if offset + series.nbytes > size:
            raise FileFormatError(
                f"{path}: the TIFF is truncated ({size} bytes, its images need "
                f"{offset + series.nbytes}); write it again"
            )
    else:
        for page in series.pages:
            if page is None:
                raise FileFormatError(f"{path}: the TIFF is missing pages (truncated?)")
            ends = [o + c for o, c in zip(page.dataoffsets, page.databytecounts, strict=False)]
            if ends and max(ends) > size:
                raise FileFormatError(f"{path}: the TIFF is truncated; write it again")
    return _StackInfo(n, int(height), int(width), np.dtype(series.dtype), offset)


def _open_error(path: Path, exc: BaseException) -> FileFormatError:
    return FileFormatError(
        f"{path}: not a readable TIFF ({type(exc).__name__}: {str(exc)[:120]}); "
        "the file may be truncated or corrupt"
    )


def _read_tiff_stack(path: Path) -> tuple[np.ndarray, _StackInfo]:
    """Read a TIFF's single image stack as ``(N, H, W)`` (or ``(H, W)`` if one plain page)."""
    if not path.is_file():
        raise FileFormatError(f"{path}: no such file")
    try:
        with _tiff_errors() as errors, tifffile.TiffFile(path) as tif:
            info = _stack_info(tif, path, errors)
            data = tif.series[0].asarray()
    except ThermocalError:
        raise
    except Exception as exc:  # tifffile raises many types on corrupt input
        raise _open_error(path, exc) from None
    return data, info


def _read_sidecar(json_path: Path) -> dict[str, Any] | None:
    """Parse a sidecar, or None if there is none."""
    if not json_path.exists():
        return None
    if not json_path.is_file():  # a FIFO would block the read for good
        raise FileFormatError(f"{json_path}: not a file (a pipe, a device): a sidecar is a "
                              "JSON file")
    def unique(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        keys = [k for k, _ in pairs]
        twice = sorted({k for k in keys if keys.count(k) > 1})
        if twice:  # JSON takes the last silently: which did the user mean?
            raise ValueError(f"the key {twice[0]!r} is given twice")
        return dict(pairs)

    try:  # utf-8-sig: a sidecar saved with a byte-order mark (Windows editors) reads too
        obj = json.loads(json_path.read_text(encoding="utf-8-sig"), object_pairs_hook=unique)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise FileFormatError(f"{json_path}: not valid JSON ({exc})") from None
    if not isinstance(obj, dict):
        raise FileFormatError(f"{json_path}: expected a JSON object, got {type(obj).__name__}")
    return obj


def _sidecar_bit_depth(sidecar: dict[str, Any] | None, json_path: Path) -> int:
    if sidecar is None or "bit_depth" not in sidecar:
        return 14
    try:
        return _check_bit_depth(sidecar["bit_depth"])
    except InvalidInputError as exc:
        raise FileFormatError(f"{json_path}: {exc}") from None


def check_time_order(times: list[float | None], labels: list[str], path: Path) -> None:
    """Refuse frames whose time stamps go backwards (naming the two frames)."""
    for k in range(1, len(times)):
        a, b = times[k - 1], times[k]
        if a is not None and b is not None and b < a:
            raise FileFormatError(
                f"{path}: frame times go backwards ({labels[k]} is {a - b:.3f} s before "
                f"{labels[k - 1]}); thermocal reads frames in time order only"
            )


def _sidecar_series(values: Any, key: str, n: int, json_path: Path) -> np.ndarray:
    if not isinstance(values, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in values
    ):
        raise FileFormatError(f"{json_path}: {key!r} must be a list of numbers (one per frame)")
    if len(values) != n:
        raise FileFormatError(
            f"{json_path}: {key!r} has {len(values)} values but the recording has {n} frames"
        )
    try:
        arr = np.asarray(values, dtype=np.float64)
    except OverflowError:  # an integer beyond float64
        raise FileFormatError(f"{json_path}: {key!r} holds a number too large to be a "
                              "reading") from None
    if not np.all(np.isfinite(arr)):
        raise FileFormatError(f"{json_path}: {key!r} holds NaN or infinite values")
    if key == "fpa_c":
        try:
            as_fpa_c(arr, key)
        except InvalidInputError as exc:
            raise FileFormatError(f"{json_path}: {exc}") from None
    if key == "time_s":  # as every other format's reader (io.open)
        check_time_order(arr.tolist(), [f"frame {k}" for k in range(arr.size)], json_path)
    return arr


def read_recording(path: str | os.PathLike[str], *, fpa_c: float | None = None) -> Recording:
    """Read a recording ``NAME.tiff`` and its optional sidecar ``NAME.json``
    (:func:`thermocal.io.open.read_any_recording` reads every format).

    Parameters
    ----------
    path : str or os.PathLike
        The multi-page uint16 TIFF. A single 2-D page gives ``N = 1``.
    fpa_c : float or None, optional
        FPA temperature in °C to use for every frame (the command line's ``--fpa-c``). It replaces
        the sidecar's ``fpa_c`` series, which is then not read.

    Returns
    -------
    Recording
        Frames ``(N, H, W)`` uint16 and the sidecar's series (float64, ``(N,)``); sidecar keys
        other than the series and ``bit_depth`` go to ``extra``.

    Raises
    ------
    FileFormatError
        If the TIFF is missing, truncated, corrupt, not uint16, holds colour or several image
        series, or counts above ``2**bit_depth - 1``; or if the sidecar is not valid JSON or one
        of its series is not a list of N finite numbers.
    InvalidInputError
        If ``fpa_c`` is not a plausible FPA temperature
        (:data:`thermocal._validate.FPA_RANGE_C`).
    """
    header = read_recording_header(path, fpa_c=fpa_c)
    data, info = _read_tiff_stack(header.path)
    frames = data.reshape(info.n, info.height, info.width)
    try:
        return Recording(frames, bit_depth=header.bit_depth, extra=header.extra, **header.series)
    except InvalidInputError as exc:
        raise FileFormatError(f"{header.path}: {exc}") from None


@dataclass(frozen=True)
class RecordingHeader:
    """What a recording holds, read without its frames: size, per-frame series, extra keys."""

    path: Path
    n_frames: int
    frame_shape: tuple[int, int]
    bit_depth: int
    series: dict[str, np.ndarray | None]
    extra: dict[str, Any]


def read_recording_header(
    path: str | os.PathLike[str], *, fpa_c: float | None = None
) -> RecordingHeader:
    """Check a recording and read its sidecar, without loading the frames (long recordings).

    Raises as :func:`read_recording`; ``fpa_c`` replaces the sidecar's FPA series.
    """
    tiff_path = Path(path)
    override = None if fpa_c is None else check_fpa_c(fpa_c, "fpa_c")
    json_path = sidecar_path(tiff_path)
    sidecar = _read_sidecar(json_path)
    bit_depth = _sidecar_bit_depth(sidecar, json_path)
    if not tiff_path.is_file():
        raise FileFormatError(f"{tiff_path}: no such file")
    try:
        with _tiff_errors() as errors, tifffile.TiffFile(tiff_path) as tif:
            info = _stack_info(tif, tiff_path, errors)
    except ThermocalError:
        raise
    except Exception as exc:  # tifffile raises many types on corrupt input
        raise _open_error(tiff_path, exc) from None
    if info.dtype != np.uint16:
        raise FileFormatError(
            f"{tiff_path}: expected uint16 raw counts, got {info.dtype} (a temperature map? "
            "give the camera's raw frames)"
        )
    n = info.n
    series: dict[str, np.ndarray | None] = dict.fromkeys(SERIES_KEYS)
    extra: dict[str, Any] = {}
    if sidecar is not None:
        for key in SERIES_KEYS:
            if key in sidecar and not (key == "fpa_c" and override is not None):
                series[key] = _sidecar_series(sidecar[key], key, n, json_path)
        extra = {k: v for k, v in sidecar.items() if k not in _RESERVED_KEYS}
    if override is not None:
        series["fpa_c"] = np.full(n, override, dtype=np.float64)
    return RecordingHeader(tiff_path, n, (info.height, info.width), bit_depth, series, extra)


def iter_recording(
    path: str | os.PathLike[str], *, chunk: int = 64, start: int = 0
) -> Iterator[tuple[int, np.ndarray]]:
    """Iterate over a recording's frames in chunks without loading the whole file.

    The file is checked (readable, one uint16 stack, not truncated) when this function is
    called; the chunks are read lazily. Uncompressed contiguous TIFFs (as written by
    :func:`write_recording`) are memory-mapped; others are read page by page.

    Parameters
    ----------
    path : str or os.PathLike
        The recording TIFF. Its sidecar, if any, is read only for ``bit_depth``.
    chunk : int, optional
        Frames per chunk (default 64); the last chunk may be shorter.
    start : int, optional
        The first frame read (default 0); the frames before it are not read.

    Yields
    ------
    start : int
        Index of the chunk's first frame.
    frames : numpy.ndarray, shape (k, H, W), uint16
        A fresh array (not a view of the file).

    Raises
    ------
    InvalidInputError
        If ``chunk`` is not a positive integer.
    FileFormatError
        As :func:`read_recording`; counts above the bit depth are found while iterating.
    """
    if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
        raise InvalidInputError(f"chunk: expected a positive number of frames, got {chunk!r}")
    if isinstance(start, bool) or not isinstance(start, int | np.integer) or start < 0:
        raise InvalidInputError(f"start: expected a frame index >= 0, got {start!r}")
    tiff_path = Path(path)
    json_path = sidecar_path(tiff_path)
    bit_depth = _sidecar_bit_depth(_read_sidecar(json_path), json_path)
    if not tiff_path.is_file():
        raise FileFormatError(f"{tiff_path}: no such file")
    try:
        with _tiff_errors() as errors, tifffile.TiffFile(tiff_path) as tif:
            info = _stack_info(tif, tiff_path, errors)
            byteorder = tif.byteorder
    except ThermocalError:
        raise
    except Exception as exc:  # tifffile raises many types on corrupt input
        raise _open_error(tiff_path, exc) from None
    if info.dtype != np.uint16:
        raise FileFormatError(f"{tiff_path}: expected uint16 raw counts, got {info.dtype}")
    return _iter_stack(tiff_path, info, byteorder, int(chunk), bit_depth, int(start))


def _iter_stack(
    path: Path, info: _StackInfo, byteorder: str, chunk: int, bit_depth: int, first: int = 0
) -> Iterator[tuple[int, np.ndarray]]:
    shape = (info.n, info.height, info.width)
    max_count = 2**bit_depth - 1

    def checked(start: int, block: np.ndarray) -> tuple[int, np.ndarray]:
        block = np.ascontiguousarray(block.reshape(-1, info.height, info.width), dtype=np.uint16)
        over = first_frame_outside(block, max_count)
        if over is not None:
            raise FileFormatError(
                f"{path}: frame {start + over} holds counts above the {bit_depth}-bit maximum "
                f"{max_count}: if the camera gives more bits, say so in its sidecar "
                f"(\"bit_depth\": 16 in {sidecar_path(path).name})")
        return start, block

    if info.dataoffset is not None:
        mm = np.memmap(
            path, dtype=np.dtype(byteorder + "u2"), mode="r", offset=info.dataoffset, shape=shape
        )
        try:
            for start in range(first, info.n, chunk):
                yield checked(start, np.array(mm[start : start + chunk]))
        finally:
            del mm
        return
    with tifffile.TiffFile(path) as tif:
        for start in range(first, info.n, chunk):
            stop = min(start + chunk, info.n)
            try:
                block = tif.asarray(key=range(start, stop), series=0)
            except Exception as exc:  # tifffile raises many types on corrupt input
                raise _open_error(path, exc) from None
            yield checked(start, block)


# --------------------------------------------------------------------------------------------
# temperature TIFFs
# --------------------------------------------------------------------------------------------


#: What a map's TIFF says of itself, in its ImageDescription (JSON, as tifffile writes it with
#: the shape): the quantity and its unit (ASCII, as TIFF requires), and what the caller adds.
TEMPERATURE_ABOUT = {"quantity": "temperature", "unit": "degC"}
SIGMA_ABOUT = {"quantity": "standard uncertainty (1 sigma) of the temperature map beside it",
               "unit": "degC"}


def map_about(base: dict[str, Any], about: dict[str, Any] | None) -> dict[str, Any]:
    """A map's ImageDescription fields: ``base`` (:data:`TEMPERATURE_ABOUT`,
    :data:`SIGMA_ABOUT`) and ``about`` (the method, the source, its σ map's name …: JSON
    values, ASCII text)."""
    out = {**base, **(about or {})}
    try:
        json.dumps(out, allow_nan=False).encode("ascii")
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"a map's description must be ASCII JSON: {exc}") from None
    return out


def write_temperature_tiff(path: str | os.PathLike[str], temps_c: Any, *,
                           tags: MapTags | None = None,
                           about: dict[str, Any] | None = None) -> Path:
    """Write temperatures in °C as a float32 TIFF, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``.tiff``/``.tif``; its directory must exist.
    temps_c : array_like, shape (H, W) or (N, H, W)
        Temperatures, °C.
    tags : thermocal.io.geotag.MapTags, optional
        Georeferencing of an (H, W) map (:func:`thermocal.io.geotag.map_tags`).
    about : dict, optional
        More for its ImageDescription beside :data:`TEMPERATURE_ABOUT` (:func:`map_about`).

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.

    Raises
    ------
    InvalidInputError
        If ``temps_c`` is not 2-D or 3-D, holds NaN or infinity, is at or below absolute zero, or
        does not fit in float32. Nothing is written then.
    """
    out = _check_tiff_name(path)
    arr = as_temperature_c(temps_c, "temps_c", ndim=(2, 3))
    if 0 in arr.shape:
        raise InvalidInputError(f"temps_c: empty image (shape {arr.shape})")
    with np.errstate(over="ignore"):
        f32 = arr.astype(np.float32)
    if not np.all(np.isfinite(f32)):
        raise InvalidInputError("temps_c: values too large for float32")
    _write_float_tiff(out, f32, tags, map_about(TEMPERATURE_ABOUT, about))
    return out


def _write_float_tiff(out: Path, arr: np.ndarray, tags: MapTags | None,
                      about: dict[str, Any]) -> None:
    """``arr`` (float32) as a TIFF at ``out``, atomically, with ``tags`` when given and
    ``about`` in its ImageDescription."""
    with atomic_path(out) as tmp:
        if tags is None:
            tifffile.imwrite(tmp, arr, photometric="minisblack", bigtiff=arr.nbytes > 2**31,
                             metadata=about)
        else:
            tmp.write_bytes(tags.encode(arr, metadata=about))


def write_sigma_tiff(path: str | os.PathLike[str], sigma_c: Any, *,
                     tags: MapTags | None = None, about: dict[str, Any] | None = None) -> Path:
    """Write standard uncertainties (1σ, °C, >= 0) as a float32 TIFF, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``.tiff``/``.tif``; its directory must exist.
    sigma_c : array_like, shape (H, W) or (N, H, W)
        1σ of the temperatures beside it, °C.
    tags : thermocal.io.geotag.MapTags, optional
        Georeferencing of an (H, W) map (:func:`thermocal.io.geotag.map_tags`).
    about : dict, optional
        More for its ImageDescription beside :data:`SIGMA_ABOUT` (:func:`map_about`).

    Raises
    ------
    InvalidInputError
        If ``sigma_c`` is not 2-D or 3-D, empty, negative, NaN or infinite. Nothing is written.
    """
    out = _check_tiff_name(path)
    arr = as_float_array(sigma_c, "sigma_c", ndim=(2, 3)).astype(np.float32)
    if 0 in arr.shape or not np.all(np.isfinite(arr)) or float(arr.min()) < 0:
        raise InvalidInputError("sigma_c: need a non-empty map of finite σ >= 0 °C")
    _write_float_tiff(out, arr, tags, map_about(SIGMA_ABOUT, about))
    return out


def read_temperature_tiff(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a temperature TIFF (°C) written by :func:`write_temperature_tiff` or another tool.

    Parameters
    ----------
    path : str or os.PathLike
        A TIFF with one stack of floating-point images.

    Returns
    -------
    numpy.ndarray, float32, shape (H, W) or (N, H, W)
        Temperatures, °C, in the shape they were written.

    Raises
    ------
    FileFormatError
        If the file is missing, truncated or corrupt, is not floating point (raw counts?), or
        holds NaN or infinity.
    """
    tiff_path = Path(path)
    data, info = _read_tiff_stack(tiff_path)
    if info.dtype.kind != "f":
        raise FileFormatError(
            f"{tiff_path}: expected float temperatures in °C, got {info.dtype} "
            "(raw counts? read them with read_recording)"
        )
    if data.ndim > 3:
        data = data.reshape(info.n, info.height, info.width)
    if not np.all(np.isfinite(data)):
        n_bad = int(np.count_nonzero(~np.isfinite(data)))
        raise FileFormatError(f"{tiff_path}: {n_bad} temperature(s) are NaN or infinite")
    return data.astype(np.float32, copy=False)
