"""One way in: :func:`open_recording` reads any recording a user brings, streamed.

``open_recording(path)`` looks at the content (not the name) of a file, or at the files of a
folder, and returns a :class:`RecordingSource`: its ``format``, ``n_frames``, ``frame_shape``,
``bit_depth`` and ``header`` are known at once (only headers are read), and
:meth:`RecordingSource.iter_frames` streams :class:`FrameChunk` objects — raw counts (uint16
``(k, H, W)``), the FPA temperature of each frame where the source has it, time stamps and
per-frame metadata — so that a flight larger than memory can be processed.
:meth:`RecordingSource.read_all` returns the whole recording as a
:class:`~thermocal.io.recording.Recording`.

========================= ======================================================================
``format``                what
========================= ======================================================================
``"tiff"``                the project's recording, ``NAME.tiff`` + ``NAME.json``
                          (:mod:`thermocal.io.recording`)
``"fff"``                 one FLIR FFF frame, either byte order (:mod:`thermocal.io.fff`)
``"seq"``                 a FLIR SEQ file: FFF records back to back
``"csq"``                 a FLIR CSQ file: FFF records with JPEG-LS raw images
``"rjpeg"``               a FLIR radiometric JPEG, DJI XT2/XT-R included (:mod:`thermocal.io.rjpeg`)
``"fff-folder"``          a folder of FFF files, one frame each, in name order
``"rjpeg-folder"``        a folder of R-JPEGs, in name order
``"dualtau"``             a DualTauUAV flight: a folder of ``.npz`` (or one file)
                          (:mod:`thermocal.io.dualtau`)
``"envchamberctrl"``      an EnvChamberCtrl ``.npz`` (:mod:`thermocal.io.envchamber`)
========================= ======================================================================

**Per-frame series.** ``fpa_c`` is the FPA temperature in °C: the sidecar's series for a TIFF
recording, the chamber's for EnvChamberCtrl, the rig's sparse readings interpolated for
DualTauUAV. ``fpa_measured`` flags the frames whose value was read rather than interpolated,
and :attr:`RecordingSource.fpa_resolution_c` says how coarse a reading is (0.1 °C for
DualTauUAV). FLIR FFF/SEQ/CSQ and R-JPEG frames have no FPA temperature (``fpa_c`` is None; a
DJI XT2/XT-R's ``FLIR:CentralTemperature`` is its spot meter, kept as ``spot_c``). ``time_s``
is the time since the first frame, s (for FLIR files from the camera's clock, ms resolution).

**Per-frame metadata** (JSON-serialisable dicts): ``source`` (the file), ``index`` (the
frame's place in that file) and, for FLIR files,
``camera_model``, ``datetime``, ``planck`` (R1, R2, B, F, O, emissivity, distance, reflected,
atmospheric and window parameters: :func:`thermocal.io.fff.planck_from_metadata` makes the
:class:`~thermocal.radiometry.FlirPlanck`), ``gps`` and, for DJI, altitudes and attitude
(:func:`thermocal.io.rjpeg.read_rjpeg`).

**Folders.** Hidden files and notes (``.txt``, ``.md``, ``.json``, ``.xml``, ``.log``) are
skipped; every other file must be of one format (FFF, R-JPEG or DualTauUAV ``.npz``) and all
frames of one size, else :class:`~thermocal.errors.FileFormatError` names the file. A folder
holding one project recording (``NAME.tiff`` + ``NAME.json``, as ``thermocal simulate flight``
writes) opens as that recording.

**Bad input** is refused with one line naming the file: an empty or unknown file, a JPEG
without FLIR records, a folder with no recording, of mixed formats or of mixed frame sizes, an
``.npz`` without the arrays of its layout or with its FPA in no plausible unit, frames whose
time stamps go backwards (within a SEQ/CSQ, between the files of a folder in name order,
within a DualTauUAV file; DualTauUAV files are put in time order, and refused when they
overlap), and a recording none of whose frames can be read.

**Damaged frames** are left out, not the recording: :func:`open_recording` indexes a file's FFF
records and checks each one's header, directory, camera info and the structure of its raw
image without decoding it (and each file of a folder likewise), leaving out a record or file
that does not pass (a header that does not parse, a record cut short, an FFF signature
destroyed, a frame of another size in a SEQ/CSQ, an R-JPEG that is not one, a DualTauUAV file
that cannot be read). They are listed in :attr:`RecordingSource.damaged` (``(where,
reason)``, ``where`` the frame's index in its file or the file's name) and not counted in
``n_frames``. A raw image that passes those checks but does not decode is found only when it is
decoded: :meth:`RecordingSource.read_all` (the commands that read a whole recording) and
``iter_frames(skip_undecodable=True)`` (``thermocal info``) leave it out and add it to the
list. A streamed run (:func:`open_stream`, whose count of frames is fixed beforehand, for
``thermocal flight``) cannot leave it out: :meth:`StreamHeader.stream` gives zeros of the frame
size in its place (``iter_frames(placeholders=True)``) and names it, by its index in the
recording, in the chunk it comes in (:attr:`FrameChunk.undecodable`: no list is shared or
updated); ``thermocal flight`` skips every group that holds it, with its own log error, lists it
in ``summary.json`` and warns of it at the end. A recording none of whose first 16 frames
decodes is refused in one line before anything is written. The commands warn in one line of
the frames left out at open: ``thermocal: warning: skipped 2 damaged frames of X.seq: 17 (raw
image does not decode (…)), 18 (truncated (…))``.
"""

from __future__ import annotations

