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
``"envchamberctrl"``      an EnvChamberCtrl ``.npz`` (:mod:`thermocal.io.chamber`)
========================= ======================================================================

**Per-frame series.** ``fpa_c`` is the FPA temperature in °C: the sidecar's series for a TIFF
recording, the chamber's for EnvChamberCtrl, the rig's sparse readings interpolated for
DualTauUAV, and the core temperature (``FLIR:CentralTemperature``, whole °C) for DJI R-JPEGs.
``fpa_measured`` flags the frames whose value was read rather than interpolated, and
:attr:`RecordingSource.fpa_resolution_c` says how coarse a reading is (0.1 °C for DualTauUAV,
1 °C for DJI). FLIR FFF/SEQ/CSQ frames have no FPA temperature (``fpa_c`` is None). ``time_s``
is the time since the first frame, s (for FLIR files from the camera's clock, ms resolution).

**Per-frame metadata** (JSON-serialisable dicts): ``source`` (the file), ``index`` (the
frame's place in that file) and, for FLIR files,
``camera_model``, ``datetime``, ``planck`` (R1, R2, B, F, O, emissivity, distance, reflected,
atmospheric and window parameters: :func:`thermocal.io.fff.planck_from_metadata` makes the
:class:`~thermocal.radiometry.FlirPlanck`), ``gps`` and, for DJI, altitudes and attitude
(:func:`thermocal.io.rjpeg.read_rjpeg`).

**Folders.** Hidden files and notes (``.txt``, ``.md``, ``.json``, ``.xml``, ``.log``) are
skipped; every other file must be of one format (FFF, R-JPEG or DualTauUAV ``.npz``) and all
frames of one size, else :class:`~thermocal.errors.FileFormatError` names the file.
"""

from __future__ import annotations

import dataclasses
import mmap
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import check_fpa_c
from thermocal.errors import FileFormatError, InvalidInputError, ThermocalError
from thermocal.io.dualtau import index_dualtau_folder, npz_keys, read_dualtau_frames
from thermocal.io.fff import (
    FFF_MAGICS,
    fff_frame_shape,
    fff_raw_codec,
    index_fff_series,
    parse_fff_record,
    read_fff_series_frame,
)
from thermocal.io.recording import (
    Recording,
    iter_recording,
    read_recording,
    read_recording_header,
)
from thermocal.io.rjpeg import JPEG_MAGIC, read_rjpeg, rjpeg_frame_shape

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
    """

    start: int
    frames: np.ndarray
    fpa_c: np.ndarray | None
    fpa_measured: np.ndarray | None
    time_s: np.ndarray | None
    metadata: list[dict[str, Any]]

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

    def __repr__(self) -> str:
        h, w = self.frame_shape
        return f"<RecordingSource {self.format} {self.path} {self.n_frames} x {h}x{w}>"

    # -- subclasses yield one frame at a time ----------------------------------------------
    def _frames(self) -> Iterator[tuple[np.ndarray, float | None, bool | None, float | None,
                                        dict[str, Any]]]:
        """Yield ``(raw (H, W), fpa_c, fpa_measured, time_s, metadata)`` per frame."""
        raise NotImplementedError

    def iter_frames(self, chunk: int = 64) -> Iterator[FrameChunk]:
        """Stream the recording in chunks of at most ``chunk`` frames.

        Raises
        ------
        InvalidInputError
            If ``chunk`` is not a positive integer.
        FileFormatError
            A frame that cannot be read, or is not of :attr:`frame_shape` (naming its file).
        """
        if isinstance(chunk, bool) or not isinstance(chunk, int | np.integer) or chunk < 1:
            raise InvalidInputError(f"chunk: expected a positive number of frames, got {chunk!r}")
        return self._chunks(int(chunk))

    def _chunks(self, chunk: int) -> Iterator[FrameChunk]:
        buf: list[tuple[np.ndarray, Any, Any, Any, dict[str, Any]]] = []
        start = 0
        for item in self._frames():
            raw = item[0]
            if raw.shape != self.frame_shape:
                where = item[4].get("source", self.path)
                raise FileFormatError(
                    f"{where}: frame of {raw.shape[0]}x{raw.shape[1]} in a recording of "
                    f"{self.frame_shape[0]}x{self.frame_shape[1]} frames"
                )
            buf.append(item)
            if len(buf) == chunk:
                yield self._assemble(start, buf)
                start += len(buf)
                buf = []
        if buf:
            yield self._assemble(start, buf)

    def _assemble(self, start: int, items: list) -> FrameChunk:
        frames = np.stack([it[0] for it in items]).astype(np.uint16, copy=False)
        fpa = np.array([it[1] for it in items], np.float64) if self.has_fpa else None
        measured = np.array([bool(it[2]) for it in items]) if self.has_fpa else None
        time_s = np.array([it[3] for it in items], np.float64) if self.has_time else None
        return FrameChunk(start, frames, fpa, measured, time_s, [it[4] for it in items])

    def read_all(self) -> Recording:
        """The whole recording in memory, as a :class:`~thermocal.io.recording.Recording`.

        ``extra`` holds ``source_format``, ``frame_metadata`` (the list of per-frame dicts) and,
        with an FPA series, ``fpa_measured`` (list of bool).
        """
        chunks = list(self.iter_frames(256))
        if not chunks:
            raise FileFormatError(f"{self.path}: the recording holds no frames")
        extra: dict[str, Any] = {
            "source_format": self.format,
            "frame_metadata": [m for c in chunks for m in c.metadata],
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

    def _frames(self) -> Iterator[tuple]:
        fpa, t = self._series["fpa_c"], self._series["time_s"]
        others = {k: v for k, v in self._series.items()
                  if v is not None and k not in ("fpa_c", "time_s")}
        for start, block in iter_recording(self.path, chunk=64):
            for k, raw in enumerate(block):
                i = start + k
                meta: dict[str, Any] = {"source": str(self.path), "index": i}
                meta.update({key: float(v[i]) for key, v in others.items()})
                yield (raw, None if fpa is None else float(fpa[i]), True,
                       None if t is None else float(t[i]), meta)


class _FlirFileSource(RecordingSource):
    """FFF, SEQ and CSQ files: FFF records, indexed at open, decoded while iterated."""

    def __init__(self, path: Path, head: bytes) -> None:
        size = path.stat().st_size
        with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            self._index = index_fff_series(mm, size, str(path))
            first = read_fff_series_frame(mm, self._index[0], str(path))
        suffix = path.suffix.lower()
        compressed = fff_raw_codec(head) == "jpegls"
        if compressed or suffix == ".csq":
            fmt = "csq"
        elif len(self._index) > 1 or suffix == ".seq":
            fmt = "seq"
        else:
            fmt = "fff"
        self._t0 = first.metadata.get("time_epoch_s")
        super().__init__(path, fmt, len(self._index), first.raw.shape, bit_depth=16,
                         has_fpa=False, has_time=self._t0 is not None,
                         header=_camera_header(first.metadata))

    def _frames(self) -> Iterator[tuple]:
        name = str(self.path)
        with open(self.path, "rb") as fh, mmap.mmap(fh.fileno(), 0,
                                                     access=mmap.ACCESS_READ) as mm:
            for i, entry in enumerate(self._index):
                where = name if len(self._index) == 1 else f"{name} (frame {i})"
                frame = read_fff_series_frame(mm, entry, where)
                meta = {"source": name, "index": i, **frame.metadata}
                yield frame.raw, None, None, _rel_time(meta, self._t0, where), meta


class _FolderSource(RecordingSource):
    """A folder of single-frame FLIR files (FFF or R-JPEG), in name order."""

    def __init__(self, path: Path, files: list[Path], kind: str) -> None:
        self._files = files
        self._kind = kind
        shape: tuple[int, int] | None = None
        for f in files:
            head = _head(f)
            try:
                shp = rjpeg_frame_shape(head, str(f)) if kind == "rjpeg" else (
                    fff_frame_shape(head, str(f)))
            except FileFormatError:
                if len(head) < _PROBE_BYTES:
                    raise
                data = f.read_bytes()  # the record directory lies further in: read it all
                shp = rjpeg_frame_shape(data, str(f)) if kind == "rjpeg" else (
                    fff_frame_shape(data, str(f)))
            if shape is None:
                shape = shp
            elif shp != shape:
                raise FileFormatError(
                    f"{f}: frames of {shp[0]}x{shp[1]} in a folder of {shape[0]}x{shape[1]} "
                    f"frames (first file {files[0].name})"
                )
        first = self._read(files[0])
        self._t0 = first.metadata.get("time_epoch_s")
        core = first.metadata.get("core_c")
        super().__init__(path, f"{kind}-folder", len(files), shape or first.raw.shape,
                         bit_depth=16, has_fpa=core is not None, has_time=self._t0 is not None,
                         fpa_resolution_c=1.0 if core is not None else None,
                         header={"files": [f.name for f in files],
                                 **_camera_header(first.metadata)})

    def _read(self, f: Path) -> Any:
        if self._kind == "rjpeg":
            return read_rjpeg(f)
        return parse_fff_record(_read_file(f), str(f))

    def _frames(self) -> Iterator[tuple]:
        for f in self._files:
            frame = self._read(f)
            meta = {"source": str(f), "index": 0, **frame.metadata}
            fpa = meta.get("core_c")
            if self.has_fpa and fpa is None:
                raise FileFormatError(f"{f}: no core temperature (FLIR:CentralTemperature), "
                                      f"which {self._files[0].name} has")
            yield frame.raw, fpa, True, _rel_time(meta, self._t0, str(f)), meta


class _RjpegSource(_FolderSource):
    """One R-JPEG: a folder source of one file, named ``"rjpeg"``."""

    def __init__(self, path: Path) -> None:
        super().__init__(path, [path], "rjpeg")
        self.format = "rjpeg"
        self.header.pop("files", None)


class _DualTauSource(RecordingSource):
    def __init__(self, path: Path, files: list[Path] | None = None) -> None:
        self._index = index_dualtau_folder(path if path.is_dir() else path.parent, files)
        ix = self._index
        super().__init__(
            path, "dualtau", int(sum(ix.counts)), ix.frame_shape, bit_depth=14, has_fpa=True,
            has_time=True, fpa_resolution_c=0.1,
            header={"files": [f.name for f in ix.files], "time_origin_ns": ix.time_origin_ns,
                    "fpa_readings": int(np.count_nonzero(ix.fpa_measured))},
        )

    def _frames(self) -> Iterator[tuple]:
        ix = self._index
        i = 0
        for f, n in zip(ix.files, ix.counts, strict=True):
            frames = read_dualtau_frames(f, (n, *ix.frame_shape))
            for k in range(n):
                meta = {"source": str(f), "index": k,
                        "fpa_reading_c": float(ix.fpa_readings_c[i])}
                yield (frames[k], float(ix.fpa_c[i]), bool(ix.fpa_measured[i]),
                       float(ix.time_s[i]), meta)
                i += 1


class _ChamberNpzSource(RecordingSource):
    def __init__(self, path: Path) -> None:
        from thermocal.io.chamber import import_envchamberctrl_npz

        self._session = s = import_envchamberctrl_npz(path)
        frames = np.asarray(s.frames)
        super().__init__(path, "envchamberctrl", frames.shape[0], frames.shape[1:],
                         bit_depth=14, has_fpa=True, has_time=s.time_s is not None,
                         header={k: v for k, v in s.attrs.items()})
        self._frames_arr = frames

    def _frames(self) -> Iterator[tuple]:
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
        raise FileFormatError(f"{p}: no such file or folder")
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
    if head[:4] == _ZIP_MAGIC:
        keys = npz_keys(p)
        if "blackbody" in keys:
            return "envchamberctrl"
        if "frames" in keys:
            return "dualtau"
        raise FileFormatError(f"{p}: an .npz without 'frames' (has {sorted(keys)}); not a "
                              "DualTauUAV or EnvChamberCtrl recording")
    raise FileFormatError(
        f"{p}: unknown recording format (expected a TIFF recording, FLIR FFF/SEQ/CSQ, FLIR "
        "R-JPEG or a DualTauUAV/EnvChamberCtrl .npz)"
    )


def _open_folder(folder: Path) -> RecordingSource:
    files = sorted(f for f in folder.iterdir()
                   if f.is_file() and not f.name.startswith(".") and f.suffix.lower() not in _NOTES)
    if not files:
        raise FileFormatError(f"{folder}: no recording in the folder (no FFF, R-JPEG or .npz "
                              "file)")
    kinds: dict[str, Path] = {}
    for f in files:
        kinds.setdefault(_kind(f, _head(f, 8)), f)
    if len(kinds) > 1:
        found = ", ".join(f"{k} ({f.name})" for k, f in kinds.items())
        raise FileFormatError(f"{folder}: files of mixed formats ({found}); a folder must hold "
                              "one format")
    kind = next(iter(kinds))
    if kind == "fff":
        return _FolderSource(folder, files, "fff")
    if kind == "rjpeg":
        return _FolderSource(folder, files, "rjpeg")
    if kind == "dualtau":
        return _DualTauSource(folder, files)
    raise FileFormatError(f"{folder}: a folder of {kind} files; open each file on its own")


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


def _camera_header(meta: dict[str, Any]) -> dict[str, Any]:
    keys = ("creator", "camera_model", "camera_serial_number", "make", "model", "datetime")
    out = {k: meta[k] for k in keys if k in meta}
    if "planck" in meta:
        out["planck"] = dict(meta["planck"])
    return out


def _project_recording(p: Path) -> bool:
    """Whether the commands read ``p`` with the project's own reader
    (:mod:`thermocal.io.recording`): a ``.tif``/``.tiff`` recording, or a path that does not
    exist (its message then names the missing file)."""
    return p.suffix.lower() in (".tif", ".tiff") or not p.exists()


def read_any_recording(path: str | os.PathLike[str], *, fpa_c: float | None = None
                       ) -> Recording:
    """A whole recording of any format, as the commands read it: the project's
    ``NAME.tiff`` + ``NAME.json`` through :func:`~thermocal.io.recording.read_recording`, any
    other through :func:`open_recording` (its per-frame metadata in ``extra``). ``fpa_c`` (the
    command line's ``--fpa-c``) replaces the FPA series."""
    p = Path(path)
    if _project_recording(p):
        return read_recording(p, fpa_c=fpa_c)
    rec = open_recording(p).read_all()
    if fpa_c is None:
        return rec
    check_fpa_c(fpa_c, "--fpa-c")
    return dataclasses.replace(rec, fpa_c=np.full(rec.frames.shape[0], float(fpa_c)))


@dataclass(frozen=True)
class StreamHeader:
    """What a streamed run over a recording of any format needs before its frames: its
    ``path``, ``n_frames``, ``frame_shape`` and per-frame ``series`` (``fpa_c``, ``time_s``:
    ``(N,)`` arrays or None; ``frame_metadata``: one dict per frame where the file carries the
    camera's Planck constants), and :meth:`chunks`, its raw frames in order."""

    path: Path
    n_frames: int
    frame_shape: tuple[int, int]
    series: dict[str, np.ndarray | None]
    source: RecordingSource | None = None
    bit_depth: int = 14

    def chunks(self, chunk: int) -> Iterator[tuple[int, np.ndarray]]:
        """``(first frame index, frames (k, H, W) uint16)`` in order."""
        if self.source is None:
            return iter_recording(self.path, chunk=chunk)
        return ((c.start, c.frames) for c in self.source.iter_frames(chunk))


def open_stream(path: str | os.PathLike[str], *, fpa_c: float | None = None) -> StreamHeader:
    """A recording of any format opened for a streamed run (``thermocal flight``): the
    project's TIFF + JSON from its header (:func:`~thermocal.io.recording.read_recording_header`),
    any other through :func:`open_recording`, whose FPA and time series take one pass over the
    frames. ``fpa_c`` (``--fpa-c``) replaces the FPA series."""
    p = Path(path)
    if _project_recording(p):
        header = read_recording_header(p, fpa_c=fpa_c)
        return StreamHeader(header.path, header.n_frames, header.frame_shape,
                            dict(header.series), bit_depth=header.bit_depth)
    source = open_recording(p)
    fpa, times, metas = [], [], []
    for c in source.iter_frames():
        fpa.append(c.fpa_c)
        times.append(c.time_s)
        metas.extend(c.metadata or [])
    series = {
        "fpa_c": None if any(f is None for f in fpa) else np.concatenate(fpa).astype(np.float64),
        "time_s": None if any(t is None for t in times) else np.concatenate(times).astype(
            np.float64),
        # the camera's own constants, frame by frame (``--method camera``), where it has them
        "frame_metadata": metas if metas and any(m.get("planck") for m in metas) else None,
    }
    if fpa_c is not None:
        series["fpa_c"] = np.full(source.n_frames, check_fpa_c(fpa_c, "--fpa-c"))
    return StreamHeader(p, source.n_frames, source.frame_shape, series, source,
                        bit_depth=source.bit_depth)


def recording_length(path: str | os.PathLike[str]) -> int:
    """How many frames a recording of any format holds (headers only)."""
    p = Path(path)
    if _project_recording(p):
        return read_recording_header(p).n_frames
    return open_recording(p).n_frames
