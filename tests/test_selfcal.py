"""``selfcal``: the residual fixed pattern of a whole pass (thermocal.estimation.pass_pattern), the
estimator (thermocal.estimation.selfcal), ground references (thermocal.pipeline.references) and
``thermocal flight --method selfcal``."""

from __future__ import annotations

import json
import math
import shutil

import cv2
import numpy as np
import pytest
from cli_run import run

from thermocal import metrics
from thermocal.errors import InvalidInputError
from thermocal.estimation.pass_pattern import (
    MIN_FRAMES,
    check_motion,
    fine_part,
    fit_residual_pattern,
)
from thermocal.estimation.registry import make_estimator
from thermocal.evaluation.passes import PassSpec, simulate_pass
from thermocal.pipeline.references import Reference, level_from_references, read_references
from thermocal.radiometry import TAU2

H, W = 40, 64


def _pass(n=60, step=(1.5, 0.0), seed=0, blur=2.0):
    """A synthetic pass in radiance: a smooth random scene (correlated over ``blur`` px) moving
    ``step`` px per frame under a sensor with a known gain, column offsets, a ramp and a radial
    offset; the true pattern."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.normal(9.0, 1.0, (H + 40, W + 140)).astype(np.float32),
                           (0, 0), blur) * 3 - 18
    big = big + 9.0
    yy, xx = np.mgrid[:H, :W]
    offset = (0.05 * rng.normal(size=W)[None, :] + 0.002 * (xx - W / 2)
              + 0.04 * ((xx - W / 2) ** 2 + (yy - H / 2) ** 2) / (W * W / 4)).astype(np.float32)
    gain = (1 + 0.02 * rng.normal(size=(H, W))).astype(np.float32)
    hs, frames, truth = [], [], []
    for k in range(n):
        dx, dy = step[0] * k, step[1] * k
        m = np.array([[1, 0, dx + 5], [0, 1, dy + 5], [0, 0, 1]], np.float64)  # frame → big
        scene = cv2.warpPerspective(big, m, (W, H), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
        truth.append(scene)
        frames.append(gain * scene + offset + rng.normal(0, 0.003, (H, W)).astype(np.float32))
        hs.append(np.array([[1, 0, dx], [0, 1, dy], [0, 0, 1]], np.float64))  # frame → frame 0
    return np.stack(frames), np.stack(hs), np.stack(truth), gain, offset


def test_the_pattern_of_a_known_pass_is_recovered():
    frames, hs, truth, gain, offset = _pass()
    before = frames.copy()
    p = fit_residual_pattern(frames, hs, fpa_c=np.full(len(frames), 30.0))
    np.testing.assert_array_equal(frames, before)  # never modified
    corrected = p.correct(frames, np.full(len(frames), 30.0))

    def pattern_left(x):  # the error fixed in the sensor, less what motion along rows cannot show
        fixed = (x - truth)[:, 3:-3, 3:-3].mean(axis=0)
        return float(np.std(fixed - fixed.mean(axis=1, keepdims=True)))

    assert pattern_left(frames) > 0.1
    assert pattern_left(corrected) < pattern_left(frames) / 10
    columns = (corrected - truth)[:, 3:-3, 3:-3].mean(axis=(0, 1))
    assert np.std(columns) < 0.01  # the column pattern and the ramp are gone
    assert np.corrcoef(p.gain.ravel(), gain.ravel())[0, 1] > 0.8
    assert p.fitted_fpa is False and p.rounds >= 2


def _row_profile(p):
    """The fitted offset's row means, less their mean."""
    rows = p.offset.mean(axis=1)
    return rows - rows.mean()


def test_a_slow_row_pattern_under_motion_along_rows_is_left_to_the_start_model():
    frames, hs, _, _, _ = _pass()
    fpa = np.full(len(frames), 30.0)
    ramp = np.linspace(-0.1, 0.1, H, dtype=np.float32)[:, None]
    before = fit_residual_pattern(frames, hs, fpa_c=fpa, radial=True)
    p = fit_residual_pattern(frames + ramp, hs, fpa_c=fpa, radial=True)
    # each ground line stays on its row: a ramp across the rows is the ground's as much as the
    # sensor's, and is not invented (nor taken for a radial quadratic)
    assert np.abs(_row_profile(p) - _row_profile(before)).max() < 0.03
    assert any("row pattern's slow part" in s for s in p.unidentified())