import dataclasses
import itertools
import mmap
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import check_fpa_c
from thermocal.errors import FileFormatError, InvalidInputError, ThermocalError
from thermocal.io.dualtau import (
    UnreadableFileError,
    index_dualtau_folder,
    npz_keys,
    read_dualtau_frames,
)
from thermocal.io.fff import (
    FFF_MAGICS,
    error_reason,
    fff_raw_codec,
    fff_record_metadata,
    index_fff_series,
    parse_fff_record,
    read_fff_series_frame,
)
from thermocal.io.recording import (
    Recording,
    check_time_order,
    iter_recording,
    read_recording,
    read_recording_header,
)
from thermocal.io.replaces import HDF5_MAGIC, hdf5_kind
from thermocal.io.rjpeg import JPEG_MAGIC, read_rjpeg, rjpeg_metadata

__all__ = ["FORMATS", "FrameChunk", "RecordingSource", "open_recording"]

#: The values of :attr:`RecordingSource.format`.
FORMATS: tuple[str, ...] = (
    "tiff", "fff", "seq", "csq", "rjpeg", "fff-folder", "rjpeg-folder", "dualtau",
    "envchamberctrl",
)

_TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
_ZIP_MAGIC = b"PK\x03\x04"
_NOTES = frozenset((".txt", ".md", ".json", ".xml", ".log"))
_PROBE_BYTES = 1 << 18
#: ``skip`` of :meth:`RecordingSource._frames` that gives a frame that does not decode as zeros.
_PLACEHOLDER = "placeholder"


@dataclass(frozen=True)
class FrameChunk:
    """Consecutive frames of a recording with their per-frame data.

    Attributes
    ----------
    start : int
        Index of the first frame in the recording.
    frames : numpy.ndarray, uint16, shape (k, H, W)
        Raw counts.
    fpa_c : numpy.ndarray or None, shape (k,)
        FPA temperature, °C (None when the source has none).
    fpa_measured : numpy.ndarray or None, bool, shape (k,)
        True where ``fpa_c`` was read at that frame, False where interpolated.
    time_s : numpy.ndarray or None, shape (k,)
        Time since the recording's first frame, s.
    metadata : list of dict
        One JSON-serialisable dict per frame.
    undecodable : tuple of (int, str, str)
        The frames whose raw image does not decode, given as zeros (only with
        ``iter_frames(placeholders=True)``): ``(index in the recording, where, reason)``,
        ``where`` naming it as :attr:`RecordingSource.damaged` does (its place in its file, or
        its file). Their ``fpa_c`` and ``time_s`` are NaN, their metadata ``source`` and
        ``undecodable`` (``[where, reason]``).
    positions : tuple of int
        Each frame's index among the :attr:`~RecordingSource.n_frames` frames found at open
        (the numbering a flight names its maps by): ``start`` onwards, unless frames that do not
        decode were left out before them (``iter_frames(skip_undecodable=True)``).
    """

    start: int
    frames: np.ndarray
    fpa_c: np.ndarray | None
    fpa_measured: np.ndarray | None
    time_s: np.ndarray | None
    metadata: list[dict[str, Any]]
    undecodable: tuple[tuple[int, str, str], ...] = ()
    positions: tuple[int, ...] = ()

    def __len__(self) -> int:
        return int(self.frames.shape[0])


