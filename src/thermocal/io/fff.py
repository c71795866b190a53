"""FLIR FFF records: one frame of raw counts with its calibration and metadata.

An FFF record (``"FFF\\0"`` or ``"AFF\\0"``) is what a FLIR core writes for one frame: a 64-byte
header, a directory of 32-byte entries, and the records it points to. The same record is the
unit of the other FLIR formats:

* a bare ``.fff`` file is one record (big- or little-endian);
* a FLIR **SEQ** file is a series of FFF records, one per frame, back to back;
* a FLIR **CSQ** file is the same series with the raw counts of each frame JPEG-LS compressed
  (decoded with ``imagecodecs.jpegls_decode``);
* a FLIR radiometric JPEG (R-JPEG) carries one record split across its FLIR APP1 segments
  (:mod:`thermocal.io.rjpeg`).

Parsed by hand because no maintained library reads them: ``flyr`` accepts only JPEGs and fails
on the Tau2-core DJI layout, exiftool is a Perl program (not a Python dependency) and flirpy's
SEQ splitter shells out to it. The layout follows exiftool's ``FLIR.pm``: the raw-data record
(type 1) holds width and height at bytes 2 and 4 and the counts from byte 32 — plain uint16 in the
record's byte order, a PNG with byte-swapped samples, a TIFF, or JPEG-LS; the camera-info record
(type 32) holds the Planck constants and object parameters (read by
:mod:`thermocal.scenes.real`), the camera's model strings at 0xD4…0x170, the field of view at
0x1B4 and the time of the frame at 0x384; the GPS record (type 43) holds position, altitude,
speed and track.

:func:`parse_fff_record` turns the bytes of one record into an :class:`FffFrame`;
:func:`index_fff_series` finds the records of a SEQ/CSQ file without reading their pixels, so
that a long file can be streamed (:func:`read_fff_series_frame`).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import io
import math
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.radiometry import FlirPlanck

# The camera-info decoder (Planck constants, object and atmosphere parameters) and the record
# byte-order rule are shared with the scene loader rather than written twice.

__all__ = [
    "CORE_CAMERAS",
    "FFF_MAGICS",
    "TAU2_CAMERAS",
    "FffFrame",
    "error_reason",
    "names_core",
    "flir_bit_depth",
    "fff_frame_shape",
    "fff_raw_codec",
    "fff_raw_image",
    "fff_record_metadata",
    "index_fff_series",
    "parse_fff_record",
    "planck_from_metadata",
    "read_fff_series_frame",
]

#: Parts of a file's make and model (upper case, found anywhere in them) that name a
#: radiometric Tau2 camera: DJI's Zenmuse XT series (EXIF make "DJI", model "FLIR"), FLIR's
#: Duo Pro R and Vue Pro R, a bare Tau2 core. Not "XT" alone: FLIR's E8-XT is a handheld.
TAU2_CAMERAS = ("DJI", "ZENMUSE", "TAU", "DUO PRO", "VUE PRO")

#: The same for every radiometric core (±5 °C or 5 %, 14-bit counts): the Tau2 cameras and a
#: Boson core (the simulator's second family writes "thermocal simulated Boson-class core").
CORE_CAMERAS = (*TAU2_CAMERAS, "BOSON")


def names_core(metadata: dict[str, Any]) -> bool:
    """Whether a FLIR file's metadata (its ``make``, ``model``, ``camera_model``) name a
    radiometric core camera (:data:`CORE_CAMERAS`) rather than one of FLIR's own cameras."""
    names = " ".join(str(metadata.get(k, "")) for k in ("make", "model", "camera_model"))
    return any(tag in names.upper() for tag in CORE_CAMERAS)


def flir_bit_depth(metadata: dict[str, Any]) -> int:
    """The bit depth of a FLIR file's sensor, whose top count is its saturation: 14 for a
    radiometric core (Tau2, Boson: their data sheets' 14-bit output, in the file's 16-bit
    container), 16 for FLIR's own cameras (a T1030sc's counts reach 16,319). The recording
    keeps its container's 16 bits (a damaged frame's counts beyond 14 bits do not refuse the
    rest); ``--method camera`` fills the counts at this top."""
    return 14 if names_core(metadata) else 16


