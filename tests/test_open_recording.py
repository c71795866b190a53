"""Tests for thermocal.io.open (open_recording) and the FLIR/DualTauUAV readers behind it.

Real files come from ``shared/data`` (read there, never copied): their metadata must equal the
exiftool dumps beside them. Synthetic files are written here in every supported format.
"""

from __future__ import annotations

import io
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from thermocal.errors import FileFormatError, InvalidInputError, ThermocalError
from thermocal.io.dualtau import interpolate_fpa_readings
from thermocal.io.envchamber import import_envchamberctrl_npz
from thermocal.io.fff import parse_fff_record, planck_from_metadata
from thermocal.io.open import FORMATS, open_recording
from thermocal.io.recording import Recording, read_temperature_tiff, write_recording
from thermocal.radiometry import FlirPlanck
from thermocal.simulate.formats import fff_record

K0 = 273.15


# --------------------------------------------------------------------------------------------
# helpers: exiftool dumps, synthetic FLIR files
# --------------------------------------------------------------------------------------------
def _dump(path: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    for line in path.read_text("utf-8").splitlines():
        key, sep, value = line.partition(":")
        if sep:
            out.setdefault(key.strip(), value.strip())
    return out


def _num(text: str) -> float:
    return float(re.match(r"[-+]?[\d.]+", text).group(0))


def _dms(text: str) -> float:
    d, m, s, ref = re.match(r"(\d+) deg (\d+)' ([\d.]+)\" ([NSEW])", text).groups()
    value = float(d) + float(m) / 60 + float(s) / 3600
    return -value if ref in "SW" else value


def _real(shared_data: Path, *parts: str) -> Path:
    path = shared_data.joinpath(*parts)
    if not path.is_file():
        pytest.skip(f"{path} not found")
    return path


def _check_against_dump(meta: dict, raw: np.ndarray, dump: dict[str, str]) -> None:
    """Metadata and raw image of one frame equal exiftool's dump (to its printed precision)."""
    planck = meta["planck"]
    shape = (int(dump["Raw Thermal Image Height"]), int(dump["Raw Thermal Image Width"]))
    assert raw.shape == shape
    for key, name in (("r1", "Planck R1"), ("r2", "Planck R2"), ("b", "Planck B"),
                      ("f", "Planck F"), ("o", "Planck O")):
        assert planck[key] == pytest.approx(_num(dump[name]), rel=1e-7), name
    assert planck["emissivity"] == pytest.approx(_num(dump["Emissivity"]), abs=0.005)
    assert planck["distance_m"] == pytest.approx(_num(dump["Object Distance"]), abs=0.005)
    for key, name in (("reflected_c", "Reflected Apparent Temperature"),
                      ("atmosphere_c", "Atmospheric Temperature"),
                      ("ir_window_c", "IR Window Temperature")):
        assert planck[key] == pytest.approx(_num(dump[name]), abs=0.05), name
    assert planck["ir_window_transmission"] == pytest.approx(_num(dump["IR Window Transmission"]),
                                                             abs=0.005)
    assert planck["humidity"] * 100 == pytest.approx(_num(dump["Relative Humidity"]), abs=0.05)
    for key, name in (("alpha1", "Atmospheric Trans Alpha 1"),
                      ("alpha2", "Atmospheric Trans Alpha 2"),
                      ("beta1", "Atmospheric Trans Beta 1"), ("beta2", "Atmospheric Trans Beta 2"),
                      ("x", "Atmospheric Trans X")):
        assert planck[key] == pytest.approx(_num(dump[name]), abs=5e-7), name
    assert meta["camera_model"] == dump["Camera Model"]
    assert meta["camera_serial_number"] == dump["Camera Serial Number"]
    assert meta["camera_part_number"] == dump["Camera Part Number"]
    assert meta["camera_software"] == dump["Camera Software"]
    assert meta["creator"] == dump["Creator Software"]
    assert meta["field_of_view_deg"] == pytest.approx(_num(dump["Field Of View"]), abs=0.05)
    assert meta["frame_rate_hz"] == int(dump["Frame Rate"])
    # the FLIR record's time: "2018:11:05 12:14:43.084+01:00"
    assert meta["datetime"].replace("-", ":").replace("T", " ")[:19] == dump[
        "Date/Time Original"][:19]
    assert meta["datetime"][19:] == dump["Date/Time Original"][19:]
    assert int(raw.max()) - int(raw.min()) == int(dump["Raw Value Range"])
    if "GPS Latitude" in dump:
        gps = meta["gps"]
        assert gps["latitude"] == pytest.approx(_dms(dump["GPS Latitude"]), abs=0.01 / 3600)
        assert gps["longitude"] == pytest.approx(_dms(dump["GPS Longitude"]), abs=0.01 / 3600)
        assert gps["altitude_m"] == pytest.approx(_num(dump["GPS Altitude"]), abs=0.05)
        assert gps["map_datum"] == dump["GPS Map Datum"]


def _fff(raw: np.ndarray, *, order: str = ">", codec: str = "plain", r1: float = 16000.0,
         r2: float = 0.02, b: float = 1430.0, f: float = 1.0, o: int = -300,
         emissivity: float = 0.9, model: str = "Synthetic Tau2", epoch: int = 1_700_000_000,
         ms: int = 0, gps: tuple[float, float, float] | None = None) -> bytes:
    """One FFF record in byte order ``order`` (:func:`thermocal.simulate.formats.fff_record`)
    with these constants, a 24° lens, the camera's clock at UTC+01:00."""
    planck = FlirPlanck(r1, r2, b, f, o, emissivity=emissivity, distance_m=10.0,
                        reflected_c=20.0, atmosphere_c=15.0, ir_window_c=20.0, humidity=0.4)
    return fff_record(raw, planck=planck, time_epoch_s=epoch + ms / 1000.0, gps=gps,
                      order=order, codec=codec, creator="SYNT", model=model,
                      field_of_view_deg=24.0, utc_offset_min=60)


def _rjpeg(record: bytes, *, parts: int = 2, xmp: str | None = None) -> bytes:
    """A JPEG carrying ``record`` in ``parts`` FLIR APP1 segments (and an optional XMP)."""
    buf = io.BytesIO()
    Image.new("RGB", (16, 12), (90, 20, 40)).save(buf, "JPEG")
    jpeg = buf.getvalue()
    size = -(-len(record) // parts)
    segs = b""
    if xmp is not None:
        body = b"http://ns.adobe.com/xap/1.0/\x00" + xmp.encode()
        segs += b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body
    for k in range(parts):
        body = b"FLIR\x00\x01" + bytes([k, parts - 1]) + record[k * size : (k + 1) * size]
        segs += b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body
    return jpeg[:2] + segs + jpeg[2:]


def _dji_xmp(spot_c: int) -> str:
    return ('<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF><rdf:Description '
            'drone-dji:AbsoluteAltitude="100.5" drone-dji:RelativeAltitude="50.25" '
            'drone-dji:GimbalPitchDegree="-90.0" drone-dji:FlightYawDegree="12.5" '
            f'FLIR:CentralTemperature="{spot_c}"/></rdf:RDF></x:xmpmeta>')


def _frames(n: int, h: int = 6, w: int = 8, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(1000, 16000, (n, h, w)).astype(np.uint16)


# --------------------------------------------------------------------------------------------
# real files
# --------------------------------------------------------------------------------------------
def test_fff_big_endian_equals_exiftool(shared_data):
    path = _real(shared_data, "flirpy", "frame_000000.fff")
    dump = _dump(_real(shared_data, "flirpy", "frame_000000.txt"))
    src = open_recording(path)
    assert (src.format, src.n_frames, src.frame_shape) == ("fff", 1, (512, 640))
    (chunk,) = list(src.iter_frames())
    assert chunk.frames.dtype == np.uint16 and chunk.fpa_c is None
    meta = chunk.metadata[0]
    _check_against_dump(meta, chunk.frames[0], dump)
    gps = meta["gps"]
    assert gps["speed"] == pytest.approx(_num(dump["GPS Speed"]), abs=0.005)
    assert gps["track_deg"] == pytest.approx(_num(dump["GPS Track"]), abs=0.005)
    assert planck_from_metadata(meta) == FlirPlanck(**meta["planck"])
    reference = FlirPlanck.from_exiftool_text(shared_data / "flirpy" / "frame_000000.txt")
    temp = planck_from_metadata(meta).raw_to_temperature_c(chunk.frames[0])
    np.testing.assert_allclose(temp, reference.raw_to_temperature_c(chunk.frames[0]), atol=0.01)


def test_rjpeg_dji_tau2_equals_exiftool(shared_data):
    path = _real(shared_data, "recordings", "dji_xtr_tau2.jpg")
    dump = _dump(_real(shared_data, "recordings", "dji_xtr_tau2.txt"))
    src = open_recording(path)
    assert (src.format, src.n_frames, src.frame_shape, src.bit_depth) == ("rjpeg", 1, (512, 640),
                                                                          16)
    rec = src.read_all()
    meta = rec.extra["frame_metadata"][0]
    _check_against_dump(meta, rec.frames[0], dump)
    assert meta["make"] == dump["Make"] and meta["model"] == dump["Camera Model Name"]
    # FLIR:CentralTemperature is the Tau2's spot meter, whole °C: the camera's own temperature
    # of the 4x4 centre pixels (25.9 °C; the frame's median 27.7), not its FPA's: no FPA series
    assert meta["spot_c"] == _num(dump["Central Temperature"]) == 26.0
    temps = FlirPlanck.from_exiftool_text(path.with_suffix(".txt")).raw_to_temperature_c(
        rec.frames[0].astype(np.float64))
    assert round(float(temps[254:258, 318:322].mean())) == 26
    assert round(float(np.median(temps))) != 26
    assert rec.fpa_c is None and src.fpa_resolution_c is None and not src.has_fpa
    assert meta["absolute_altitude_m"] == pytest.approx(_num(dump["Absolute Altitude"]))
    assert meta["relative_altitude_m"] == pytest.approx(_num(dump["Relative Altitude"]))
    for key, name in (("gimbal_roll_deg", "Gimbal Roll Degree"),
                      ("gimbal_yaw_deg", "Gimbal Yaw Degree"),
                      ("gimbal_pitch_deg", "Gimbal Pitch Degree"),
                      ("flight_roll_deg", "Flight Roll Degree"),
                      ("flight_yaw_deg", "Flight Yaw Degree"),
                      ("flight_pitch_deg", "Flight Pitch Degree")):
        assert meta["attitude"][key] == pytest.approx(_num(dump[name])), name
    json.dumps(rec.extra)  # per-frame metadata is JSON-serialisable
    temp = planck_from_metadata(meta).raw_to_temperature_c(rec.frames[0])
    assert -20 < float(np.median(temp)) < 80


def test_fff_little_endian_real_file(shared_data):
    path = _real(shared_data, "recordings", "flirpy_frame_le.fff")
    src = open_recording(path)
    assert (src.format, src.frame_shape) == ("fff", (240, 320))
    rec = src.read_all()
    meta = rec.extra["frame_metadata"][0]
    assert meta["camera_model"].startswith("FLIR T420")
    assert meta["planck"]["o"] == -5588.0 and meta["planck"]["b"] == pytest.approx(1420.1)
    temp = planck_from_metadata(meta).raw_to_temperature_c(rec.frames[0])
    assert 0 < float(temp.min()) < float(temp.max()) < 100


def test_csq_real_file(shared_data):
    path = _real(shared_data, "recordings", "thermimage_sample.csq")
    src = open_recording(path)
    assert (src.format, src.n_frames, src.frame_shape) == ("csq", 8, (768, 1024))
    chunks = list(src.iter_frames(3))
    assert [len(c) for c in chunks] == [3, 3, 2]
    time_s = np.concatenate([c.time_s for c in chunks])
    np.testing.assert_allclose(np.diff(time_s), 1 / 30, atol=0.002)
    meta = chunks[0].metadata[0]
    assert meta["camera_model"].startswith("FLIR T1030sc")
    frames = np.concatenate([c.frames for c in chunks])
    temp = planck_from_metadata(meta).raw_to_temperature_c(frames)
    assert 0 < float(np.median(temp)) < 60


def test_rjpeg_scenes_equal_flyr(shared_data):
    """Every FLIR R-JPEG of scenes/ (PNG and plain raw layouts, 8 camera models): the counts
    and constants read here give flyr's temperatures (load_scene)."""
    from thermocal.scenes.real import load_scene

    paths = sorted((shared_data / "scenes").glob("*.jpg"))
    if not paths:
        pytest.skip("no scenes in shared/data")
    for path in paths:
        rec = open_recording(path).read_all()
        meta = rec.extra["frame_metadata"][0]
        temp = planck_from_metadata(meta).raw_to_temperature_c(rec.frames[0])
        np.testing.assert_allclose(temp, load_scene(path), atol=1e-3, err_msg=path.name)


# --------------------------------------------------------------------------------------------
# synthetic FLIR files
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [">", "<"])
@pytest.mark.parametrize("codec", ["plain", "tiff", "jpegls"])
def test_fff_synthetic_both_byte_orders(tmp_path, order, codec):
    raw = _frames(1)[0]
    path = tmp_path / "one.fff"
    path.write_bytes(_fff(raw, order=order, codec=codec, gps=(-20.5, 43.25, 812.5), ms=250))
    src = open_recording(path)
    assert src.format == ("csq" if codec == "jpegls" else "fff")
    rec = src.read_all()
    np.testing.assert_array_equal(rec.frames[0], raw)
    meta = rec.extra["frame_metadata"][0]
    assert meta["planck"]["r1"] == 16000.0 and meta["planck"]["o"] == -300.0
    assert meta["planck"]["emissivity"] == pytest.approx(0.9)
    assert meta["planck"]["reflected_c"] == pytest.approx(20.0, abs=1e-4)
    assert meta["camera_model"] == "Synthetic Tau2"
    assert meta["datetime"] == "2023-11-14T23:13:20.250+01:00"
    assert meta["gps"]["latitude"] == -20.5 and meta["gps"]["longitude"] == 43.25
    assert meta["gps"]["altitude_m"] == 812.5


def test_seq_streams_records_in_order(tmp_path):
    frames = _frames(5)
    seq = b"".join(_fff(fr, epoch=1_700_000_000, ms=40 * k) for k, fr in enumerate(frames))
    path = tmp_path / "flight.seq"
    path.write_bytes(seq)
    src = open_recording(path)
    assert (src.format, src.n_frames, src.frame_shape) == ("seq", 5, (6, 8))
    chunks = list(src.iter_frames(2))
    assert [c.start for c in chunks] == [0, 2, 4]
    np.testing.assert_array_equal(np.concatenate([c.frames for c in chunks]), frames)
    np.testing.assert_allclose(np.concatenate([c.time_s for c in chunks]), 0.04 * np.arange(5))
    # a stream from frame 3 on: the frames before it dropped, numbered in the recording
    from thermocal.io.open import open_stream

    part = list(open_stream(path).stream(2, start=3))
    assert part[0][0] == 3
    np.testing.assert_array_equal(np.concatenate([c[1] for c in part]), frames[3:])
    # a SEQ whose records are separated by padding, with another name
    padded = tmp_path / "padded.bin"
    padded.write_bytes(_fff(frames[0]) + b"\x00" * 7 + _fff(frames[1]))
    assert open_recording(padded).n_frames == 2


def test_seq_truncated_last_record_is_left_out_and_named(tmp_path):
    frames = _frames(3)
    seq = b"".join(_fff(fr) for fr in frames)
    path = tmp_path / "cut.seq"
    path.write_bytes(seq[:-100])
    src = open_recording(path)
    assert src.n_frames == 2 and [w for w, _ in src.damaged] == ["2"]
    assert src.damaged[0][1].startswith("truncated")
    np.testing.assert_array_equal(src.read_all().frames, frames[:2])
    assert src.damaged_summary() == f"skipped 1 damaged frame of {path}: 2 ({src.damaged[0][1]})"
    # a single record cut short: nothing to read, one line naming the file
    one = tmp_path / "one.fff"
    one.write_bytes(_fff(frames[0])[:-100])
    with pytest.raises(FileFormatError, match=r"one\.fff: truncated") as exc:
        open_recording(one)
    _one_line(exc)


def test_csq_corrupt_frame_is_found_while_streaming(tmp_path):
    records = [_fff(fr, codec="jpegls") for fr in _frames(3)]
    bad = bytearray(records[2])
    end = bad.rfind(b"\xff\xd9")
    bad[end - 40 : end] = b"\x00" * 40  # damage the compressed image, keep the record intact
    path = tmp_path / "flight.csq"
    path.write_bytes(records[0] + records[1] + bytes(bad))
    src = open_recording(path)  # headers only: opens
    assert (src.format, src.n_frames) == ("csq", 3)
    chunks = src.iter_frames(2)
    assert len(next(chunks)) == 2
    with pytest.raises(FileFormatError, match=r"flight\.csq \(frame 2\)"):
        next(chunks)


def test_a_frame_that_does_not_decode_keeps_the_others_numbers(tmp_path, capsys):
    """A CSQ frame whose image does not decode is left out of ``read_all`` with a warning, and
    the others keep their numbers (``frame_positions``): ``estimate --pivot K`` is frame K of
    the file, as ``flight`` and ``info`` number it (it was the K-th frame that decoded: --pivot 3
    gave frame 4, and the last frame's number was refused); a pivot or burst holding the
    undecodable frame is refused, naming it."""
    import tifffile
    from cli_run import run

    frames = (_frames(6, 16, 20) // 2 + 4000).astype(np.uint16)  # counts the constants convert
    records = [_fff(fr, codec="jpegls", ms=100 * k) for k, fr in enumerate(frames)]
    bad = bytearray(records[2])
    end = bad.rfind(b"\xff\xd9")
    bad[end - 40 : end] = b"\x00" * 40
    good, damaged = tmp_path / "good.csq", tmp_path / "damaged.csq"
    good.write_bytes(b"".join(records))
    damaged.write_bytes(b"".join(records[:2]) + bytes(bad) + b"".join(records[3:]))
    rec = open_recording(damaged).read_all()
    assert rec.extra["frame_positions"] == [0, 1, 3, 4, 5] and rec.extra["frames_at_open"] == 6
    np.testing.assert_array_equal(rec.frames, frames[[0, 1, 3, 4, 5]])
    for pivot in (3, 5):
        outs = []
        for src in (good, damaged):
            out = tmp_path / f"{src.stem}{pivot}.tiff"
            code, _, err = run(["estimate", src, "--method", "camera", "--pivot", pivot,
                                "--out", out], capsys)
            assert code == 0, err
            outs.append(tifffile.imread(out))
        np.testing.assert_array_equal(*outs)
    code, _, err = run(["estimate", damaged, "--method", "camera", "--pivot", 2, "--out",
                        tmp_path / "two.tiff"], capsys)
    assert code == 2 and "frame 2 does not decode" in err and not (tmp_path / "two.tiff").exists()
    # no --pivot: the middle of the frames that decode, never refused for the damaged one
    from thermocal.estimation.commands import _burst_of

    assert _burst_of(rec, 3, None, damaged) == (slice(1, 4), 1)  # frames 1, 3, 4 of the file
    with pytest.raises(InvalidInputError, match="frame 2 of the burst 1-3 does not decode"):
        _burst_of(rec, 3, 2, damaged)
    assert _burst_of(rec, 3, 4, damaged) == (slice(2, 5), 1)  # frames 3, 4, 5: rec's 2..4


def test_rjpeg_synthetic_and_folder_series(tmp_path):
    frames = _frames(3)
    folder = tmp_path / "flight"
    folder.mkdir()
    for k, fr in enumerate(frames):
        record = _fff(fr, order="<", ms=100 * k)
        (folder / f"DJI_{k:04d}.jpg").write_bytes(_rjpeg(record, parts=3, xmp=_dji_xmp(30 + k)))
    (folder / "notes.txt").write_text("exiftool dumps and notes are skipped")
    src = open_recording(folder)
    assert (src.format, src.n_frames, src.frame_shape) == ("rjpeg-folder", 3, (6, 8))
    assert src.header["files"] == ["DJI_0000.jpg", "DJI_0001.jpg", "DJI_0002.jpg"]
    rec = src.read_all()
    np.testing.assert_array_equal(rec.frames, frames)
    assert rec.fpa_c is None  # the spot meter is a scene temperature
    assert [m["spot_c"] for m in rec.extra["frame_metadata"]] == [30.0, 31.0, 32.0]
    np.testing.assert_allclose(rec.time_s, [0.0, 0.1, 0.2])
    meta = rec.extra["frame_metadata"][1]
    assert meta["relative_altitude_m"] == 50.25 and meta["attitude"]["gimbal_pitch_deg"] == -90.0
    assert meta["source"].endswith("DJI_0001.jpg")


def test_fff_folder_series(tmp_path):
    frames = _frames(4)
    for k, fr in enumerate(frames):
        (tmp_path / f"frame_{k:06d}.fff").write_bytes(_fff(fr, order="<" if k % 2 else ">"))
    src = open_recording(tmp_path)
    assert (src.format, src.n_frames) == ("fff-folder", 4)
    np.testing.assert_array_equal(src.read_all().frames, frames)


# --------------------------------------------------------------------------------------------
# TIFF + JSON, DualTauUAV, EnvChamberCtrl
# --------------------------------------------------------------------------------------------
def test_project_tiff_recording(tmp_path):
    frames = _frames(7, seed=2)
    rec = Recording(frames, fpa_c=np.linspace(25, 26, 7), time_s=np.arange(7) / 30,
                    housing_c=np.full(7, 27.5), extra={"pivot": 3})
    write_recording(tmp_path / "rec.tiff", rec)
    src = open_recording(tmp_path / "rec.tiff")
    assert (src.format, src.n_frames, src.frame_shape, src.bit_depth) == ("tiff", 7, (6, 8), 14)
    assert src.header["extra"] == {"pivot": 3}
    chunks = list(src.iter_frames(4))
    assert [len(c) for c in chunks] == [4, 3]
    np.testing.assert_array_equal(np.concatenate([c.frames for c in chunks]), frames)
    np.testing.assert_allclose(np.concatenate([c.fpa_c for c in chunks]), rec.fpa_c)
    assert chunks[1].metadata[0]["housing_c"] == 27.5
    back = src.read_all()
    np.testing.assert_array_equal(back.time_s, rec.time_s)


def _dualtau_file(path: Path, frames: np.ndarray, fpa_centi: np.ndarray, t0_ns: int) -> None:
    n = len(frames)
    start = t0_ns + np.arange(n, dtype=np.int64) * 100_000_000  # 10 Hz
    np.savez(path, frames=frames, fpa=fpa_centi.astype(np.uint16), time_ns_start=start,
             time_ns_end=start + 50_000_000)


def test_dualtau_folder_in_time_order_with_fpa_interpolated(tmp_path):
    frames = _frames(12, seed=3)
    # the rig repeats its last reading (0.1 °C steps) on every frame; readings at t = 0 and 0.6 s
    held = np.array([3010] * 6 + [3020] * 6)
    t0 = 1_700_000_000_000_000_000
    # file names out of time order: the reader sorts by the first time stamp
    _dualtau_file(tmp_path / "b.npz", frames[:4], held[:4], t0)
    _dualtau_file(tmp_path / "a.npz", frames[4:8], held[4:8], t0 + 400_000_000)
    _dualtau_file(tmp_path / "c.npz", frames[8:], held[8:], t0 + 800_000_000)
    src = open_recording(tmp_path)
    assert (src.format, src.n_frames, src.frame_shape, src.fpa_resolution_c) == (
        "dualtau", 12, (6, 8), 0.1)
    assert src.header["files"] == ["b.npz", "a.npz", "c.npz"]
    rec = src.read_all()
    np.testing.assert_array_equal(rec.frames, frames)
    np.testing.assert_allclose(rec.time_s, np.arange(12) / 10)
    expected = np.r_[30.1 + 0.1 * np.arange(7) / 6, np.full(5, 30.2)]
    np.testing.assert_allclose(rec.fpa_c, expected, atol=1e-9)
    assert rec.extra["fpa_measured"] == [True] + [False] * 5 + [True] + [False] * 5
    # one file on its own is a (short) flight
    one = open_recording(tmp_path / "a.npz")
    assert (one.format, one.n_frames) == ("dualtau", 4)


def test_interpolate_fpa_readings_holds_a_constant_series():
    fpa, measured = interpolate_fpa_readings(np.arange(4.0), np.full(4, 31.0))
    assert fpa.tolist() == [31.0] * 4 and measured.tolist() == [True, False, False, False]


def test_envchamberctrl_npz(tmp_path):
    frames = _frames(5, seed=4)
    path = tmp_path / "session.npz"
    np.savez(path, frames=frames, fpa=np.full(5, 2534, np.uint16),
             housing=np.full(5, 2600, np.uint16), blackbody=np.arange(5, dtype=np.uint16) * 500,
             time_ns=np.arange(5, dtype=np.int64) * 10**9)
    src = open_recording(path)
    assert (src.format, src.n_frames) == ("envchamberctrl", 5)
    rec = src.read_all()
    session = import_envchamberctrl_npz(path)
    np.testing.assert_array_equal(rec.frames, session.frames)
    np.testing.assert_allclose(rec.fpa_c, 25.34)
    assert [m["blackbody_c"] for m in rec.extra["frame_metadata"]] == [0, 5, 10, 15, 20]


# --------------------------------------------------------------------------------------------
# bad input: one line naming the file
# --------------------------------------------------------------------------------------------
def _one_line(exc: pytest.ExceptionInfo) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_jpeg_without_flir_records(tmp_path):
    path = tmp_path / "photo.jpg"
    Image.new("RGB", (8, 8)).save(path, "JPEG")
    with pytest.raises(FileFormatError, match="no FLIR APP1") as exc:
        open_recording(path)
    assert "photo.jpg" in _one_line(exc)


def test_rjpeg_missing_segment_and_corrupt_record(tmp_path):
    record = _fff(_frames(1)[0])
    data = _rjpeg(record, parts=3)
    # drop the second FLIR segment
    start = data.find(b"FLIR\x00\x01\x01") - 4
    (length,) = struct.unpack(">H", data[start + 2 : start + 4])
    path = tmp_path / "cut.jpg"
    path.write_bytes(data[:start] + data[start + 2 + length :])
    with pytest.raises(FileFormatError, match=r"cut\.jpg: truncated R-JPEG"):
        open_recording(path)
    bad = tmp_path / "bad.fff"
    bad.write_bytes(b"FFF\x00" + b"\xff" * 60)
    with pytest.raises(FileFormatError, match=r"bad\.fff: unsupported FFF version"):
        open_recording(bad)
    with pytest.raises(FileFormatError, match="no raw data record"):
        parse_fff_record(record[:64] + b"\x00" * (len(record) - 64), "zeros.fff")


def test_folders_mixed_empty_and_of_mixed_sizes(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileFormatError, match="no recording in the folder"):
        open_recording(empty)
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    (mixed / "a.fff").write_bytes(_fff(_frames(1)[0]))
    (mixed / "b.jpg").write_bytes(_rjpeg(_fff(_frames(1)[0])))
    with pytest.raises(FileFormatError, match="mixed formats") as exc:
        open_recording(mixed)
    _one_line(exc)
    sizes = tmp_path / "sizes"
    sizes.mkdir()
    (sizes / "a.fff").write_bytes(_fff(_frames(1)[0]))
    (sizes / "b.fff").write_bytes(_fff(_frames(1, 4, 4)[0]))
    with pytest.raises(FileFormatError, match=r"b\.fff: frames of 4x4 in a folder of 8x6"):
        open_recording(sizes)
    npz = tmp_path / "npz"
    npz.mkdir()
    _dualtau_file(npz / "a.npz", _frames(2), np.full(2, 3000), 0)
    _dualtau_file(npz / "b.npz", _frames(2, 4, 4), np.full(2, 3000), 10**9)
    with pytest.raises(FileFormatError, match=r"b\.npz: frames of 4x4 in a flight of 8x6"):
        open_recording(npz)


def test_unknown_missing_and_bad_chunk(tmp_path):
    with pytest.raises(FileFormatError, match="no such file"):
        open_recording(tmp_path / "absent.seq")
    (tmp_path / "x.bin").write_bytes(b"hello world")
    with pytest.raises(FileFormatError, match=r"x\.bin: unknown recording format"):
        open_recording(tmp_path / "x.bin")
    np.savez(tmp_path / "other.npz", values=np.arange(3))
    with pytest.raises(FileFormatError, match="without 'frames'"):
        open_recording(tmp_path / "other.npz")
    np.savez(tmp_path / "nofpa.npz", frames=_frames(2))
    with pytest.raises(FileFormatError, match=r"nofpa\.npz: missing array"):
        open_recording(tmp_path / "nofpa.npz")
    (tmp_path / "f.fff").write_bytes(_fff(_frames(1)[0]))
    with pytest.raises(InvalidInputError, match="chunk"):
        open_recording(tmp_path / "f.fff").iter_frames(0)


def test_formats_listed():
    assert set(FORMATS) == {"tiff", "fff", "seq", "csq", "rjpeg", "fff-folder", "rjpeg-folder",
                            "dualtau", "envchamberctrl"}


def test_the_package_gives_the_one_way_in():
    import thermocal.io
    from thermocal.io.open import open_recording

    assert thermocal.io.open_recording is open_recording
    with pytest.raises(AttributeError):
        _ = thermocal.io.no_such_reader


def test_info_says_what_a_recording_holds(shared_data, tmp_path, capsys):
    """``thermocal info``: format, frames, size, FPA, GPS and the Planck constants, as the
    file's exiftool dump has them; one line and exit 2 for what it cannot read."""
    from cli_run import run

    dji = _real(shared_data, "recordings", "dji_xtr_tau2.jpg")
    code, out, err = run(["info", dji], capsys)
    assert code == 0, err
    dump = _dump(dji.with_suffix(".txt"))
    assert "rjpeg, 1 frame(s) of 640x512" in out and "GPS in 1 of 1 frames" in out
    assert "attitude in 1" in out and "camera model: DJI FLIR" in out
    assert f"R1 {_num(dump['Planck R1']):g}" in out and "no FPA temperature" in out
    assert "spot meter (the centre pixels' temperature, whole °C; FLIR:CentralTemperature) " \
           "26…26 °C in 1 of 1 frames" in out
    code, out, err = run(["info", tmp_path / "nothing.seq"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "no such file" in err


def test_info_says_what_a_chamber_session_holds(tmp_path, capsys):
    """`thermocal info` of a chamber session: its frames, set points, FPA range, time span and
    camera, from the file's series (it refused it as "not a recording", though it reads an
    EnvChamberCtrl .npz: a helper's audit)."""
    from cli_run import run

    assert run(["simulate", "chamber", tmp_path / "c.h5", "--size", "16x12", "--preset", "boson",
                "--unit", "7", "--blackbody-c", "10:40:10", "--frames-per-point", "2"],
               capsys)[0] == 0
    code, out, err = run(["info", tmp_path / "c.h5"], capsys)
    assert code == 0, err
    assert "a chamber session (HDF5)" in out and "of 16x12, 14-bit" in out
    assert "blackbody 10…40 °C at 4 set point(s)" in out and "camera: preset boson, unit 7" in out


def test_info_warns_of_counts_beyond_the_bit_depth(tmp_path, capsys):
    """A DualTau flight of 16-bit counts (the rig's format says 14): ``info`` still describes
    it but warns, naming the first such frame and the largest count (the other commands refuse
    it); a flight within 14 bits gets no warning."""
    from cli_run import run

    frames = _frames(6, seed=4)
    t0 = 1_700_000_000_000_000_000
    _dualtau_file(tmp_path / "a.npz", frames[:3], np.full(3, 3010), t0)
    code, out, err = run(["info", tmp_path], capsys)
    assert code == 0 and "14-bit" in out and "warning" not in err
    frames[4, 2, 3] = 40_000
    _dualtau_file(tmp_path / "b.npz", frames[3:], np.full(3, 3010), t0 + 300_000_000)
    code, out, err = run(["info", tmp_path], capsys)
    assert code == 0 and "14-bit" in out
    assert "counts reach 40000, beyond 14-bit (from frame 4)" in err
    from thermocal.io.open import read_any_recording

    with pytest.raises(ThermocalError, match="frame 4"):  # what the other commands read with
        read_any_recording(tmp_path)


def test_the_commands_read_any_format(shared_data):
    """The commands' reader (``read_any_recording``) reads a FLIR file through the one way in;
    its ``--fpa-c`` replaces the file's FPA series."""
    from thermocal.io.open import read_any_recording as read_recording

    fff = _real(shared_data, "recordings", "flirpy_frame_le.fff")
    rec = read_recording(fff, fpa_c=31.0)
    assert rec.frames.shape == (1, 240, 320) and rec.frames.dtype == np.uint16
    assert rec.fpa_c.tolist() == [31.0]
    with pytest.raises(InvalidInputError):
        read_recording(fff, fpa_c=1e6)


@pytest.mark.parametrize(("parts", "dump"), [
    (("recordings", "dji_xtr_tau2.jpg"), ("recordings", "dji_xtr_tau2.txt")),
    (("flirpy", "frame_000000.fff"), ("flirpy", "frame_000000.txt")),
])
def test_method_camera_is_the_flir_formula_by_hand(shared_data, tmp_path, capsys, parts, dump):
    """``--method camera``: the temperatures of the FLIR formula with the constants of the
    file's exiftool dump, applied by hand to the raw counts, to 0.01 °C; σ is the vendor's
    stated accuracy as 2σ: both files are of Tau2 cameras (a DJI XT-R, a FLIR Duo Pro R),
    ±5 °C or 5 % of the reading (the Duo Pro R was given FLIR's ±2 °C before)."""
    import tifffile
    from cli_run import run

    path = _real(shared_data, *parts)
    planck = FlirPlanck.from_exiftool_text(_real(shared_data, *dump))
    raw = open_recording(path).read_all().frames[0].astype(np.float64)
    by_hand = planck.raw_to_temperature_c(raw)
    out, sig = tmp_path / "t.tiff", tmp_path / "s.tiff"
    code, _, err = run(["estimate", path, "--method", "camera", "--out", out, "--sigma-out", sig],
                       capsys)
    assert code == 0, err
    temps = tifffile.imread(out)
    assert float(np.abs(temps - by_hand).max()) < 0.01
    sigma = tifffile.imread(sig)
    assert sigma.shape == temps.shape
    np.testing.assert_allclose(sigma, np.maximum(5.0, 0.05 * np.abs(temps)) / 2, rtol=1e-6)


@pytest.mark.parametrize(("parts", "dump"), [
    (("recordings", "dji_xtr_tau2.jpg"), ("recordings", "dji_xtr_tau2.txt")),
    (("flirpy", "frame_000000.fff"), ("flirpy", "frame_000000.txt")),
])
def test_the_measuring_range_is_the_exiftool_dumps(shared_data, parts, dump):
    """The camera's measuring range (camera-info record, K at 0x94 and 0x90) is exiftool's
    Camera Temperature Range Min and Max."""
    import re

    text = _real(shared_data, *dump).read_text(encoding="utf-8", errors="replace")
    want = [float(re.search(rf"Camera Temperature Range {k}\s*:\s*(-?[\d.]+) C", text).group(1))
            for k in ("Min", "Max")]
    meta = open_recording(_real(shared_data, *parts)).read_all().extra["frame_metadata"][0]
    assert meta["temperature_range_c"] == pytest.approx(want, abs=1e-3)


def test_method_camera_is_held_to_the_measuring_range(shared_data, tmp_path, capsys):
    """The stated accuracy holds within the measuring range the file states: a damaged DJI
    frame whose pixels read up to hundreds of °C (σ of a few degrees before: a helper's audit)
    keeps them, σ grown by the distance beyond the range, and says so; a scene beyond the range
    (its 1st–99th percentile) is outside, refused unless forced."""
    import tifffile
    from cli_run import run

    from thermocal.estimation.vendor import VendorCalibration

    raw = bytearray(_real(shared_data, "recordings", "dji_xtr_tau2.jpg").read_bytes())
    raw[200000:202000] = np.random.default_rng(1).integers(0, 256, 2000, np.uint8).tobytes()
    (tmp_path / "c.jpg").write_bytes(bytes(raw))
    out, sig = tmp_path / "t.tiff", tmp_path / "s.tiff"
    code, _, err = run(["estimate", tmp_path / "c.jpg", "--method", "camera", "--out", out,
                        "--sigma-out", sig], capsys)
    assert code == 0 and "beyond the camera's measuring range -25…135 °C" in err, err
    temps, sigma = tifffile.imread(out), tifffile.imread(sig)
    beyond = np.maximum(-25.0 - temps, 0) + np.maximum(temps - 135.0, 0)
    assert beyond.max() > 100.0
    np.testing.assert_allclose(sigma, np.maximum(5.0, 0.05 * np.abs(temps)) / 2 + beyond,
                               rtol=1e-5)
    planck = FlirPlanck.from_exiftool_text(_real(shared_data, "recordings", "dji_xtr_tau2.txt"))
    vendor = VendorCalibration([planck], [(5.0, 0.05)], [(-25.0, 20.0)])
    why = vendor.outside(temps[None], None)
    assert len(why) == 1 and "beyond the camera's measuring range -25…20 °C" in why[0]
    assert VendorCalibration([planck], [(5.0, 0.05)]).outside(temps[None], None) == ()


def test_method_camera_forced_beyond_the_measuring_range(tmp_path, capsys):
    """A scene beyond the range its file states is refused, the remedy naming --force; forced,
    it is written with σ the stated accuracy's plus the distance beyond the range (--force had
    been refused for ``--method camera``: "no domain to force")."""
    import tifffile
    from cli_run import run

    frame = (9000 + np.random.default_rng(0).integers(0, 50, (32, 48))).astype(np.uint16)
    records = [fff_record(frame, planck=FlirPlanck(16000.0, 0.02, 1430.0, 1.0, -300,
                                                   emissivity=0.9, distance_m=10.0),
                          time_epoch_s=1.7e9 + 0.033 * k, model="Synthetic Tau2",
                          range_c=(-25.0, 20.0)) for k in range(3)]
    (tmp_path / "f.seq").write_bytes(b"".join(records))
    out, sig = tmp_path / "t.tiff", tmp_path / "s.tiff"
    args = ["estimate", tmp_path / "f.seq", "--method", "camera", "--out", out, "--sigma-out",
            sig]
    code, _, err = run(args, capsys)
    assert code == 2 and "beyond the camera's measuring range -25…20 °C" in err, err
    assert "--force gives them with σ grown" in err and not out.exists() and not sig.exists()
    code, _, err = run([*args, "--force"], capsys)
    assert code == 0, err
    temps, sigma = tifffile.imread(out), tifffile.imread(sig)
    assert temps.min() > 40.0
    np.testing.assert_allclose(sigma, np.maximum(5.0, 0.05 * temps) / 2 + (temps - 20.0),
                               rtol=1e-5)


def test_method_camera_refuses_a_recording_without_constants(tmp_path, capsys):
    from cli_run import run

    path, _ = write_recording(tmp_path / "r.tiff", Recording(np.full((3, 8, 8), 5000, np.uint16)))
    code, _, err = run(["estimate", path, "--method", "camera", "--out", tmp_path / "t.tiff"],
                       capsys)
    assert code == 2 and "Planck constants" in err and not (tmp_path / "t.tiff").exists()


def test_method_camera_refuses_a_frame_of_many_counts_without_a_temperature(tmp_path, capsys):
    """More than 0.1 % of a frame's pixels at counts its file's constants give no temperature
    are not dead pixels (a damaged frame, or constants not the camera's): refused in words a
    user can act on (it said "mask dead pixels before converting", the library's)."""
    from cli_run import run

    frame = np.full((32, 48), 9000, np.uint16)
    frame[:2] = 1  # 6 % of the pixels, below the constants' zero kelvin
    (tmp_path / "f.seq").write_bytes(b"".join(_fff(frame, ms=33 * k) for k in range(3)))
    code, _, err = run(["estimate", tmp_path / "f.seq", "--method", "camera", "--out",
                        tmp_path / "t.tiff"], capsys)
    assert code == 2 and "96 pixel(s) (6.2 %) of a frame" in err, err
    assert "constants that are not this camera's" in err and "mask" not in err
    assert not (tmp_path / "t.tiff").exists()


@pytest.mark.parametrize(("model", "filled"), [("Synthetic Tau2", True),
                                              ("FLIR T1030sc", False)])
def test_method_camera_fills_a_saturated_cores_defects_and_refuses_its_saturated_objects(
        tmp_path, capsys, model, filled):
    """A radiometric core's counts are 14-bit: a pixel alone at 16,383 is a saturated defect
    that says nothing of the scene (it read 125 °C with σ 3 where the scene was 32-39 °C: a
    helper's audit), filled from its neighbours with a warning, as a dead one at 0 is; a group
    of them is a scene beyond the sensor's range, a lower bound: outside, refused, and forced,
    its σ grows by SATURATED_SIGMA_C (filled, it had read as its surroundings: a review). A
    FLIR camera's 16-bit counts reach 16,383 in a warm scene, where the count is a
    temperature."""
    import tifffile
    from cli_run import run

    from thermocal.estimation.vendor import SATURATED_SIGMA_C
    from thermocal.io.fff import flir_bit_depth

    frame = (9000 + np.random.default_rng(0).integers(0, 40, (32, 48))).astype(np.uint16)
    frame[10, 20] = frame[25, 40] = 16383
    frame[5, 5] = 0

    def write(name, fr):
        (tmp_path / name).write_bytes(b"".join(_fff(fr, ms=33 * k, model=model)
                                               for k in range(3)))
        return tmp_path / name

    meta = open_recording(write("f.seq", frame)).read_all().extra["frame_metadata"][0]
    assert flir_bit_depth(meta) == (14 if filled else 16)
    out, sig = tmp_path / "t.tiff", tmp_path / "s.tiff"
    code, _, err = run(["estimate", tmp_path / "f.seq", "--method", "camera", "--out", out,
                        "--sigma-out", sig], capsys)
    assert code == 0, err
    temps = tifffile.imread(out)
    if not filled:  # 0 has no temperature; 16,383 is a warm pixel of a 16-bit camera
        assert "1 pixel(s) of a frame dead or saturated alone" in err, err
        assert temps[10, 20] > np.median(temps) + 20
        return
    assert "3 pixel(s) of a frame dead or saturated alone" in err, err
    assert abs(temps[10, 20] - np.median(temps)) < 0.5 and abs(temps[5, 5] - np.median(temps)) < 0.5
    frame[20:24, 10:14] = 16383  # a saturated object: 16 touching pixels
    write("g.seq", frame)
    args = ["estimate", tmp_path / "g.seq", "--method", "camera", "--out", tmp_path / "u.tiff",
            "--sigma-out", tmp_path / "v.tiff"]
    code, _, err = run(args, capsys)
    assert code == 2 and "16 pixel(s) saturated in groups" in err and "--force" in err, err
    code, _, err = run([*args, "--force"], capsys)
    assert code == 0, err
    sigma = tifffile.imread(tmp_path / "v.tiff")
    assert sigma[20:24, 10:14].min() >= SATURATED_SIGMA_C and np.median(sigma) < 10


def test_flight_runs_on_a_seq(tmp_path):
    """``thermocal flight`` streams a SEQ as it streams the project's TIFF: the same maps from
    the same frames (FPA from ``--fpa-c``; a SEQ has none)."""
    import tifffile

    from thermocal.calibration.report import fit_with_report
    from thermocal.camera.presets import make_camera
    from thermocal.pipeline.flight import FlightOptions, process_flight
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
    from thermocal.simulate.flight import simulate_flight

    camera = make_camera("tau2", unit=2, size=(48, 32))
    plan = ChamberPlan(setpoints_c=(10.0, 20.0, 30.0, 40.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(20.0, 30.0), rate_c_per_min=0.25,
                       interval_s=20.0)
    write_simulated_chamber(tmp_path / "c.h5", camera, plan, seed=1)
    cal, report = fit_with_report(tmp_path / "c.h5", "polynomial", frames="settled")
    cal.save(tmp_path / "cal.h5")
    fpa = round(0.5 * sum(report.fpa_range_c), 2)
    scene = 22.0 + 6.0 * np.random.default_rng(4).random((64, 64))
    fl = simulate_flight(scene, camera, n_frames=6, motion="walk", fpa_c=fpa, seed=4)
    (tmp_path / "f.seq").write_bytes(b"".join(_fff(fr, ms=33 * k) for k, fr in
                                              enumerate(fl.frames)))
    write_recording(tmp_path / "f.tiff", Recording(fl.frames, fpa_c=np.full(6, fpa)))
    options = FlightOptions(method="calibration", calibration=str(tmp_path / "cal.h5"),
                            frames=3, stride=3, fpa_c=fpa, preview_every=0)
    maps = {}
    for name in ("f.seq", "f.tiff"):
        out = tmp_path / f"out_{name}"
        summary = process_flight(tmp_path / name, out, options)
        assert summary["processed"] == 2, summary
        maps[name] = sorted((out / "temps").glob("frame_*.tiff"))
    assert [p.name for p in maps["f.seq"]] == [p.name for p in maps["f.tiff"]]
    for a, b in zip(maps["f.seq"], maps["f.tiff"], strict=True):  # the SEQ's maps also keep
        np.testing.assert_array_equal(read_temperature_tiff(a), read_temperature_tiff(b))
        with tifffile.TiffFile(a) as tif:  # the camera's model and time (EXIF)
            assert tif.pages[0].tags["Model"].value == "Synthetic Tau2"


def test_flight_method_camera_uses_each_frames_constants(tmp_path):
    """``thermocal flight --method camera`` on a SEQ whose frames carry different constants:
    each pivot's map is its own frame through its own constants (the FLIR formula by hand)."""
    import tifffile

    from thermocal.pipeline.flight import FlightOptions, process_flight

    frames = _frames(6, h=40, w=48, seed=3) + 9000
    r1s = [15000.0 + 500.0 * k for k in range(6)]
    (tmp_path / "f.seq").write_bytes(b"".join(
        _fff(fr, r1=r1, ms=33 * k) for k, (fr, r1) in enumerate(zip(frames, r1s, strict=True))))
    options = FlightOptions(method="camera", frames=1, stride=2, preview_every=0)
    summary = process_flight(tmp_path / "f.seq", tmp_path / "out", options)
    assert summary["processed"] == 3, summary
    for pivot in (0, 2, 4):
        got = tifffile.imread(tmp_path / "out" / "temps" / f"frame_{pivot:06d}.tiff")
        src = open_recording(tmp_path / "f.seq")
        meta = next(m for c in src.iter_frames() for m in c.metadata if m["index"] == pivot)
        planck = planck_from_metadata(meta)
        assert planck.r1 == pytest.approx(r1s[pivot])  # each frame its own constants
        by_hand = planck.raw_to_temperature_c(frames[pivot].astype(np.float64))
        assert float(np.abs(got - by_hand).max()) < 0.01
        assert (tmp_path / "out" / "temps" / f"frame_{pivot:06d}_sigma.tiff").exists()
    with pytest.raises(InvalidInputError, match="Planck constants"):
        write_recording(tmp_path / "r.tiff", Recording(frames.astype(np.uint16), bit_depth=16))
        process_flight(tmp_path / "r.tiff", tmp_path / "out2", options)


def test_a_damaged_exif_is_one_warning_naming_the_file(shared_data, tmp_path, capsys):
    """Bytes 252–3151 of the DJI R-JPEG inverted (its EXIF IFDs): Pillow warned per tag, three
    unattributed lines; now one naming the file, and the frame is still read."""
    from cli_run import run

    data = bytearray(_real(shared_data, "recordings", "dji_xtr_tau2.jpg").read_bytes())
    data[252:3152] = bytes(b ^ 0xFF for b in data[252:3152])
    (tmp_path / "dmg.jpg").write_bytes(bytes(data))
    code, out, err = run(["info", tmp_path / "dmg.jpg"], capsys)
    assert code == 0 and "1 frame(s) of 640x512" in out
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "dmg.jpg: damaged EXIF" in lines[0], err


def test_a_flir_file_renamed_tiff_is_read_by_its_content(shared_data, tmp_path, capsys):
    """A DJI R-JPEG renamed ``.tif`` is read as the R-JPEG it is (it was "not a readable
    TIFF"), the same frames as under its own name; an HDF5 file given as a recording says
    what it is."""
    from cli_run import run

    from thermocal.io.open import read_any_recording

    dji = _real(shared_data, "recordings", "dji_xtr_tau2.jpg")
    renamed = tmp_path / "i.tif"
    renamed.write_bytes(dji.read_bytes())
    np.testing.assert_array_equal(read_any_recording(renamed).frames,
                                  read_any_recording(dji).frames)
    (tmp_path / "c.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(64))
    code, _, err = run(["info", tmp_path / "c.h5"], capsys)
    assert code == 2 and "an HDF5 file" in err and "thermocal calibrate" in err
