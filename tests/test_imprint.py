"""Frames of another camera through a calibration: the imprint of its pattern (issue 18,
item 2: a response inconsistent with the calibration; `thermocal.calibration.imprint`)."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal.calibration.imprint import (
    IMPRINT_MAX,
    OTHER_CAMERA_SIGMA_C,
    Imprint,
    imprint,
    imprint_reason,
)
from thermocal.camera.presets import make_camera
from thermocal.errors import OutsideDomainError
from thermocal.estimation.calibrated import OzMean, PivotCalibration
from thermocal.estimation.pipeline import estimate
from thermocal.simulate.flight import flat_field_corrected, simulate_flight

SIZE = (64, 48)  # the `fitted` calibration's


def _walk(camera, fpa_c: float, seed: int = 1):
    scene = 15.0 + 10.0 * np.random.default_rng(0).random((128, 128))
    return simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=fpa_c, seed=seed)


@pytest.mark.parametrize("other", [("tau2", 4), ("boson", 3)])
def test_imprint_tells_the_calibrations_camera_from_another(fitted, other):
    """On its own camera the pattern a calibration removes is gone from its output (imprint
    near 0); on another unit of the family, or a camera of the other family, it is printed
    whole (near 1), beyond doubt; the inputs are left as they were."""
    camera, cal, report = fitted
    fpa = 0.5 * sum(report.fpa_range_c)
    mine = _walk(camera, fpa)
    theirs = _walk(make_camera(other[0], unit=other[1], size=SIZE), fpa)
    for flight, want in ((mine, 0.0), (theirs, 1.0)):
        raw = flight.frames[2].copy()
        temps = cal.apply(flight.frames, fpa_c=flight.fpa_c)[2]
        before = temps.copy()
        got = imprint(cal, raw, temps, fpa_c=fpa)
        assert got.slope == pytest.approx(want, abs=0.15) and got.se < 0.1
        assert got.foreign == (want == 1.0)
        assert np.array_equal(raw, flight.frames[2]) and np.array_equal(temps, before)
    temps = cal.apply(theirs.frames, fpa_c=theirs.fpa_c)
    why = imprint_reason(cal, theirs.frames, temps, fpa_c=theirs.fpa_c)
    assert "not raw frames of the camera the polynomial calibration was made for" in why
    assert "thermocal calibrate" in why
    assert imprint_reason(cal, mine.frames, cal.apply(mine.frames, fpa_c=mine.fpa_c),
                          fpa_c=mine.fpa_c) is None


def test_frames_the_camera_flat_field_corrected_itself_are_refused(fitted):
    """The calibration's own camera with its flat-field correction on (a closed shutter's
    pattern removed, as a Tau2's FFC does; the chamber session was raw): the pattern the
    calibration removes is no longer in the frames, and removing it prints it — degrees off.
    Refused, naming the FFC; the raw frames of the same walk are not."""
    camera, cal, report = fitted
    fpa = 0.5 * sum(report.fpa_range_c)
    raw = _walk(camera, fpa)
    ffc = flat_field_corrected(camera, raw)
    temps = cal.apply(ffc, fpa_c=raw.fpa_c)
    assert float(np.abs(temps - raw.truth_c).mean()) > 0.5  # what it guards against
    why = imprint_reason(cal, ffc, temps, fpa_c=raw.fpa_c)
    assert "flat-field correction (FFC) off" in why
    assert imprint_reason(cal, raw.frames, cal.apply(raw.frames, fpa_c=raw.fpa_c),
                          fpa_c=raw.fpa_c) is None


def test_a_pattern_too_weak_to_measure_is_never_another_cameras(fitted):
    """Noise alone where the pattern should be: the slope's standard error is large, so the
    frame is not called another camera's, whatever the slope."""
    rng = np.random.default_rng(3)
    weak = Imprint(slope=0.9, se=0.3)
    assert not weak.foreign and Imprint(slope=0.9, se=0.1).foreign
    assert Imprint(slope=IMPRINT_MAX + 0.01, se=0.0).foreign
    assert not Imprint(slope=IMPRINT_MAX - 0.01, se=0.0).foreign
    _, cal, report = fitted
    fpa = 0.5 * sum(report.fpa_range_c)
    raw = np.full(cal.shape, 8000, dtype=np.uint16)
    # an output that is noise: uncorrelated with the pattern
    noise = (20.0 + rng.normal(0.0, 5.0, cal.shape)).astype(np.float32)
    got = imprint(cal, raw, noise, fpa_c=fpa)
    assert abs(got.slope) < 3 * got.se and not got.foreign
    assert imprint(cal, raw[:20, :20], noise[:20, :20], fpa_c=fpa) is None  # too small


def test_estimate_refuses_another_cameras_burst_and_forced_grows_sigma(fitted):
    """Through the pipeline (a per-frame calibration and eq. 9's mean): another unit's burst is
    refused with the reason and the remedy; forced, its σ is at least
    OTHER_CAMERA_SIGMA_C, where it erred by degrees; the own unit's burst is not refused."""
    camera, cal, report = fitted
    fpa = 0.5 * sum(report.fpa_range_c)
    theirs = _walk(make_camera("tau2", unit=4, size=SIZE), fpa)
    for estimator in (PivotCalibration(cal), OzMean(cal)):
        with pytest.raises(OutsideDomainError, match="not raw frames of the camera .* made for"):
            estimate(theirs.frames, estimator, fpa_c=theirs.fpa_c)
        forced = estimate(theirs.frames, estimator, fpa_c=theirs.fpa_c, force=True)
        error = np.abs(forced.temperature_c - theirs.truth_c[forced.pivot])
        assert forced.outside and np.all(forced.sigma_c >= OTHER_CAMERA_SIGMA_C)
        assert float(np.median(error)) > 0.5  # what it guards against
        mine = estimate(_walk(camera, fpa).frames, estimator, fpa_c=fpa)
        assert mine.outside == () and float(np.median(mine.sigma_c)) < 2.0


