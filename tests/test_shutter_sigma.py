"""A ``shutter`` calibration's closures and its σ (issue 18, item 1: every temperature with its
uncertainty). The report, made on a chamber session without closures, is two-point's; a
closure re-reads the offsets from a shutter taken at the FPA sensor's temperature, which a
shutter lagging with the housing is not, and nothing checks it: σ takes how far the closures
move the temperatures, in quadrature
(:meth:`~thermocal.calibration.shutter.ShutterCalibration.closure_shift`)."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from cli_run import run

from thermocal.calibration.base import (
    ThermocalWarning,
    calibration_sigma_extra,
    filled_pixel_spread,
)
from thermocal.calibration.report import fit_with_report
from thermocal.camera.model import render
from thermocal.camera.presets import make_camera
from thermocal.io.recording import Recording, write_recording
from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
from thermocal.simulate.flight import simulate_flight

SCENE_C = 22.0


@pytest.fixture(scope="module")
def still_camera(tmp_path_factory):
    """`tau2` unit 3 (64×48), its shutter calibration from a chamber session at one ambient
    (σ small at that FPA), and a walk over a uniform scene at that FPA: ``(camera, cal,
    walk)``."""
    path = tmp_path_factory.mktemp("shutter") / "c.h5"
    camera = make_camera("tau2", unit=3, size=(64, 48))
    plan = ChamberPlan(setpoints_c=(0.0, 10.0, 20.0, 30.0, 40.0, 50.0), frames_per_point=3,
                       profile="constant", ambient_c=(25.0, 25.0), interval_s=20.0)
    write_simulated_chamber(path, camera, plan, seed=1)
    cal, _ = fit_with_report(path, "shutter")
    walk = simulate_flight(np.full((128, 128), SCENE_C), camera, n_frames=5, motion="walk",
                           fpa_c=cal.fpa_ref_c, seed=1)
    return camera, cal, walk


def _closed(camera, cal, walk, warmer_c: float, time_s: float = -1.0):
    """``cal`` with one closure of a shutter ``warmer_c`` above the FPA sensor."""
    fpa = cal.fpa_ref_c
    shut = render(camera, np.full(camera.shape, fpa + warmer_c), fpa,
                  rng=np.random.default_rng(3))
    return cal.with_shutter(shut, fpa_c=[fpa], time_s=[walk.time_s[0] + time_s])


def test_the_shift_is_how_far_the_closures_move_the_temperatures(still_camera):
    camera, cal, walk = still_camera
    closed = _closed(camera, cal, walk, 2.0)
    frames = walk.frames.copy()
    closed_temps = closed.apply(frames, time_s=walk.time_s)
    shift = closed.closure_shift(frames, closed_temps, time_s=walk.time_s)
    moved = (closed_temps - cal.apply(frames))
    np.testing.assert_allclose(shift, np.abs(moved), atol=1e-5)
    assert float(np.median(shift)) > 1.0  # a shutter 2 °C warmer than the sensor
    assert np.array_equal(frames, walk.frames)  # inputs unchanged
    assert cal.closure_shift(frames, closed_temps, time_s=walk.time_s) is None  # no closure
    assert closed.closure_shift(frames, closed_temps, time_s=None) is None
    # before the first closure a frame keeps the reference offset: nothing moved
    late = _closed(camera, cal, walk, 2.0, time_s=1e6)
    with pytest.warns(ThermocalWarning, match="long before the first closure"):
        late_temps = late.apply(frames, time_s=walk.time_s)
    assert not late.closure_shift(frames, late_temps, time_s=walk.time_s).any()
    # what σ adds: the shift, and at the calibration's bad pixels their neighbours' range
    added = calibration_sigma_extra(closed, frames, closed_temps, time_s=walk.time_s)
    good = ~cal.bad
    np.testing.assert_allclose(added[:, good], shift[:, good], atol=1e-6)
    assert cal.bad.any() and np.all(added[:, cal.bad] >= shift[:, cal.bad])


def test_a_filled_pixels_sigma_grows_by_its_neighbours_range():
    """A bad pixel's output is its good neighbours' median: the scene there may lie anywhere
    among them, so σ grows by their range (a `lin-lag` bad pixel erred 4.5 °C where σ said
    1.4: a helper's audit); good pixels add nothing; one without a good neighbour takes its
    frame's range."""
    temps = np.zeros((2, 5, 6), np.float32)
    temps[:, 1:4, 1:4] = np.arange(9, dtype=np.float32).reshape(3, 3)  # around (2, 2)
    temps[1] *= 2.0
    bad = np.zeros((5, 6), bool)
    bad[2, 2] = True
    before = temps.copy()
    spread = filled_pixel_spread(temps, bad)
    assert spread[0, 2, 2] == 8.0 and spread[1, 2, 2] == 16.0  # 8 − 0, its own 4 left out
    assert not spread[:, ~bad].any() and np.array_equal(temps, before)
    bad[1:4, 1:4] = True  # none of (2, 2)'s neighbours is good: the frame's good range
    temps[:, 1:4, 1:4] = 100.0
    temps[:, 0, 5] = (5.0, 7.0)
    spread = filled_pixel_spread(temps, bad)
    assert list(spread[:, 2, 2]) == [5.0, 7.0]
    assert calibration_sigma_extra(object(), temps, temps, time_s=None) is None


def test_correct_covers_a_closure_that_errs_with_its_sigma(still_camera, tmp_path, capsys):
    """`thermocal correct` with a shutter file holding a closure of a shutter 2 °C warmer than
    the sensor: the frames err by degrees, where the report's σ alone (two-point's, a few
    hundredths here) left every frame silent (a helper's audit: 43 of 105 frames); σ grown by
    the shift covers them. Without the closure the same frames err little and σ is small."""
    camera, cal, walk = still_camera
    rec, _ = write_recording(tmp_path / "walk.tiff", Recording(walk.frames, fpa_c=walk.fpa_c,
                                                               time_s=walk.time_s))
    good = ~camera.defects
    got = {}
    for name, c in (("plain", cal), ("closed", _closed(camera, cal, walk, 2.0))):
        c.save(tmp_path / f"{name}.h5")
        code, _, err = run(["correct", rec, "--calibration", tmp_path / f"{name}.h5", "--out",
                            tmp_path / f"{name}_t.tiff", "--sigma-out",
                            tmp_path / f"{name}_s.tiff"], capsys)
        assert code == 0, err
        error = np.abs(tifffile.imread(tmp_path / f"{name}_t.tiff") - SCENE_C)[:, good]
        got[name] = error, tifffile.imread(tmp_path / f"{name}_s.tiff")[:, good]
    error, sigma = got["plain"]
    assert error.mean() < 0.3 and np.median(sigma) < 0.3 and np.mean(error <= 2 * sigma) > 0.95
    error, sigma = got["closed"]
    assert error.mean() > 1.0  # the closure errs ...
    assert np.mean(error <= 2 * got["plain"][1]) < 0.05  # ... beyond the report's σ alone
    assert np.mean(error <= 2 * sigma) > 0.95
    silent = (error.mean(axis=1) > 1.0) & (error.mean(axis=1) > 2 * np.median(sigma, axis=1))
    assert not silent.any()


def test_frames_long_after_their_closure_are_warned_of(still_camera):
    """Closures of another recording, or a shutter that stopped: frames more than two
    intervals after the closure they use are warned of, naming how long."""
    camera, cal, walk = still_camera
    stale = _closed(camera, cal, walk, 0.0, time_s=-3.0 * cal.interval_s)
    with pytest.warns(ThermocalWarning, match=r"5 frame\(s\) lie up to 5\d\d s after the "
                                              "closure they use"):
        stale.apply(walk.frames, time_s=walk.time_s)


def test_a_bursts_sigma_grows_by_its_pivots_closure_shift(still_camera):
    """`estimate` and `flight` through a shutter calibration with closures: the pivot's σ is
    the report's and how far the closure moved the pivot, in quadrature."""
    from thermocal.estimation.calibrated import PivotCalibration
    from thermocal.estimation.pipeline import estimate

    camera, cal, _ = still_camera
    scene = SCENE_C + 6.0 * np.random.default_rng(0).random((128, 128))
    walk = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=cal.fpa_ref_c,
                           seed=2)
    closed = _closed(camera, cal, walk, 2.0)
    args = {"fpa_c": walk.fpa_c, "time_s": walk.time_s}
    plain = estimate(walk.frames, PivotCalibration(cal), **args)
    got = estimate(walk.frames, PivotCalibration(closed), **args)
    pivot = walk.frames.shape[0] // 2
    one = walk.frames[pivot][None]
    shift = closed.closure_shift(one, closed.apply(one, time_s=[walk.time_s[pivot]]),
                                 time_s=[walk.time_s[pivot]])[0]
    assert float(np.median(shift)) > 1.0
    good = ~cal.bad  # (the bad pixels add their neighbours' range, which the shift moves)
    np.testing.assert_allclose(np.hypot(plain.sigma_c, shift)[good], got.sigma_c[good], atol=0.05)


