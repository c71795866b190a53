"""Tests for thermocal.scenes.real: loading real radiometric scenes (R-JPEG, TIFF, FFF)."""

from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.radiometry import FlirPlanck
from thermocal.scenes.real import find_shared_data, list_shared_scenes, load_scene, read_fff

# scenes/ in shared/data/SOURCES.md: file -> (min, max) in °C, as decoded with the embedded
# camera parameters (flyr's default)
SOURCES_RANGES = {
    "01_200_deg_neutral.jpg": ((120, 120), 31.7, 87.4),
    "02_irwatercooler.jpg": ((480, 640), 10.7, 24.4),
    "03_thermal_image_of_four_ducks_swimming.jpg": ((120, 120), 7.2, 23.2),
    "05_aqua_tower_thermal_image.jpg": ((180, 180), -68.1, -0.2),
    "06_aqua_tower_thermal_imaging.jpg": ((180, 180), -71.9, 3.6),
    "10_ir_fussbodenheizung.jpg": ((240, 320), 16.7, 34.5),
    "11_ir_moving_car.jpg": ((240, 320), -10.3, 15.0),
    "12_ir_moving_mercedes.jpg": ((240, 320), -16.9, 19.3),
    "14_kujawy_wiatrak.jpg": ((240, 320), -44.0, 2.5),
    "15_linear_load.jpg": ((120, 120), 30.0, 89.3),
    "17_solar_halo_thermal.jpg": ((240, 320), -35.5, -8.1),
}


@pytest.fixture(scope="module")
def shared_data() -> Path:
    root = find_shared_data()
    if root is None:
        pytest.skip("shared/data not found (set THERMOCAL_DATA)")
    return root


def _assert_one_line_error(excinfo):
    msg = str(excinfo.value)
    assert "\n" not in msg and msg
    assert excinfo.value.__cause__ is None
    assert excinfo.value.__suppress_context__ or excinfo.value.__context__ is None


# ---------------------------------------------------------------------------------------------
# real files
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SOURCES_RANGES))
def test_rjpeg_scenes_load_to_sources_ranges(shared_data, name):
    shape, lo, hi = SOURCES_RANGES[name]
    temp = load_scene(shared_data / "scenes" / name)
    assert temp.dtype == np.float32 and temp.shape == shape
    assert np.all(np.isfinite(temp))
    assert float(temp.min()) == pytest.approx(lo, abs=0.5)
    assert float(temp.max()) == pytest.approx(hi, abs=0.5)


def test_every_scene_file_is_covered(shared_data):
    assert sorted(p.name for p in (shared_data / "scenes").glob("*.jpg")) == sorted(SOURCES_RANGES)


def test_rjpeg_emissivity_override(shared_data):
    path = shared_data / "scenes" / "10_ir_fussbodenheizung.jpg"  # stored emissivity 0.95
    default = load_scene(str(path))
    np.testing.assert_allclose(load_scene(path, emissivity=0.95), default, atol=1e-3)
    black = load_scene(path, emissivity=1.0)
    # warmer than the 20 °C surroundings: assuming a black body lowers the estimate
    hot = default > 25.0
    assert np.all(black[hot] < default[hot])
    assert float(black.max()) == pytest.approx(33.8, abs=0.1)


def test_a_dji_tau2_rjpeg_flyr_cannot_read_loads_as_the_flir_formula_by_hand(shared_data):
    """flyr fails on a DJI Zenmuse XT-R's R-JPEG (a Tau2 core; "corrupt FLIR radiometric data
    (KeyError: 1)", a helper's audit): the scene loads through thermocal's own reader, equal to
    the FLIR formula with exiftool's constants on its raw counts; an emissivity given is used."""
    import flyr

    from thermocal.io import open_recording

    path = shared_data / "recordings" / "dji_xtr_tau2.jpg"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    with pytest.raises(Exception):  # noqa: B017, PT011 - flyr's own error, whichever it is
        flyr.unpack(str(path))
    planck = FlirPlanck.from_exiftool_text(path.with_suffix(".txt"))
    raw = open_recording(path).read_all().frames[0].astype(np.float64)
    temp = load_scene(path)
    assert temp.dtype == np.float32 and temp.shape == raw.shape
    np.testing.assert_allclose(temp, planck.raw_to_temperature_c(raw), atol=2e-3)
    lower = load_scene(path, emissivity=0.95)  # the file says 0.70: warm objects read cooler
    assert float(np.median(temp - lower)) > 1.0


def test_flirpy_tiff(shared_data):
    temp = load_scene(shared_data / "flirpy" / "example_radiometric.tiff")
    assert temp.dtype == np.float32 and temp.shape == (512, 640)
    assert float(temp.min()) == pytest.approx(-3.4, abs=0.5)
    assert float(temp.max()) == pytest.approx(9.9, abs=0.5)
    # the scale is a keyword: 0.04 K per count by default
    raw = tifffile.imread(shared_data / "flirpy" / "example_radiometric.tiff")
    np.testing.assert_allclose(temp, raw * 0.04 - 273.15, atol=1e-4)
    other = load_scene(
        shared_data / "flirpy" / "example_radiometric.tiff", tiff_kelvin_per_count=0.05
    )
    np.testing.assert_allclose(other, raw * 0.05 - 273.15, atol=1e-4)