class RecordingSource:
    """A recording opened by :func:`open_recording`; frames are read when iterated.

    Attributes
    ----------
    path : pathlib.Path
        The file or folder.
    format : str
        One of :data:`FORMATS`.
    n_frames : int
        Number of frames.
    frame_shape : tuple of int
        ``(H, W)``.
    bit_depth : int
        Bits of the raw counts (14 for the Tau2 rigs and the project's default, 16 for FLIR
        files, whose counts use the full uint16 range).
    has_fpa, has_time : bool
        Whether chunks carry ``fpa_c`` / ``time_s``.
    fpa_resolution_c : float or None
        Resolution of the FPA readings, °C, where the source rounds them coarsely.
    header : dict
        File-level information (JSON-serialisable), e.g. the sidecar's extra keys, the files
        of a folder, the camera of the first frame.
    damaged : list of (str, str)
        The frames left out, as ``(where, reason)``: ``where`` is the frame's index in its file
        for a single file (``"17"``), the file's name in a folder. Found at open (a record or
        file that does not parse, a truncated last record, a frame of another size), and by
        :meth:`read_all` and ``iter_frames(skip_undecodable=True)`` (a raw image that does not
        decode, added as it is met). They are not counted in :attr:`n_frames`; the frames that
        remain are numbered on, ``metadata["index"]`` keeping each one's place in its file.
    """

    def __init__(self, path: Path, fmt: str, n_frames: int, frame_shape: tuple[int, int], *,
                 bit_depth: int, has_fpa: bool, has_time: bool,
                 fpa_resolution_c: float | None = None,
                 header: dict[str, Any] | None = None) -> None:
        self.path = path
        self.format = fmt
        self.n_frames = int(n_frames)
        self.frame_shape = (int(frame_shape[0]), int(frame_shape[1]))
        self.bit_depth = int(bit_depth)
        self.has_fpa = has_fpa
        self.has_time = has_time
        self.fpa_resolution_c = fpa_resolution_c
        self.header = dict(header or {})
        self.damaged: list[tuple[str, str]] = list(getattr(self, "damaged", []))

    def __repr__(self) -> str:
        h, w = self.frame_shape
        return f"<RecordingSource {self.format} {self.path} {self.n_frames} x {h}x{w}>"

    # -- subclasses yield one frame at a time ----------------------------------------------
    def _frames(self, decode: bool = True, skip: bool | str = False) -> Iterator[
            tuple[np.ndarray | None, float | None, bool | None, float | None, dict[str, Any]]]:
        """Yield ``(raw (H, W), fpa_c, fpa_measured, time_s, metadata)`` per frame; ``raw`` is
        None with ``decode=False`` (the sources that can then skip reading the pixels do);
        ``skip``, for a frame whose raw image does not decode (:meth:`_undecodable`): False
        raises, True adds it to :attr:`damaged`, :data:`_PLACEHOLDER` yields zeros instead."""
        raise NotImplementedError

    def iter_frames(self, chunk: int = 64, *, skip_undecodable: bool = False,
                    placeholders: bool = False) -> Iterator[FrameChunk]:
        """Stream the recording in chunks of at most ``chunk`` frames.

        Frames found damaged at open are not among them (:attr:`damaged`). A frame that passed
        those checks but whose raw image does not decode raises (the count of frames is fixed
        at open), or with ``skip_undecodable`` is left out and added to :attr:`damaged` (the
        chunks' ``start`` then counts the frames given), or with ``placeholders`` is given as
        zeros and named in its chunk's :attr:`~FrameChunk.undecodable` (:attr:`damaged` is left
        as it is; the count of frames stays :attr:`n_frames`).

        Raises
        ------
        InvalidInputError
            If ``chunk`` is not a positive integer, or both ``skip_undecodable`` and
            ``placeholders`` are given.
        FileFormatError
            A frame that cannot be read, or is not of :attr:`frame_shape` (naming its file).
        """
        if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
            raise InvalidInputError(f"chunk: expected a positive number of frames, got {chunk!r}")
        if skip_undecodable and placeholders:
            raise InvalidInputError("skip_undecodable or placeholders: a frame that does not "
                                    "decode is either left out or given as zeros, not both")
        return self._chunks(int(chunk), _PLACEHOLDER if placeholders else skip_undecodable)

    def iter_series(self) -> Iterator[tuple[float | None, bool | None, float | None,
                                            dict[str, Any]]]:
        """``(fpa_c, fpa_measured, time_s, metadata)`` of every frame, in order, without
        decoding raw images where the format allows (FLIR records' headers, R-JPEGs' metadata,
        DualTauUAV's small arrays): what a streamed run needs before its frames."""
        for _, *rest in self._frames(decode=False):
            yield tuple(rest)  # type: ignore[misc]

    def _undecodable(self, skip: bool | str, exc: FileFormatError, label: str, where: str,
                     note: str = "", count: int = 1) -> list[tuple]:
        """A frame (``count`` frames: a file of them) met damaged while iterated: raise
        ``exc``; with ``skip`` list it (once, however often the recording is read) and return
        no item; with ``skip=_PLACEHOLDER`` return an item of zeros for each frame, its
        metadata naming it (``undecodable``: ``[label, reason]``), and list nothing."""
        if not skip:
            raise exc
        entry = (label, error_reason(exc, where) + note)
        if skip == _PLACEHOLDER:
            return [(np.zeros(self.frame_shape, np.uint16), None, None, None,
                     {"source": str(self.path), "undecodable": list(entry)})
                    for _ in range(count)]
        if entry not in self.damaged:
            self.damaged.append(entry)
        return [None] * count  # left out: counted by _chunks, so the others keep their numbers

    def damaged_summary(self) -> str | None:
        """One line naming the frames left out (None when none was): ``skipped 2 damaged
        frames of X.seq: 17 (raw image does not decode), 18 (truncated)``."""
        if not self.damaged:
            return None
        n = len(self.damaged)
        listed = ", ".join(f"{w} ({r})" for w, r in self.damaged[:10])
        more = f", and {n - 10} more" if n > 10 else ""
        return (f"skipped {n} damaged frame{'s' if n > 1 else ''} of {self.path}: "
                f"{listed}{more}")

    def _chunks(self, chunk: int, skip: bool | str = False) -> Iterator[FrameChunk]:
        buf: list[tuple[np.ndarray, Any, Any, Any, dict[str, Any]]] = []
        start, position, positions = 0, -1, []
        for item in self._frames(skip=skip):
            position += 1
            if item is None:  # a frame that does not decode, left out (_undecodable)
                continue
            raw = item[0]
            if raw.shape != self.frame_shape:
                where = item[4].get("source", self.path)
                raise FileFormatError(
                    f"{where}: frame of {raw.shape[1]}x{raw.shape[0]} in a recording of "
                    f"{self.frame_shape[1]}x{self.frame_shape[0]} frames (width x height)"
                )
            buf.append(item)
            positions.append(position)
            if len(buf) == chunk:
                yield self._assemble(start, buf, positions)
                start += len(buf)
                buf, positions = [], []
        if buf:
            yield self._assemble(start, buf, positions)

    def _assemble(self, start: int, items: list, positions: list[int]) -> FrameChunk:
        frames = np.stack([it[0] for it in items]).astype(np.uint16, copy=False)
        fpa = np.array([it[1] for it in items], np.float64) if self.has_fpa else None
        measured = np.array([bool(it[2]) for it in items]) if self.has_fpa else None
        time_s = np.array([it[3] for it in items], np.float64) if self.has_time else None
        metas = [it[4] for it in items]
        undecodable = tuple((start + k, *m["undecodable"]) for k, m in enumerate(metas)
                            if "undecodable" in m)
        return FrameChunk(start, frames, fpa, measured, time_s, metas, undecodable,
                          tuple(positions))

    def read_all(self) -> Recording:
        """The whole recording in memory, as a :class:`~thermocal.io.recording.Recording`.

        ``extra`` holds ``source_format``, ``frame_metadata`` (the list of per-frame dicts),
        ``frame_positions`` (each frame's index among the frames found at open, ``frames_at_open``
        of them: frames that do not decode are left out, with a warning, and the others keep
        their numbers) and, with an FPA series, ``fpa_measured`` (list of bool).
        """
        chunks = list(self.iter_frames(256, skip_undecodable=True))
        if not chunks:
            if self.damaged:
                raise no_frames_error(self.path, self.damaged)
            raise FileFormatError(f"{self.path}: the recording holds no frames")
        extra: dict[str, Any] = {
            "source_format": self.format,
            "frame_metadata": [m for c in chunks for m in c.metadata],
            "frame_positions": [p for c in chunks for p in c.positions],
            "frames_at_open": self.n_frames,
        }
        fpa = time_s = None
        if self.has_fpa:
            fpa = np.concatenate([c.fpa_c for c in chunks])  # type: ignore[misc]
            extra["fpa_measured"] = np.concatenate(
                [c.fpa_measured for c in chunks]  # type: ignore[misc]
            ).tolist()
        if self.has_time:
            time_s = np.concatenate([c.time_s for c in chunks])  # type: ignore[misc]
        frames = np.concatenate([c.frames for c in chunks])
        try:
            return Recording(frames, fpa_c=fpa, time_s=time_s, bit_depth=self.bit_depth,
                             extra=extra)
        except InvalidInputError as exc:
            raise FileFormatError(f"{self.path}: {exc}") from None