def test_a_pass_that_crosses_the_rows_by_little_shows_their_stripes_not_their_ramp():
    frames, hs, _, _, _ = _pass(step=(1.5, 0.3))  # 18 px across 40 rows
    fpa = np.full(len(frames), 30.0)
    ramp = np.linspace(-0.1, 0.1, H, dtype=np.float32)[:, None]
    stripes = (0.05 * np.random.default_rng(3).standard_normal(H)).astype(np.float32)[:, None]
    before = fit_residual_pattern(frames, hs, fpa_c=fpa)
    p = fit_residual_pattern(frames + ramp + stripes, hs, fpa_c=fpa)
    found = _row_profile(p) - _row_profile(before)
    truth = fine_part(stripes[:, 0] - stripes.mean())
    assert np.std(fine_part(found)[2:-2] - truth[2:-2]) < np.std(truth) / 2  # seen by motion
    assert np.abs(found - fine_part(found)).max() < 0.03  # the ramp is not invented


def test_fine_row_stripes_under_motion_along_rows_come_from_the_grounds_statistics():
    frames, hs, _, _, _ = _pass()
    fpa = np.full(len(frames), 30.0)
    stripes = (0.05 * np.random.default_rng(3).standard_normal(H)).astype(np.float32)
    before = fit_residual_pattern(frames, hs, fpa_c=fpa)
    p = fit_residual_pattern(frames + stripes[:, None], hs, fpa_c=fpa)
    found = fine_part(_row_profile(p) - _row_profile(before))
    truth = fine_part(stripes - stripes.mean())
    assert np.std(found - truth) < np.std(truth) / 4


def test_a_radial_offset_along_unseen_rows_comes_from_the_columns_when_the_family_has_one():
    frames, hs, _, _, _ = _pass(blur=6.0)
    yy, xx = np.mgrid[:H, :W]
    u, v = xx / (W - 1) - 0.5, yy / (H - 1) - 0.5
    extra = (0.4 * (u**2 + v**2)).astype(np.float32)
    rows = extra.mean(axis=1) - extra.mean()
    fpa = np.full(len(frames), 30.0)
    # the gain held (a scene of little contrast cannot tell a smooth gain from an offset)
    plain = fit_residual_pattern(frames + extra, hs, fpa_c=fpa, fit_gain=False)
    radial = fit_residual_pattern(frames + extra, hs, fpa_c=fpa, fit_gain=False, radial=True)
    # the synthetic sensor's own radial offset stays in both fits: compare their difference
    gained = _row_profile(radial) - _row_profile(plain)
    assert np.std(gained - (rows - rows.mean())) < 0.2 * np.std(rows)


@pytest.mark.parametrize("step, lines", [((1.5, 0.0), {"rows": "all"}),
                                         ((1.5, 0.3), {"rows": "slow"}),
                                         ((1.5, 1.0), {})])
def test_what_the_motion_across_the_rows_shows_is_said(step, lines):
    frames, hs, _, _, _ = _pass(step=step)
    p = fit_residual_pattern(frames, hs, fpa_c=np.full(len(frames), 30.0))
    # 18 px across 40 rows shows stripes, not a ramp across the frame; 59 px shows it
    assert p.lines_not_identified() == lines
    said = " ".join(p.unidentified())
    assert ("row pattern's slow part" in said) == bool(lines)
    assert ("under 0.5 of the frame" in said) == (lines == {"rows": "slow"})


def test_a_short_or_still_pass_is_refused_with_what_it_needs():
    frames, hs, _, _, _ = _pass(n=MIN_FRAMES - 1)
    with pytest.raises(InvalidInputError, match=f"at least {MIN_FRAMES} frames"):
        fit_residual_pattern(frames, hs, fpa_c=np.full(len(frames), 30.0))
    frames, hs, _, _, _ = _pass(n=40, step=(0.2, 0.0))
    with pytest.raises(InvalidInputError, match=r"moved 8 px .* at least 32 px"):
        check_motion(hs, (H, W))


