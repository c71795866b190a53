"""FLIR radiometric JPEGs (R-JPEG), including the Tau2-core DJI layout (Zenmuse XT2 / XT-R).

An R-JPEG is a visible JPEG whose APP1 segments starting ``"FLIR\\0"`` carry, split in parts
(byte 6 the part's index, byte 7 the last index), one FFF record: raw counts and the camera's
Planck constants (:mod:`thermocal.io.fff` decodes it). The camera adds EXIF (make, model, time,
GPS) and, on DJI drones, XMP (``drone-dji:`` altitudes and gimbal/flight attitude;
``FLIR:CentralTemperature``, the Tau2's spot meter: the centre pixels' scene temperature in
whole °C, not the core's; on the real XT-R sample it reads 26 where the camera's own formula
gives 25.9 °C over the 4×4 centre pixels and 27.7 °C over the frame, so no FPA temperature is
taken from an R-JPEG).

The FLIR segments are joined by hand because ``flyr`` 5.1 raises ``KeyError`` on the DJI
layout (a 2-entry record directory with a raw-data record of subtype 2); EXIF is read with
Pillow and the XMP packet, a few attributes of one ``rdf:Description``, with a regular
expression (no XMP library is a dependency).
"""

from __future__ import annotations

import io
import math
import re
import struct
import warnings
from pathlib import Path
from typing import Any

from thermocal.errors import FileFormatError
from thermocal.io.fff import FffFrame, fff_frame_shape, fff_raw_image, fff_record_metadata
from thermocal.radiometry import FlirPlanck

__all__ = ["JPEG_MAGIC", "flir_segments", "read_rjpeg", "rjpeg_frame_shape", "rjpeg_metadata"]

#: First bytes of a JPEG.
JPEG_MAGIC = b"\xff\xd8\xff"
_FLIR = b"FLIR\x00"
_XMP_ATTRS = {
    "AbsoluteAltitude": "absolute_altitude_m",
    "RelativeAltitude": "relative_altitude_m",
    "GimbalRollDegree": "gimbal_roll_deg",
    "GimbalYawDegree": "gimbal_yaw_deg",
    "GimbalPitchDegree": "gimbal_pitch_deg",
    "FlightRollDegree": "flight_roll_deg",
    "FlightYawDegree": "flight_yaw_deg",
    "FlightPitchDegree": "flight_pitch_deg",
    "CentralTemperature": "spot_c",
}


def flir_segments(data: bytes, name: str, *, complete: bool = True) -> bytes:
    """The FFF record of an R-JPEG: its FLIR APP1 segments joined in part order.

    With ``complete=False`` the parts found in ``data`` (a prefix of the file) are joined
    without checking that none is missing (enough to read the record's header).

    Raises
    ------
    FileFormatError
        Not a JPEG, a corrupt marker structure, no FLIR segment, or missing parts.
    """
    if data[:3] != JPEG_MAGIC:
        raise FileFormatError(f"{name}: not a JPEG")
    parts: dict[int, bytes] = {}
    last = -1
    pos, n = 2, len(data)
    while pos + 4 <= n:
        if data[pos] != 0xFF:
            raise FileFormatError(f"{name}: corrupt JPEG (bad marker segment structure)")
        marker = data[pos + 1]
        if marker == 0xFF:
            pos += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD7:
            pos += 2
            continue
        if marker in (0xDA, 0xD9):  # the scan: no more APP segments
            break
        (length,) = struct.unpack_from(">H", data, pos + 2)
        if marker == 0xE1 and data[pos + 4 : pos + 9] == _FLIR:
            seg = data[pos + 4 : pos + 2 + length]
            if len(seg) >= 8:
                parts[seg[6]] = seg[8:]
                last = max(last, seg[7])
        pos += 2 + length
    if not parts:
        raise FileFormatError(
            f"{name}: JPEG without FLIR radiometric data (no FLIR APP1 segment); only FLIR "
            "radiometric JPEGs (R-JPEG) hold raw counts"
        )
    if complete:
        missing = [k for k in range(last + 1) if k not in parts]
        if missing:
            raise FileFormatError(f"{name}: truncated R-JPEG (FLIR segment(s) {missing} missing)")
    return b"".join(parts[k] for k in sorted(parts))


def rjpeg_frame_shape(head: bytes, name: str) -> tuple[int, int]:
    """``(H, W)`` of an R-JPEG's raw image from the first bytes of the file (64 KiB suffice for
    a camera that puts the record directory first)."""
    return fff_frame_shape(flir_segments(head, name, complete=False), name)


