"""Georeferencing of output maps: the source frame's GPS, time, camera and attitude in each map.

A temperature or σ map of a frame that had a GPS position gets, in its float32 TIFF:

* **EXIF** as a camera writes it: ``Make``/``Model`` in the first IFD, an EXIF IFD
  (``DateTimeOriginal``, ``SubSecTimeOriginal``, ``OffsetTimeOriginal``) and a GPS IFD
  (``GPSLatitude``/``Ref``, ``GPSLongitude``/``Ref``, ``GPSAltitude``/``Ref``, ``GPSMapDatum``,
  ``GPSTimeStamp``/``GPSDateStamp`` in UTC where the frame's time is known): what OpenDroneMap
  (``exifread``), Metashape and Pix4D read to place a photo;
* **XMP** (TIFF tag 700) in DJI's ``drone-dji:`` namespace with DJI's names
  (``AbsoluteAltitude``, ``RelativeAltitude`` in m, ``GimbalRollDegree``, ``GimbalYawDegree``,
  ``GimbalPitchDegree``, ``FlightRollDegree``, ``FlightYawDegree``, ``FlightPitchDegree`` in
  degrees), ``tiff:Make``/``tiff:Model``, and ``Camera:BandName="LWIR"`` (Pix4D's camera
  namespace, which OpenDroneMap reads to tell a thermal band);
* with ``--geotiff``, where a footprint can be computed (:func:`footprint`), **GeoTIFF** tags in
  the same file: ``ModelTransformationTag`` (an affine map from pixel corners to longitude and
  latitude, rotated by the camera's yaw) and a ``GeoKeyDirectoryTag`` for EPSG:4326 (WGS 84,
  pixel is area). A GIS then shows the map in place; photogrammetry tools ignore these tags.

A frame without a GPS position keeps its time and camera (EXIF, without a GPS IFD) and its
attitude and altitudes (XMP); one with none of them gives the plain writer's bytes.

The EXIF and GPS IFDs are the only bytes written by hand here: tifffile writes every tag of the
image's IFD (the ``ExifTag``/``GPSTag`` pointers included, named so that tifffile does not filter
them), but it cannot write an IFD that a tag points to ("Extratags cannot be used to write IFD
type tags", :meth:`tifffile.TiffWriter.write`). So the two small IFDs (a few dozen entries, the
classic little-endian TIFF layout of TIFF 6.0 section 2) are appended to the file tifffile wrote,
and the file is written twice by tifffile: first to learn where the IFDs go, then with the
pointers set (same length, so the offsets hold).
"""

from __future__ import annotations

import datetime as _dt
import io
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError

__all__ = [
    "DEFAULT_HFOV_DEG",
    "Footprint",
    "MapTags",
    "LENS_HFOV_DEG",
    "NADIR_TOLERANCE_DEG",
    "PIXEL_PITCH_UM",
    "default_hfov_deg",
    "dms",
    "footprint",
    "has_gps",
    "map_tags",
]

#: How far the gimbal pitch may be from straight down (−90°) for a footprint, degrees.
NADIR_TOLERANCE_DEG = 10.0

#: Horizontal field of view by (make, model, frame width in pixels), lower case, degrees, for
#: cameras whose files say neither it nor their lens. DJI Zenmuse XT / XT-R (a FLIR Tau2 core;
#: EXIF ``Make=DJI``, ``Model=FLIR``) and XT2: DJI's specifications (dji.com/zenmuse-xt/info,
#: dji.com/zenmuse-xt2/info) give, for the 13 mm lens assumed here, 45° x 37° at 640 x 512 and
#: 25° x 19° at 336 x 256 (their files state the lens, EXIF ``FocalLength``:
#: :data:`LENS_HFOV_DEG`).
DEFAULT_HFOV_DEG: dict[tuple[str, str, int], float] = {
    ("dji", "flir", 640): 45.0,
    ("dji", "flir", 336): 25.0,
    ("dji", "xt2", 640): 45.0,
    ("dji", "xt2", 336): 25.0,
}