def test_references_fix_a_known_level():
    yy, xx = np.mgrid[:H, :W]
    truth = 20.0 + 0.1 * xx
    slope = float(TAU2.radiance(294.15 + 0.5) - TAU2.radiance(294.15 - 0.5))
    # the map is 0.6 °C warm at 21 °C: an offset in counts is one in radiance
    shown = TAU2.temperature(TAU2.radiance(truth + 273.15) + 0.6 * slope) - 273.15
    refs = (Reference(2, 0, 30.0, 20.0, 4.0, float(truth[20, 30])),
            Reference(3, 1, 10.0, 10.0, 3.0, float(truth[10, 10])))
    fix = level_from_references(refs, {0: shown, 1: shown}, TAU2)
    assert fix.offset == pytest.approx(0.6 * slope, rel=1e-3)
    fixed = TAU2.temperature(TAU2.radiance(shown + 273.15) - fix.offset) - 273.15
    assert np.abs(fixed - truth).max() < 1e-3
    assert fix.disagreeing == [] and fix.sigma_c < 0.1
    bad = refs + (Reference(4, 1, 40.0, 20.0, 3.0, float(truth[20, 40]) + 3.0),)
    fix = level_from_references(bad, {0: shown, 1: shown}, TAU2)
    assert fix.disagreeing == [4] and fix.offset == pytest.approx(0.6 * slope, rel=1e-3)
    assert [r["used"] for r in fix.residuals] == [True, True, False]  # reported, left out
    two = level_from_references(bad[1:], {0: shown, 1: shown}, TAU2)  # which one is right?
    assert two.disagreeing and two.sigma_c > 1.0  # both used, σ widened by their scatter


@pytest.mark.parametrize("text, message", [
    ("frame,x,y,temperature_c\n1,5,5,20\n", "missing column(s) radius_px"),
    ("frame,x,y,radius_px,temperature_c\n", "no references"),
    ("frame,x,y,radius_px,temperature_c\n999,5,5,2,20\n", "frame 999 does not exist"),
    ("frame,x,y,radius_px,temperature_c\n1,2,5,4,20\n", "not wholly inside the 64x40 frame"),
    ("frame,x,y,radius_px,temperature_c\n1,20,20,4,nan\n", "temperature_c is nan"),
    ("frame,x,y,radius_px,temperature_c,emissivity\n1,20,20,4,20,1.5\n", "emissivity must be"),
    ("frame,x,y,radius_px,temperature_c\n1.5,20,20,4,20\n", "frame 1.5 does not exist"),
    ("frame,x,y,radius_px,temperature_c\n1,20,20,4,700\n",
     "temperature_c 700 °C is outside the -123…627 °C"),
    ("frame,x,y,radius_px,temperature_c,reflected_c\n1,20,20,4,20,5000\n",
     "reflected_c 5000 °C is outside"),
])
def test_bad_reference_files_get_one_line(tmp_path, text, message):
    path = tmp_path / "REF.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InvalidInputError, match="line|column|references") as exc:
        read_references(path, n_frames=50, frame_shape=(H, W))
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_selfcal_outside_a_flight_is_refused_with_the_remedy():
    est = make_estimator("selfcal")
    with pytest.raises(InvalidInputError, match="thermocal flight --method selfcal"):
        est.check(np.zeros((7, H, W), np.uint16), registered=False, homographies=None)


# ------------------------------------------------------------------------------ the flight

FLIGHT = PassSpec(scene="builtin:aerial", unit=100, n_frames=70, size=(96, 72), fpa_c=30.0,
                  seed=5)


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """A 70-frame 96×72 pass of a held-out unit through ``flight --method selfcal``."""
    work = tmp_path_factory.mktemp("selfcal")
    rec = simulate_pass(FLIGHT, work / "pass")
    return work, rec