# --------------------------------------------------------------------------------------------
# sources
# --------------------------------------------------------------------------------------------
class _TiffSource(RecordingSource):
    def __init__(self, path: Path) -> None:
        h = read_recording_header(path)
        self._series = h.series
        super().__init__(path, "tiff", h.n_frames, h.frame_shape, bit_depth=h.bit_depth,
                         has_fpa=h.series["fpa_c"] is not None,
                         has_time=h.series["time_s"] is not None,
                         header={"extra": h.extra})

    def _frames(self, decode: bool = True, skip: bool | str = False) -> Iterator[tuple]:
        fpa, t = self._series["fpa_c"], self._series["time_s"]
        others = {k: v for k, v in self._series.items()
                  if v is not None and k not in ("fpa_c", "time_s")}
        blocks = (iter_recording(self.path, chunk=64) if decode
                  else ((i, [None]) for i in range(self.n_frames)))
        for start, block in blocks:
            for k, raw in enumerate(block):
                i = start + k
                meta: dict[str, Any] = {"source": str(self.path), "index": i}
                meta.update({key: float(v[i]) for key, v in others.items()})
                yield (raw, None if fpa is None else float(fpa[i]), True,
                       None if t is None else float(t[i]), meta)


class _FlirFileSource(RecordingSource):
    """FFF, SEQ and CSQ files: FFF records, indexed and checked at open (headers, no pixels
    decoded), decoded while iterated."""

    def __init__(self, path: Path, head: bytes) -> None:
        size = path.stat().st_size
        name = str(path)
        good: list[tuple[int, int]] = []
        times: list[float | None] = []
        self.damaged = []
        first: Any = None
        with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            index, bad = index_fff_series(mm, size, name)
            damaged = dict(bad)
            numbers: list[int] = []
            for k, (off, length) in zip(self._positions(index, damaged), index, strict=True):
                where = f"{name} (frame {k})"
                try:
                    shape, _, meta = fff_record_metadata(bytes(mm[off : off + length]), where)
                except FileFormatError as exc:
                    damaged[k] = error_reason(exc, where)
                    continue
                if first is not None and shape != first[0]:
                    damaged[k] = (f"a frame of {shape[1]}x{shape[0]} in a recording of "
                                  f"{first[0][1]}x{first[0][0]} frames")
                    continue
                if first is None:
                    first = (shape, meta)
                good.append((off, length))
                numbers.append(k)
                times.append(meta.get("time_epoch_s"))
        self.damaged = [(str(k), damaged[k]) for k in sorted(damaged)]
        if first is None:
            raise no_frames_error(path, self.damaged)
        self._index, self._numbers = good, numbers
        check_time_order(times, [f"frame {k}" for k in numbers], path)
        suffix = path.suffix.lower()
        compressed = fff_raw_codec(head) == "jpegls"
        if compressed or suffix == ".csq":
            fmt = "csq"
        elif len(index) + len(bad) > 1 or suffix == ".seq":
            fmt = "seq"
        else:
            fmt = "fff"
        self._t0 = times[0]
        super().__init__(path, fmt, len(good), first[0], bit_depth=16,
                         has_fpa=False, has_time=self._t0 is not None,
                         header=_camera_header(first[1]))

    @staticmethod
    def _positions(index: list[tuple[int, int]], damaged: dict[int, str]) -> list[int]:
        """The frame numbers (places in the file) of the records of ``index``, the damaged
        ones that the index found between them left out."""
        out, k = [], 0
        for _ in index:
            while k in damaged:
                k += 1
            out.append(k)
            k += 1
        return out

    def _frames(self, decode: bool = True, skip: bool | str = False) -> Iterator[tuple]:
        name = str(self.path)
        with open(self.path, "rb") as fh, mmap.mmap(fh.fileno(), 0,
                                                     access=mmap.ACCESS_READ) as mm:
            for k, entry in zip(self._numbers, self._index, strict=True):
                where = name if self.format == "fff" else f"{name} (frame {k})"
                try:
                    frame = read_fff_series_frame(mm, entry, where, decode=decode)
                except FileFormatError as exc:
                    yield from self._undecodable(skip, exc, str(k), where)
                    continue
                meta = {"source": name, "index": k, **frame.metadata}
                yield (frame.raw if decode else None, None, None,
                       _rel_time(meta, self._t0, where), meta)