#: Horizontal field of view by (frame width in pixels, the lens's focal length in mm) of the
#: Zenmuse XT, XT-R and XT2 (DJI's specifications, as above): 9, 13 and 19 mm lenses. The
#: nominal focal length does not give them by a pinhole formula (9 mm at 640 px: 62° from
#: 17 µm pixels, 69° specified); other lenses fall back to it (:data:`PIXEL_PITCH_UM`).
LENS_HFOV_DEG: dict[tuple[int, float], float] = {
    (640, 9.0): 69.0, (640, 13.0): 45.0, (640, 19.0): 32.0,
    (336, 9.0): 35.0, (336, 13.0): 25.0, (336, 19.0): 17.0,
}

#: Pixel pitch by (make, model), lower case, µm, of the cameras :data:`LENS_HFOV_DEG` is for:
#: for a lens it does not list, 2·atan(W·pitch / 2f) with the file's EXIF ``FocalLength`` f.
#: The Zenmuse XT, XT-R and XT2 carry FLIR Tau2 cores of 17 µm pixels (FLIR's Tau2 data sheet;
#: for 13 and 19 mm at 640 px the formula gives 45.4° and 32.0°).
PIXEL_PITCH_UM: dict[tuple[str, str], float] = {
    ("dji", "flir"): 17.0,
    ("dji", "xt2"): 17.0,
}

# WGS 84 ellipsoid (EPSG:7030): semi-major axis, m, and first eccentricity squared
_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3

# TIFF field types (TIFF 6.0, section 2)
_BYTE, _ASCII, _SHORT, _LONG, _RATIONAL, _UNDEFINED, _DOUBLE = 1, 2, 3, 4, 5, 7, 12
_TYPE_FORMAT = {_BYTE: "B", _ASCII: "B", _SHORT: "H", _LONG: "I", _RATIONAL: "II",
                _UNDEFINED: "B"}

#: XMP attributes: metadata key → ``drone-dji:`` name.
_DJI_XMP = {
    "absolute_altitude_m": "AbsoluteAltitude",
    "relative_altitude_m": "RelativeAltitude",
    "gimbal_roll_deg": "GimbalRollDegree",
    "gimbal_yaw_deg": "GimbalYawDegree",
    "gimbal_pitch_deg": "GimbalPitchDegree",
    "flight_roll_deg": "FlightRollDegree",
    "flight_yaw_deg": "FlightYawDegree",
    "flight_pitch_deg": "FlightPitchDegree",
}

#: Altitudes at or beyond this (m) are a corrupt record's, not written (nor do they fit the
#: rational's 32-bit numerator in millimetres).
_MAX_ALTITUDE_M = 1e6

#: A tag of an IFD written by hand: (code, TIFF type, values) — bytes for BYTE/ASCII/UNDEFINED,
#: a sequence of ints (SHORT, LONG) or of (numerator, denominator) pairs (RATIONAL).
_Entry = tuple[int, int, Any]