def test_a_recording_long_before_the_first_closure_is_warned_of(still_camera):
    """Closures on another clock (epoch times against a recording from 0): every frame keeps
    the reference offset, said."""
    camera, cal, walk = still_camera
    late = _closed(camera, cal, walk, 0.0, time_s=1.7e9)
    with pytest.warns(ThermocalWarning, match=r"5 frame\(s\) end at t = .* long before the first "
                                              "closure"):
        late.apply(walk.frames, time_s=walk.time_s)


def test_what_sigma_adds_leaves_other_threads_warnings_alone(tmp_path):
    """What σ adds drops the warnings its second application of a calibration repeats (a rate
    correction's, at an FPA outside the calibrated range) on its own thread only: a flight's
    other pivots, on other threads, keep theirs (warnings.catch_warnings changed the filters
    for every thread: a review found another thread catching none of 400)."""
    import threading
    import warnings

    from thermocal.calibration.base import rate_correction
    from thermocal.calibration.registry import fit_calibration
    from thermocal.threads import caught_warnings, routed_warnings

    camera = make_camera("tau2", unit=3, size=(32, 24))
    points = (10.0, 30.0, 50.0, 70.0)
    write_simulated_chamber(tmp_path / "c.h5", camera, ChamberPlan(
        setpoints_c=points, ambient_c=(15.0, 35.0), interval_s=10.0), seed=1)
    lin = fit_calibration(tmp_path / "c.h5", "lin")
    fpa = lin.fpa_range_c[1] + 10.0  # outside: its apply warns
    walk = simulate_flight(np.full((128, 128), SCENE_C), camera, n_frames=5, motion="walk",
                           fpa_c=fpa, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ThermocalWarning)
        temps = lin.apply(walk.frames, fpa_c=walk.fpa_c, time_s=walk.time_s)
    stop = threading.Event()

    def correcting() -> None:
        while not stop.is_set():
            rate_correction(lin, walk.frames, temps, fpa_c=walk.fpa_c, time_s=walk.time_s)

    with routed_warnings():
        other = threading.Thread(target=correcting)
        other.start()
        try:
            with caught_warnings() as caught:
                for k in range(400):
                    warnings.warn(f"pivot {k}", ThermocalWarning, stacklevel=1)
        finally:
            stop.set()
            other.join(30)
    assert len(caught) == 400