#: The signatures an FFF record starts with.
FFF_MAGICS: tuple[bytes, ...] = (b"FFF\x00", b"AFF\x00")

_RAW_DATA = 1
_CAMERA_INFO = 32
_GPS_INFO = 43
_HEADER = 64
_MAX_GAP = 1 << 16  # most bytes of padding looked through between two records of a series
_ENTRY = 32


@dataclass(frozen=True)
class FffFrame:
    """One FFF record, decoded.

    Attributes
    ----------
    raw : numpy.ndarray, uint16, shape (H, W)
        Raw counts (native byte order).
    planck : FlirPlanck
        The record's Planck constants and object/atmosphere parameters.
    metadata : dict
        JSON-serialisable: ``creator``, ``camera_model``, ``camera_part_number``,
        ``camera_serial_number``, ``camera_software``, ``lens_model``, ``field_of_view_deg``,
        ``frame_rate_hz``, ``datetime`` (ISO 8601 with the camera's time zone, or None),
        ``time_epoch_s`` (s since 1970 UTC, or None), ``planck`` (the fields of
        :class:`FlirPlanck`; see :func:`planck_from_metadata`) and ``gps`` (a dict of
        ``latitude``, ``longitude`` (signed degrees), ``altitude_m``, ``speed``, ``track_deg``,
        ``map_datum``; or None).
    """

    raw: np.ndarray
    planck: FlirPlanck
    metadata: dict[str, Any]


def planck_from_metadata(metadata: dict[str, Any]) -> FlirPlanck:
    """The :class:`FlirPlanck` of a frame's metadata (its ``"planck"`` entry)."""
    try:
        return FlirPlanck(**metadata["planck"])
    except (KeyError, TypeError):
        raise FileFormatError("frame metadata has no FLIR Planck constants") from None


# --------------------------------------------------------------------------------------------
# directory
# --------------------------------------------------------------------------------------------
def _directory(
    buf: Any, base: int, limit: int, name: str
) -> tuple[str, str, dict[int, tuple[int, int, int]], int]:
    """Header and directory of the record at ``buf[base:]``.

    Returns (byte order, creator, records, end of the directory relative to ``base``).

    ``records`` maps a record type to ``(subtype, offset, length)``, offsets relative to
    ``base``. ``limit`` is the number of bytes available from ``base`` (checks truncation).
    """
    head = bytes(buf[base : base + _HEADER])
    if head[:4] not in FFF_MAGICS:
        raise FileFormatError(f"{name}: not a FLIR FFF record (no 'FFF' signature)")
    if len(head) < _HEADER:
        raise FileFormatError(f"{name}: truncated FFF record (header is {len(head)} of 64 bytes)")
    order = ">"
    version, dir_offset, n_entries = struct.unpack_from(">III", head, 0x14)
    if not 100 <= version < 200:
        order = "<"
        version, dir_offset, n_entries = struct.unpack_from("<III", head, 0x14)
        if not 100 <= version < 200:
            raise FileFormatError(f"{name}: unsupported FFF version in the record header")
    if n_entries > 4096 or dir_offset + _ENTRY * n_entries > limit:
        raise FileFormatError(f"{name}: truncated FFF record (record directory cut short)")
    table = bytes(buf[base + dir_offset : base + dir_offset + _ENTRY * n_entries])
    records: dict[int, tuple[int, int, int]] = {}
    for k in range(n_entries):
        rtype, subtype, _ver, _idx, offset, length = struct.unpack_from(
            order + "HHIIII", table, _ENTRY * k
        )
        if rtype and rtype not in records:
            records[rtype] = (subtype, offset, length)
    creator = head[4:20].split(b"\x00")[0].decode("latin-1").strip()
    return order, creator, records, dir_offset + _ENTRY * n_entries


