"""Write a simulated recording in a real camera's file format.

:func:`write_recording_as` writes a :class:`~thermocal.io.recording.Recording` (raw counts, FPA
series, times) as one of :data:`WRITE_FORMATS`, laid out as the cameras and rigs lay them out and
as :func:`thermocal.io.open_recording` reads them:

================ =============================================================================
``format``       what is written
================ =============================================================================
``"tiff"``       the project's ``NAME.tiff`` + ``NAME.json`` (:mod:`thermocal.io.recording`)
``"seq"``        a FLIR SEQ file: one FFF record per frame, back to back, big-endian
``"csq"``        a FLIR CSQ file: the same, raw counts JPEG-LS compressed
                 (``imagecodecs.jpegls_encode``, lossless)
``"fff"``        a folder of ``.fff`` files, one FFF record each (big-endian by default)
``"rjpeg"``      a folder of FLIR R-JPEGs: a grey preview JPEG whose FLIR APP1 segments carry a
                 little-endian FFF record with the raw counts as a PNG of byte-swapped samples
                 (FLIR's handheld layout), plus EXIF GPS
``"dji-rjpeg"``  a folder of DJI Zenmuse XT2/XT-R R-JPEGs: the Tau2 core's 2-entry record (raw
                 counts as a TIFF, creator ``ATAU_RBFO``), EXIF make/model/GPS and DJI XMP
                 (``AbsoluteAltitude``, nadir gimbal, flight yaw, ``FLIR:CentralTemperature``:
                 the Tau2's spot meter, its own reading of the 4×4 centre pixels in whole °C;
                 no FPA temperature, as the real camera)
``"dualtau"``    a DualTauUAV flight: a folder of ``np.savez`` files, one per 2 s, with
                 ``frames``, ``fpa`` (hundredths of °C, read every 30 s and rounded to 0.1 °C,
                 repeated on every frame), ``time_ns_start`` and ``time_ns_end``
================ =============================================================================

Every FLIR record holds the Planck constants (``planck``, stored as float32 with O an int32, as
the cameras store them), the frame's time (epoch s, ms resolution, UTC) and frame rate, and,
where ``gps`` is given, a GPS record (latitude, longitude, altitude, track). What a format has no
place for is lost, as with the real camera: FLIR SEQ/CSQ/FFF and R-JPEGs, DJI's too, carry no
FPA temperature; DualTauUAV files carry no GPS and no Planck constants (``gps`` is refused there).

The FFF records are assembled by hand (:func:`fff_record`, the byte layout of exiftool's
``FLIR.pm`` that :mod:`thermocal.io.fff` reads) because no library writes them: exiftool can
only edit tags of an existing record, and ``flyr``/``flirpy``/Thermimage only read. The
compressed images inside (JPEG-LS, PNG, TIFF), the preview JPEG, its EXIF and XMP are written
with imagecodecs, OpenCV, tifffile and Pillow.

Outputs are written whole or not at all: a file through
:func:`thermocal.io.atomic.atomic_path`, a folder in a temporary folder beside it that is
renamed into place at the end.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import struct
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError
from thermocal.io.atomic import atomic_path, staging_folder
from thermocal.io.geotag import dms
from thermocal.io.recording import Recording, RecordingWriter
from thermocal.radiometry import FlirPlanck

__all__ = [
    "SIMULATED_RANGE_C",
    "DEFAULT_PLANCK",
    "DEFAULT_START_EPOCH_S",
    "FILE_LIKE_SUFFIXES",
    "FOLDER_FORMATS",
    "WRITE_FORMATS",
    "check_output_path",
    "convert_recording",
    "fff_record",
    "gps_line",
    "rjpeg_bytes",
    "unit_planck",
    "simulated_model",
    "write_chunks_as",
    "write_recording_as",
]

#: The formats :func:`write_recording_as` writes.
WRITE_FORMATS: tuple[str, ...] = ("tiff", "seq", "csq", "fff", "rjpeg", "dji-rjpeg", "dualtau")

#: Formats written as a folder of files (one per frame, or per 2 s for DualTauUAV).
FOLDER_FORMATS: tuple[str, ...] = ("fff", "rjpeg", "dji-rjpeg", "dualtau")

_FILE_SUFFIXES = {"tiff": (".tiff", ".tif"), "seq": (".seq",), "csq": (".csq",)}
_FRAME_SUFFIX = {"fff": ".fff", "rjpeg": ".jpg", "dji-rjpeg": ".jpg", "dualtau": ".npz"}
#: Suffixes of recording and data files: refused as the name of an output folder.
FILE_LIKE_SUFFIXES = frozenset((".tiff", ".tif", ".seq", ".csq", ".fff", ".jpg", ".jpeg",
                                ".npz", ".h5", ".hdf5", ".json"))

#: Planck constants and object parameters written by default: those of a DJI Zenmuse XT-R
#: (Tau2 core; ``shared/data/recordings/dji_xtr_tau2.jpg``); R1, R2, B, F and O are exact in
#: float32 / int32, so they read back equal.
DEFAULT_PLANCK = FlirPlanck(17096.453125, 0.048084795475006104, 1428.0, 1.0, -370.0,
                            emissivity=0.95, distance_m=20.0, reflected_c=20.0,
                            atmosphere_c=20.0, ir_window_c=20.0, humidity=0.5)


def unit_planck(camera: Any, fpa_c: float) -> FlirPlanck:
    """Planck constants that describe a simulated unit, for the FLIR files it is written to:
    FLIR's ``U(T) = R1 / (R2·(exp(B/T) − F)) − O`` is Lin et al.'s eq. 4 with ``R = R1/R2``
    (R2 = 1) and ``O`` negated, fitted (:func:`~thermocal.calibration.lin.fit_planck_curve`)
    to the median over the unit's pixels of its noise-free counts for blackbodies at
    −20…120 °C (those inside its bit depth), the FPA at ``fpa_c`` °C; object parameters that
    leave the raw signal as it is (ε = 1, no distance, a window that transmits all). What a FLIR
    camera states of itself, so that ``--method camera`` reads a simulated file as the camera
    would: its unit's level and fixed pattern left (the file's raw is not
    nonuniformity-corrected), not another camera's constants (:data:`DEFAULT_PLANCK`, an
    XT-R's, put such a file 70 °C off). R1, B and F are rounded as the FFF record stores them
    (float32), O to an integer."""
    from thermocal.calibration.lin import fit_planck_curve
    from thermocal.camera.model import expected_counts

    temps = np.linspace(-20.0, 120.0, 57)
    counts = expected_counts(camera, temps, np.full(temps.size, float(fpa_c)))
    level = np.median(counts[:, ~np.asarray(camera.defects)], axis=1).astype(np.float64)
    keep = (level > 0) & (level < 2**camera.bit_depth - 1)
    if keep.sum() < 8:
        raise InvalidInputError(f"the simulated unit saturates at FPA {fpa_c:g} °C: no Planck "
                                "constants describe it")
    r, b, f, o = fit_planck_curve(temps[keep] + ZERO_CELSIUS_K, level[keep])
    return FlirPlanck(float(np.float32(r)), 1.0, float(np.float32(b)), float(np.float32(f)),
                      float(round(-o)), emissivity=1.0, distance_m=0.0, reflected_c=20.0,
                      atmosphere_c=20.0, ir_window_c=20.0, humidity=0.5)


#: Time of the first frame by default, s since 1970 UTC (2023-11-14 22:13:20).
DEFAULT_START_EPOCH_S = 1_700_000_000.0

_RAW_DATA, _CAMERA_INFO, _GPS_INFO = 1, 32, 43
_CAMERA_INFO_BYTES = 0x480  # up to the frame rate at 0x464 (exiftool FLIR::CameraInfo)
_GPS_BYTES = 0x68
_APP1_CHUNK = 0xFFFF - 2 - 8  # APP1 length field counts itself; 8 bytes of FLIR part header
_DUALTAU_FILE_S = 2.0  # the rig saves a file about every 2 s
_DUALTAU_FPA_EVERY_S = 30.0  # and reads the FPA temperature every 30 s
#: The camera model written: a simulated core (Tau2 or Boson class), whose raw counts keep their
#: fixed pattern (a camera's own files hold them after its shutter's correction), so
#: ``--method camera`` takes a radiometric core's stated accuracy for it (±5 °C or 5 %,
#: :func:`thermocal.estimation.vendor.vendor_accuracy`), not a FLIR camera's.
_MODEL = "thermocal simulated Tau2-class core"


#: The measuring range a simulated file states (exiftool's CameraTemperatureRangeMin/Max), °C:
#: the high-gain range of a radiometric Tau2 camera, which the DJI Zenmuse XT-R's files state;
#: ``--method camera`` vouches for its stated accuracy within it alone.
SIMULATED_RANGE_C = (-25.0, 135.0)


def simulated_model(preset: str) -> str:
    """The camera model a simulated camera of family ``preset`` writes in its files
    (``"thermocal simulated Boson-class core"`` for ``boson``)."""
    family = "Tau2" if preset == "tau2" else preset.capitalize()
    return f"thermocal simulated {family}-class core"


# --------------------------------------------------------------------------------------------
# GPS
# --------------------------------------------------------------------------------------------
def gps_line(start: tuple[float, float, float], end: tuple[float, float, float],
             n_frames: int) -> np.ndarray:
    """Positions along a straight line, one per frame.

    Parameters
    ----------
    start, end : tuple of float
        ``(latitude, longitude, altitude)`` of the first and the last frame: signed degrees
        (north, east positive) and m above sea level.
    n_frames : int
        Number of frames (≥ 1).

    Returns
    -------
    numpy.ndarray, float64, shape (n_frames, 3)
        Latitude, longitude (degrees) and altitude (m), linear in the frame index.
    """
    if isinstance(n_frames, bool) or not isinstance(n_frames, int | np.integer) or n_frames < 1:
        raise InvalidInputError(f"n_frames: expected a positive number of frames, got {n_frames!r}")
    a, b = (_checked_position(p, name) for p, name in ((start, "start"), (end, "end")))
    frac = np.linspace(0.0, 1.0, int(n_frames))[:, None] if n_frames > 1 else np.zeros((1, 1))
    return a + (b - a) * frac


def _checked_position(p: Any, name: str) -> np.ndarray:
    arr = np.asarray(p, dtype=np.float64).reshape(-1)
    if arr.size != 3 or not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name}: expected finite (latitude, longitude, altitude), "
                                f"got {p!r}")
    if abs(arr[0]) > 90 or abs(arr[1]) > 180:
        raise InvalidInputError(f"{name}: latitude must be within ±90°, longitude within ±180°")
    return arr


def _checked_gps(gps: Any, n: int) -> np.ndarray | None:
    if gps is None:
        return None
    arr = np.asarray(gps, dtype=np.float64)
    if arr.shape != (n, 3) or not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"gps: expected finite (latitude, longitude, altitude) for each "
                                f"of the {n} frames, shape ({n}, 3), got {arr.shape}")
    for row in (arr.min(axis=0), arr.max(axis=0)):
        _checked_position(row, "gps")
    return arr


def _tracks_deg(gps: np.ndarray) -> np.ndarray:
    """Heading of the path at each position, degrees clockwise from north (the next position's
    direction; the last frame keeps the one before it)."""
    if len(gps) < 2:
        return np.zeros(len(gps))
    lat, lon = np.radians(gps[:, 0]), np.radians(gps[:, 1])
    dlon = np.diff(lon)
    y = np.sin(dlon) * np.cos(lat[1:])
    x = np.cos(lat[:-1]) * np.sin(lat[1:]) - np.sin(lat[:-1]) * np.cos(lat[1:]) * np.cos(dlon)
    track = np.degrees(np.arctan2(y, x)) % 360.0
    return np.append(track, track[-1])


# --------------------------------------------------------------------------------------------
# one FFF record
# --------------------------------------------------------------------------------------------
def fff_record(raw: np.ndarray, *, planck: FlirPlanck = DEFAULT_PLANCK,
               time_epoch_s: float = DEFAULT_START_EPOCH_S, frame_rate_hz: float = 30.0,
               gps: tuple[float, float, float] | None = None, track_deg: float = 0.0,
               order: str = ">", codec: str = "plain", creator: str = "thermocal",
               model: str = _MODEL, field_of_view_deg: float = 45.0,
               utc_offset_min: int = 0,
               range_c: tuple[float, float] | None = None) -> bytes:
    """One FLIR FFF record: header, directory, raw-data, camera-info and (optional) GPS records.

    Parameters
    ----------
    raw : numpy.ndarray, uint16, shape (H, W)
        Raw counts.
    planck : FlirPlanck
        Planck constants and object parameters (float32 in the record; O rounded to an int32).
    time_epoch_s : float
        Time of the frame, s since 1970 UTC (ms resolution in the record; time zone UTC).
    frame_rate_hz : float
        Frame rate written in the camera-info record (rounded to a whole Hz).
    gps : tuple of float, optional
        ``(latitude, longitude, altitude)`` in signed degrees and m: a GPS record (WGS84).
    track_deg : float
        Heading written in the GPS record, degrees from north.
    order : {">", "<"}
        Byte order of the record (FLIR cameras: ">" in SEQ/CSQ/FFF; R-JPEGs: "<").
    codec : {"plain", "jpegls", "png", "tiff"}
        How the raw counts are stored.
    creator, model : str
        Creator software (≤ 16 bytes) and camera model (≤ 32 bytes) strings.
    field_of_view_deg : float
        Horizontal field of view, degrees.
    utc_offset_min : int
        The camera's time zone, minutes east of UTC (the record's local time).
    range_c : (float, float) or None
        The camera's measuring range, °C (None: stated as zeros, none).

    Returns
    -------
    bytes
        The record, starting ``"FFF\\0"``.
    """
    if order not in (">", "<"):
        raise InvalidInputError(f"order: expected '>' or '<', got {order!r}")
    frame = np.asarray(raw)
    if frame.ndim != 2 or frame.dtype.kind not in "ui":
        raise InvalidInputError(f"raw: expected integer counts (H, W), got {frame.dtype} "
                                f"{frame.shape}")
    frame = frame.astype(np.uint16, copy=False)
    h, w = frame.shape
    raw_rec = bytearray(32)
    struct.pack_into(order + "HHH", raw_rec, 0, 2, w, h)  # byte-order check value 2, W, H
    raw_rec += _encode_raw(frame, codec, order)
    records = [(_RAW_DATA, 2 if codec == "tiff" else 1, bytes(raw_rec)),
               (_CAMERA_INFO, 1, _camera_info(planck, time_epoch_s, frame_rate_hz, order,
                                              model, field_of_view_deg, utc_offset_min,
                                              range_c))]
    if gps is not None:
        records.append((_GPS_INFO, 1, _gps_record(gps, track_deg, order)))
    head = bytearray(64)
    head[:4] = b"FFF\x00"
    name = creator.encode("latin-1")[:16]
    head[4 : 4 + len(name)] = name
    struct.pack_into(order + "III", head, 0x14, 100, 64, len(records))  # version, dir offset
    offset = 64 + 32 * len(records)
    directory, body = bytearray(), bytearray()
    for k, (rtype, sub, data) in enumerate(records):
        entry = bytearray(32)
        struct.pack_into(order + "HHIIII", entry, 0, rtype, sub, 100, k + 1,
                         offset + len(body), len(data))
        directory += entry
        body += data
    return bytes(head + directory + body)


def _encode_raw(frame: np.ndarray, codec: str, order: str) -> bytes:
    if codec == "plain":
        return frame.astype(order + "u2").tobytes()
    if codec == "jpegls":
        import imagecodecs

        return bytes(imagecodecs.jpegls_encode(frame))  # lossless by default
    if codec == "png":  # FLIR stores the 16-bit samples byte-swapped
        import cv2

        ok, png = cv2.imencode(".png", frame.byteswap())
        if not ok:  # pragma: no cover - OpenCV encodes any uint16 image
            raise InvalidInputError("raw: OpenCV could not encode the PNG")
        return png.tobytes()
    if codec == "tiff":
        import tifffile

        buf = io.BytesIO()
        tifffile.imwrite(buf, frame, byteorder=order, metadata=None)
        return buf.getvalue()
    raise InvalidInputError(f"codec: expected plain, jpegls, png or tiff, got {codec!r}")


def _camera_info(planck: FlirPlanck, time_epoch_s: float, frame_rate_hz: float, order: str,
                 model: str, fov_deg: float, utc_offset_min: int = 0,
                 range_c: tuple[float, float] | None = None) -> bytes:
    """The camera-info record at exiftool's FLIR::CameraInfo offsets (temperatures in K)."""
    cam = bytearray(_CAMERA_INFO_BYTES)
    struct.pack_into(order + "H", cam, 0, 2)
    p, k0 = planck, ZERO_CELSIUS_K
    for off, val in ((0x20, p.emissivity), (0x24, p.distance_m), (0x28, p.reflected_c + k0),
                     (0x2C, p.atmosphere_c + k0), (0x30, p.ir_window_c + k0),
                     (0x34, p.ir_window_transmission),
                     (0x3C, p.humidity), (0x58, p.r1), (0x5C, p.b), (0x60, p.f),
                     (0x70, p.alpha1), (0x74, p.alpha2), (0x78, p.beta1), (0x7C, p.beta2),
                     (0x80, p.x), (0x1B4, fov_deg), (0x30C, p.r2)):
        struct.pack_into(order + "f", cam, off, val)
    struct.pack_into(order + "i", cam, 0x308, int(round(p.o)))
    if range_c is not None:  # CameraTemperatureRangeMax at 0x90, Min at 0x94
        struct.pack_into(order + "ff", cam, 0x90, range_c[1] + k0, range_c[0] + k0)
    text = model.encode("latin-1")[:31]
    cam[0xD4 : 0xD4 + len(text)] = text
    ms_total = int(round(time_epoch_s * 1000.0))
    # the record's zone is minutes west of UTC
    struct.pack_into(order + "IIh", cam, 0x384, ms_total // 1000, ms_total % 1000,
                     -utc_offset_min)
    struct.pack_into(order + "H", cam, 0x464, int(round(frame_rate_hz)))
    return bytes(cam)