def test_fff_frame(shared_data):
    path = shared_data / "flirpy" / "frame_000000.fff"
    raw, planck = read_fff(path)
    assert raw.dtype == np.uint16 and raw.shape == (512, 640)
    assert int(raw.max()) - int(raw.min()) == 116  # "Raw Value Range" in the exiftool dump
    reference = FlirPlanck.from_exiftool_text(shared_data / "flirpy" / "frame_000000.txt")
    assert (planck.r1, planck.r2, planck.b, planck.f, planck.o) == (
        364058.0,
        1.0,
        1428.0,
        1.0,
        -228.0,
    )
    for name in (
        "r1", "r2", "b", "f", "o", "emissivity", "distance_m", "reflected_c", "atmosphere_c",
        "ir_window_c", "ir_window_transmission", "humidity", "alpha1", "alpha2", "beta1", "beta2",
        "x",
    ):  # fmt: skip
        # the dump prints rounded values (emissivity 0.94 is stored as 0.93994)
        assert getattr(planck, name) == pytest.approx(getattr(reference, name), abs=1e-3), name

    temp = load_scene(path)
    assert temp.dtype == np.float32 and temp.shape == (512, 640)
    np.testing.assert_allclose(temp, planck.raw_to_temperature_c(raw), atol=1e-4)
    # a near-uniform scene around 11 °C (emissivity 0.94, 50 m, 30 % RH)
    assert 9.0 < float(temp.min()) < float(temp.max()) < 13.0
    black = load_scene(path, emissivity=1.0)
    assert not np.allclose(black, temp)


def test_fff_fields_by_hand(shared_data):
    # an independent read of the first pixels and the Planck R1 field of the FFF layout
    data = (shared_data / "flirpy" / "frame_000000.fff").read_bytes()
    raw, _ = read_fff(shared_data / "flirpy" / "frame_000000.fff")
    first = np.frombuffer(data, "<u2", count=4, offset=0x200 + 32)
    np.testing.assert_array_equal(raw[0, :4], first)
    assert np.frombuffer(data, "<f4", count=1, offset=0xA0220 + 0x58)[0] == 364058.0


def test_list_shared_scenes(shared_data):
    scenes = list_shared_scenes()
    assert len(scenes) == 13
    assert scenes["frame_000000"].suffix == ".fff"
    assert scenes["example_radiometric"].suffix == ".tiff"
    assert list_shared_scenes(shared_data) == scenes
    assert list_shared_scenes(shared_data / "nothing-here") == {}


# ---------------------------------------------------------------------------------------------
# made-up files
# ---------------------------------------------------------------------------------------------
def test_float_tiff_is_celsius(tmp_path):
    values = np.linspace(-20.0, 80.0, 48, dtype=np.float32).reshape(6, 8)
    tifffile.imwrite(tmp_path / "t.tif", values)
    out = load_scene(tmp_path / "t.tif")
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, values)


def test_uint16_tiff_scale(tmp_path):
    counts = np.full((4, 5), 7500, dtype=np.uint16)  # 300 K
    tifffile.imwrite(tmp_path / "t.tiff", counts)
    np.testing.assert_allclose(load_scene(tmp_path / "t.tiff"), 26.85, atol=1e-4)
    np.testing.assert_allclose(
        load_scene(tmp_path / "t.tiff", tiff_kelvin_per_count=0.01), 75.0 - 273.15, atol=1e-4
    )


@pytest.mark.parametrize(
    ("array", "match"),
    [
        (np.zeros((3, 4, 5), np.float32), "single-page"),
        (np.zeros((4, 5), np.uint8), "not a radiometric map"),
        (np.full((4, 5), np.nan, np.float32), "NaN"),
        (np.full((4, 5), -300.0, np.float32), "absolute zero"),
        (np.zeros((4, 5), np.uint16), "absolute zero"),
    ],
)
def test_bad_tiffs(tmp_path, array, match):
    tifffile.imwrite(tmp_path / "bad.tif", array, photometric="minisblack")
    with pytest.raises(FileFormatError, match=match) as excinfo:
        load_scene(tmp_path / "bad.tif")
    _assert_one_line_error(excinfo)