def _record_end(records: dict[int, tuple[int, int, int]], dir_end: int) -> int:
    return max([dir_end, *(off + length for _, off, length in records.values())])


def fff_frame_shape(data: bytes, name: str) -> tuple[int, int]:
    """``(H, W)`` of the raw image of the FFF record at the start of ``data`` (header only).

    ``data`` need only hold the header, the directory and the first 32 bytes of the raw record.
    """
    _, _, records, _ = _directory(data, 0, len(data), name)
    if _RAW_DATA not in records:
        raise FileFormatError(f"{name}: FFF record has no raw data record")
    _, offset, _ = records[_RAW_DATA]
    if offset + 6 > len(data):
        raise FileFormatError(f"{name}: truncated FFF record (raw data record cut short)")
    order = fff_record_order(data, offset)
    width, height = struct.unpack_from(order + "HH", data, offset + 2)
    return int(height), int(width)


def fff_raw_codec(data: bytes) -> str:
    """How the raw image of the record at the start of ``data`` is stored: ``"plain"``,
    ``"png"``, ``"tiff"`` or ``"jpegls"``; ``"unknown"`` when ``data`` does not reach it."""
    try:
        _, _, records, _ = _directory(data, 0, len(data), "")
        _, off, _ = records[_RAW_DATA]
    except (FileFormatError, KeyError, struct.error):
        return "unknown"
    magic = data[off + 32 : off + 36]
    if len(magic) < 4:
        return "unknown"
    if magic == b"\x89PNG":
        return "png"
    if magic in (b"II*\x00", b"MM\x00*"):
        return "tiff"
    if magic[:3] == b"\xff\xd8\xff":  # JPEG-LS: SOF55 (FF F7), or a SPIFF header first
        return "jpegls"
    return "plain"


# --------------------------------------------------------------------------------------------
# one record
# --------------------------------------------------------------------------------------------
def parse_fff_record(data: bytes, name: str) -> FffFrame:
    """Decode one FFF record (the bytes of a ``.fff`` file, one SEQ/CSQ frame, or an R-JPEG's
    joined FLIR segments).

    Parameters
    ----------
    data : bytes
        The record, starting with ``"FFF\\0"``.
    name : str
        What to call it in error messages (the file, and the frame for a series).

    Raises
    ------
    FileFormatError
        A missing signature, an unknown version, a truncated record, no raw-data or camera-info
        record, a raw image that does not match its declared size or does not decode, or
        invalid Planck constants.
    """
    _, planck, meta = fff_record_metadata(data, name)
    return FffFrame(fff_raw_image(data, name), planck, meta)


def fff_raw_image(data: bytes, name: str) -> np.ndarray:
    """The raw counts of a record that :func:`fff_record_metadata` passed, decoded."""
    return _raw_image(data, _directory(data, 0, len(data), name)[2][_RAW_DATA], name)