def read_rjpeg(path: str | Path) -> FffFrame:
    """Read an R-JPEG: raw counts, Planck constants and metadata.

    The metadata are those of :class:`~thermocal.io.fff.FffFrame` plus, where the file has
    them, ``make``, ``model`` and ``focal_length_mm`` (EXIF), ``gps`` from EXIF when the FLIR
    record has none
    (``latitude``, ``longitude`` in signed degrees, ``altitude_m``, ``map_datum``), the DJI
    XMP values ``absolute_altitude_m``, ``relative_altitude_m``, ``attitude`` (a dict of
    ``gimbal_roll_deg``, ``gimbal_yaw_deg``, ``gimbal_pitch_deg``, ``flight_roll_deg``,
    ``flight_yaw_deg``, ``flight_pitch_deg``) and ``spot_c`` (``FLIR:CentralTemperature``, °C:
    the camera's spot meter at the frame's centre, a scene temperature, not the FPA's).

    Raises
    ------
    FileFormatError
        Missing, empty, corrupt or truncated file; a JPEG without FLIR segments; a bad FFF record.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read ({exc.strerror or exc})") from None
    record, _, planck, meta = rjpeg_metadata(data, str(p))
    return FffFrame(fff_raw_image(record, str(p)), planck, meta)


def rjpeg_metadata(data: bytes, name: str, *, exif: bool = True) -> tuple[
        bytes, tuple[int, int], FlirPlanck, dict[str, Any]]:
    """Every check of :func:`read_rjpeg` on the bytes of an R-JPEG but decoding its raw image:
    ``(FFF record, (H, W), planck, metadata)`` (:func:`~thermocal.io.fff.fff_record_metadata`);
    ``exif=False`` leaves out what only EXIF holds (make, model, GPS), the slowest part."""
    if data[:3] != JPEG_MAGIC:
        raise FileFormatError(f"{name}: not a JPEG")
    _, state = scan_jpeg(data)
    if state == "corrupt":
        raise FileFormatError(f"{name}: corrupt JPEG (bad marker segment structure)")
    record = flir_segments(data, name)
    if state == "truncated":
        raise FileFormatError(
            f"{name}: truncated JPEG (the file ends before its end-of-image marker)")
    shape, planck, meta = fff_record_metadata(record, name)
    meta.update(_exif(data, name) if exif else {})
    exif_gps = meta.pop("exif_gps", None)
    if meta.get("gps") is None and exif_gps is not None:
        meta["gps"] = exif_gps
    meta.update(_xmp(data))
    return record, shape, planck, meta


def _rational(v: Any) -> float:
    return float(v)


def _dms(values: Any, ref: str) -> float:
    d, m, s = (_rational(v) for v in values)
    deg = d + m / 60.0 + s / 3600.0
    return -deg if ref in ("S", "W") else deg


def _exif(data: bytes, name: str = "the R-JPEG") -> dict[str, Any]:
    """Make, model, the lens's focal length (``focal_length_mm``) and GPS from the EXIF
    segment (Pillow); {} when there is none. Pillow's
    complaints about a damaged segment (one warning per tag) become one warning naming
    ``name``."""
    from PIL import Image

    from thermocal.threads import caught_warnings

    out: dict[str, Any] = {}
    try:
        with caught_warnings() as said, Image.open(io.BytesIO(data)) as im:
            exif = im.getexif()
            gps = exif.get_ifd(0x8825)
            sub = exif.get_ifd(0x8769)  # the Exif IFD: FocalLength
    except Exception:  # a JPEG whose EXIF Pillow cannot read: the FLIR record still counts
        return out
    if said:
        warnings.warn(f"{name}: damaged EXIF ({len(said)} problem(s), first: "
                      f"{' '.join(str(said[0].message).split())}): its make, model or GPS may "
                      "be missing", stacklevel=3)
    for tag, key in ((0x010F, "make"), (0x0110, "model")):
        if tag in exif:
            out[key] = str(exif[tag]).strip("\x00 ")
    try:
        focal = _rational(sub[0x920A]) if 0x920A in sub else None
    except (TypeError, ValueError, ZeroDivisionError):
        focal = None
    if focal is not None and math.isfinite(focal) and focal > 0:
        out["focal_length_mm"] = focal
    try:
        if 2 in gps and 4 in gps:
            g: dict[str, Any] = {
                "latitude": _dms(gps[2], str(gps.get(1, "N"))),
                "longitude": _dms(gps[4], str(gps.get(3, "E"))),
                "altitude_m": None,
                "map_datum": str(gps.get(18, "")).strip("\x00 "),
            }
            if 6 in gps:
                below = gps.get(5, b"\x00") in (b"\x01", 1)
                g["altitude_m"] = -_rational(gps[6]) if below else _rational(gps[6])
            out["exif_gps"] = g
    except (TypeError, ValueError, ZeroDivisionError):
        pass
    return out


_XMP_ATTR = re.compile(rb'(?:drone-dji|FLIR):(\w+)="([^"]*)"')


def _xmp(data: bytes) -> dict[str, Any]:
    """DJI altitudes, attitude and the spot meter's reading from the XMP packet."""
    start = data.find(b"<x:xmpmeta")
    end = data.find(b"</x:xmpmeta>", start)
    if start == -1 or end == -1:
        return {}
    values: dict[str, float] = {}
    for key, text in _XMP_ATTR.findall(data[start:end]):
        name = _XMP_ATTRS.get(key.decode("ascii", "replace"))
        if name is None:
            continue
        try:
            values[name] = float(text)
        except ValueError:
            continue
    out: dict[str, Any] = {}
    attitude = {k: v for k, v in values.items() if k.startswith(("gimbal_", "flight_"))}
    if attitude:
        out["attitude"] = attitude
    for key in ("absolute_altitude_m", "relative_altitude_m", "spot_c"):
        if key in values:
            out[key] = values[key]
    return out


#: The identifier that opens a FLIR APP1 segment.
_FLIR_APP1 = b"FLIR\x00"


def scan_jpeg(data: bytes) -> tuple[bool, str]:
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