def _gps_record(gps: tuple[float, float, float], track_deg: float, order: str) -> bytes:
    """The GPS record at exiftool's FLIR::GPSInfo offsets (unsigned degrees with N/S, E/W)."""
    lat, lon, alt = (float(v) for v in gps)
    g = bytearray(_GPS_BYTES)
    struct.pack_into(order + "I", g, 0, 1)  # valid
    g[0x08:0x0A] = b"N\x00" if lat >= 0 else b"S\x00"
    g[0x0A:0x0C] = b"E\x00" if lon >= 0 else b"W\x00"
    struct.pack_into(order + "ddf", g, 0x10, abs(lat), abs(lon), alt)
    struct.pack_into(order + "ff", g, 0x4C, 0.0, track_deg)  # speed not simulated
    g[0x58:0x5D] = b"WGS84"
    return bytes(g)


# --------------------------------------------------------------------------------------------
# R-JPEG
# --------------------------------------------------------------------------------------------
def rjpeg_bytes(record: bytes, preview: np.ndarray, *, make: str = "FLIR Systems AB",
                model: str = _MODEL, gps: tuple[float, float, float] | None = None,
                xmp: bytes | None = None) -> bytes:
    """A radiometric JPEG: ``preview`` (uint8 ``(H, W)``) with ``record`` in FLIR APP1 segments.

    Pillow writes the JPEG with its EXIF (make, model and, with ``gps``, the GPS IFD in
    degrees/minutes/seconds) and ``xmp``; the FLIR segments (``"FLIR\\0"``, 1, part index, last
    index, then up to 65525 bytes of the record) follow its APP segments, as in the cameras'
    files.
    """
    from PIL import Image

    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = make, model
    if gps is not None:
        lat, lon, alt = (float(v) for v in gps)
        ifd = exif.get_ifd(0x8825)
        ifd.update({0: b"\x02\x03\x00\x00", 1: "N" if lat >= 0 else "S", 2: _dms(lat),
                    3: "E" if lon >= 0 else "W", 4: _dms(lon), 5: b"\x00" if alt >= 0 else b"\x01",
                    6: abs(alt), 18: "WGS-84"})
    buf = io.BytesIO()
    options: dict[str, Any] = {"exif": exif, "quality": 90}
    if xmp is not None:
        options["xmp"] = xmp
    Image.fromarray(np.ascontiguousarray(preview, dtype=np.uint8)).save(buf, "JPEG", **options)
    jpeg = buf.getvalue()
    parts = [record[k : k + _APP1_CHUNK] for k in range(0, len(record), _APP1_CHUNK)] or [b""]
    if len(parts) > 256:
        raise InvalidInputError(f"record: {len(record)} bytes need {len(parts)} FLIR segments, "
                                "more than an R-JPEG can number (256)")
    segments = b"".join(
        b"\xff\xe1" + struct.pack(">H", 2 + 8 + len(part)) + b"FLIR\x00\x01"
        + bytes([k, len(parts) - 1]) + part for k, part in enumerate(parts))
    pos = _after_app_segments(jpeg)
    return jpeg[:pos] + segments + jpeg[pos:]