def test_correct_refuses_another_cameras_recording(fitted, tmp_path, capsys):
    """`thermocal correct` of another unit's recording: exit 2, one line, nothing written;
    --force writes it with σ of at least OTHER_CAMERA_SIGMA_C; the own unit's is corrected."""
    import tifffile

    from tests.cli_run import run
    from thermocal.io.recording import Recording, write_recording

    camera, cal, report = fitted
    cal_path = cal.save(tmp_path / "cal.h5")
    fpa = 0.5 * sum(report.fpa_range_c)
    paths = {}
    for name, cam in (("mine", camera), ("theirs", make_camera("tau2", unit=4, size=SIZE))):
        fl = _walk(cam, fpa)
        paths[name], _ = write_recording(tmp_path / f"{name}.tiff",
                                         Recording(fl.frames, fpa_c=fl.fpa_c, time_s=fl.time_s))
    args = ["correct", paths["theirs"], "--calibration", cal_path, "--out", tmp_path / "t.tiff",
            "--sigma-out", tmp_path / "s.tiff"]
    code, _, err = run(args, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "not raw frames of the camera the polynomial calibration was made for" in err
    assert not (tmp_path / "t.tiff").exists() and not (tmp_path / "s.tiff").exists()
    code, _, err = run(args + ["--force"], capsys)
    assert code == 0 and "corrected all the same (--force)" in err
    assert np.all(tifffile.imread(tmp_path / "s.tiff") >= OTHER_CAMERA_SIGMA_C)
    code, _, err = run(["correct", paths["mine"], "--calibration", cal_path, "--out",
                        tmp_path / "m.tiff", "--sigma-out", tmp_path / "ms.tiff"], capsys)
    assert code == 0, err
    assert float(np.median(tifffile.imread(tmp_path / "ms.tiff"))) < 2.0


def test_a_shutter_calibrations_closures_are_checked_at_the_bursts_time(fitted_session,
                                                                        fitted):
    """A shutter calibration with closures: its pattern at a burst is that of the closure
    before the pivot's time, which the pipeline passes on: another unit's burst refused, the
    own unit's not (without the time no pattern could be made, and nothing was checked)."""
    from dataclasses import replace

    from thermocal.calibration.registry import fit_calibration
    from thermocal.calibration.uncertainty import CalibrationSigma

    camera, path = fitted_session
    _, _, report = fitted
    fpa = 0.5 * sum(report.fpa_range_c)
    closed = simulate_flight(np.full((128, 128), fpa), camera, n_frames=1, motion="walk",
                             fpa_c=fpa, seed=2)
    cal = fit_calibration(path, "shutter").with_shutter(
        closed.frames, fpa_c=closed.fpa_c, time_s=[-1.0])
    estimator = PivotCalibration(cal)
    estimator.sigma_model = CalibrationSigma(replace(report, method="shutter"))
    theirs = _walk(make_camera("tau2", unit=4, size=SIZE), fpa)
    for times in (theirs.time_s, float(theirs.time_s[2])):  # one per frame, or one for all
        with pytest.raises(OutsideDomainError, match="not raw frames of the camera the shutter"):
            estimate(theirs.frames, estimator, fpa_c=theirs.fpa_c, time_s=times)
    mine = _walk(camera, fpa)
    assert estimate(mine.frames, estimator, fpa_c=mine.fpa_c, time_s=mine.time_s).outside == ()


@pytest.mark.parametrize("fraction", [0.02, 0.04])
def test_dead_pixels_neither_hide_another_camera_nor_make_one(fitted, fraction):
    """Pixels dead at 0 counts or full scale (up to 4 % of the frame): their output is left
    out, and their neighbours' median replaces it before the high-pass, so it does not ring
    around them: another unit's frame is still foreign beyond doubt, the own unit's not."""
    camera, cal, report = fitted
    fpa = 0.5 * sum(report.fpa_range_c)
    for cam, foreign in ((camera, False), (make_camera("tau2", unit=4, size=SIZE), True)):
        raw = _walk(cam, fpa).frames[2].copy()
        rng = np.random.default_rng(5)
        dead = rng.random(raw.shape) < fraction
        raw[dead] = np.where(rng.random(int(dead.sum())) < 0.5, 0, 2**14 - 1)
        got = imprint(cal, raw, cal.apply(raw[None], fpa_c=[fpa])[0], fpa_c=fpa)
        assert got.foreign == foreign and got.se < 0.1, got


def test_stuck_pixels_are_found_at_the_frames_edges_too(fitted):
    """A dead pixel within the edge the slope leaves out still rings into the pixels it
    judges: it is found there as anywhere (the high-pass of the whole frame)."""
    from thermocal.calibration.imprint import EDGE_PX, _stuck

    camera, _, report = fitted
    raw = _walk(camera, 0.5 * sum(report.fpa_range_c)).frames[2].copy()
    where = [(1, 1), (EDGE_PX - 2, 20), (30, raw.shape[1] - 3), (25, 25)]
    for (r, c), value in zip(where, (0, 2**14 - 1, 0, 0), strict=True):
        raw[r, c] = value
    stuck = _stuck(raw)
    assert all(stuck[r, c] for r, c in where) and stuck.sum() < 0.01 * stuck.size