class _FolderSource(RecordingSource):
    """A folder of single-frame FLIR files (FFF or R-JPEG), in name order; each file is read
    and checked at open (no pixels decoded); a file that does not pass is left out."""

    def __init__(self, path: Path, files: list[Path], kind: str,
                 damaged: list[tuple[str, str]] | None = None) -> None:
        self._kind = kind
        self.damaged = list(damaged or [])
        good: list[Path] = []
        times: list[float | None] = []
        first: tuple[Path, tuple[int, int], dict[str, Any]] | None = None
        for f in files:
            try:
                shape, meta = self._check(f, exif=False)
            except FileFormatError as exc:
                self.damaged.append((f.name, error_reason(exc, str(f))))
                continue
            if first is None:
                first = (f, shape, meta)
            elif shape != first[1]:
                raise FileFormatError(
                    f"{f}: frames of {shape[1]}x{shape[0]} in a folder of {first[1][1]}x"
                    f"{first[1][0]} frames (first file {first[0].name}; width x height)"
                )
            good.append(f)
            times.append(meta.get("time_epoch_s"))
        self.damaged.sort()
        if first is None:
            raise no_frames_error(path, self.damaged)
        check_time_order(times, [f.name for f in good], path)
        self._files = good
        self._t0 = times[0]
        # no FPA temperature: a FLIR file records none (a DJI XT2/XT-R's
        # FLIR:CentralTemperature is its spot meter, a scene temperature: rjpeg)
        super().__init__(path, f"{kind}-folder", len(good), first[1],
                         bit_depth=16, has_fpa=False, has_time=self._t0 is not None,
                         header={"files": [f.name for f in good],
                                 **_camera_header(self._check(good[0])[1])})

    def _check(self, f: Path, exif: bool = True) -> tuple[tuple[int, int], dict[str, Any]]:
        data = _read_file(f)
        if self._kind == "rjpeg":
            _, shape, _, meta = rjpeg_metadata(data, str(f), exif=exif)
        else:
            shape, _, meta = fff_record_metadata(data, str(f))
        return shape, meta

    def _read(self, f: Path) -> Any:
        if self._kind == "rjpeg":
            return read_rjpeg(f)
        return parse_fff_record(_read_file(f), str(f))

    def _frames(self, decode: bool = True, skip: bool | str = False) -> Iterator[tuple]:
        for f in self._files:
            try:
                frame: Any = self._read(f) if decode else (None, self._check(f)[1])
            except FileFormatError as exc:
                yield from self._undecodable(skip, exc, f.name, str(f))
                continue
            raw, metadata = (frame.raw, frame.metadata) if decode else frame
            meta = {"source": str(f), "index": 0, **metadata}
            yield raw, None, None, _rel_time(meta, self._t0, str(f)), meta


class _RjpegSource(_FolderSource):
    """One R-JPEG: a folder source of one file, named ``"rjpeg"``."""

    def __init__(self, path: Path) -> None:
        super().__init__(path, [path], "rjpeg")
        self.format = "rjpeg"
        self.header.pop("files", None)


class _DualTauSource(RecordingSource):
    def __init__(self, path: Path, files: list[Path] | None = None,
                 damaged: list[tuple[str, str]] | None = None) -> None:
        self._index = index_dualtau_folder(path if path.is_dir() else path.parent, files)
        ix = self._index
        self.damaged = sorted([*(damaged or []), *ix.damaged])
        super().__init__(
            path, "dualtau", int(sum(ix.counts)), ix.frame_shape, bit_depth=14, has_fpa=True,
            has_time=True, fpa_resolution_c=0.1,
            header={"files": [f.name for f in ix.files], "time_origin_ns": ix.time_origin_ns,
                    "fpa_readings": int(np.count_nonzero(ix.fpa_measured))},
        )

    def _frames(self, decode: bool = True, skip: bool | str = False) -> Iterator[tuple]:
        ix = self._index
        i = 0
        for f, n in zip(ix.files, ix.counts, strict=True):
            try:
                frames = read_dualtau_frames(f, (n, *ix.frame_shape)) if decode else None
            except UnreadableFileError as exc:
                yield from self._undecodable(skip, exc, f.name, str(f), f" ({n} frames)", n)
                i += n
                continue
            for k in range(n):
                meta = {"source": str(f), "index": k,
                        "fpa_reading_c": float(ix.fpa_readings_c[i])}
                yield (None if frames is None else frames[k], float(ix.fpa_c[i]),
                       bool(ix.fpa_measured[i]), float(ix.time_s[i]), meta)
                i += 1


class _ChamberNpzSource(RecordingSource):
    def __init__(self, path: Path) -> None:
        from thermocal.io.envchamber import import_envchamberctrl_npz

        self._session = s = import_envchamberctrl_npz(path)
        frames = np.asarray(s.frames)
        super().__init__(path, "envchamberctrl", frames.shape[0], frames.shape[1:],
                         bit_depth=14, has_fpa=True, has_time=s.time_s is not None,
                         header={k: v for k, v in s.attrs.items()})
        self._frames_arr = frames

    def _frames(self, decode: bool = True, skip: bool | str = False) -> Iterator[tuple]:
        s = self._session
        for i in range(self.n_frames):
            meta: dict[str, Any] = {"source": str(self.path), "index": i,
                                    "blackbody_c": float(s.blackbody_c[i])}
            if s.housing_c is not None:
                meta["housing_c"] = float(s.housing_c[i])
            yield (self._frames_arr[i], float(s.fpa_c[i]), True,
                   None if s.time_s is None else float(s.time_s[i]), meta)