def _dms(value: float) -> tuple[float, float, float]:
    """The absolute value of ``value`` degrees as EXIF degrees, minutes, seconds
    (:func:`thermocal.io.geotag.dms`), as the numbers Pillow writes as rationals."""
    d, m, micro = dms(value)
    return float(d), float(m), micro / 1e6


def _after_app_segments(jpeg: bytes) -> int:
    """Offset of the first marker after SOI that is not an APPn segment."""
    pos = 2
    while jpeg[pos] == 0xFF and 0xE0 <= jpeg[pos + 1] <= 0xEF:
        (length,) = struct.unpack_from(">H", jpeg, pos + 2)
        pos += 2 + length
    return pos


def _preview(raw: np.ndarray) -> np.ndarray:
    """A grey rendering of the counts, 1st to 99th percentile stretched to 0..255."""
    lo, hi = np.percentile(raw, (1.0, 99.0))
    scale = 255.0 / max(float(hi - lo), 1.0)
    return np.clip((raw.astype(np.float32) - lo) * scale, 0, 255).astype(np.uint8)


def _dji_xmp(altitude_m: float | None, relative_m: float | None, yaw_deg: float | None,
             spot_c: float | None) -> bytes:
    """The DJI XMP packet: altitudes, nadir gimbal, flight yaw and the spot meter's reading."""
    attrs = ['drone-dji:GimbalPitchDegree="-90.0"', 'drone-dji:GimbalRollDegree="0.0"']
    if altitude_m is not None:
        attrs.append(f'drone-dji:AbsoluteAltitude="{altitude_m:.6f}"')
    if relative_m is not None:
        attrs.append(f'drone-dji:RelativeAltitude="{relative_m:.6f}"')
    if yaw_deg is not None:
        yaw = (yaw_deg + 180.0) % 360.0 - 180.0  # DJI writes -180..180
        attrs += [f'drone-dji:{key}YawDegree="{yaw:.6f}"' for key in ("Flight", "Gimbal")]
    if spot_c is not None:
        attrs.append(f'FLIR:CentralTemperature="{int(round(spot_c))}"')  # whole °C, as the XT-R
    return ('<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>'
            '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
            'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description '
            'rdf:about="DJI Meta Data" xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/" '
            'xmlns:FLIR="http://ns.flir.com/xmp/1.0/" ' + " ".join(attrs)
            + '/></rdf:RDF></x:xmpmeta><?xpacket end="w"?>').encode("utf-8")