def _scores(out, truth_path):
    import tifffile

    from thermocal.camera.presets import make_camera

    truth = tifffile.imread(truth_path)
    good = ~make_camera("tau2", unit=FLIGHT.unit, size=FLIGHT.size).defects
    maps, sig, idx = [], [], []
    for f in sorted((out / "temps").glob("frame_??????.tiff")):
        k = int(f.stem.split("_")[1])
        maps.append(tifffile.imread(f))
        sig.append(tifffile.imread(f.with_name(f.stem + "_sigma.tiff")))
        idx.append(k)
    maps, sig = np.stack(maps), np.stack(sig)
    return maps, sig, truth[idx], good


def test_flight_selfcal_removes_the_units_pattern(flown, capsys, tmp_path):
    work, rec = flown
    out = tmp_path / "out"
    code, text, err = run(["flight", rec, "--out", out, "--method", "selfcal",
                           "--preview-every", "0"], capsys)
    # 96×72 frames: smaller than any its calibration-free σ was measured on
    assert code == 2 and "frames of 96x72, smaller than the 320x256" in err, err
    assert "--force estimates anyway with σ grown by 0.5 °C" in err
    shutil.rmtree(out)
    code, text, err = run(["flight", rec, "--out", out, "--method", "selfcal", "--force",
                           "--preview-every", "0"], capsys)
    assert code == 0, err
    maps, sigma, truth, good = _scores(out, rec.parent / "truth.tiff")
    # the same pass through the family's average unit alone (the start model), pivot by pivot
    import tifffile

    from thermocal.estimation.selfcal import _nominal
    from thermocal.nn.inputs import calibrate_frames

    raw = tifffile.imread(rec)
    pivots = [int(f.stem.split("_")[1]) for f in sorted((out / "temps").glob("frame_??????.tiff"))]
    start = calibrate_frames(_nominal("tau2", raw.shape[1:]), raw[pivots], 30.0)
    inner = np.zeros_like(good)
    inner[4:-4, 4:-4] = True
    v = good & inner
    assert metrics.bias_free_mae(maps, truth, valid=v) < 0.5 * metrics.bias_free_mae(
        start, truth, valid=v)
    assert metrics.column_bands(maps, truth, valid=v) < 0.3 * metrics.column_bands(
        start, truth, valid=v)
    # every map has its σ, never below the level no motion reveals and the size's growth
    assert sigma.shape == maps.shape and float(sigma.min()) >= math.hypot(0.42, 0.5)
    summary = json.loads((out / "summary.json").read_text())
    seg = summary["selfcal"]["segments"]
    assert len(seg) == 1 and seg[0]["frames"] == [0, 69] and seg[0]["motion_px"][0] > 48
    assert "the global level" in seg[0]["not_identified"][0]
    report = (out / "report.html").read_text(encoding="utf-8")
    assert "<h2>Self-calibration</h2>" in report and "0–69" in report


def test_flight_selfcal_with_a_reference_fixes_the_level(flown, capsys, tmp_path):
    import tifffile

    work, rec = flown
    truth = tifffile.imread(rec.parent / "truth.tiff")
    k, x, y, r = 35, 48, 36, 5
    yy, xx = np.mgrid[:72, :96]
    disc = (xx - x) ** 2 + (yy - y) ** 2 <= r * r
    outs = {}
    for name, shift in (("free", None), ("ref", 0.0), ("warmer", 0.5)):
        extra = []
        if shift is not None:
            ref = tmp_path / f"REF_{name}.csv"
            ref.write_text(f"frame,x,y,radius_px,temperature_c\n{k},{x},{y},{r},"
                           f"{truth[k][disc].mean() + shift:.3f}\n", encoding="utf-8")
            extra = ["--reference", ref]
        outs[name] = tmp_path / name
        code, _, err = run(["flight", rec, "--out", outs[name], "--method", "selfcal",
                            "--force", "--preview-every", "0", *extra], capsys)  # 96×72
        assert code == 0, err
    free, fixed, warmer = (_scores(outs[n], rec.parent / "truth.tiff")
                           for n in ("free", "ref", "warmer"))
    # the level follows the reference: half a degree warmer there, half a degree warmer
    # everywhere (its radiance offset, converted at each pixel's temperature)
    assert abs(float(np.mean(warmer[0] - fixed[0])) - 0.5) < 0.03
    # what is left is the pattern under the disc that no straight pass shows: within the σ
    # the maps state for their level
    bias = float(np.mean((fixed[0] - fixed[2])[:, fixed[3]]))
    assert abs(bias) < 2 * float(np.median(fixed[1]))
    assert float(np.median(fixed[1])) < float(np.median(free[1]))  # σ shrinks
    summary = json.loads((outs["ref"] / "summary.json").read_text())
    assert summary["selfcal"]["references"]["residuals"][0]["frame"] == k
    assert "Level fixed by 1 ground reference" in (outs["ref"] / "report.html").read_text(
        encoding="utf-8")