# --------------------------------------------------------------------------------------------
# detection
# --------------------------------------------------------------------------------------------
def open_recording(path: str | os.PathLike[str]) -> RecordingSource:
    """Open a recording of any supported format (file or folder), reading only its headers.

    Parameters
    ----------
    path : str or os.PathLike
        A file (TIFF recording, FFF, SEQ, CSQ, R-JPEG, DualTauUAV or EnvChamberCtrl ``.npz``) or
        a folder (of FFF files, R-JPEGs, or DualTauUAV ``.npz`` files).

    Returns
    -------
    RecordingSource

    Raises
    ------
    FileFormatError
        A missing path, an unknown, truncated or corrupt file, a JPEG without FLIR records, a
        folder with no recording, of mixed formats or of mixed frame sizes; the one-line
        message names the file and what is wrong.
    """
    p = Path(path)
    if p.is_dir():
        return _open_folder(p)
    if not p.is_file():
        raise FileFormatError(f"{p}: " + ("not a file or a folder (a pipe, a device): give the "
                                          "recording's file" if p.exists()
                                          else "no such file or folder"))
    head = _head(p)
    try:
        kind = _kind(p, head)
        if kind == "tiff":
            return _TiffSource(p)
        if kind == "fff":
            return _FlirFileSource(p, head)
        if kind == "rjpeg":
            return _RjpegSource(p)
        if kind == "envchamberctrl":
            return _ChamberNpzSource(p)
        return _DualTauSource(p, [p])
    except ThermocalError:
        raise
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"{p}: cannot be read ({type(exc).__name__}: {exc})") from None


def _kind(p: Path, head: bytes) -> str:
    if not head:
        raise FileFormatError(f"{p}: file is empty")
    if head[:4] in _TIFF_MAGICS:
        return "tiff"
    if head[:4] in FFF_MAGICS:
        return "fff"
    if head[:3] == JPEG_MAGIC:
        return "rjpeg"
    if head[:8] == HDF5_MAGIC:
        kind = hdf5_kind(p)
        reads = {"chamber session": "`thermocal calibrate` reads it",
                 "calibration": "`thermocal correct --calibration` uses it"}.get(
                     kind, "`thermocal calibrate` reads chamber sessions")
        what = f"a {kind}" if kind in ("chamber session", "calibration") else "an HDF5 file"
        raise FileFormatError(f"{p}: {what} (HDF5), not a recording: {reads}")
    if head[:4] == _ZIP_MAGIC:
        keys = npz_keys(p)
        if "blackbody" in keys:
            return "envchamberctrl"
        if "frames" in keys:
            return "dualtau"
        if any(k.endswith("data.pkl") for k in keys):  # torch.save's zip layout
            raise FileFormatError(f"{p}: a PyTorch file (network weights?), not a recording")
        listed = sorted(keys)
        shown = ", ".join(listed[:5]) + (f", … {len(listed)} in all" if len(listed) > 5 else "")
        raise FileFormatError(f"{p}: an .npz without 'frames' (has {shown or 'nothing'}); not "
                              "a DualTauUAV or EnvChamberCtrl recording")
    raise FileFormatError(
        f"{p}: unknown recording format (expected a TIFF recording, FLIR FFF/SEQ/CSQ, FLIR "
        "R-JPEG or a DualTauUAV/EnvChamberCtrl .npz)"
    )


def _open_folder(folder: Path) -> RecordingSource:
    # `thermocal simulate flight OUT --format seq|csq|fff|rjpeg|dji-rjpeg|dualtau`'s folder:
    # its recording is OUT/frames(.seq, .csq, a folder), beside the truth and flight.json
    made = [f for f in folder.glob("frames*") if f.stem == "frames" and f.suffix != ".json"]
    if (folder / "flight.json").is_file() and len(made) == 1 and made[0].suffix != ".tiff":
        return open_recording(made[0])
    files = sorted(f for f in folder.iterdir()
                   if f.is_file() and not f.name.startswith(".") and f.suffix.lower() not in _NOTES)
    if not files:
        raise FileFormatError(f"{folder}: no recording in the folder (no FFF, R-JPEG or .npz "
                              "file)")
    kinds: dict[str, Path] = {}
    unreadable: dict[Path, FileFormatError] = {}
    for f in files:
        try:
            kinds.setdefault(_kind(f, _head(f, 8)), f)
        except FileFormatError as exc:  # an empty or damaged file: decided below
            unreadable[f] = exc
    if len(kinds) > 1:
        found = ", ".join(f"{k} ({f.name})" for k, f in kinds.items())
        raise FileFormatError(f"{folder}: files of mixed formats ({found}); a folder must hold "
                              "one format")
    if not kinds:
        raise next(iter(unreadable.values())) if len(unreadable) == 1 else FileFormatError(
            f"{folder}: no recording in the folder: none of its {len(unreadable)} files is an "
            f"FFF, R-JPEG or .npz file that can be read (the first, "
            f"{next(iter(unreadable.values()))})")
    kind = next(iter(kinds))
    if kind == "tiff":  # the project's recording (NAME.tiff + NAME.json), e.g. simulate's
        recordings = [f for f in files if _kind_or_none(f) == "tiff"
                      and f.with_suffix(".json").is_file()]
        if len(recordings) == 1:
            return _TiffSource(recordings[0])
    if kind not in _FOLDER_SUFFIXES:
        raise FileFormatError(f"{folder}: a folder of {kind} files; open each file on its own")
    # a file of the folder's kind by its name that is empty or damaged is a damaged frame;
    # any other file is not part of the recording: refused, as a folder of mixed files
    for f, exc in unreadable.items():
        if f.suffix.lower() not in _FOLDER_SUFFIXES[kind]:
            raise exc
    damaged = [(f.name, error_reason(exc, str(f))) for f, exc in unreadable.items()]
    good = [f for f in files if f not in unreadable]
    if kind == "dualtau":
        return _DualTauSource(folder, good, damaged)
    return _FolderSource(folder, good, kind, damaged)


def _kind_or_none(f: Path) -> str | None:
    try:
        return _kind(f, _head(f, 8))
    except FileFormatError:
        return None


#: The names a folder's files of each kind have (a damaged one is told by its name).
_FOLDER_SUFFIXES = {"fff": (".fff",), "rjpeg": (".jpg", ".jpeg"), "dualtau": (".npz",)}


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _head(p: Path, n: int = _PROBE_BYTES) -> bytes:
    try:
        with open(p, "rb") as fh:
            return fh.read(n)
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read ({exc.strerror or exc})") from None