def _number(value: Any) -> float | None:
    """``value`` as a finite float; None when it is not a finite number."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    v = float(value)
    return v if math.isfinite(v) else None


def _gps(metadata: Mapping[str, Any] | None) -> tuple[float, float] | None:
    gps = (metadata or {}).get("gps")
    if not isinstance(gps, Mapping):
        return None
    lat, lon = _number(gps.get("latitude")), _number(gps.get("longitude"))
    if lat is None or lon is None or abs(lat) > 90 or abs(lon) > 180:
        return None
    return lat, lon


def has_gps(metadata: Mapping[str, Any] | None) -> bool:
    """Whether a frame's metadata (:func:`thermocal.io.open.open_stream`'s ``frame_metadata``)
    hold a valid GPS position (``gps.latitude``, ``gps.longitude`` in signed degrees)."""
    return _gps(metadata) is not None


# --------------------------------------------------------------------------------------------
# footprint (GeoTIFF)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Footprint:
    """Where a nadir frame lies on the ground.

    Attributes
    ----------
    latitude, longitude : float
        The image centre, signed degrees (WGS 84).
    gsd_m : float
        Ground size of a pixel, m (square pixels).
    yaw_deg : float
        Azimuth of the image's top edge, degrees clockwise from north.
    shape : tuple of int
        The frame's (H, W), pixels.
    hfov_deg : float or None
        The horizontal field of view the ground size was computed with, degrees.
    """

    latitude: float
    longitude: float
    gsd_m: float
    yaw_deg: float
    shape: tuple[int, int]
    hfov_deg: float | None = None

    def model_transformation(self) -> np.ndarray:
        """GeoTIFF's ``ModelTransformationTag``: the 4x4 matrix mapping a pixel corner
        ``(column, row, 0, 1)`` to ``(longitude, latitude, 0, 1)``, degrees.

        The ground offsets in metres are turned into degrees with the WGS 84 radii of curvature
        at the centre (meridional M, prime vertical N): exact to a few millimetres over the few
        hundred metres of a frame.
        """
        h, w = self.shape
        s = math.sin(math.radians(self.latitude))
        den = 1.0 - _WGS84_E2 * s * s
        m_radius = _WGS84_A * (1.0 - _WGS84_E2) / den**1.5
        n_radius = _WGS84_A / math.sqrt(den)
        deg_e = math.degrees(1.0 / (n_radius * math.cos(math.radians(self.latitude))))
        deg_n = math.degrees(1.0 / m_radius)
        c, t = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        g = self.gsd_m
        # east = g·(cos ψ·(col − W/2) − sin ψ·(row − H/2)); north = −g·(sin ψ·(col − W/2) +
        # cos ψ·(row − H/2)): the image's top edge points to azimuth ψ
        a, b = g * c * deg_e, -g * t * deg_e
        e, f = -g * t * deg_n, -g * c * deg_n
        return np.array([
            [a, b, 0.0, self.longitude - a * w / 2 - b * h / 2],
            [e, f, 0.0, self.latitude - e * w / 2 - f * h / 2],
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ])


def default_hfov_deg(metadata: Mapping[str, Any] | None, width: int) -> float | None:
    """The horizontal field of view of a frame's camera, degrees: the file's own (a FLIR
    record's ``field_of_view_deg``), else its lens's (EXIF ``focal_length_mm``:
    :data:`LENS_HFOV_DEG`, else by the camera's :data:`PIXEL_PITCH_UM`), else
    :data:`DEFAULT_HFOV_DEG`'s; None when unknown."""
    meta = metadata or {}
    own = _number(meta.get("field_of_view_deg"))
    if own is not None and 0 < own < 180:
        return own
    make = str(meta.get("make") or "").strip().lower()
    model = str(meta.get("model") or meta.get("camera_model") or "").strip().lower()
    focal = _number(meta.get("focal_length_mm"))
    pitch = PIXEL_PITCH_UM.get((make, model))
    if focal is not None and focal > 0 and pitch is not None:
        listed = LENS_HFOV_DEG.get((int(width), round(focal, 1)))
        if listed is not None:
            return listed
        return math.degrees(2.0 * math.atan(int(width) * pitch * 1e-3 / (2.0 * focal)))
    return DEFAULT_HFOV_DEG.get((make, model, int(width)))


def footprint(metadata: Mapping[str, Any] | None, *, shape: tuple[int, int],
              hfov_deg: float | None = None) -> Footprint:
    """The ground footprint of a nadir frame, from its metadata.

    Needs the GPS position, the height above the take-off point (DJI ``RelativeAltitude``,
    taken as the height above ground: flat terrain), a gimbal pitch within
    :data:`NADIR_TOLERANCE_DEG` of −90° (the small tilt is then neglected, as are terrain relief
    and lens distortion), a yaw (the gimbal's, else the aircraft's) and the horizontal field of
    view.

    Parameters
    ----------
    metadata : mapping or None
        One frame's metadata (``frame_metadata`` of :func:`thermocal.io.open.open_stream`).
    shape : tuple of int
        The frame's (H, W), pixels.
    hfov_deg : float, optional
        Horizontal field of view, degrees; default :func:`default_hfov_deg`.

    Returns
    -------
    Footprint

    Raises
    ------
    InvalidInputError
        When the footprint cannot be computed; the message says why.
    """
    meta = metadata or {}
    where = _gps(meta)
    if where is None:
        raise InvalidInputError("no GPS position")
    height = _number(meta.get("relative_altitude_m"))
    if height is None or height <= 0:
        raise InvalidInputError("no height above ground (DJI RelativeAltitude > 0 m)")
    attitude = meta.get("attitude") if isinstance(meta.get("attitude"), Mapping) else {}
    pitch = _number(attitude.get("gimbal_pitch_deg"))
    if pitch is None:
        raise InvalidInputError("camera attitude unknown (no gimbal pitch): cannot tell it is "
                                "looking straight down")
    if abs(pitch + 90.0) > NADIR_TOLERANCE_DEG:
        raise InvalidInputError(f"gimbal pitch {pitch:g}° is not nadir "
                                f"(-90° ± {NADIR_TOLERANCE_DEG:g}°)")
    yaw = _number(attitude.get("gimbal_yaw_deg"))
    if yaw is None:
        yaw = _number(attitude.get("flight_yaw_deg"))
    if yaw is None:
        raise InvalidInputError("camera yaw unknown (no gimbal or flight yaw)")
    h, w = shape
    fov = hfov_deg if hfov_deg is not None else default_hfov_deg(meta, w)
    if fov is not None and not 0 < fov < 180:
        raise InvalidInputError(f"field of view {fov:g}° is not between 0° and 180°")
    if fov is None:
        raise InvalidInputError(
            f"field of view unknown for camera {meta.get('make') or ''} "
            f"{meta.get('model') or meta.get('camera_model') or ''} ({w} px wide); "
            "give --hfov-deg".replace("  ", " "))
    gsd = 2.0 * height * math.tan(math.radians(fov) / 2.0) / w
    return Footprint(where[0], where[1], gsd, yaw, (int(h), int(w)), float(fov))


# --------------------------------------------------------------------------------------------
# tags
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MapTags:
    """The georeferencing tags of one map TIFF (:func:`map_tags`); :meth:`encode` writes it.

    Attributes
    ----------
    extratags : tuple
        Tags of the image's IFD, as tifffile's ``extratags`` (the EXIF and GPS IFD pointers
        excluded).
    exif : tuple
        Entries of the EXIF IFD, (code, TIFF type, values).
    gps : tuple
        Entries of the GPS IFD, (code, TIFF type, values); none: no GPS IFD.
    """

    extratags: tuple[tuple[Any, ...], ...]
    exif: tuple[_Entry, ...]
    gps: tuple[_Entry, ...]

    def encode(self, image: np.ndarray, *, metadata: dict[str, Any] | None = None) -> bytes:
        """The bytes of a classic little-endian TIFF of ``image`` (2-D) carrying these tags
        (and ``metadata`` in its ImageDescription, as :func:`tifffile.imwrite` writes it)."""
        import tifffile

        if image.ndim != 2:
            raise InvalidInputError(f"a georeferenced map is one (H, W) image, got {image.shape}")

        def tiff(exif_at: int, gps_at: int) -> bytes:
            buf = io.BytesIO()
            pointers = [("ExifTag", _LONG, 1, exif_at, True)]
            if self.gps:
                pointers.append(("GPSTag", _LONG, 1, gps_at, True))
            tifffile.imwrite(buf, image, photometric="minisblack", byteorder="<", bigtiff=False,
                             extratags=[*self.extratags, *pointers],
                             metadata={} if metadata is None else metadata)
            return buf.getvalue()

        end = len(tiff(0, 0))
        end += end % 2  # IFDs start on a word boundary
        exif = _ifd_bytes(self.exif, end)
        gps = _ifd_bytes(self.gps, end + len(exif)) if self.gps else b""
        head = tiff(end, end + len(exif))
        return head + bytes(end - len(head)) + exif + gps


def _ifd_bytes(entries: Sequence[_Entry], at: int) -> bytes:
    """A classic little-endian TIFF IFD placed at file offset ``at``: its entries (sorted by
    code), a zero next-IFD offset, then the values longer than 4 bytes, each on a word
    boundary."""
    entries = sorted(entries, key=lambda e: e[0])
    head = struct.pack("<H", len(entries))
    values = b""
    data_at = at + 2 + 12 * len(entries) + 4
    for code, typ, value in entries:
        if typ == _RATIONAL:
            flat = [int(x) for pair in value for x in pair]
            count, raw = len(value), struct.pack(f"<{len(flat)}I", *flat)
        elif typ in (_BYTE, _ASCII, _UNDEFINED):
            count, raw = len(value), bytes(value)
        else:
            count, raw = len(value), struct.pack(f"<{len(value)}{_TYPE_FORMAT[typ]}", *value)
        if len(raw) <= 4:
            field = raw.ljust(4, b"\x00")
        else:
            field = struct.pack("<I", data_at + len(values))
            values += raw + b"\x00" * (len(raw) % 2)
        head += struct.pack("<HHI", code, typ, count) + field
    return head + b"\x00\x00\x00\x00" + values


def _ascii(text: str) -> bytes:
    """A NUL-terminated 7-bit ASCII TIFF string (other characters as ``?``)."""
    return text.encode("ascii", "replace") + b"\x00"


def dms(degrees: float) -> tuple[int, int, int]:
    """The absolute value of ``degrees`` as whole degrees, whole minutes and millionths of an
    arc-second, rounded to the nearest 1e-6″ (within 1.4e-10°, 0.02 mm on the ground): EXIF's
    GPS latitude and longitude."""
    micro = round(abs(degrees) * 3600e6)
    d, rest = divmod(micro, 3_600_000_000)
    m, s = divmod(rest, 60_000_000)
    return d, m, s


def _dms(degrees: float) -> tuple[tuple[int, int], ...]:
    """:func:`dms` as EXIF rationals d/1, m/1, s·10⁶/10⁶."""
    d, m, s = dms(degrees)
    return (d, 1), (m, 1), (s, 1_000_000)


def _rational(value: float, denominator: int) -> tuple[int, int]:
    return round(abs(value) * denominator), denominator


def _when(metadata: Mapping[str, Any]) -> _dt.datetime | None:
    text = metadata.get("datetime")
    if not isinstance(text, str) or not text:
        return None
    try:
        return _dt.datetime.fromisoformat(text)
    except ValueError:
        return None


def _make_model(metadata: Mapping[str, Any]) -> tuple[str | None, str | None]:
    """Make and model: EXIF's, else the FLIR record's model (make ``FLIR`` for a FLIR record)."""
    model = str(metadata.get("model") or metadata.get("camera_model") or "").strip() or None
    make = str(metadata.get("make") or "").strip() or None
    if make is None and "planck" in metadata and model is not None:
        make = "FLIR"
    return make, model


def _xmp(metadata: Mapping[str, Any], make: str | None, model: str | None) -> bytes:
    """The XMP packet: DJI's altitudes and attitude, make, model, the LWIR band."""
    from xml.sax.saxutils import quoteattr

    attitude = metadata.get("attitude")
    values = dict(attitude) if isinstance(attitude, Mapping) else {}
    for key in ("absolute_altitude_m", "relative_altitude_m"):
        values[key] = metadata.get(key)
    attrs = [f"drone-dji:{name}={quoteattr(f'{v:+.6f}')}" for key, name in _DJI_XMP.items()
             if (v := _number(values.get(key))) is not None]
    attrs += [f"tiff:{name}={quoteattr(v)}" for name, v in (("Make", make), ("Model", model))
              if v is not None]
    attrs.append('Camera:BandName="LWIR"')
    body = "\n    ".join(attrs)
    return (
        '<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>\n'
        '<x:xmpmeta xmlns:x="adobe:ns:meta/">\n'
        ' <rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">\n'
        '  <rdf:Description rdf:about=""\n'
        '    xmlns:tiff="http://ns.adobe.com/tiff/1.0/"\n'
        '    xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/"\n'
        '    xmlns:Camera="http://pix4d.com/camera/1.0/"\n'
        f'    {body}/>\n'
        ' </rdf:RDF>\n'
        '</x:xmpmeta>\n'
        '<?xpacket end="w"?>'
    ).encode()


def _geotiff_tags(where: Footprint) -> list[tuple[Any, ...]]:
    """ModelTransformationTag and a GeoKeyDirectoryTag for EPSG:4326, pixel is area."""
    keys = [1, 1, 0, 3,  # version 1.1.0, 3 keys
            1024, 0, 1, 2,  # GTModelTypeGeoKey: geographic
            1025, 0, 1, 1,  # GTRasterTypeGeoKey: pixel is area
            2048, 0, 1, 4326]  # GeographicTypeGeoKey: WGS 84
    return [(34264, _DOUBLE, 16, tuple(where.model_transformation().ravel()), True),
            (34735, _SHORT, len(keys), keys, True)]


def map_tags(metadata: Mapping[str, Any] | None, *,
             footprint: Footprint | None = None) -> MapTags | None:
    """The georeferencing tags of a map made from a frame with ``metadata``.

    Parameters
    ----------
    metadata : mapping or None
        The frame's metadata (``frame_metadata`` of :func:`thermocal.io.open.open_stream`):
        ``gps`` (``latitude``, ``longitude``, signed degrees; ``altitude_m``; ``map_datum``),
        ``datetime`` (ISO 8601), ``make``, ``model``/``camera_model``, ``attitude`` (degrees),
        ``absolute_altitude_m``, ``relative_altitude_m`` (m).
    footprint : Footprint, optional
        When given, GeoTIFF tags too (:func:`footprint`).

    Returns
    -------
    MapTags or None
        None when the frame has no GPS position, capture time, make, model, attitude or
        altitude: its map is written without tags. Without a position, the capture time,
        make, model and XMP alone (no GPS IFD).
    """
    where = _gps(metadata)
    meta: Mapping[str, Any] = metadata or {}
    when = _when(meta)
    make, model = _make_model(meta)
    aloft = meta.get("attitude") or any(_number(meta.get(k)) is not None for k in (
        "absolute_altitude_m", "relative_altitude_m"))
    if where is None and when is None and make is None and model is None and not aloft:
        return None
    exif, gps = _time_entries(when)
    extratags: list[tuple[Any, ...]] = [
        (code, _ASCII, 0, text.encode("ascii", "replace"), True)
        for code, text in ((271, make), (272, model)) if text is not None]
    xmp = _xmp(meta, make, model)
    extratags.append((700, _BYTE, len(xmp), xmp, True))
    if where is None:
        return MapTags(tuple(extratags), tuple(exif), ())
    if footprint is not None:
        extratags += _geotiff_tags(footprint)
    return MapTags(tuple(extratags), tuple(exif),
                   tuple(_position_entries(meta, *where)) + tuple(gps))


def _position_entries(meta: Mapping[str, Any], lat: float, lon: float) -> list[_Entry]:
    """The GPS IFD's version, position, altitude and map datum."""
    gps_meta = meta["gps"]
    gps: list[_Entry] = [
        (0, _BYTE, bytes((2, 3, 0, 0))),  # GPSVersionID
        (1, _ASCII, _ascii("N" if lat >= 0 else "S")),
        (2, _RATIONAL, _dms(lat)),
        (3, _ASCII, _ascii("E" if lon >= 0 else "W")),
        (4, _RATIONAL, _dms(lon)),
    ]
    altitude = _number(gps_meta.get("altitude_m"))
    if altitude is None:
        altitude = _number(meta.get("absolute_altitude_m"))
    if altitude is not None and abs(altitude) < _MAX_ALTITUDE_M:
        below_sea_level = bytes((int(altitude < 0),))
        gps += [(5, _BYTE, below_sea_level), (6, _RATIONAL, (_rational(altitude, 1000),))]
    datum = str(gps_meta.get("map_datum") or "").strip()
    if datum:
        gps.append((18, _ASCII, _ascii(datum)))
    return gps


def _time_entries(when: _dt.datetime | None) -> tuple[list[_Entry], list[_Entry]]:
    """The EXIF IFD (its version; the local time, milliseconds, time zone) and the GPS IFD's
    UTC time and date (where the zone is known)."""
    exif: list[_Entry] = [(0x9000, _UNDEFINED, b"0232")]  # ExifVersion 2.32
    gps: list[_Entry] = []
    if when is not None:
        exif.append((0x9003, _ASCII, _ascii(when.strftime("%Y:%m:%d %H:%M:%S"))))
        exif.append((0x9291, _ASCII, _ascii(f"{when.microsecond // 1000:03d}")))
        if when.utcoffset() is not None:
            utc = when.astimezone(_dt.UTC)
            zone = when.strftime("%z")  # ±HHMM → OffsetTimeOriginal ±HH:MM
            exif.append((0x9011, _ASCII, _ascii(f"{zone[:3]}:{zone[3:5]}")))
            gps.append((7, _RATIONAL, ((utc.hour, 1), (utc.minute, 1),
                                       (utc.second * 1000 + utc.microsecond // 1000, 1000))))
            gps.append((29, _ASCII, _ascii(utc.strftime("%Y:%m:%d"))))
    return exif, gps