@pytest.mark.parametrize("ref_text, message", [
    ("frame,x,y,radius_px\n3,10,10,2\n", "missing column(s) temperature_c"),
    ("frame,x,y,radius_px,temperature_c\n500,10,10,2,20\n", "frame 500 does not exist"),
    ("frame,x,y,radius_px,temperature_c\n3,94,10,5,20\n", "not wholly inside"),
    ("frame,x,y,radius_px,temperature_c\n3,10,10,2,nan\n", "not a finite number"),
])
def test_flight_refuses_bad_references_and_writes_nothing(flown, capsys, tmp_path, ref_text,
                                                          message):
    _, rec = flown
    ref = tmp_path / "REF.csv"
    ref.write_text(ref_text, encoding="utf-8")
    out = tmp_path / "out"
    code, _, err = run(["flight", rec, "--out", out, "--method", "selfcal", "--reference", ref],
                       capsys)
    assert code == 2 and message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_flight_refuses_a_pass_too_short_or_a_reference_without_selfcal(flown, capsys,
                                                                         tmp_path):
    import tifffile

    _, rec = flown
    short = tmp_path / "short"
    short.mkdir()
    tifffile.imwrite(short / "frames.tiff", tifffile.imread(rec)[:20])
    meta = json.loads(rec.with_suffix(".json").read_text())
    meta = {k: (v[:20] if isinstance(v, list) and len(v) == 70 else v) for k, v in meta.items()}
    (short / "frames.json").write_text(json.dumps(meta))
    out = tmp_path / "out"
    code, _, err = run(["flight", short / "frames.tiff", "--out", out, "--method", "selfcal"],
                       capsys)
    assert code == 2 and f"at least {MIN_FRAMES} frames" in err and not out.exists()
    # 35 frames, but groups of 9 every 9 frames use 27: said so (it said "this one has 27")
    tifffile.imwrite(short / "frames.tiff", tifffile.imread(rec)[:35])
    meta = json.loads(rec.with_suffix(".json").read_text())
    meta = {k: (v[:35] if isinstance(v, list) and len(v) == 70 else v) for k, v in meta.items()}
    (short / "frames.json").write_text(json.dumps(meta))
    code, _, err = run(["flight", short / "frames.tiff", "--out", out, "--method", "selfcal",
                        "--frames", "9", "--stride", "9"], capsys)
    assert code == 2 and "the groups at this --frames and --stride use 27" in err
    assert not out.exists()
    ref = tmp_path / "REF.csv"
    ref.write_text("frame,x,y,radius_px,temperature_c\n3,10,10,2,20\n")
    code, _, err = run(["flight", rec, "--out", out, "--method", "kpn", "--reference", ref],
                       capsys)
    assert code == 2 and "--method selfcal" in err and not out.exists()


def test_flight_refuses_a_hover_and_says_what_it_needs(capsys, tmp_path):
    rec = tmp_path / "hover"
    code, _, err = run(["simulate", "flight", rec, "--motion", "hover", "--frames", 40,
                        "--size", "80x64", "--unit", 100, "--seed", 3], capsys)
    assert code == 0, err
    out = tmp_path / "out"
    code, _, err = run(["flight", rec / "frames.tiff", "--out", out, "--method", "selfcal"],
                       capsys)
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "selfcal needs at least" in err or "it needs at least" in err
    assert "40 px along the rows" in err or "at least 40 px" in err  # half the frame's width
    assert not out.exists()