def _read_file(p: Path) -> bytes:
    try:
        return p.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read ({exc.strerror or exc})") from None


def _rel_time(meta: dict[str, Any], t0: float | None, where: str) -> float | None:
    if t0 is None:
        return None
    t = meta.get("time_epoch_s")
    if t is None:
        raise FileFormatError(f"{where}: the frame has no time stamp, the first frame has one")
    # the camera's clock has ms resolution: round away the float error of epoch seconds
    return round((float(t) - float(t0)) * 1000.0) / 1000.0


def no_frames_error(path: Path, damaged: list[tuple[str, str]]) -> FileFormatError:
    """The error for a recording whose every frame is damaged: the one reason, or the first."""
    if len(damaged) == 1:
        where, reason = damaged[0]
        return FileFormatError(f"{path / where if path.is_dir() else path}: {reason}")
    listed = "; ".join(f"{w}: {r}" for w, r in damaged[:3])
    return FileFormatError(f"{path}: none of its {len(damaged)} frames can be read ({listed}"
                           f"{'; …' if len(damaged) > 3 else ''})")


def _camera_header(meta: dict[str, Any]) -> dict[str, Any]:
    keys = ("creator", "camera_model", "camera_serial_number", "make", "model", "datetime")
    out = {k: meta[k] for k in keys if k in meta}
    if "planck" in meta:
        out["planck"] = dict(meta["planck"])
    return out


def _project_recording(p: Path) -> bool:
    """Whether the commands read ``p`` with the project's own reader
    (:mod:`thermocal.io.recording`): a ``.tif``/``.tiff`` recording whose content is a TIFF's
    (or cannot be read: that reader names why), or a path that does not exist (its message
    then names the missing file). A FLIR file renamed ``.tiff`` goes to :func:`open_recording`,
    which tells it by its content."""
    if not p.exists():
        return True
    if p.suffix.lower() not in (".tif", ".tiff"):
        return False
    try:  # by its content: a FLIR file renamed .tiff is read as what it is
        head = _head(p, 4)
    except FileFormatError:
        return True  # its reader names the file and why it cannot be read
    return not head or head in _TIFF_MAGICS or not p.is_file()


def read_any_recording(path: str | os.PathLike[str], *, fpa_c: float | None = None
                       ) -> Recording:
    """A whole recording of any format, as the commands read it: the project's
    ``NAME.tiff`` + ``NAME.json`` through :func:`~thermocal.io.recording.read_recording`, any
    other through :func:`open_recording` (its per-frame metadata in ``extra``). ``fpa_c`` (the
    command line's ``--fpa-c``) replaces the FPA series."""
    p = Path(path)
    if _project_recording(p):
        return read_recording(p, fpa_c=fpa_c)
    source = open_recording(p)
    rec = source.read_all()
    warn_damaged(source)
    if fpa_c is None:
        return rec
    check_fpa_c(fpa_c, "--fpa-c")
    return dataclasses.replace(rec, fpa_c=np.full(rec.frames.shape[0], float(fpa_c)))


def warn_damaged(source: RecordingSource) -> None:
    """Warn, in one line, of the frames of ``source`` left out as damaged (if any)."""
    text = source.damaged_summary()
    if text:
        warnings.warn(text, stacklevel=3)


@dataclass(frozen=True)
class StreamHeader:
    """What a streamed run over a recording of any format needs before its frames: its
    ``path``, ``n_frames``, ``frame_shape`` and per-frame ``series`` (``fpa_c``, ``time_s``:
    ``(N,)`` arrays or None; ``frame_metadata``: one dict per frame where any frame carries the
    camera's Planck constants, GPS or attitude), ``damaged`` (the frames left out at open:
    ``(where, reason)``, :attr:`RecordingSource.damaged`), and its raw frames in order:
    :meth:`stream` (a frame that does not decode given as zeros, and named) or :meth:`chunks`
    (such a frame ends the stream)."""

    path: Path
    n_frames: int
    frame_shape: tuple[int, int]
    series: dict[str, np.ndarray | None]
    source: RecordingSource | None = None
    bit_depth: int = 14
    damaged: tuple[tuple[str, str], ...] = ()
    prefetched: list[Iterator[FrameChunk]] = dataclasses.field(
        default_factory=list, repr=False, compare=False)

    def stream(self, chunk: int, *, start: int = 0) -> Iterator[
            tuple[int, np.ndarray, tuple[tuple[int, str, str], ...]]]:
        """``(first frame index, frames (k, H, W) uint16, undecodable)`` in order from frame
        ``start`` (the first call of this or :meth:`chunks` goes on from the frames
        :func:`open_stream` decoded already; the chunks' sizes may differ). A frame whose raw
        image does not decode is zeros, named in its chunk's ``undecodable``: ``(index in the
        recording, where, reason)`` (:attr:`FrameChunk.undecodable`). The project's TIFF
        starts reading at ``start``; the other formats are read from their first frame (their
        frames before ``start`` decoded and dropped)."""
        if self.source is None:
            return ((first, frames, ()) for first, frames in iter_recording(
                self.path, chunk=chunk, start=start))
        if not self.prefetched:
            chunks = ((c.start, c.frames, c.undecodable)
                      for c in self.source.iter_frames(chunk, placeholders=True))
        else:
            chunks = _rechunk(self.prefetched.pop(), chunk)
        return chunks if start == 0 else _from_frame(chunks, start)

    def chunks(self, chunk: int) -> Iterator[tuple[int, np.ndarray]]:
        """``(first frame index, frames (k, H, W) uint16)`` in order, as :meth:`stream`; a
        frame that does not decode ends it with one line naming it."""
        for start, frames, undecodable in self.stream(chunk):
            if undecodable:
                raise FileFormatError(f"{self.path}: {undecodable_text(*undecodable[0])}")
            yield start, frames


