"""Real radiometric scenes: FLIR R-JPEG, radiometric TIFF and FLIR FFF files as °C maps.

:func:`load_scene` looks at a file's first bytes and returns a float32 ``(H, W)`` temperature map
in °C:

* FLIR radiometric JPEG (R-JPEG): decoded by ``flyr`` (raw counts and Planck constants from the
  FLIR APP1 segments);
* TIFF: integer counts scaled to kelvin (``tiff_kelvin_per_count``, 0.04 K for the flirpy / FLIR
  Duo Pro R radiometric TIFF), or float values taken as °C;
* FLIR FFF (the raw file a FLIR core writes, ``"FFF\\0"``): read by :func:`read_fff` and converted
  with :class:`thermocal.radiometry.FlirPlanck`.

:func:`find_shared_data` locates the project's ``shared/data`` folder of real files (see its
``SOURCES.md``) so that tests and benchmarks can use them without packaging them.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import os
import struct
from collections.abc import Iterator
from dataclasses import replace
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.radiometry import FlirPlanck

__all__ = [
    "bundled_shared_data",
    "find_shared_data",
    "list_shared_scenes",
    "load_scene",
    "read_fff",
]

_JPEG_MAGIC = b"\xff\xd8\xff"
_TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
_FFF_MAGICS = (b"FFF\x00", b"AFF\x00")
_FLIR_APP1 = b"FLIR\x00"

# FFF record types (exiftool, FLIR.pm: "FLIR record directory").
_FFF_RAW_DATA = 1
_FFF_CAMERA_INFO = 32


# --------------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------------
def load_scene(
    path: str | os.PathLike[str],
    *,
    emissivity: float | None = None,
    tiff_kelvin_per_count: float = 0.04,
) -> np.ndarray:
    """Load a real radiometric scene as a temperature map in °C.

    The format is chosen from the file's content, not its name: FLIR R-JPEG, TIFF or FLIR FFF.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    emissivity : float, optional
        Object emissivity (0 < ε ≤ 1) used instead of the one stored in an R-JPEG or FFF file.
        ``None`` (default) keeps the file's value. Not applicable to TIFF files, which hold
        temperatures already.
    tiff_kelvin_per_count : float, optional
        Scale of integer TIFF values, in K per count (default 0.04 K, the FLIR Duo Pro R /
        flirpy radiometric TIFF). Float TIFFs are taken as °C and not scaled.

    Returns
    -------
    numpy.ndarray
        Temperature in °C, float32, shape ``(H, W)``, all finite.

    Raises
    ------
    FileFormatError
        Missing, empty, truncated or unknown file; a JPEG without FLIR radiometric data; a TIFF
        that is not a single 2-D map; a map with non-finite values or values at or below 0 K.
    InvalidInputError
        An invalid ``emissivity`` or ``tiff_kelvin_per_count``, or ``emissivity`` for a TIFF.
    """
    if emissivity is not None:
        emissivity = float(emissivity)
        if not (0.0 < emissivity <= 1.0):
            raise InvalidInputError(f"emissivity: must be in (0, 1], got {emissivity}")
    scale = float(tiff_kelvin_per_count)
    if not (math.isfinite(scale) and scale > 0.0):
        raise InvalidInputError(f"tiff_kelvin_per_count: must be > 0 K, got {scale}")

    p = Path(path)
    data = _read_bytes(p)
    head = data[:4]
    if head[:3] == _JPEG_MAGIC:
        celsius = _load_rjpeg(data, p, emissivity)
    elif head in _TIFF_MAGICS:
        if emissivity is not None:
            raise InvalidInputError(
                f"{p}: emissivity applies only to files with raw counts (R-JPEG, FFF); "
                "a TIFF holds temperatures already"
            )
        celsius = _load_tiff(data, p, scale)
    elif head in _FFF_MAGICS:
        raw, planck = _parse_fff(data, p)
        if emissivity is not None:
            planck = replace(planck, emissivity=emissivity)
        try:
            celsius = planck.raw_to_temperature_c(raw)
        except InvalidInputError as exc:
            raise FileFormatError(f"{p}: {exc}") from None
    else:
        raise FileFormatError(
            f"{p}: unknown file format (expected a FLIR radiometric JPEG, a TIFF or a FLIR FFF "
            "file)"
        )
    return _finish(celsius, p)


def read_fff(path: str | os.PathLike[str]) -> tuple[np.ndarray, FlirPlanck]:
    """Read the raw counts and the calibration of a FLIR FFF file.

    Parameters
    ----------
    path : str or os.PathLike
        An FFF file (starts with ``"FFF\\0"``), e.g. one frame of a FLIR Duo Pro R / Tau2 core.

    Returns
    -------
    raw : numpy.ndarray
        Raw counts, uint16, shape ``(H, W)``.
    planck : FlirPlanck
        Planck constants and object/atmosphere parameters from the camera-info record (humidity
        as a fraction, temperatures in °C).

    Raises
    ------
    FileFormatError
        Missing, truncated or non-FFF file, or one without raw-data or camera-info records.
    """
    p = Path(path)
    return _parse_fff(_read_bytes(p), p)


def find_shared_data() -> Path | None:
    """Locate the project's ``shared/data`` folder of real measurement files.

    Looks, in order, at the environment variable ``THERMOCAL_DATA``; then, walking up from this
    source file and then from the current working directory, at ``<dir>/shared/data`` for every
    ancestor ``<dir>`` (this finds ``<repo root>/../shared/data`` as well as
    ``<repo root>/shared/data``); then at the copy bundled with the package
    (``thermocal/data/shared``: the same files, all under licenses that allow it, listed in its
    ``SOURCES.md``), so that training, tests and benchmarks find the real scenes anywhere. A
    folder counts only if it holds ``SOURCES.md``, ``scenes/`` or ``flirpy/``.

    Returns
    -------
    pathlib.Path or None
        The folder (absolute), or ``None`` if none was found.
    """
    env = os.environ.get("THERMOCAL_DATA")
    if env:
        candidate = Path(env).expanduser()
        if candidate.is_dir():
            return candidate.resolve()
    for start in (Path(__file__).resolve().parent, Path.cwd().resolve()):
        for directory in (start, *start.parents):
            candidate = directory / "shared" / "data"
            if _looks_like_shared_data(candidate):
                return candidate
    bundled = bundled_shared_data()
    return bundled if _looks_like_shared_data(bundled) else None


def bundled_shared_data() -> Path:
    """The copy of ``shared/data`` shipped inside the package (``thermocal/data/shared``)."""
    return Path(str(files("thermocal") / "data" / "shared")).resolve()


def list_shared_scenes(data_dir: str | os.PathLike[str] | None = None) -> dict[str, Path]:
    """Real scene files in ``shared/data``, by short name.

    Parameters
    ----------
    data_dir : str or os.PathLike, optional
        The ``shared/data`` folder; default :func:`find_shared_data`.

    Returns
    -------
    dict of str to Path
        File stem → path for ``scenes/*.jpg`` and the flirpy TIFF and FFF files, sorted by name;
        empty when no data folder is found.
    """
    root = Path(data_dir) if data_dir is not None else find_shared_data()
    if root is None or not root.is_dir():
        return {}
    files = sorted((root / "scenes").glob("*.jpg"))
    for pattern in ("*.tif", "*.tiff", "*.fff"):
        files += sorted((root / "flirpy").glob(pattern))
    return {f.stem: f for f in files}


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _looks_like_shared_data(candidate: Path) -> bool:
    return candidate.is_dir() and any(
        (candidate / name).exists() for name in ("SOURCES.md", "scenes", "flirpy")
    )


def _read_bytes(p: Path) -> bytes:
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise FileFormatError(f"{p}: file not found") from None
    except IsADirectoryError:
        raise FileFormatError(f"{p}: is a directory, not a file") from None
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not data:
        raise FileFormatError(f"{p}: file is empty")
    return data


def _finish(celsius: Any, p: Path) -> np.ndarray:
    arr = np.asarray(celsius)
    if arr.ndim != 2 or arr.size == 0:
        raise FileFormatError(f"{p}: expected a single 2-D temperature map, got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        n_bad = int(arr.size - np.count_nonzero(finite))
        raise FileFormatError(f"{p}: {n_bad} pixel(s) decode to NaN or infinite temperatures")
    # checked before the cast to float32, which would round absolute zero up
    if float(arr.min()) <= -ZERO_CELSIUS_K:
        raise FileFormatError(
            f"{p}: temperatures at or below absolute zero ({float(arr.min()):.2f} °C); "
            "check the file's scale (tiff_kelvin_per_count)"
        )
    return arr.astype(np.float32)


def _scan_jpeg(data: bytes) -> tuple[bool, str]:
    """Walk the JPEG marker segments: (has a FLIR APP1 segment, ``"ok"|"truncated"|"corrupt"``).

    Written by hand because flyr reads only the APP1 segments and accepts a file cut short in
    its image data; a marker walk is a few lines and needs no decoder.
    """
    n = len(data)
    pos = 2
    has_flir = False
    while pos + 4 <= n:
        if data[pos] != 0xFF:
            return has_flir, "corrupt"
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD7:  # standalone markers
            pos += 2
            continue
        if marker == 0xD9:  # end of image before any scan
            return has_flir, "corrupt"
        (length,) = struct.unpack_from(">H", data, pos + 2)
        if marker == 0xE1 and data[pos + 4 : pos + 9] == _FLIR_APP1:
            has_flir = True
        if pos + 2 + length > n:
            return has_flir, "truncated"
        if marker == 0xDA:  # start of scan: entropy-coded data, then EOI
            # In entropy-coded data 0xFF is followed by 0x00 or a restart marker, so FF D9 after
            # the scan header can only be the end-of-image marker.
            found = data.find(b"\xff\xd9", pos + 2 + length) != -1
            return has_flir, "ok" if found else "truncated"
        pos += 2 + length
    return has_flir, "truncated"


def _load_rjpeg(data: bytes, p: Path, emissivity: float | None) -> np.ndarray:
    import flyr  # imported here: only needed for R-JPEG files

    has_flir, state = _scan_jpeg(data)
    if state == "corrupt":
        raise FileFormatError(f"{p}: corrupt JPEG (bad marker segment structure)")
    if state == "truncated" and not has_flir:
        raise FileFormatError(f"{p}: truncated JPEG (file ends inside its header segments)")
    if not has_flir:
        raise FileFormatError(
            f"{p}: JPEG without FLIR radiometric data (no FLIR APP1 segment); "
            "only FLIR radiometric JPEGs (R-JPEG) can be loaded"
        )
    if state == "truncated":
        raise FileFormatError(f"{p}: truncated JPEG (file ends before its end-of-image marker)")
    try:
        thermogram = flyr.unpack(io.BytesIO(data))
        if emissivity is not None:
            thermogram = thermogram.adjust_metadata(emissivity=emissivity)
        with np.errstate(all="ignore"):
            celsius = np.asarray(thermogram.celsius, dtype=np.float64)
    except Exception as exc:  # flyr raises ValueError, KeyError, struct.error, PIL errors, ...
        raise FileFormatError(
            f"{p}: corrupt FLIR radiometric data ({type(exc).__name__}: {exc})"
        ) from None
    return celsius


class _DropRecords(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return False


@contextlib.contextmanager
def _quiet_tifffile() -> Iterator[None]:
    """Silence tifffile's log messages about a corrupt file while it is read.

    A corrupt TIFF becomes one FileFormatError; tifffile would also log each bad tag to stderr.
    The filter is added to tifffile's own logger only for the duration of the read.
    """
    logger = logging.getLogger("tifffile")
    flt = _DropRecords()
    logger.addFilter(flt)
    try:
        yield
    finally:
        logger.removeFilter(flt)


def _load_tiff(data: bytes, p: Path, kelvin_per_count: float) -> np.ndarray:
    import tifffile

    try:
        with _quiet_tifffile(), tifffile.TiffFile(io.BytesIO(data)) as tif:
            arr = tif.asarray()
    except Exception as exc:  # tifffile/imagecodecs raise many types for corrupt files
        raise FileFormatError(
            f"{p}: corrupt or truncated TIFF ({type(exc).__name__}: {exc})"
        ) from None
    if arr.ndim == 3 and arr.shape[0] == 1:
        arr = arr[0]
    if arr.ndim != 2:
        raise FileFormatError(
            f"{p}: expected a single-page, single-channel TIFF (H, W), got shape {arr.shape}"
        )
    if arr.dtype.kind == "f":
        return arr.astype(np.float64)
    if arr.dtype.kind in "iu" and arr.dtype.itemsize >= 2:
        return arr.astype(np.float64) * kelvin_per_count - ZERO_CELSIUS_K
    raise FileFormatError(
        f"{p}: TIFF of dtype {arr.dtype} is not a radiometric map (expected 16/32-bit counts "
        "or float °C)"
    )


def _parse_fff(data: bytes, p: Path) -> tuple[np.ndarray, FlirPlanck]:
    """Parse a FLIR FFF file: raw counts (record 1) and camera info (record 32).

    Written by hand because ``flyr.unpack`` only accepts JPEGs (it looks for FLIR APP1 segments
    and fails on a bare FFF file with "no metadata encountered"), and its record-directory reader
    ignores the directory offset from the header. The layout follows exiftool's FLIR.pm:
    a 64-byte header (``"FFF\\0"``, creator, int32 version at 0x14, directory offset at 0x18,
    entry count at 0x1c; big-endian unless the version only makes sense little-endian), then
    32-byte directory entries (int16 type, int16 subtype, int32 version, int32 index, int32
    offset, int32 length, ...).
    """
    if data[:4] not in _FFF_MAGICS:
        raise FileFormatError(f"{p}: not a FLIR FFF file (no 'FFF' signature)")
    if len(data) < 64:
        raise FileFormatError(f"{p}: truncated FFF file (header is {len(data)} of 64 bytes)")
    order = ">"
    version, dir_offset, n_entries = struct.unpack_from(">III", data, 0x14)
    if not 100 <= version < 200:
        order = "<"
        version, dir_offset, n_entries = struct.unpack_from("<III", data, 0x14)
        if not 100 <= version < 200:
            raise FileFormatError(f"{p}: unsupported FFF version in header")
    if dir_offset + 32 * n_entries > len(data):
        raise FileFormatError(f"{p}: truncated FFF file (record directory cut short)")
    records: dict[int, tuple[int, int, int]] = {}
    for k in range(n_entries):
        rtype, subtype, _ver, _idx, offset, length = struct.unpack_from(
            order + "HHIIII", data, dir_offset + 32 * k
        )
        if rtype and rtype not in records:
            records[rtype] = (subtype, offset, length)
    for rtype, what in ((_FFF_RAW_DATA, "raw data"), (_FFF_CAMERA_INFO, "camera info")):
        if rtype not in records:
            raise FileFormatError(f"{p}: FFF file has no {what} record")
        _, offset, length = records[rtype]
        if offset + length > len(data):
            raise FileFormatError(
                f"{p}: truncated FFF file ({what} record ends at byte {offset + length}, "
                f"file has {len(data)})"
            )
    if records[_FFF_CAMERA_INFO][2] < 0x310:
        raise FileFormatError(f"{p}: FFF camera info record is too short for Planck constants")
    raw = _fff_raw(data, records[_FFF_RAW_DATA], p)
    planck = _fff_camera_info(data, records[_FFF_CAMERA_INFO][1], p)
    return raw, planck


def _record_order(data: bytes, offset: int) -> str:
    """Byte order of a record: its first int16 is small (e.g. 2) in the record's own order."""
    (check,) = struct.unpack_from("<H", data, offset)
    return "<" if check < 0x100 else ">"


def _fff_raw(data: bytes, record: tuple[int, int, int], p: Path) -> np.ndarray:
    subtype, offset, length = record
    if length < 32:
        raise FileFormatError(f"{p}: FFF raw data record is too short")
    order = _record_order(data, offset)
    width, height = struct.unpack_from(order + "HH", data, offset + 2)
    payload = data[offset + 32 : offset + length]
    if payload[:4] == b"\x89PNG":  # subtype 3: PNG with byte-swapped 16-bit samples
        import cv2

        img = cv2.imdecode(np.frombuffer(payload, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None or img.dtype != np.uint16:
            raise FileFormatError(f"{p}: corrupt PNG in FFF raw data record")
        raw = img.byteswap()
    else:
        n = width * height
        if width == 0 or height == 0 or len(payload) < 2 * n:
            raise FileFormatError(
                f"{p}: FFF raw data record holds {len(payload)} bytes, need {2 * n} for "
                f"{width}x{height} (subtype {subtype})"
            )
        raw = np.frombuffer(payload, dtype=np.dtype(order + "u2"), count=n).reshape(height, width)
    if raw.shape != (height, width):
        raise FileFormatError(f"{p}: FFF raw image is {raw.shape}, header says {height}x{width}")
    return raw.astype(np.uint16)  # native byte order, a copy the caller owns


def _fff_camera_info(data: bytes, offset: int, p: Path) -> FlirPlanck:
    """Camera-info record fields (exiftool FLIR::CameraInfo byte offsets; temperatures in K)."""
    o = _record_order(data, offset)

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
    except InvalidInputError as exc:
        raise FileFormatError(f"{p}: invalid camera-info record in FFF file ({exc})") from None