def fff_record_metadata(data: bytes, name: str) -> tuple[tuple[int, int], FlirPlanck,
                                                         dict[str, Any]]:
    """Check one FFF record without decoding its raw image: ``((H, W), planck, metadata)``.

    Every check of :func:`parse_fff_record` but the decoding itself: the header, the
    directory, the records' lengths, the Planck constants and, of the raw image, its declared
    size against its bytes (plain counts), or the structure of its compressed stream (JPEG-LS
    or PNG: signature, declared size, end marker). A record that passes may still fail to
    decode when its compressed data are damaged inside.

    Raises
    ------
    FileFormatError
        As :func:`parse_fff_record`.
    """
    _, creator, records, _ = _directory(data, 0, len(data), name)
    for rtype, what in ((_RAW_DATA, "raw data"), (_CAMERA_INFO, "camera info")):
        if rtype not in records:
            raise FileFormatError(f"{name}: FFF record has no {what} record")
        _, offset, length = records[rtype]
        if rtype == _RAW_DATA:
            # the raw record may declare a few bytes of padding past the end of the last frame
            # of a series (Thermimage's SampleCSQ.csq); its decoder checks that it is whole
            length = min(length, max(32, len(data) - offset))
        if offset + length > len(data):
            raise FileFormatError(
                f"{name}: truncated FFF record ({what} record ends at byte {offset + length}, "
                f"only {len(data)} bytes)"
            )
    cam_off, cam_len = records[_CAMERA_INFO][1], records[_CAMERA_INFO][2]
    if cam_len < 0x310:
        raise FileFormatError(f"{name}: FFF camera info record is too short for Planck constants")
    shape = _check_raw_payload(data, records[_RAW_DATA], name)
    planck = fff_camera_info(data, cam_off, Path(name))
    meta = _camera_metadata(data, cam_off, cam_len)
    meta["creator"] = creator
    meta["planck"] = dataclasses.asdict(planck)
    meta["gps"] = None
    if _GPS_INFO in records:
        _, g_off, g_len = records[_GPS_INFO]
        if g_len >= 0x68 and g_off + g_len <= len(data):
            meta["gps"] = _gps(data, g_off)
    return shape, planck, meta


_PNG_END = b"IEND\xaeB`\x82"


def _check_raw_payload(data: bytes, record: tuple[int, int, int], name: str) -> tuple[int, int]:
    """``(H, W)`` of a raw-data record, after the checks that need no decoding."""
    subtype, offset, length = record
    if length < 32:
        raise FileFormatError(f"{name}: FFF raw data record is too short")
    order = fff_record_order(data, offset)
    width, height = struct.unpack_from(order + "HH", data, offset + 2)
    if width == 0 or height == 0:
        raise FileFormatError(f"{name}: FFF raw data record declares a {width}x{height} image")
    payload = memoryview(data)[offset + 32 : offset + length]
    magic = bytes(payload[:4])
    tail = bytes(payload[-64:]).rstrip(b"\x00")
    if magic[:3] == b"\xff\xd8\xff":  # JPEG-LS
        if not tail.endswith(b"\xff\xd9"):
            raise FileFormatError(f"{name}: truncated FFF record (compressed raw image cut short)")
        head = bytes(payload[:512])
        sof = head.find(b"\xff\xf7")
        if sof != -1 and sof + 9 <= len(head):
            rows, cols = struct.unpack_from(">HH", head, sof + 5)
            if (rows, cols) != (height, width):
                raise FileFormatError(
                    f"{name}: compressed raw image is {cols}x{rows}, its record says "
                    f"{width}x{height}"
                )
    elif magic == b"\x89PNG":
        if not tail.endswith(_PNG_END):
            raise FileFormatError(f"{name}: truncated FFF record (PNG raw image cut short)")
        if len(payload) >= 24:
            cols, rows = struct.unpack_from(">II", payload, 16)
            if (rows, cols) != (height, width):
                raise FileFormatError(
                    f"{name}: PNG raw image is {cols}x{rows}, its record says {width}x{height}"
                )
    elif magic not in (b"II*\x00", b"MM\x00*") and len(payload) < 2 * width * height:
        raise FileFormatError(
            f"{name}: FFF raw data record holds {len(payload)} bytes, need "
            f"{2 * width * height} for {width}x{height} (subtype {subtype}); truncated?"
        )
    return int(height), int(width)


