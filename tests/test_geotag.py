"""Georeferenced output maps (thermocal.io.geotag through ``thermocal flight``): the source
frame's GPS, time and attitude read back by independent readers (exifread, Pillow, tifffile, the
standard library's XML parser), GeoTIFF corners against a hand computation, frames without GPS
unchanged, and ``--geotiff`` refused where it cannot be done.

Tolerances: latitude and longitude are written as EXIF rationals d/1, m/1, s·10⁶/10⁶, so they read
back within 1.4e-10° (half a micro-arcsecond; 2e-10° asserted); the altitude in millimetres
(within 0.0005 m).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import exifread
import numpy as np
import pytest
import tifffile
from cli_run import run
from PIL import Image
from test_open_recording import _dji_xmp, _fff, _frames, _rjpeg

from thermocal.errors import InvalidInputError
from thermocal.io.geotag import default_hfov_deg, footprint, map_tags
from thermocal.io.recording import read_temperature_tiff, write_temperature_tiff

DJI_NS = "{http://www.dji.com/drone-dji/1.0/}"
RDF_DESCRIPTION = "{http://www.w3.org/1999/02/22-rdf-syntax-ns#}Description"
#: Source positions of the synthetic frames: (latitude, longitude, altitude m).
GPS = [(45.123456789, 7.654321098, 312.25), (-33.8765432, -70.1234567, 520.5),
       (45.1235, 7.6544, 310.0)]
EPOCH = 1_700_000_000  # the synthetic FFF records' time (2023-11-14 22:13:20 UTC), +01:00


def _series(folder: Path, gps: list | None, *, xmp: bool = True) -> Path:
    """A folder of synthetic R-JPEGs (DJI XMP: relative altitude 50.25 m, gimbal pitch −90°,
    flight yaw 12.5°; the FLIR record's field of view 24°), with GPS when given."""
    folder.mkdir()
    for k, fr in enumerate(_frames(3)):
        record = _fff(fr, order="<", ms=100 * k, gps=None if gps is None else gps[k])
        (folder / f"DJI_{k:04d}.jpg").write_bytes(
            _rjpeg(record, parts=2, xmp=_dji_xmp(30 + k) if xmp else None))
    return folder


def _flight(recording: Path, out: Path, capsys, *extra) -> tuple[int, str]:
    code, _, err = run(["flight", recording, "--out", out, "--method", "camera", "--frames", 1,
                        "--stride", 1, "--preview-every", 0, *extra], capsys)
    return code, err


def _exif_degrees(tag) -> float:
    d, m, s = (float(v.num) / float(v.den) for v in tag.values)
    return d + m / 60 + s / 3600


def _exifread(path: Path) -> dict:
    with open(path, "rb") as f:
        return exifread.process_file(f, details=True)


def _xmp(path: Path) -> dict[str, str]:
    """The ``drone-dji:`` attributes of the map's XMP (tag 700), parsed as XML."""
    with tifffile.TiffFile(path) as tif:
        packet = bytes(tif.pages[0].tags[700].value)
    root = ET.fromstring(packet[packet.find(b"<x:xmpmeta"):packet.find(b"</x:xmpmeta>") + 12])
    (desc,) = root.iter(RDF_DESCRIPTION)
    return {k.removeprefix(DJI_NS): v for k, v in desc.attrib.items() if k.startswith(DJI_NS)}


def _check_gps(path: Path, lat: float, lon: float, alt: float | None) -> None:
    """The map's GPS by exifread and by Pillow equals (lat, lon, alt)."""
    tags = _exifread(path)
    sign = {"N": 1, "S": -1, "E": 1, "W": -1}
    assert sign[str(tags["GPS GPSLatitudeRef"])] * _exif_degrees(
        tags["GPS GPSLatitude"]) == pytest.approx(lat, abs=2e-10)
    assert sign[str(tags["GPS GPSLongitudeRef"])] * _exif_degrees(
        tags["GPS GPSLongitude"]) == pytest.approx(lon, abs=2e-10)
    with Image.open(path) as im:
        gps = im.getexif().get_ifd(0x8825)
    pil_lat = sum(float(v) / 60**k for k, v in enumerate(gps[2])) * sign[gps[1]]
    assert pil_lat == pytest.approx(lat, abs=2e-10)
    if alt is not None:
        (value,) = tags["GPS GPSAltitude"].values
        assert tags["GPS GPSAltitudeRef"].values == [int(alt < 0)]
        assert float(value.num) / value.den == pytest.approx(abs(alt), abs=5e-4)
        assert float(gps[6]) == pytest.approx(abs(alt), abs=5e-4)


# --------------------------------------------------------------------------------------------
# EXIF/XMP round trip
# --------------------------------------------------------------------------------------------
def test_rjpeg_series_gps_time_attitude_round_trip(tmp_path, capsys):
    rec = _series(tmp_path / "flight", GPS)
    code, err = _flight(rec, tmp_path / "out", capsys)
    assert code == 0, err
    for k, (lat, lon, alt) in enumerate(GPS):
        maps = sorted((tmp_path / "out" / "temps").glob(f"frame_{k:06d}*.tiff"))
        assert maps  # the map and, where the method gives one, its σ map: both tagged
        for path in maps:
            _check_gps(path, lat, lon, alt)
            tags = _exifread(path)
            assert str(tags["GPS GPSMapDatum"]) == "WGS84"
            assert str(tags["Image Model"]) == "Synthetic Tau2"
            assert str(tags["Image Make"]) == "FLIR"
            local = dt.datetime.fromtimestamp(EPOCH + 0.1 * k, dt.timezone(dt.timedelta(hours=1)))
            assert str(tags["EXIF DateTimeOriginal"]) == local.strftime("%Y:%m:%d %H:%M:%S")
            assert str(tags["EXIF SubSecTimeOriginal"]) == f"{100 * k:03d}"
            assert str(tags["EXIF OffsetTimeOriginal"]) == "+01:00"
            h, m, s = (float(v.num) / v.den for v in tags["GPS GPSTimeStamp"].values)
            assert (h, m, s) == (22, 13, pytest.approx(20 + 0.1 * k))
            assert str(tags["GPS GPSDate"]) == "2023:11:14"
            xmp = _xmp(path)
            assert {n: float(v) for n, v in xmp.items()} == {
                "AbsoluteAltitude": 100.5, "RelativeAltitude": 50.25,
                "GimbalPitchDegree": -90.0, "FlightYawDegree": 12.5}
            with tifffile.TiffFile(path) as tif:  # tifffile's own parsing of the GPS IFD
                gps = tif.pages[0].tags["GPSTag"].value
                assert tif.series[0].dtype == np.float32 and tif.geotiff_metadata is None
            assert gps["GPSLatitudeRef"] == ("N" if lat >= 0 else "S")
            assert gps["GPSMapDatum"] == "WGS84"


def _about(path: Path) -> dict:
    """A map's ImageDescription (JSON)."""
    with tifffile.TiffFile(path) as tif:
        return json.loads(tif.pages[0].description)


def test_estimate_keeps_the_pivots_gps_and_says_what_each_map_is(tmp_path, capsys):
    """``thermocal estimate`` keeps its pivot frame's GPS, time, make and model, as a flight's
    maps do (it wrote none: a helper's audit); each map says what it holds, its unit, the
    method and source, and names the other (a σ map could not be told from a temperature
    map)."""
    rec = _series(tmp_path / "flight", GPS)
    out, sig = tmp_path / "t.tiff", tmp_path / "s.tiff"
    code, _, err = run(["estimate", rec, "--method", "camera", "--pivot", 1, "--out", out,
                        "--sigma-out", sig], capsys)
    assert code == 0, err
    for path in (out, sig):
        _check_gps(path, *GPS[1])
        assert str(_exifread(path)["Image Model"]) == "Synthetic Tau2"
    base = {"method": "camera", "source": "flight", "frame": 1, "unit": "degC"}
    assert _about(out) == {"shape": [6, 8], "quantity": "temperature", **base,
                           "sigma": "s.tiff"}
    assert _about(sig) == {"shape": [6, 8], **base, "temperature": "t.tiff",
                           "quantity": "standard uncertainty (1 sigma) of the temperature map "
                                       "beside it"}
    # a flight's maps say the same, each naming the other
    code, err = _flight(rec, tmp_path / "out", capsys)
    assert code == 0, err
    temps = tmp_path / "out" / "temps"
    assert _about(temps / "frame_000002.tiff")["sigma"] == "frame_000002_sigma.tiff"
    assert _about(temps / "frame_000002_sigma.tiff") | {"shape": 0} == {
        "shape": 0, "quantity": "standard uncertainty (1 sigma) of the temperature map beside "
        "it", "unit": "degC", "method": "camera", "frame": 2, "temperature": "frame_000002.tiff"}


def _dump(path: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        key, sep, value = line.partition(":")
        if sep:
            out.setdefault(key.strip(), value.strip())
    return out


def _dump_degrees(text: str) -> float:
    d, m, s, ref = re.fullmatch(r"(\d+) deg (\d+)' ([\d.]+)\" ([NSEW])", text).groups()
    return (int(d) + int(m) / 60 + float(s) / 3600) * (-1 if ref in "SW" else 1)


def _real(shared_data: Path, *parts: str) -> Path:
    """A real recording of ``shared/data`` (skipped where only the package's copy, which holds
    no recordings, is found)."""
    path = shared_data.joinpath(*parts)
    if not path.is_file():
        pytest.skip(f"{path} not found")
    return path


def test_real_dji_rjpeg_gps_equals_exiftool(shared_data, tmp_path, capsys):
    """The DJI XT-R frame's map carries the GPS, altitude, time and attitude exiftool reads in
    the source (the dump gives seconds to 0.01″: compared within 0.005″)."""
    source = _real(shared_data, "recordings", "dji_xtr_tau2.jpg")
    dump = _dump(_real(shared_data, "recordings", "dji_xtr_tau2.txt"))
    code, err = _flight(source, tmp_path / "out", capsys)
    assert code == 0, err
    path = tmp_path / "out" / "temps" / "frame_000000.tiff"
    lat, lon = (_dump_degrees(dump[k]) for k in ("GPS Latitude", "GPS Longitude"))
    tags = _exifread(path)
    assert _exif_degrees(tags["GPS GPSLatitude"]) * -1 == pytest.approx(lat, abs=0.005 / 3600)
    assert _exif_degrees(tags["GPS GPSLongitude"]) * -1 == pytest.approx(lon, abs=0.005 / 3600)
    assert (str(tags["GPS GPSLatitudeRef"]), str(tags["GPS GPSLongitudeRef"])) == ("S", "W")
    assert float(dump["GPS Altitude"].split()[0]) == pytest.approx(
        float(tags["GPS GPSAltitude"].values[0].num) / tags["GPS GPSAltitude"].values[0].den)
    assert str(tags["GPS GPSMapDatum"]) == dump["GPS Map Datum"] == "WGS-84"
    assert (str(tags["Image Make"]), str(tags["Image Model"])) == (
        dump["Make"], dump["Camera Model Name"])
    # exiftool's FLIR Date/Time Original "2018:05:16 10:22:57.045+00:00"
    assert (str(tags["EXIF DateTimeOriginal"]) + "." + str(tags["EXIF SubSecTimeOriginal"])
            + str(tags["EXIF OffsetTimeOriginal"])) == dump["Date/Time Original"]
    xmp = _xmp(path)
    for name in ("AbsoluteAltitude", "RelativeAltitude", "GimbalRollDegree", "GimbalYawDegree",
                 "GimbalPitchDegree", "FlightRollDegree", "FlightYawDegree", "FlightPitchDegree"):
        label = re.sub(r"(?<!^)([A-Z])", r" \1", name)  # GimbalYawDegree → Gimbal Yaw Degree
        assert float(xmp[name]) == pytest.approx(float(dump[label]), abs=5e-7)
    # exactly the source's EXIF GPS, both read by exifread (within the rational rounding)
    src = _exifread(source)
    (alt,) = src["GPS GPSAltitude"].values
    _check_gps(path, -_exif_degrees(src["GPS GPSLatitude"]),
               -_exif_degrees(src["GPS GPSLongitude"]), float(alt.num) / alt.den)


# --------------------------------------------------------------------------------------------
# GeoTIFF
# --------------------------------------------------------------------------------------------
def _metres_per_degree(lat: float) -> tuple[float, float]:
    """Length of a degree of latitude and of longitude at ``lat`` on WGS 84, m: the textbook
    series (Wikipedia, "Latitude", "Length of a degree"; within 1 cm per degree), independent of
    the radii of curvature the module uses."""
    p = math.radians(lat)
    along = 111132.92 - 559.82 * math.cos(2 * p) + 1.175 * math.cos(4 * p) - 0.0023 * math.cos(
        6 * p)
    across = 111412.84 * math.cos(p) - 93.5 * math.cos(3 * p) + 0.118 * math.cos(5 * p)
    return along, across


def _corners(path: Path) -> dict[tuple[int, int], tuple[float, float]]:
    """(lat, lon) of the four pixel corners by tifffile's GeoTIFF parsing."""
    with tifffile.TiffFile(path) as tif:
        geo = tif.geotiff_metadata
        h, w = tif.pages[0].shape
    assert geo["GTModelTypeGeoKey"] == 2 and geo["GTRasterTypeGeoKey"] == 1
    assert geo["GeographicTypeGeoKey"] == 4326
    matrix = np.array(geo["ModelTransformation"])
    out = {}
    for col, row in ((0, 0), (w, 0), (0, h), (w, h)):
        lon, lat = (matrix @ [col, row, 0, 1])[:2]
        out[col, row] = (lat, lon)
    return out


def _hand_corners(lat0, lon0, height, hfov, yaw, shape):
    """The corners by hand: ground pixel size from the height and field of view, image axes
    rotated by the yaw (the top edge points to azimuth ``yaw``), metres to degrees."""
    h, w = shape
    g = 2 * height * math.tan(math.radians(hfov / 2)) / w
    along, across = _metres_per_degree(lat0)
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    out = {}
    for col, row in ((0, 0), (w, 0), (0, h), (w, h)):
        right, up = (col - w / 2) * g, (h / 2 - row) * g
        east, north = right * c + up * s, -right * s + up * c
        out[col, row] = (lat0 + north / along, lon0 + east / across)
    return out


def test_geotiff_corners_known_answer(tmp_path):
    """45° N, 7° E, 100 m above ground, 45° field of view, 640 x 512, north up: the ground
    pixel is 2·100·tan 22.5°/640 = 0.1294417 m, the frame 82.842712 m x 66.274170 m; the
    top-left corner lies 33.137085 m north and 41.421356 m west of the centre, that is
    33.137085/111131.745 ° and 41.421356/78846.806 ° (the degree lengths at 45°)."""
    meta = {"gps": {"latitude": 45.0, "longitude": 7.0, "altitude_m": 400.0},
            "relative_altitude_m": 100.0,
            "attitude": {"gimbal_pitch_deg": -90.0, "gimbal_yaw_deg": 0.0}}
    temp = np.full((512, 640), 20.0, np.float32)
    where = footprint(meta, shape=temp.shape, hfov_deg=45.0)
    assert where.gsd_m == pytest.approx(0.1294417, abs=1e-7)
    path = write_temperature_tiff(tmp_path / "map.tiff", temp,
                                  tags=map_tags(meta, footprint=where))
    corners = _corners(path)
    assert corners[0, 0] == pytest.approx((45 + 33.137085 / 111131.745, 7 - 41.421356 / 78846.806),
                                          abs=1e-9)
    assert corners[640, 512] == pytest.approx(
        (45 - 33.137085 / 111131.745, 7 + 41.421356 / 78846.806), abs=1e-9)
    # yaw 90°: the top edge faces east, so the top-left corner is north (its left) and east
    rotated = dict(meta, attitude={"gimbal_pitch_deg": -85.0, "gimbal_yaw_deg": 90.0})
    path = write_temperature_tiff(
        tmp_path / "east.tiff", temp,
        tags=map_tags(rotated, footprint=footprint(rotated, shape=temp.shape, hfov_deg=45.0)))
    assert _corners(path)[0, 0] == pytest.approx(
        (45 + 41.421356 / 111131.745, 7 + 33.137085 / 78846.806), abs=1e-9)
    np.testing.assert_array_equal(read_temperature_tiff(path), temp)
    _check_gps(path, 45.0, 7.0, 400.0)


def test_flight_geotiff_corners(tmp_path, capsys):
    """``--geotiff`` through the command: the synthetic frames (50.25 m above ground, flight yaw
    12.5°, the record's 24° field of view, 8 x 6 pixels) against the hand computation."""
    rec = _series(tmp_path / "flight", GPS)
    code, err = _flight(rec, tmp_path / "out", capsys, "--geotiff")
    assert code == 0, err
    for k, (lat, lon, _) in enumerate(GPS):
        for path in (tmp_path / "out" / "temps").glob(f"frame_{k:06d}*.tiff"):
            got, want = _corners(path), _hand_corners(lat, lon, 50.25, 24.0, 12.5, (6, 8))
            for corner in want:
                assert got[corner] == pytest.approx(want[corner], abs=1e-9)
    log = [json.loads(line) for line in (tmp_path / "out" / "log.jsonl").read_text().splitlines()]
    assert [e["ground"]["hfov_deg"] for e in log] == [24.0] * 3  # what the tags came from
    assert log[0]["ground"]["gsd_m"] == pytest.approx(2 * 50.25 * math.tan(math.radians(12)) / 8)
    # --hfov-deg overrides the file's field of view
    code, err = _flight(rec, tmp_path / "wide", capsys, "--geotiff", "--hfov-deg", 48)
    assert code == 0, err
    got = _corners(tmp_path / "wide" / "temps" / "frame_000000.tiff")
    assert got[0, 0] == pytest.approx(
        _hand_corners(*GPS[0][:2], 50.25, 48.0, 12.5, (6, 8))[0, 0], abs=1e-9)


def test_real_dji_lens_gives_the_field_of_view(shared_data):
    """The XT-R frame's EXIF FocalLength (19.0 mm, as exiftool reads it): DJI's 32° for that
    lens at 640 px, not the 13 mm lens's 45° assumed before (a footprint 1.41 times too wide;
    a new-user audit found it); a lens DJI does not list, by the Tau2's 17 µm pixels (the
    listed 9 mm lens's 69° is not its pinhole 62°: listed, not computed)."""
    from thermocal.io.rjpeg import read_rjpeg

    source = _real(shared_data, "recordings", "dji_xtr_tau2.jpg")
    dump = _dump(_real(shared_data, "recordings", "dji_xtr_tau2.txt"))
    meta = read_rjpeg(source).metadata
    assert meta["focal_length_mm"] == _num_mm(dump["Focal Length"]) == 19.0
    assert default_hfov_deg(meta, 640) == 32.0 and default_hfov_deg(meta, 336) == 17.0
    assert default_hfov_deg(dict(meta, focal_length_mm=9.0), 640) == 69.0
    assert default_hfov_deg(dict(meta, focal_length_mm=25.0), 640) == pytest.approx(
        math.degrees(2 * math.atan(640 * 0.017 / 50.0)))
    nadir = dict(meta, relative_altitude_m=100.0,
                 attitude={**meta["attitude"], "gimbal_pitch_deg": -90.0})
    where = footprint(nadir, shape=(512, 640))
    assert where.hfov_deg == 32.0
    assert where.gsd_m * 640 == pytest.approx(2 * 100 * math.tan(math.radians(16.0)))  # 57.3 m
    assert footprint(nadir, shape=(512, 640), hfov_deg=45.0).gsd_m * 640 == pytest.approx(
        82.84, abs=0.01)  # --hfov-deg still overrides


def _num_mm(text: str) -> float:
    return float(text.removesuffix(" mm"))


def test_footprint_refusals():
    base = {"gps": {"latitude": 1.0, "longitude": 2.0}, "relative_altitude_m": 30.0,
            "attitude": {"gimbal_pitch_deg": -90.0, "gimbal_yaw_deg": 0.0}}
    for meta, why in [
        ({}, "no GPS position"),
        (dict(base, relative_altitude_m=None), "no height above ground"),
        (dict(base, attitude={}), "attitude unknown"),
        (dict(base, attitude={"gimbal_pitch_deg": -75.0, "gimbal_yaw_deg": 0.0}),
         "gimbal pitch -75° is not nadir"),
        (base, "field of view unknown .*give --hfov-deg"),
    ]:
        with pytest.raises(InvalidInputError, match=why):
            footprint(meta, shape=(512, 640))
    # the DJI XT/XT-R default (13 mm lens): 45°
    dji = dict(base, make="DJI", model="FLIR")
    assert footprint(dji, shape=(512, 640)).gsd_m == pytest.approx(
        2 * 30 * math.tan(math.radians(22.5)) / 640)


# --------------------------------------------------------------------------------------------
# without GPS; bad input; resume
# --------------------------------------------------------------------------------------------
def test_frames_without_gps_keep_their_time_make_and_model(tmp_path, capsys):
    """No GPS: the maps keep the frame's capture time, make and model (EXIF) and its XMP, with
    no GPS IFD (they were written without any tag, against README); a frame with none of
    them (the project's TIFF) gives the bytes of the plain writer."""
    rec = _series(tmp_path / "flight", None)
    code, err = _flight(rec, tmp_path / "out", capsys)
    assert code == 0, err
    maps = sorted((tmp_path / "out" / "temps").glob("frame_*[0-9].tiff"))
    assert len(maps) == 3
    for k, path in enumerate(maps):
        tags = _exifread(path)
        assert not any(name.startswith("GPS") for name in tags)
        assert (str(tags["Image Make"]), str(tags["Image Model"])) == ("FLIR", "Synthetic Tau2")
        local = dt.datetime.fromtimestamp(EPOCH + 0.1 * k, dt.timezone(dt.timedelta(hours=1)))
        assert str(tags["EXIF DateTimeOriginal"]) == local.strftime("%Y:%m:%d %H:%M:%S")
        assert float(_xmp(path)["RelativeAltitude"]) == 50.25
        with tifffile.TiffFile(path) as tif:
            assert "GPSTag" not in tif.pages[0].tags and tif.geotiff_metadata is None
        np.testing.assert_array_equal(read_temperature_tiff(path), tifffile.imread(path))
    assert map_tags(None) is None and map_tags({"gps": None}) is None
    assert map_tags({"source": "frames.tiff", "index": 3}) is None  # nothing to keep: plain


def test_geotiff_refused_without_gps_or_nadir(tmp_path, capsys, shared_data):
    rec = _series(tmp_path / "flight", None)
    out = tmp_path / "out"
    code, err = _flight(rec, out, capsys, "--geotiff")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--geotiff: no pivot can be georeferenced" in err and "no GPS position" in err
    assert not out.exists()
    # the real DJI frame looks ahead (gimbal pitch −8.3°)
    code, err = _flight(_real(shared_data, "recordings", "dji_xtr_tau2.jpg"), out, capsys,
                        "--geotiff")
    assert code == 2 and "gimbal pitch -8.3° is not nadir" in err and not out.exists()
    code, err = _flight(rec, out, capsys, "--hfov-deg", 40)
    assert code == 2 and "--hfov-deg" in err and not out.exists()


def test_geotagged_maps_resume_to_the_same_bytes(tmp_path, capsys):
    rec = _series(tmp_path / "flight", GPS)
    out = tmp_path / "out"
    assert _flight(rec, out, capsys, "--geotiff")[0] == 0
    first = {p.name: p.read_bytes() for p in (out / "temps").glob("*.tiff")}
    (out / "temps" / "frame_000001.tiff").unlink()
    code, _, _ = run(["flight", rec, "--out", out, "--method", "camera", "--frames", 1,
                      "--stride", 1, "--preview-every", 0, "--geotiff"], capsys)
    assert code == 0
    assert {p.name: p.read_bytes() for p in (out / "temps").glob("*.tiff")} == first
    log = (out / "log.jsonl").read_text().splitlines()
    assert len(log) == 4  # the two kept maps passed the resume check; one pivot was redone


def test_pivots_not_nadir_keep_exif_without_geotiff(tmp_path, capsys):
    """A frame that cannot be georeferenced among ones that can: its maps keep the EXIF, lose
    the GeoTIFF tags, and its log line says why."""
    folder = tmp_path / "flight"
    folder.mkdir()
    for k, fr in enumerate(_frames(2)):
        xmp = _dji_xmp(30).replace('GimbalPitchDegree="-90.0"',
                                   f'GimbalPitchDegree="{-90.0 + 40 * k}"')
        (folder / f"DJI_{k:04d}.jpg").write_bytes(
            _rjpeg(_fff(fr, order="<", gps=GPS[k]), parts=2, xmp=xmp))
    code, err = _flight(folder, tmp_path / "out", capsys, "--geotiff")
    assert code == 0, err
    temps = tmp_path / "out" / "temps"
    with tifffile.TiffFile(temps / "frame_000001.tiff") as tif:
        assert tif.geotiff_metadata is None
    _check_gps(temps / "frame_000001.tiff", *GPS[1])
    assert _corners(temps / "frame_000000.tiff")
    log = [json.loads(line) for line in (tmp_path / "out" / "log.jsonl").read_text().splitlines()]
    assert "gimbal pitch -50° is not nadir" in log[1]["warnings"][0] and not log[0]["warnings"]


def test_map_tags_edge_cases(tmp_path):
    """A corrupt altitude is left out, a time without zone gives no GPS time, a position next
    to the antimeridian and south of the equator reads back."""
    meta = {"gps": {"latitude": -0.5, "longitude": 179.99999999, "altitude_m": 5e9},
            "datetime": "2024-02-29T23:59:59.999"}
    path = write_temperature_tiff(tmp_path / "m.tiff", np.ones((3, 4)), tags=map_tags(meta))
    tags = _exifread(path)
    assert "GPS GPSAltitude" not in tags and "GPS GPSTimeStamp" not in tags
    assert str(tags["EXIF DateTimeOriginal"]) == "2024:02:29 23:59:59"
    assert str(tags["EXIF SubSecTimeOriginal"]) == "999"
    _check_gps(path, -0.5, 179.99999999, None)
    with pytest.raises(InvalidInputError, match="field of view 180"):
        footprint({**meta, "relative_altitude_m": 10.0,
                   "attitude": {"gimbal_pitch_deg": -90.0, "flight_yaw_deg": 3.0}},
                  shape=(3, 4), hfov_deg=180.0)


def test_encode_refuses_stacks():
    tags = map_tags({"gps": {"latitude": 1.0, "longitude": 2.0}})
    with pytest.raises(InvalidInputError, match="one"):
        tags.encode(np.zeros((2, 3, 4), np.float32))
    assert isinstance(tags.encode(np.zeros((3, 4), np.float32)), bytes)
