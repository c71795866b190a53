"""Tests for thermocal.simulate.formats: a simulated recording written in every camera format
reads back through open_recording with the same counts, FPA (to its resolution), times, GPS and
Planck constants."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.io.fff import planck_from_metadata
from thermocal.io.open import open_recording
from thermocal.io.recording import Recording
from thermocal.radiometry import FlirPlanck
from thermocal.simulate.formats import (
    DEFAULT_PLANCK,
    DEFAULT_START_EPOCH_S,
    WRITE_FORMATS,
    check_output_path,
    gps_line,
    write_chunks_as,
    write_recording_as,
)

N, H, W = 12, 24, 32
PLANCK = FlirPlanck(16384.0, 0.0625, 1430.5, 1.0, -300.0, emissivity=0.9, distance_m=12.0,
                    reflected_c=21.0, atmosphere_c=18.0, humidity=0.4)
LINE = ((-20.2328, -43.4914, 863.5), (-20.2310, -43.4890, 870.0))
#: (format, file or folder name, format open_recording reports)
CASES = [("tiff", "rec.tiff", "tiff"), ("seq", "rec.seq", "seq"), ("csq", "rec.csq", "csq"),
         ("fff", "rec", "fff-folder"), ("rjpeg", "rec", "rjpeg-folder"),
         ("dji-rjpeg", "rec", "rjpeg-folder"), ("dualtau", "rec", "dualtau")]
FLIR = ("seq", "csq", "fff", "rjpeg", "dji-rjpeg")


def _recording(fps: float = 30.0) -> Recording:
    rng = np.random.default_rng(7)
    frames = rng.integers(0, 1 << 14, (N, H, W)).astype(np.uint16)
    frames[0, 0, 0], frames[0, 0, 1] = 0, (1 << 14) - 1  # the extremes survive
    time_s = np.arange(N) / fps
    fpa_c = 31.0 + 0.37 * np.arange(N) / N + rng.normal(0, 0.01, N)
    return Recording(frames, fpa_c=fpa_c, time_s=time_s)


def _snapshot(rec: Recording) -> tuple[bytes, bytes, bytes]:
    return rec.frames.tobytes(), rec.fpa_c.tobytes(), rec.time_s.tobytes()


@pytest.mark.parametrize(("fmt", "name", "reported"), CASES)
def test_round_trip(tmp_path, fmt, name, reported):
    rec = _recording()
    before = _snapshot(rec)
    gps = gps_line(*LINE, N) if fmt in FLIR else None
    out = write_recording_as(rec, tmp_path / name, format=fmt, planck=PLANCK, gps=gps,
                             ground_altitude_m=850.0 if gps is not None else None)
    assert _snapshot(rec) == before  # the input is not changed
    src = open_recording(out)
    assert (src.format, src.n_frames, src.frame_shape) == (reported, N, (H, W))
    back = src.read_all()
    np.testing.assert_array_equal(back.frames, rec.frames)
    # times: the FLIR clock has ms resolution, DualTauUAV ns
    np.testing.assert_allclose(back.time_s, rec.time_s, atol=0.5e-3 if fmt in FLIR else 1e-9)
    if fmt in FLIR:
        assert back.fpa_c is None  # the camera has no place for it
    elif fmt == "dualtau":  # one reading (12 frames < 30 s), rounded to 0.1 °C, held
        assert src.fpa_resolution_c == 0.1
        np.testing.assert_allclose(back.fpa_c, round(rec.fpa_c[0], 1), atol=1e-9)
        assert back.extra["fpa_measured"] == [True] + [False] * (N - 1)
    else:
        np.testing.assert_array_equal(back.fpa_c, rec.fpa_c)
    if fmt not in FLIR:
        return
    metas = back.extra["frame_metadata"]
    for meta, (lat, lon, alt), t, frame in zip(metas, gps, rec.time_s, rec.frames, strict=True):
        planck = planck_from_metadata(meta)
        for key in ("r1", "r2", "b", "f", "o"):  # float32-exact constants: equal
            assert getattr(planck, key) == getattr(PLANCK, key), key
        for fld in dataclasses.fields(PLANCK):  # the others to float32 precision
            assert getattr(planck, fld.name) == pytest.approx(getattr(PLANCK, fld.name),
                                                              rel=1e-6, abs=1e-5), fld.name
        assert meta["time_epoch_s"] == pytest.approx(DEFAULT_START_EPOCH_S + t, abs=0.5e-3)
        g = meta["gps"]
        assert g["latitude"] == pytest.approx(lat, abs=1e-7)  # EXIF: 1e-4 arc-s
        assert g["longitude"] == pytest.approx(lon, abs=1e-7)
        assert g["altitude_m"] == pytest.approx(alt, abs=1e-3)
        if fmt == "dji-rjpeg":
            assert (meta["make"], meta["model"], meta["creator"]) == ("DJI", "FLIR", "ATAU_RBFO")
            assert meta["absolute_altitude_m"] == pytest.approx(alt, abs=1e-5)
            assert meta["relative_altitude_m"] == pytest.approx(alt - 850.0, abs=1e-5)
            assert meta["attitude"]["gimbal_pitch_deg"] == -90.0
            # the spot meter: the camera's own reading of the 4x4 centre pixels, whole °C
            centre = frame[H // 2 - 2 : H // 2 + 2, W // 2 - 2 : W // 2 + 2].astype(float)
            assert meta["spot_c"] == round(PLANCK.raw_to_temperature_c(centre.mean()))
        else:
            assert 0.0 <= g["track_deg"] < 360.0
            assert meta["frame_rate_hz"] == 30


def test_a_dji_frame_of_counts_the_constants_cannot_read_has_no_spot_meter(tmp_path):
    """The DJI writer's spot meter: none where the camera's constants give the centre's counts
    no temperature (a dead frame; the writer failed on it), the centre of a frame under 4 px
    from its own pixels."""
    frames = np.full((3, 16, 16), 9000, np.uint16)
    frames[1] = 0  # below a 0 K blackbody's counts
    frames[2, 6:10, 6:10] = 12000  # the centre 4x4 alone
    out = write_recording_as(Recording(frames), tmp_path / "dji", format="dji-rjpeg",
                             planck=PLANCK)
    metas = open_recording(out).read_all().extra["frame_metadata"]
    assert "spot_c" not in metas[1]
    assert metas[0]["spot_c"] == round(PLANCK.raw_to_temperature_c(9000.0))
    assert metas[2]["spot_c"] == round(PLANCK.raw_to_temperature_c(12000.0))
    tiny = np.full((2, 3, 3), 9000, np.uint16)
    tiny[:, 0, 0] = 15000
    out = write_recording_as(Recording(tiny), tmp_path / "tiny", format="dji-rjpeg",
                             planck=PLANCK)
    spot = open_recording(out).read_all().extra["frame_metadata"][0]["spot_c"]
    assert spot == round(PLANCK.raw_to_temperature_c((15000 + 8 * 9000) / 9))


def test_headings_follow_the_line(tmp_path):
    rec = _recording()
    out = write_recording_as(rec, tmp_path / "rec.seq", format="seq",
                             gps=gps_line((0.0, 0.0, 100.0), (0.001, 0.001, 100.0), N))
    metas = open_recording(out).read_all().extra["frame_metadata"]
    assert [m["gps"]["track_deg"] for m in metas] == pytest.approx([45.0] * N, abs=0.01)


def test_little_endian_fff_and_default_planck(tmp_path):
    rec = _recording()
    out = write_recording_as(rec, tmp_path / "le", format="fff", byte_order="<")
    assert (out / "frame_000000.fff").read_bytes()[0x14:0x18] == b"d\x00\x00\x00"
    back = open_recording(out).read_all()
    np.testing.assert_array_equal(back.frames, rec.frames)
    planck = planck_from_metadata(back.extra["frame_metadata"][0])
    assert (planck.r1, planck.r2, planck.b, planck.f, planck.o) == (
        DEFAULT_PLANCK.r1, DEFAULT_PLANCK.r2, DEFAULT_PLANCK.b, DEFAULT_PLANCK.f, DEFAULT_PLANCK.o)
    assert back.extra["frame_metadata"][0]["gps"] is None


def test_dualtau_files_every_2_s_and_fpa_every_30_s(tmp_path):
    """65 s at 2 Hz: one file per 2 s, FPA readings at 0, 30 and 60 s."""
    n, fps = 130, 2.0
    rng = np.random.default_rng(1)
    fpa = 25.0 + 0.05 * np.arange(n)  # warming 0.1 °C/s
    rec = Recording(rng.integers(0, 1 << 14, (n, 4, 6)).astype(np.uint16), fpa_c=fpa,
                    time_s=np.arange(n) / fps)
    out = write_recording_as(rec, tmp_path / "flight", format="dualtau")
    files = sorted(out.glob("*.npz"))
    assert len(files) == 33
    with np.load(files[0]) as z:
        assert sorted(z.files) == ["fpa", "frames", "time_ns_end", "time_ns_start"]
        assert z["frames"].shape == (4, 4, 6) and z["fpa"].dtype == np.uint16
        assert (z["time_ns_end"] - z["time_ns_start"] == 500_000_000).all()
    src = open_recording(out)
    back = src.read_all()
    np.testing.assert_array_equal(back.frames, rec.frames)
    assert src.header["fpa_readings"] == 3
    readings = np.flatnonzero(back.extra["fpa_measured"])
    np.testing.assert_array_equal(readings, [0, 60, 120])
    np.testing.assert_allclose(back.fpa_c[readings], np.round(fpa[readings], 1), atol=1e-9)


def test_chunks_stream_the_same_bytes_as_a_whole_recording(tmp_path):
    rec = _recording()
    gps = gps_line(*LINE, N)
    write_recording_as(rec, tmp_path / "whole.csq", format="csq", gps=gps)
    pieces = [Recording(rec.frames[s], fpa_c=rec.fpa_c[s], time_s=rec.time_s[s])
              for s in (slice(0, 5), slice(5, 6), slice(6, N))]
    assert write_chunks_as(pieces, tmp_path / "parts.csq", format="csq", gps=gps,
                           n_frames=N) == N
    assert (tmp_path / "whole.csq").read_bytes() == (tmp_path / "parts.csq").read_bytes()


@pytest.mark.parametrize(("fmt", "name", "match"), [
    ("mp4", "rec.mp4", "unknown format"),
    ("seq", "rec", "named \\*.seq"),
    ("csq", "rec.seq", "named \\*.csq"),
    ("fff", "rec.seq", "is a folder, not a .seq file"),
    ("dualtau", "rec.npz", "is a folder"),
    ("rjpeg", "missing/rec", "does not exist"),
])
def test_wrong_output_paths_are_refused_before_writing(tmp_path, fmt, name, match):
    with pytest.raises(InvalidInputError, match=match):
        write_recording_as(_recording(), tmp_path / name, format=fmt)
    assert list(tmp_path.iterdir()) == []


def test_refusals(tmp_path):
    rec = _recording()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    with pytest.raises(InvalidInputError, match="not empty"):
        check_output_path(tmp_path / "full", format="fff")
    with pytest.raises(InvalidInputError, match="no place for GPS"):
        write_recording_as(rec, tmp_path / "d", format="dualtau", gps=gps_line(*LINE, N))
    with pytest.raises(InvalidInputError, match="shape"):
        write_recording_as(rec, tmp_path / "r.seq", format="seq", gps=gps_line(*LINE, N - 1))
    with pytest.raises(InvalidInputError, match="needs the FPA"):
        write_recording_as(Recording(rec.frames), tmp_path / "d", format="dualtau")
    with pytest.raises(InvalidInputError, match="latitude"):
        gps_line((91.0, 0.0, 0.0), (0.0, 0.0, 0.0), 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]  # nothing half-written


def test_every_format_is_tested():
    assert sorted(f for f, _, _ in CASES) == sorted(WRITE_FORMATS)


# --------------------------------------------------------------------------------------------
# thermocal simulate flight --format
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("fmt", "frames"), [("seq", "frames.seq"), ("dualtau", "frames"),
                                             ("dji-rjpeg", "frames")])
def test_simulate_flight_in_a_camera_format(tmp_path, capsys, fmt, frames):
    from cli_run import run

    args = ["simulate", "flight", "{}", "--frames", "4", "--size", "32x24", "--seed", "3"]
    code, _, err = run([a.format(tmp_path / "tiff") for a in args], capsys)
    assert code == 0, err
    code, _, err = run([a.format(tmp_path / fmt) for a in args] + ["--format", fmt], capsys)
    assert code == 0, err
    out = tmp_path / fmt
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [frames, "flight.json", "truth.tiff", "homographies.npy"])
    back = open_recording(out / frames).read_all()
    want = open_recording(tmp_path / "tiff" / "frames.tiff").read_all()
    np.testing.assert_array_equal(back.frames, want.frames)
    np.testing.assert_allclose(back.time_s, want.time_s, atol=0.5e-3)


@pytest.mark.parametrize("preset", ["tau2", "boson"])
def test_a_simulated_flir_file_states_its_own_units_constants(tmp_path, capsys, preset):
    """`--method camera` on a simulated SEQ reads it as the camera would: the unit's Planck
    constants (an XT-R's put it 73 °C off), its fixed pattern left (raw, not corrected), within
    the core's stated ±5 °C (2σ) on most pixels; its dead pixels filled, with a warning."""
    import tifffile
    from cli_run import run

    code, _, err = run(["simulate", "flight", tmp_path / "f", "--frames", "7", "--size", "64x48",
                        "--seed", "3", "--format", "seq", "--preset", preset], capsys)
    assert code == 0, err
    meta = open_recording(tmp_path / "f" / "frames.seq").read_all().extra["frame_metadata"][0]
    # the file names its family's core (a boson's said Tau2: a helper's audit)
    family = "Tau2" if preset == "tau2" else "Boson"
    assert meta["camera_model"] == f"thermocal simulated {family}-class"
    # and states a measuring range, as an XT-R's files do (none: no scene was ever outside)
    assert meta["temperature_range_c"] == [-25.0, 135.0]
    code, _, err = run(["estimate", tmp_path / "f" / "frames.seq", "--method", "camera",
                        "--out", tmp_path / "t.tiff", "--sigma-out", tmp_path / "s.tiff"],
                       capsys)
    assert code == 0, err
    err_c = tifffile.imread(tmp_path / "t.tiff") - tifffile.imread(tmp_path / "f" /
                                                                    "truth.tiff")[3]
    sigma = tifffile.imread(tmp_path / "s.tiff")
    assert abs(float(err_c.mean())) < 2.5 and float(np.median(sigma)) == pytest.approx(2.5)
    assert np.mean(np.abs(err_c) <= 2 * sigma) > 0.85


@pytest.mark.parametrize("fmt", ["seq", "dualtau"])
def test_a_simulated_flights_folder_opens_as_its_recording(tmp_path, capsys, fmt):
    """``simulate flight OUT --format seq|dualtau`` then ``info OUT``: the folder's recording
    (OUT/frames.seq, the OUT/frames folder) is read, as OUT is for the TIFF format (it said
    "files of mixed formats" or "open each file on its own": a helper's audit)."""
    from cli_run import run

    out = tmp_path / "f"
    assert run(["simulate", "flight", out, "--frames", "3", "--size", "32x24", "--format",
                fmt], capsys)[0] == 0
    code, text, err = run(["info", out], capsys)
    assert code == 0 and f"{fmt}, 3 frame(s) of 32x24" in text, err


def test_unit_planck_inverts_the_units_median_response():
    from thermocal.camera.model import expected_counts
    from thermocal.camera.presets import make_camera
    from thermocal.simulate.formats import unit_planck

    cam = make_camera("tau2", unit=4, size=(32, 24))
    planck = unit_planck(cam, 25.0)
    temps = np.linspace(0.0, 100.0, 11)
    counts = np.median(expected_counts(cam, temps, np.full(11, 25.0))[:, ~cam.defects], axis=1)
    np.testing.assert_allclose(planck.raw_to_temperature_c(counts), temps, atol=0.1)
    assert (planck.emissivity, planck.distance_m) == (1.0, 0.0)


@pytest.mark.parametrize(("args", "message"), [
    (["{tmp}/f", "--format", "mp4"], "'mp4' is not one of"),
    (["{tmp}/f.seq", "--format", "fff"], "OUT_DIR is a folder, not a .seq file"),
    (["{tmp}/f.npz", "--format", "dualtau"], "OUT_DIR is a folder"),
    (["{tmp}/full", "--format", "rjpeg"], "simulate flight did not write"),
])
def test_simulate_flight_bad_format_exits_2_writing_nothing(tmp_path, capsys, args, message):
    from cli_run import run

    (tmp_path / "full" / "frames").mkdir(parents=True)
    (tmp_path / "full" / "frames" / "x.jpg").write_bytes(b"")
    code, out, err = run(["simulate", "flight", "--size", "32x24"]
                         + [a.replace("{tmp}", str(tmp_path)) for a in args], capsys)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["frames", "full", "x.jpg"]


def test_simulated_dji_flight_is_georeferenced_end_to_end(tmp_path, capsys):
    """A DJI R-JPEG flight with GPS and a take-off altitude gives GeoTIFF maps."""
    import tifffile
    from cli_run import run

    rec = Recording(np.random.default_rng(0).integers(3000, 5000, (7, 48, 64)).astype(np.uint16),
                    fpa_c=np.full(7, 30.0), time_s=np.arange(7) / 30.0)
    gps = gps_line((-20.2328, -43.4914, 900.0), (-20.2310, -43.4890, 900.0), 7)
    write_recording_as(rec, tmp_path / "dji", format="dji-rjpeg", gps=gps,
                       ground_altitude_m=850.0)
    code, _, err = run(["flight", tmp_path / "dji", "--out", tmp_path / "maps", "--method",
                        "camera", "--geotiff", "--preview-every", "0"], capsys)
    assert code == 0, err
    (first,) = sorted((tmp_path / "maps" / "temps").glob("frame_*[0-9].tiff"))
    with tifffile.TiffFile(first) as tif:
        assert tif.pages[0].geotiff_tags is not None