def _raw_image(data: bytes, record: tuple[int, int, int], name: str) -> np.ndarray:
    """Decode a raw-data record that :func:`_check_raw_payload` passed."""
    _, offset, length = record
    order = fff_record_order(data, offset)
    width, height = struct.unpack_from(order + "HH", data, offset + 2)
    payload = data[offset + 32 : offset + length]
    try:
        if payload[:4] == b"\x89PNG":  # PNG with byte-swapped 16-bit samples
            import cv2

            img = cv2.imdecode(np.frombuffer(payload, np.uint8), cv2.IMREAD_UNCHANGED)
            if img is None or img.dtype != np.uint16:
                raise ValueError("not a 16-bit PNG")
            raw = img.byteswap()
        elif payload[:4] in (b"II*\x00", b"MM\x00*"):  # a TIFF (some DJI/FLIR cores)
            import tifffile

            raw = tifffile.imread(io.BytesIO(payload))
        elif payload[:3] == b"\xff\xd8\xff":  # JPEG-LS (CSQ frames)
            import imagecodecs

            raw = imagecodecs.jpegls_decode(payload)
        else:
            n = width * height
            raw = np.frombuffer(payload, np.dtype(order + "u2"), count=n).reshape(height, width)
    except Exception as exc:  # decoders raise many types on corrupt data
        raise FileFormatError(
            f"{name}: raw image does not decode ({type(exc).__name__}: {str(exc)[:80]})"
        ) from None
    raw = np.asarray(raw)
    if raw.shape != (height, width) or raw.dtype.kind not in "ui":
        raise FileFormatError(
            f"{name}: FFF raw image is {raw.dtype} {raw.shape}, its record says {height}x{width}"
        )
    return raw.astype(np.uint16)  # native byte order, a copy the caller owns


def _text(data: bytes, start: int, size: int) -> str:
    return data[start : start + size].split(b"\x00")[0].decode("latin-1").strip()


def _camera_metadata(data: bytes, off: int, length: int) -> dict[str, Any]:
    """Strings, field of view, frame rate and time of a camera-info record (exiftool offsets)."""
    order = fff_record_order(data, off)
    meta: dict[str, Any] = {
        "camera_model": _text(data, off + 0xD4, 32),
        "camera_part_number": _text(data, off + 0xF4, 16),
        "camera_serial_number": _text(data, off + 0x104, 16),
        "camera_software": _text(data, off + 0x114, 16),
        "lens_model": _text(data, off + 0x170, 32),
        "field_of_view_deg": float(struct.unpack_from(order + "f", data, off + 0x1B4)[0]),
        "temperature_range_c": _measuring_range(data, off, order),
        "datetime": None,
        "time_epoch_s": None,
        "frame_rate_hz": None,
    }
    if length >= 0x38E:
        # exiftool: int32u seconds since 1970 (UTC), int32u whose low 16 bits are the
        # milliseconds, int16s time-zone offset in minutes (west positive)
        sec, sub, tz_min = struct.unpack_from(order + "IIh", data, off + 0x384)
        ms = sub & 0xFFFF
        if sec > 0 and ms < 1000:
            tz = _dt.timezone(_dt.timedelta(minutes=-tz_min))
            when = _dt.datetime.fromtimestamp(sec, _dt.UTC).astimezone(tz)
            meta["datetime"] = when.replace(microsecond=1000 * ms).isoformat(
                timespec="milliseconds"
            )
            meta["time_epoch_s"] = sec + ms / 1000.0
    if length >= 0x466:
        meta["frame_rate_hz"] = int(struct.unpack_from(order + "H", data, off + 0x464)[0])
    return meta


def _measuring_range(data: bytes, off: int, order: str) -> list[float] | None:
    """The camera's measuring range, ``[min, max]`` °C: exiftool's CameraTemperatureRangeMin
    and Max (float32 K at 0x94 and 0x90 of the camera-info record; a DJI XT-R's −25…135 °C);
    None where the file states none (zeros) or an implausible one."""
    hi, lo = (v - ZERO_CELSIUS_K for v in struct.unpack_from(order + "ff", data, off + 0x90))
    if not (math.isfinite(lo) and math.isfinite(hi) and -273.0 < lo < hi < 3000.0):
        return None
    return [round(float(lo), 4), round(float(hi), 4)]