# --------------------------------------------------------------------------------------------
# output paths
# --------------------------------------------------------------------------------------------
def check_output_path(path: str | os.PathLike[str], *, format: str,  # noqa: A002
                      parent_made_later: bool = False) -> Path:
    """Check, creating nothing, that ``path`` suits ``format``: a file name with the format's
    suffix (``.tiff``/``.tif``, ``.seq``, ``.csq``) that is not a folder, or, for
    :data:`FOLDER_FORMATS`, a folder name without a recording file's suffix that is not a file
    and, if it exists, is empty. Its parent must exist, unless ``parent_made_later``.

    Raises
    ------
    InvalidInputError
        An unknown format or a path of the wrong kind (one line naming both).
    """
    if format not in WRITE_FORMATS:
        raise InvalidInputError(f"unknown format {format!r}; choose from "
                                f"{', '.join(WRITE_FORMATS)}")
    p = Path(path)
    if format in _FILE_SUFFIXES:
        suffixes = _FILE_SUFFIXES[format]
        if p.suffix.lower() not in suffixes:
            raise InvalidInputError(f"{p}: a {format} recording is a file named *{suffixes[0]}")
        if p.is_dir():
            raise InvalidInputError(f"{p}: is a folder; a {format} recording is a file")
    else:
        if p.suffix.lower() in FILE_LIKE_SUFFIXES:
            raise InvalidInputError(f"{p}: a {format} recording is a folder, not a "
                                    f"{p.suffix} file; give a folder name")
        if p.exists() and not p.is_dir():
            raise InvalidInputError(f"{p}: exists and is a file; a {format} recording is a "
                                    "folder")
        if p.is_dir() and any(p.iterdir()):
            raise InvalidInputError(f"{p}: the folder exists and is not empty; give a new one")
    if not parent_made_later and not p.parent.is_dir():
        raise InvalidInputError(f"{p}: its folder {p.parent} does not exist")
    return p