def test_a_pass_of_another_family_is_refused_and_forced_with_sigma_grown(capsys, tmp_path):
    """Starting from a family's average unit, a pass whose fixed pattern runs the other way
    (a ``boson`` pass from ``tau2``'s start, 9.5 °C off before) is refused, saying which
    families there are; ``--family boson`` takes it; ``--force`` gives σ of at least
    OTHER_FAMILY_SIGMA_C. Frames of 160×128: large enough to check (LINE_CHECK_MIN_PX)."""
    import tifffile

    from thermocal.estimation.selfcal import OTHER_FAMILY_SIGMA_C

    rec = tmp_path / "boson"
    assert run(["simulate", "flight", rec, "--preset", "boson", "--size", "160x128",
                "--frames", "35", "--motion", "uav"], capsys)[0] == 0
    code, _, err = run(["flight", rec, "--out", tmp_path / "a", "--method", "selfcal",
                        "--preview-every", "0"], capsys)
    assert code == 2 and "not a camera of the tau2 family" in err and "--family" in err
    assert not list((tmp_path / "a").glob("temps/frame_*.tiff"))
    code, _, err = run(["flight", rec, "--out", tmp_path / "b", "--method", "selfcal",
                        "--family", "boson", "--preview-every", "0"], capsys)
    assert code == 2 and "frames of 160x128, smaller than the 320x256" in err, err
    shutil.rmtree(tmp_path / "b")
    code, _, err = run(["flight", rec, "--out", tmp_path / "b", "--method", "selfcal",
                        "--family", "boson", "--force", "--preview-every", "0"], capsys)
    assert code == 0, err
    truth = tifffile.imread(rec / "truth.tiff")
    maps = sorted((tmp_path / "b" / "temps").glob("frame_??????.tiff"))
    k = int(maps[0].stem.split("_")[1])
    assert abs(float(np.median(tifffile.imread(maps[0]) - truth[k]))) < 1.5
    code, _, err = run(["flight", rec, "--out", tmp_path / "c", "--method", "selfcal",
                        "--force", "--preview-every", "0"], capsys)
    assert code == 0, err
    sigma = tifffile.imread(tmp_path / "c" / "temps" / f"{maps[0].stem}_sigma.tiff")
    assert sigma.min() >= OTHER_FAMILY_SIGMA_C


def test_family_level_sigma_covers_other_units_levels_and_grows_with_the_fpa():
    """The level σ of a calibration-free pass is the family's unit-to-unit spread at the pass's
    FPA and scene: other units' frame-mean shifts from the family (computed apart, by the
    unit-spread benchmark's route: the exact family model, whole 336×256 frames) lie within it
    about as often as a Gaussian's do, and it grows with the FPA as the units' spread does."""
    from thermocal.estimation.selfcal import LEVEL_UNITS, family_level_sigma
    from thermocal.evaluation.references import ExactModel
    from thermocal.evaluation.suites import unit_spread
    from thermocal.nn.data import TRAIN_UNITS

    others = tuple(range(2000, 2060))
    assert not set(others) & (set(LEVEL_UNITS) | set(TRAIN_UNITS))
    family = ExactModel.family(TRAIN_UNITS).model
    shifts = unit_spread.shifts_c(others, family)  # (units, FPA 15/30/45, scene −20/5/30)
    for i, fpa in enumerate(unit_spread.FPAS_C):
        for j, scene in enumerate(unit_spread.SCENES_C):
            sigma = family_level_sigma("tau2", fpa, scene)
            rms = float(np.sqrt(np.mean(shifts[:, i, j] ** 2)))
            assert 0.8 * rms < sigma < 1.35 * rms, (fpa, scene, sigma, rms)
            assert 0.55 < np.mean(np.abs(shifts[:, i, j]) <= sigma) < 0.9
    assert family_level_sigma("tau2", 45.0, 5.0) > 1.25 * family_level_sigma("tau2", 30.0, 5.0)
    # computed once per 5 °C cell: another FPA and scene within the cell is a cache hit
    from thermocal.estimation.selfcal import _family_level_sigma

    before = _family_level_sigma.cache_info()
    assert family_level_sigma("tau2", 31.2, 19.1) == family_level_sigma("tau2", 30.0, 20.0)
    after = _family_level_sigma.cache_info()
    assert after.misses - before.misses <= 1 and after.hits - before.hits >= 1