def test_non_radiometric_jpeg(tmp_path):
    path = tmp_path / "photo.jpg"
    img = (np.arange(64 * 48 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    assert cv2.imwrite(str(path), img)
    with pytest.raises(FileFormatError, match="FLIR") as excinfo:
        load_scene(path)
    _assert_one_line_error(excinfo)


@pytest.mark.parametrize("fraction", [0.01, 0.3, 0.5, 0.95])
def test_truncated_rjpeg(shared_data, tmp_path, fraction):
    data = (shared_data / "scenes" / "10_ir_fussbodenheizung.jpg").read_bytes()
    path = tmp_path / "cut.jpg"
    path.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(FileFormatError, match="truncated") as excinfo:
        load_scene(path)
    _assert_one_line_error(excinfo)


@pytest.mark.parametrize(
    ("name", "fraction"),
    [
        ("flirpy/example_radiometric.tiff", 0.5),
        ("flirpy/example_radiometric.tiff", 0.001),
        ("flirpy/frame_000000.fff", 0.5),
        ("flirpy/frame_000000.fff", 0.999),
        ("flirpy/frame_000000.fff", 0.00005),
    ],
)
def test_truncated_tiff_and_fff(shared_data, tmp_path, name, fraction):
    data = (shared_data / name).read_bytes()
    path = tmp_path / Path(name).name
    path.write_bytes(data[: max(4, int(len(data) * fraction))])
    with pytest.raises(FileFormatError) as excinfo:
        load_scene(path)
    _assert_one_line_error(excinfo)
    if name.endswith(".fff"):
        with pytest.raises(FileFormatError):
            read_fff(path)


def test_text_missing_empty_and_directory(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("Planck R1 : 1\nthis is not an image\n")
    with pytest.raises(FileFormatError, match="unknown file format") as excinfo:
        load_scene(text)
    _assert_one_line_error(excinfo)
    with pytest.raises(FileFormatError, match="not found"):
        load_scene(tmp_path / "missing.jpg")
    (tmp_path / "empty.jpg").write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty"):
        load_scene(tmp_path / "empty.jpg")
    with pytest.raises(FileFormatError, match="directory"):
        load_scene(tmp_path)
    with pytest.raises(FileFormatError, match="FFF"):
        read_fff(text)


def test_bad_options(shared_data, tmp_path):
    tifffile.imwrite(tmp_path / "t.tif", np.full((2, 2), 7500, np.uint16))
    with pytest.raises(InvalidInputError, match="emissivity"):
        load_scene(tmp_path / "t.tif", emissivity=0.9)
    with pytest.raises(InvalidInputError, match="emissivity"):
        load_scene(tmp_path / "t.tif", emissivity=0.0)
    with pytest.raises(InvalidInputError, match="tiff_kelvin_per_count"):
        load_scene(tmp_path / "t.tif", tiff_kelvin_per_count=-1.0)


def test_find_shared_data_env(tmp_path, monkeypatch):
    monkeypatch.setenv("THERMOCAL_DATA", str(tmp_path))
    assert find_shared_data() == tmp_path.resolve()


def test_find_shared_data_walks_up_from_cwd(tmp_path, monkeypatch):
    import thermocal.scenes.real as real

    data = tmp_path / "shared" / "data"
    (data / "scenes").mkdir(parents=True)
    work = tmp_path / "repo" / "sub"
    work.mkdir(parents=True)
    elsewhere = tmp_path / "site-packages" / "thermocal" / "scenes"
    elsewhere.mkdir(parents=True)
    # an env var naming a missing folder is skipped; the package location leads nowhere
    monkeypatch.setenv("THERMOCAL_DATA", str(tmp_path / "does-not-exist"))
    monkeypatch.setattr(real, "__file__", str(elsewhere / "real.py"))
    monkeypatch.chdir(work)
    assert find_shared_data() == data.resolve()
    # nothing anywhere: the copy bundled with the package (unless the machine has a
    # shared/data above the temporary folder)
    monkeypatch.chdir(elsewhere)
    (data / "scenes").rmdir()
    if not any(real._looks_like_shared_data(d / "shared" / "data") for d in tmp_path.parents):
        assert find_shared_data() == real.bundled_shared_data()
    monkeypatch.setattr(real, "bundled_shared_data", lambda: tmp_path / "nowhere")
    if not any(real._looks_like_shared_data(d / "shared" / "data") for d in tmp_path.parents):
        assert find_shared_data() is None


def test_bundled_copy_is_the_shared_data():
    """The package's copy holds every shared file, byte for byte where the original is here."""
    import thermocal.scenes.real as real

    bundled = real.bundled_shared_data()
    names = sorted(p.relative_to(bundled).as_posix() for p in bundled.rglob("*") if p.is_file())
    assert "SOURCES.md" in names and "flirpy/frame_000000.fff" in names
    assert len([n for n in names if n.startswith("scenes/")]) == len(SOURCES_RANGES)
    outside = Path(__file__).resolve().parents[2] / "shared" / "data"
    if outside.is_dir():  # the data files (not the notes) are unmodified copies
        for name in names:
            if name.startswith(("scenes/", "flirpy/")):
                assert (outside / name).read_bytes() == (bundled / name).read_bytes(), name