def undecodable_text(index: int, where: str, reason: str) -> str:
    """``frame 20 does not decode (REASON)``: a frame of :attr:`FrameChunk.undecodable`, named
    by its index in the recording and, where it differs, by ``where`` (its place in its file,
    or its file)."""
    named = ("" if where == str(index)
             else f" (frame {where} of its file)" if where.isdigit() else f" ({where})")
    return f"frame {index}{named} does not decode ({reason})"


def _from_frame(chunks: Iterator[tuple[int, np.ndarray, tuple[tuple[int, str, str], ...]]],
                start: int) -> Iterator[tuple[int, np.ndarray, tuple[tuple[int, str, str], ...]]]:
    """The chunks of :meth:`StreamHeader.stream` from frame ``start`` on: those before it
    dropped, the one across it cut."""
    for first, frames, undecodable in chunks:
        if first + len(frames) <= start:
            continue
        cut = max(0, start - first)
        yield (first + cut, frames[cut:], tuple(u for u in undecodable if u[0] >= start))


def _rechunk(stream: Iterator[FrameChunk], chunk: int) -> Iterator[
        tuple[int, np.ndarray, tuple[tuple[int, str, str], ...]]]:
    """The frames of ``stream`` in chunks of ``chunk`` frames (the last may be shorter), with
    their undecodable frames (:attr:`FrameChunk.undecodable`)."""
    parts: list[np.ndarray] = []
    undecodable: list[tuple[int, str, str]] = []
    start = have = 0
    for c in stream:
        if not parts:
            start = c.start
        parts.append(c.frames)
        undecodable += c.undecodable
        have += len(c)
        if have >= chunk:
            yield start, np.concatenate(parts), tuple(undecodable)
            parts, undecodable, have = [], [], 0
    if parts:
        yield start, np.concatenate(parts), tuple(undecodable)


def open_stream(path: str | os.PathLike[str], *, fpa_c: float | None = None) -> StreamHeader:
    """A recording of any format opened for a streamed run (``thermocal flight``): the
    project's TIFF + JSON from its header (:func:`~thermocal.io.recording.read_recording_header`),
    any other through :func:`open_recording`, whose FPA and time series take one pass over the
    frames' headers and metadata (:meth:`RecordingSource.iter_series`: no raw image decoded).
    ``fpa_c`` (``--fpa-c``) replaces the FPA series. Frames left out as damaged are warned of
    in one line and listed in ``damaged``; a frame whose raw image passed the checks at open
    but does not decode while streamed is kept in its place as zeros, and named
    (:meth:`StreamHeader.stream`: the count of frames is fixed). A recording none of whose
    first :data:`_PREFETCH` frames decodes is refused here, before anything is written."""
    p = Path(path)
    if _project_recording(p):
        header = read_recording_header(p, fpa_c=fpa_c)
        return StreamHeader(header.path, header.n_frames, header.frame_shape,
                            dict(header.series), bit_depth=header.bit_depth)
    source = open_recording(p)
    warn_damaged(source)
    rows = list(source.iter_series())
    metas = [r[3] for r in rows]
    series = {
        "fpa_c": (np.array([r[0] for r in rows], np.float64) if source.has_fpa else None),
        "time_s": (np.array([r[2] for r in rows], np.float64) if source.has_time else None),
        # the camera's own constants (``--method camera``), GPS and attitude, frame by frame,
        # where any frame has them
        "frame_metadata": metas if any(m.get(k) for m in metas for k in _FRAME_KEYS) else None,
    }
    if fpa_c is not None:
        series["fpa_c"] = np.full(source.n_frames, check_fpa_c(fpa_c, "--fpa-c"))
    # the first frames decoded now (and streamed from there): a recording whose raw images do
    # not decode is refused before anything is written
    stream = source.iter_frames(_PREFETCH, placeholders=True)
    first = next(stream)
    if len(first.undecodable) == len(first):
        damaged = list(dict.fromkeys((where, reason) for _, where, reason in first.undecodable))
        if len(first) == source.n_frames:
            raise no_frames_error(p, damaged)
        raise FileFormatError(f"{p}: none of its first {len(first)} frames decodes (the first, "
                              f"{undecodable_text(*first.undecodable[0])})")
    return StreamHeader(p, source.n_frames, source.frame_shape, series, source,
                        bit_depth=source.bit_depth, damaged=tuple(source.damaged),
                        prefetched=[itertools.chain([first], stream)])


#: Frames :func:`open_stream` decodes before it returns.
_PREFETCH = 16


#: Per-frame metadata that makes ``series["frame_metadata"]`` worth keeping.
_FRAME_KEYS = ("planck", "gps", "attitude")


def check_outside_recording(recording: str | os.PathLike[str],
                            *outputs: tuple[str | os.PathLike[str] | None, str]) -> None:
    """Refuse an output ``(path, option name)`` inside a recording that is a folder: written
    there, it would make the folder no longer one recording.

    Raises
    ------
    InvalidInputError
        An output path within the folder ``recording``.
    """
    folder = Path(recording)
    if not folder.is_dir():
        return
    inside = folder.resolve()
    for out, what in outputs:
        if out is not None and inside in Path(out).resolve().parents:
            raise InvalidInputError(
                f"{what} {out} is inside the recording's folder {recording}; write it elsewhere "
                "(the folder would no longer hold one recording)"
            )


def recording_length(path: str | os.PathLike[str]) -> int:
    """How many frames a recording of any format holds (headers only)."""
    p = Path(path)
    if _project_recording(p):
        return read_recording_header(p).n_frames
    return open_recording(p).n_frames