@contextlib.contextmanager
def _atomic_folder(path: Path) -> Iterator[Path]:
    """A temporary folder beside ``path``, renamed onto it (absent or empty) when the block
    ends without an error and removed otherwise."""
    tmp = staging_folder(path.parent, f".{path.name}.", ".tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


# --------------------------------------------------------------------------------------------
# writers
# --------------------------------------------------------------------------------------------
class _Frames:
    """What the writers need besides the frames: Planck constants, clock, GPS and headings."""

    def __init__(self, *, planck: FlirPlanck, gps: np.ndarray | None, start_epoch_s: float,
                 fps: float, ground_m: float | None, model: str = _MODEL) -> None:
        self.planck, self.gps, self.start, self.fps = planck, gps, start_epoch_s, fps
        self.ground_m, self.model = ground_m, model
        self.tracks = None if gps is None else _tracks_deg(gps)

    def time_s(self, chunk: Recording, start: int) -> np.ndarray:
        if chunk.time_s is not None:
            return np.asarray(chunk.time_s, dtype=np.float64)
        return (start + np.arange(chunk.n_frames)) / self.fps

    def position(self, i: int) -> tuple[tuple[float, float, float] | None, float]:
        if self.gps is None or self.tracks is None:
            return None, 0.0
        lat, lon, alt = (float(v) for v in self.gps[i])
        return (lat, lon, alt), float(self.tracks[i])


def _write_flir(out: Path, fmt: str, chunks: Iterable[Recording], ctx: _Frames,
                order: str | None) -> int:
    """SEQ/CSQ (records appended to one file) or a folder of FFF files / R-JPEGs."""
    codec = {"seq": "plain", "fff": "plain", "csq": "jpegls", "rjpeg": "png",
             "dji-rjpeg": "tiff"}[fmt]
    byte_order = order or ("<" if fmt in ("rjpeg", "dji-rjpeg") else ">")
    n = 0
    with contextlib.ExitStack() as stack:
        if fmt in ("seq", "csq"):
            series = stack.enter_context(open(stack.enter_context(atomic_path(out)), "wb"))
        else:
            folder = stack.enter_context(_atomic_folder(out))
        for chunk in chunks:
            times = ctx.time_s(chunk, n)
            for k in range(chunk.n_frames):
                position, track = ctx.position(n)
                dji = fmt == "dji-rjpeg"
                record = fff_record(
                    chunk.frames[k], planck=ctx.planck, time_epoch_s=ctx.start + times[k],
                    frame_rate_hz=ctx.fps, gps=None if dji else position, track_deg=track,
                    order=byte_order, codec=codec, creator="ATAU_RBFO" if dji else "thermocal",
                    model=ctx.model, range_c=SIMULATED_RANGE_C)
                if fmt in ("seq", "csq"):
                    series.write(record)
                else:
                    spot = _spot_meter_c(chunk.frames[k], ctx.planck) if dji else None
                    data = _frame_file(fmt, record, chunk.frames[k], position, track, spot,
                                       ctx.ground_m, ctx.model)
                    (folder / f"frame_{n:06d}{_FRAME_SUFFIX[fmt]}").write_bytes(data)
                n += 1
    return n


def _spot_meter_c(raw: np.ndarray, planck: FlirPlanck) -> float | None:
    """A Tau2's spot meter: the camera's own temperature (``planck``) of the mean counts of the
    (up to) 4×4 pixels at the frame's centre, °C; None where its constants give the counts no
    temperature (no reading written, as a camera shows none)."""
    h, w = raw.shape
    y0, x0 = max(h // 2 - 2, 0), max(w // 2 - 2, 0)
    centre = raw[y0 : h // 2 + 2, x0 : w // 2 + 2].astype(np.float64)
    try:
        return float(planck.raw_to_temperature_c(float(centre.mean())))
    except InvalidInputError:  # counts below a 0 K blackbody's (a dead frame)
        return None


def _frame_file(fmt: str, record: bytes, raw: np.ndarray,
                position: tuple[float, float, float] | None, track: float,
                spot_c: float | None, ground_m: float | None, model: str = _MODEL) -> bytes:
    """The bytes of one frame's file: the FFF record itself, or an R-JPEG around it."""
    if fmt == "fff":
        return record
    if fmt == "rjpeg":
        return rjpeg_bytes(record, _preview(raw), model=model, gps=position)
    if position is None:
        xmp = _dji_xmp(None, None, None, spot_c)
    else:
        relative = None if ground_m is None else position[2] - ground_m
        xmp = _dji_xmp(position[2], relative, track, spot_c)
    return rjpeg_bytes(record, _preview(raw), make="DJI", model="FLIR", gps=position, xmp=xmp)


def _write_dualtau(out: Path, chunks: Iterable[Recording], ctx: _Frames) -> int:
    """The DualTauUAV rig's folder: one ``np.savez`` per 2 s of flight."""
    if ctx.gps is not None:
        raise InvalidInputError("gps: the DualTauUAV layout has no place for GPS positions")
    start_ns = int(round(ctx.start * 1e9))
    frame_ns = int(round(1e9 / ctx.fps))
    pending: list[tuple[np.ndarray, int, int]] = []  # (frame, time ns since start, centi-°C)
    state = {"n": 0, "files": 0, "reading_s": -math.inf, "held": 0}

    def flush(folder: Path) -> None:
        if not pending:
            return
        t_ns = start_ns + np.array([p[1] for p in pending], dtype=np.int64)
        np.savez(folder / f"dualtau_{state['files']:06d}.npz",
                 frames=np.stack([p[0] for p in pending]).astype(np.uint16),
                 fpa=np.array([p[2] for p in pending], dtype=np.int64).astype(np.uint16),
                 time_ns_start=t_ns, time_ns_end=t_ns + frame_ns)
        state["files"] += 1
        pending.clear()

    with _atomic_folder(out) as folder:
        for chunk in chunks:
            if chunk.fpa_c is None:
                raise InvalidInputError("recording: a DualTauUAV flight needs the FPA "
                                        "temperature of each frame (fpa_c)")
            times = ctx.time_s(chunk, state["n"])
            for k in range(chunk.n_frames):
                t = float(times[k])
                if t >= state["reading_s"] + _DUALTAU_FPA_EVERY_S:  # a new reading, 0.1 °C
                    state["reading_s"] = t
                    state["held"] = 10 * int(round(float(chunk.fpa_c[k]) * 10.0))
                if pending and int(t // _DUALTAU_FILE_S) != int(pending[0][1] / 1e9
                                                                // _DUALTAU_FILE_S):
                    flush(folder)
                pending.append((chunk.frames[k], int(round(t * 1e9)), state["held"]))
                state["n"] += 1
        flush(folder)
    return state["n"]


def write_chunks_as(chunks: Iterable[Recording], path: str | os.PathLike[str], *, format: str,  # noqa: A002
                    planck: FlirPlanck = DEFAULT_PLANCK, gps: Any = None,
                    start_epoch_s: float = DEFAULT_START_EPOCH_S, fps: float = 30.0,
                    n_frames: int | None = None, byte_order: str | None = None,
                    ground_altitude_m: float | None = None, model: str = _MODEL) -> int:
    """Write a recording given in consecutive pieces (bounded memory) as ``format``.

    Parameters
    ----------
    chunks : iterable of Recording
        Consecutive frames with their series; a series (``fpa_c``, ``time_s``) must be in every
        piece or in none. ``time_s`` is the time since the first frame, s (default: the frame
        index / ``fps``).
    path : str or os.PathLike
        The output file (tiff, seq, csq) or folder (:data:`FOLDER_FORMATS`), checked by
        :func:`check_output_path`.
    format : str
        One of :data:`WRITE_FORMATS`.
    planck : FlirPlanck
        Planck constants and object parameters written in every FLIR record.
    gps : array_like, shape (N, 3), optional
        Latitude, longitude (signed degrees) and altitude (m) of each frame (:func:`gps_line`);
        needs ``n_frames``. Refused for tiff and dualtau, which have no place for it.
    start_epoch_s : float
        Time of the first frame, s since 1970 UTC.
    fps : float
        Frame rate, Hz: written in FLIR records, the frame interval of DualTauUAV's
        ``time_ns_end``, and the times when the recording has none.
    n_frames : int, optional
        Number of frames in all (required with ``gps``).
    byte_order : {">", "<"}, optional
        Byte order of the FLIR records (default: ">" for seq, csq and fff, "<" for R-JPEGs).
    ground_altitude_m : float, optional
        Altitude of the take-off point, m above sea level: with ``gps``, DJI R-JPEGs get
        ``RelativeAltitude`` (the height above it, which ``thermocal flight --geotiff`` needs).
    model : str
        The camera model written in FLIR records and plain R-JPEGs' EXIF
        (:func:`simulated_model`; a DJI R-JPEG's EXIF says DJI's "FLIR").

    Returns
    -------
    int
        Frames written.

    Raises
    ------
    InvalidInputError
        A bad format, path or option; a DualTauUAV recording without FPA temperatures.
    """
    out = check_output_path(path, format=format)
    if not (isinstance(fps, int | float) and math.isfinite(fps) and fps > 0):
        raise InvalidInputError(f"fps: must be > 0 and finite, got {fps!r}")
    if not isinstance(planck, FlirPlanck):
        raise InvalidInputError(f"planck: expected a FlirPlanck, got {type(planck).__name__}")
    if gps is not None:
        if format in ("tiff", "dualtau"):
            raise InvalidInputError(f"gps: the {format} layout has no place for GPS positions")
        if n_frames is None:
            raise InvalidInputError("gps: give n_frames, the number of frames in all")
    gps_arr = None if gps is None else _checked_gps(gps, int(n_frames or 0))
    if ground_altitude_m is not None and not math.isfinite(ground_altitude_m):
        raise InvalidInputError(f"ground_altitude_m: must be finite, got {ground_altitude_m}")
    if not isinstance(model, str) or not model:
        raise InvalidInputError(f"model: expected a camera model's name, got {model!r}")
    ctx = _Frames(planck=planck, gps=gps_arr, start_epoch_s=float(start_epoch_s), fps=float(fps),
                  ground_m=ground_altitude_m, model=model)
    counted = _counting(chunks, n_frames)
    if format == "tiff":
        return _write_tiff(out, counted)
    if format == "dualtau":
        return _write_dualtau(out, counted, ctx)
    return _write_flir(out, format, counted, ctx, byte_order)


def _counting(chunks: Iterable[Recording], n_frames: int | None) -> Iterator[Recording]:
    """The pieces, checked to be Recordings and, when ``n_frames`` is given, to add up to it."""
    seen = 0
    for chunk in chunks:
        if not isinstance(chunk, Recording):
            raise InvalidInputError(f"chunks: expected Recording pieces, got "
                                    f"{type(chunk).__name__}")
        seen += chunk.n_frames
        if n_frames is not None and seen > n_frames:
            raise InvalidInputError(f"chunks: more than the {n_frames} frames announced")
        yield chunk
    if n_frames is not None and seen != n_frames:
        raise InvalidInputError(f"chunks: {seen} frames, {n_frames} announced")


def _write_tiff(out: Path, chunks: Iterator[Recording]) -> int:
    n = 0
    writer: RecordingWriter | None = None
    with contextlib.ExitStack() as stack:
        for chunk in chunks:
            if writer is None:
                writer = stack.enter_context(RecordingWriter(out, bit_depth=chunk.bit_depth,
                                                             extra=chunk.extra))
            writer.append(chunk.frames, fpa_c=chunk.fpa_c, time_s=chunk.time_s,
                          housing_c=chunk.housing_c, ambient_c=chunk.ambient_c)
            n += chunk.n_frames
    return n


def write_recording_as(recording: Recording, path: str | os.PathLike[str], *, format: str,  # noqa: A002
                       planck: FlirPlanck = DEFAULT_PLANCK, gps: Any = None,
                       start_epoch_s: float = DEFAULT_START_EPOCH_S, fps: float | None = None,
                       byte_order: str | None = None,
                       ground_altitude_m: float | None = None, model: str = _MODEL) -> Path:
    """Write ``recording`` in a camera's file format (see the module's table).

    ``fps`` defaults to the median frame interval of ``recording.time_s`` (30 Hz without
    times); the other options are those of :func:`write_chunks_as`. ``recording`` is not
    changed. Returns the path written (file or folder).
    """
    if not isinstance(recording, Recording):
        raise InvalidInputError(f"recording: expected a Recording, got "
                                f"{type(recording).__name__}")
    if fps is None:
        fps = _frame_rate(recording.time_s)
    write_chunks_as([recording], path, format=format, planck=planck, gps=gps,
                    start_epoch_s=start_epoch_s, fps=fps, n_frames=recording.n_frames,
                    byte_order=byte_order, ground_altitude_m=ground_altitude_m, model=model)
    return Path(path)


def _frame_rate(time_s: np.ndarray | None) -> float:
    """Frames per s from the median interval of ``time_s`` (30 Hz without usable times)."""
    if time_s is None or len(time_s) < 2:
        return 30.0
    step = float(np.median(np.diff(np.asarray(time_s, dtype=np.float64))))
    return 1.0 / step if step > 0 else 30.0



def convert_recording(src: str | os.PathLike[str], dst: str | os.PathLike[str], *,
                      format: str, fps: float | None = None, chunk: int = 64,  # noqa: A002
                      **options: Any) -> int:
    """Write the project's TIFF recording ``src`` (``NAME.tiff`` + ``NAME.json``) as ``format``
    at ``dst``, ``chunk`` frames at a time (bounded memory; ``src`` is not changed).

    ``fps`` defaults to the median interval of the sidecar's ``time_s`` (30 Hz without it);
    ``options`` are those of :func:`write_chunks_as` (``planck``, ``gps``, ``start_epoch_s``,
    ``byte_order``, ``ground_altitude_m``, ``model``). Returns the number of frames written.
    """
    from thermocal.io.recording import iter_recording, read_recording_header

    header = read_recording_header(src)
    series = {k: v for k, v in header.series.items() if v is not None}
    pieces = (Recording(frames, bit_depth=header.bit_depth,
                        **{k: v[start : start + len(frames)] for k, v in series.items()})
              for start, frames in iter_recording(src, chunk=chunk))
    return write_chunks_as(pieces, dst, format=format, n_frames=header.n_frames,
                           fps=_frame_rate(series.get("time_s")) if fps is None else fps,
                           **options)