def _gps(data: bytes, off: int) -> dict[str, Any] | None:
    """The GPS record (exiftool FLIR::GPSInfo); None when it is marked invalid."""
    (valid_le,) = struct.unpack_from("<I", data, off)
    order = "<" if valid_le < 0x10000 else ">"
    (valid,) = struct.unpack_from(order + "I", data, off)
    lat, lon, alt = struct.unpack_from(order + "ddf", data, off + 0x10)
    if not (abs(lat) <= 90 and abs(lon) <= 180):
        order = "<" if order == ">" else ">"
        (valid,) = struct.unpack_from(order + "I", data, off)
        lat, lon, alt = struct.unpack_from(order + "ddf", data, off + 0x10)
    if valid != 1 or not all(math.isfinite(v) for v in (lat, lon, alt)):
        return None
    lat_ref, lon_ref = _text(data, off + 0x08, 2), _text(data, off + 0x0A, 2)
    lat = -abs(lat) if lat_ref == "S" else abs(lat) if lat_ref == "N" else lat
    lon = -abs(lon) if lon_ref == "W" else abs(lon) if lon_ref == "E" else lon
    speed, track = struct.unpack_from(order + "ff", data, off + 0x4C)
    return {
        "latitude": float(lat),
        "longitude": float(lon),
        "altitude_m": float(alt),
        "speed": float(speed),
        "speed_ref": _text(data, off + 0x44, 2),
        "track_deg": float(track),
        "map_datum": _text(data, off + 0x58, 16),
    }


# --------------------------------------------------------------------------------------------
# series (SEQ, CSQ)
# --------------------------------------------------------------------------------------------
def index_fff_series(buf: Any, size: int, name: str) -> tuple[
    list[tuple[int, int]], list[tuple[int, str]]
]:
    """Find the FFF records of a SEQ/CSQ file from their headers: ``(records, damaged)``.

    ``records`` are the ``(offset, length)`` of the records whose header and directory parse;
    ``damaged`` the ``(frame index in the file, reason)`` of those that do not: a header or
    directory that does not parse, bytes where a record should start that are none (its
    signature damaged), a last record cut short by the end of the file. ``buf`` is the file's
    bytes or a memory map of them (``size`` bytes). Up to 64 KiB between records (padding) are
    skipped to the next ``"FFF\\0"``; after a damaged record the next signature is looked for
    one record length on, then anywhere further; bytes after the last record with no signature
    after them are ignored.
    """
    records_out: list[tuple[int, int]] = []
    damaged: list[tuple[int, str]] = []
    pos, stride = 0, 0
    while pos + 4 <= size:
        k = len(records_out) + len(damaged)
        where = f"{name} (frame {k})" if k else name
        try:
            _, _, records, dir_end = _directory(buf, pos, size - pos, where)
            if _RAW_DATA not in records:
                raise FileFormatError(f"{where}: FFF record has no raw data record")
            end = _record_end(records, dir_end)
        except FileFormatError as exc:
            damaged.append((k, error_reason(exc, where)))
            nxt = _next_signature(buf, pos + 4, size, pos + stride if stride else None)
            if nxt is None:
                break
            pos = nxt
            continue
        if pos + end > size and not _only_padding_missing(buf, pos, records, size):
            nxt = _next_signature(buf, pos + 4, size, None)
            if nxt is None:
                damaged.append((k, f"truncated (the record needs {end} bytes, the file has "
                                   f"{size - pos} left)"))
                break
            damaged.append((k, "record directory damaged (it runs past the end of the file)"))
            pos = nxt
            continue
        end = min(end, size - pos)
        records_out.append((pos, end))
        stride = end
        nxt = pos + end
        if bytes(buf[nxt : nxt + 4]) in FFF_MAGICS:
            pos = nxt
            continue
        # padding between records: a signature close by; further on, the record in between is
        # damaged (its signature); none: bytes after the last record, ignored
        found = _next_signature(buf, nxt, size, None)
        if found is None:
            break
        if found - nxt > _MAX_GAP:
            damaged.append((k + 1, f"no FFF signature where the record starts ({found - nxt} "
                                   "bytes skipped)"))
        pos = found
    return records_out, damaged


def error_reason(exc: Exception, where: str) -> str:
    """The message of ``exc`` without the ``where`` (and colon) it starts with."""
    text = str(exc)
    return text[len(where) + 2 :] if text.startswith(f"{where}: ") else text


def _next_signature(buf: Any, start: int, size: int, guess: int | None) -> int | None:
    """Offset of the next ``"FFF\\0"``/``"AFF\\0"`` at or after ``start`` (``guess`` first,
    where the records are of one length); None when there is none."""
    if guess is not None and start <= guess and bytes(buf[guess : guess + 4]) in FFF_MAGICS:
        return guess
    hits = [k for k in (buf.find(m, start, size) for m in FFF_MAGICS) if k != -1]
    return min(hits) if hits else None


def _only_padding_missing(
    buf: Any, pos: int, records: dict[int, tuple[int, int, int]], size: int
) -> bool:
    """True if a record cut short by the end of the file lacks only the padding of its
    compressed raw image (the last frame of Thermimage's SampleCSQ.csq): everything else is
    there and the JPEG-LS stream ends with its end-of-image marker."""
    for rtype, (_, off, length) in records.items():
        if rtype != _RAW_DATA and pos + off + length > size:
            return False
    _, off, length = records[_RAW_DATA]
    shortfall = pos + off + length - size
    if not 0 < shortfall <= 16:
        return False
    tail = bytes(buf[max(pos + off, size - 4) : size])
    return tail.endswith(b"\xff\xd9")


def read_fff_series_frame(buf: Any, entry: tuple[int, int], name: str, *,
                          decode: bool = True) -> FffFrame:
    """Decode the record ``entry = (offset, length)`` of :func:`index_fff_series`; with
    ``decode=False`` its checks and metadata only (:func:`fff_record_metadata`), ``raw`` then
    an empty ``(0, 0)`` array."""
    offset, length = entry
    data = bytes(buf[offset : offset + length])
    if decode:
        return parse_fff_record(data, name)
    _, planck, meta = fff_record_metadata(data, name)
    return FffFrame(np.zeros((0, 0), np.uint16), planck, meta)


def fff_record_order(data: bytes, offset: int) -> str:
    """Byte order of a record: its first int16 is small (e.g. 2) in the record's own order."""
    (check,) = struct.unpack_from("<H", data, offset)
    return "<" if check < 0x100 else ">"


def fff_camera_info(data: bytes, offset: int, p: Path) -> FlirPlanck:
    """Camera-info record fields (exiftool FLIR::CameraInfo byte offsets; temperatures in K)."""
    o = fff_record_order(data, offset)

    def f32(rel: int) -> float:
        return float(struct.unpack_from(o + "f", data, offset + rel)[0])

    o_val = struct.unpack_from(o + "i", data, offset + 0x308)[0]
    humidity = f32(0x3C)
    try:
        return FlirPlanck(
            f32(0x58),  # Planck R1
            f32(0x30C),  # Planck R2
            f32(0x5C),  # Planck B
            f32(0x60),  # Planck F
            float(o_val),  # Planck O (int32)
            emissivity=f32(0x20),
            distance_m=f32(0x24),
            reflected_c=f32(0x28) - ZERO_CELSIUS_K,
            atmosphere_c=f32(0x2C) - ZERO_CELSIUS_K,
            ir_window_c=f32(0x30) - ZERO_CELSIUS_K,
            ir_window_transmission=f32(0x34),
            humidity=humidity / 100.0 if humidity > 2.0 else humidity,
            alpha1=f32(0x70),
            alpha2=f32(0x74),
            beta1=f32(0x78),
            beta2=f32(0x7C),
            x=f32(0x80),
        )
    except (InvalidInputError, ArithmeticError, ValueError) as exc:  # a damaged record's
        # numbers may overflow the atmosphere's formulas before they are found out of range
        raise FileFormatError(f"{p}: invalid camera-info record in FFF file ({exc})") from None
