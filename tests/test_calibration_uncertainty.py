"""A calibration's σ and domain from its cross-validation report (issue 18, items 1–2)."""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

from thermocal.calibration.base import OutsideCalibrationRangeWarning
from thermocal.calibration.registry import CALIBRATION_METHODS
from thermocal.calibration.report import CalibrationReport
from thermocal.calibration.uncertainty import MIN_GROWTH_PER_C, CalibrationSigma
from thermocal.camera.model import render
from thermocal.errors import InvalidInputError, OutsideDomainError
from thermocal.estimation.calibrated import OzMean, PivotCalibration
from thermocal.estimation.pipeline import estimate
from thermocal.simulate.flight import simulate_flight

G = math.sqrt(math.pi / 2)


def _report(**kw) -> CalibrationReport:
    folds = [
        {"kind": "setpoint", "held_out": 10.0, "extrapolation": True, "frames": 5, "mae_c": 0.5},
        {"kind": "setpoint", "held_out": 20.0, "extrapolation": False, "frames": 5, "mae_c": 0.2},
        {"kind": "setpoint", "held_out": 30.0, "extrapolation": False, "frames": 5, "mae_c": 0.4},
        {"kind": "setpoint", "held_out": 40.0, "extrapolation": True, "frames": 5, "mae_c": 0.6},
        {"kind": "fpa", "held_out": [20.0, 25.0], "extrapolation": True, "frames": 5,
         "mae_c": 1.3},
        {"kind": "fpa", "held_out": [25.0, 30.0], "extrapolation": False, "frames": 5,
         "mae_c": 0.3},
        {"kind": "fpa", "held_out": [30.0, 35.0], "extrapolation": True, "frames": 5,
         "mae_c": 0.3},
    ]
    args = {"method": "polynomial", "expected_mae_c": 0.3, "folds": folds,
            "fpa_range_c": (20.0, 35.0), "scene_range_c": (10.0, 40.0),
            "fpa_rate_c_per_min": (-0.5, 0.5),
            "by_rate": [{"rate_c_per_min": [0.0, 0.05], "frames": 5, "mae_c": 0.15},
                        {"rate_c_per_min": [0.5, 1.0], "frames": 5, "mae_c": 0.6}]}
    return CalibrationReport(**(args | kw))


def test_sigma_inside_follows_the_cross_validation():
    """Inside both ranges: the level (√(π/2) × MAE here: no rate, no σ stored) times 1 plus
    each curve's excess over its own interior folds' mean, relative to it."""
    model = CalibrationSigma(_report())
    s = model.sigma(np.array([[20.0, 25.0, 30.0]]), 27.5)
    np.testing.assert_allclose(s[0], G * np.array([0.2, 0.3, 0.4]), rtol=1e-6)
    # FPA folds that all err less (or more) than the set points' tell nothing of where σ is
    # larger: a segment left out is a gap of its own size; the level is the rate bins'
    better = CalibrationSigma(_report(folds=[
        f | {"mae_c": 0.15} if f["kind"] == "fpa" and not f["extrapolation"] else f
        for f in _report().folds]))
    np.testing.assert_allclose(better.sigma(np.array([[20.0, 25.0, 30.0]]), 27.5), s)
    # the rate: settled frames are better, fast ones worse; unknown rates average
    slow, fast, faster = (model.sigma(np.array([[25.0]]), 27.5, rate_c_per_min=[r])[0, 0]
                          for r in (0.01, -0.5, 1.0))
    assert slow == pytest.approx(G * 0.3 * 0.5, rel=1e-5)
    assert fast == pytest.approx(G * 0.3 * 2.0, rel=1e-5)
    # faster than the session ever changed (0.5 °C/min): σ grows with the rate
    assert faster == pytest.approx(2.0 * fast, rel=1e-5)


def test_sigma_grows_outside_without_bound():
    """Outside, σ grows linearly with the distance at the end folds' measured rate; beyond the
    one set-point step (10 °C here) those folds extrapolated, by the whole distance past it;
    beyond one end FPA segment (5 °C here), by UNMEASURED_FPA_GROWTH_PER_C per °C past it."""
    from thermocal.calibration.uncertainty import UNMEASURED_FPA_GROWTH_PER_C as UNMEASURED

    model = CalibrationSigma(_report())
    fpa_rate = (1.3 - 0.3) / 2.5  # excess MAE of the low end segment over half its width
    inside = model.sigma(np.array([[25.0]]), 27.5)[0, 0]
    for d in (1.0, 10.0, 100.0):
        out = model.sigma(np.array([[25.0]]), 20.0 - d)[0, 0]
        m_fpa = 0.3  # interpolated MAE clamps at the end of the interior curve
        expected = G * (0.3 + m_fpa - 0.3 + fpa_rate * d) + UNMEASURED * max(d - 5.0, 0.0)
        assert out == pytest.approx(expected, rel=1e-5) and out > inside
    hot = model.sigma(np.array([[140.0]]), 27.5)[0, 0]
    scene_rate = (0.6 - 0.3) / 10.0
    assert hot == pytest.approx(G * (0.4 + 0.3 - 0.3 + scene_rate * 100.0) + 90.0, rel=1e-5)
    near = model.sigma(np.array([[48.0]]), 27.5)[0, 0]  # 8 °C out: measured growth alone
    assert near == pytest.approx(G * (0.4 + 0.3 - 0.3 + scene_rate * 8.0), rel=1e-5)
    # a pixel clipped at the radiance tables' floor is not given a few degrees
    assert model.sigma(np.array([[-123.15]]), 27.5)[0, 0] > 120.0
    flat = CalibrationSigma(_report(folds=[f | {"mae_c": 0.1} for f in _report().folds],
                                    expected_mae_c=0.1))
    assert flat.sigma(np.array([[25.0]]), 45.0)[0, 0] == pytest.approx(
        G * (0.1 + MIN_GROWTH_PER_C * 10.0) + UNMEASURED * 5.0, rel=1e-5)


def test_outside_names_the_fpa_and_the_scene():
    model = CalibrationSigma(_report())
    assert model.outside(np.full((2, 4, 4), 25.0), [27.0, 28.0]) == ()
    (why,) = model.outside(np.full((1, 4, 4), 25.0), [36.0])
    assert "FPA temperature 36.0…36.0 °C is outside the 20.0…35.0 °C" in why
    (why,) = model.outside(np.full((1, 4, 4), 55.0), [27.0])
    assert "scene spans 55.0…55.0 °C" in why
    assert model.outside(np.full((1, 4, 4), 25.0), [27.0], rate_c_per_min=[0.6]) == ()
    (why,) = model.outside(np.full((1, 4, 4), 25.0), [27.0], rate_c_per_min=[-0.9])
    assert "FPA changes at up to 0.90 °C/min, faster than the 0.50 °C/min" in why


def test_a_scene_out_of_range_far_from_the_fits_fpa_names_the_fpa():
    """A two-point fitted at one FPA reads a scene out of range at an FPA far from it: the
    refusal says the FPA may be the cause (it blamed the scene alone); near it, it does not."""
    model = CalibrationSigma(_report(method="two-point"), fitted_fpa_c=(21.0, 21.0))
    (why,) = model.outside(np.full((1, 4, 4), 55.0), [34.0])
    assert "scene spans 55.0…55.0 °C" in why
    assert "fit made at FPA 21.0 °C, 13.0 °C from these frames'" in why
    (why,) = model.outside(np.full((1, 4, 4), 55.0), [24.0])
    assert "scene spans" in why and "fit made at" not in why
    assert "fit made at" not in CalibrationSigma(_report()).outside(
        np.full((1, 4, 4), 55.0), [34.0])[0]


def test_sparse_start_up_bins_are_pooled_with_the_bins_after_them():
    """The report's sample holds few frames of a recording's first minutes: a time bin of fewer
    than MIN_BIN_FRAMES frames is pooled with the next (the last with the one before), so that
    σ covers an online method's start-up instead of skipping it; rate bins stay as they are."""
    from thermocal.calibration.report import MIN_BIN_FRAMES, TIME_EDGES, _binned

    since = np.concatenate([[30.0], np.full(9, 200.0), np.full(24, 600.0), np.full(3, 2000.0)])
    errors = np.concatenate([np.full((10, 4), 5.0), np.full((24, 4), 1.0), np.full((3, 4), 2.0)])
    bins = _binned(errors, since, TIME_EDGES, "time_s", min_frames=MIN_BIN_FRAMES)
    assert [(b["time_s"], b["frames"]) for b in bins] == [([0.0, 300.0], 10),
                                                          ([300.0, None], 27)]
    assert bins[0]["mae_c"] == 5.0 and bins[1]["mae_c"] == pytest.approx(30.0 / 27)
    # one per edge, empty bins left out, without pooling
    plain = _binned(errors, since, TIME_EDGES, "time_s")
    assert [b["time_s"] for b in plain] == [[0.0, 60.0], [60.0, 300.0], [300.0, 900.0],
                                            [1800.0, None]]
    # σ in the pooled start-up; a report's bins of too few frames (made before) are skipped
    model = CalibrationSigma(_report(by_time=bins))
    np.testing.assert_allclose(model.start_sigma([30.0, 250.0, 5000.0]),
                               [bins[0]["sigma_c"]] * 2 + [bins[1]["sigma_c"]])
    assert model.start_sigma([30.0])[0] >= 5.0
    assert CalibrationSigma(_report(by_time=plain)).start_sigma([30.0])[0] == 0.0
    (few,) = _binned(errors[:5], since[:5], TIME_EDGES, "time_s", min_frames=MIN_BIN_FRAMES)
    assert few["time_s"] == [0.0, None] and few["frames"] == 5
    # pooled, no gap: frames only after the first minute still cover it
    late = _binned(errors[1:], since[1:], TIME_EDGES, "time_s", min_frames=MIN_BIN_FRAMES)
    assert late[0]["time_s"][0] == 0.0 and sum(b["frames"] for b in late) == 36


def test_report_survives_json_with_its_rate_bins():
    r = _report()
    again = CalibrationReport.from_dict(r.to_dict())
    assert again.by_rate == r.by_rate and again.folds == r.folds
    # damaged bins are refused when read, not met later as a KeyError
    good = r.to_dict()
    for bins in ([{"frames": 5, "mae_c": 0.1}],
                 [{"rate_c_per_min": [0.0, 0.05], "pace_c_per_min": [0.0, 0.05], "mae_c": 0.1}],
                 [{"rate_c_per_min": [0.0, 0.05], "mae_c": 0.1},
                  {"pace_c_per_min": [0.05, 0.2], "mae_c": 0.1}],
                 [{"rate_c_per_min": [0.2, 0.05], "mae_c": 0.1}],
                 [{"pace_c_per_min": [0.0, None], "mae_c": float("nan")}]):
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(good | {"mae_by_fpa_rate_c": bins})


def test_estimators_refuse_outside_and_give_sigma(fitted):
    camera, cal, report = fitted
    assert CalibrationSigma.of(cal).report == CalibrationReport.from_dict(report.to_dict())
    scene = 15.0 + 10.0 * np.random.default_rng(0).random((96, 96))
    fpa_in = 0.5 * sum(report.fpa_range_c)
    inside = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=fpa_in, seed=1)
    sigmas = []
    for estimator in (PivotCalibration(cal), OzMean(cal)):
        est = estimate(inside.frames, estimator, fpa_c=inside.fpa_c)
        assert est.outside == () and est.sigma_c.shape == (48, 64)
        assert np.all(est.sigma_c > 0)
        sigmas.append(est.sigma_c)
    # eq. 9's mean adds its views' spread, whole (its σ_cal at its own, slightly different
    # temperatures): above one frame's σ where the views disagree; the pivot alone adds at its
    # bad pixels, filled from their neighbours, their range (which the mean's other views see)
    good = ~cal.bad
    assert cal.bad.any() and np.all(sigmas[1][good] >= sigmas[0][good] - 0.02)
    assert np.median(sigmas[1] - sigmas[0]) > 0
    from thermocal.estimation.base import view_spread

    class Spy(OzMean):
        def uncertainty(self, burst, temperature_c, *, outside):
            self.seen = (burst, temperature_c)
            return super().uncertainty(burst, temperature_c, outside=outside)

    spy = Spy(cal)
    got = estimate(inside.frames, spy, fpa_c=inside.fpa_c).sigma_c
    burst, t = spy.seen
    cal_sigma = super(OzMean, spy).uncertainty(burst, t, outside=False)
    spread, _ = view_spread(burst.warped, burst.valid)  # not over √n: blur is alike in views
    np.testing.assert_allclose(got, np.hypot(cal_sigma, spread), rtol=1e-5)
    hot = simulate_flight(scene, camera, n_frames=5, motion="walk",
                          fpa_c=report.fpa_range_c[1] + 8.0, seed=1)
    with warnings.catch_warnings():  # refused: the refusal alone, no warning before it
        warnings.simplefilter("error")
        with pytest.raises(OutsideDomainError, match="FPA temperature .* is outside"):
            estimate(hot.frames, PivotCalibration(cal), fpa_c=hot.fpa_c)
    with pytest.warns(OutsideCalibrationRangeWarning, match="leave the calibrated range"):
        forced = estimate(hot.frames, PivotCalibration(cal), fpa_c=hot.fpa_c, force=True)
    normal = estimate(inside.frames, PivotCalibration(cal), fpa_c=inside.fpa_c)
    assert forced.outside and float(np.median(forced.sigma_c)) > float(np.median(normal.sigma_c))



# ---------------------------------------------------------------------------- paces


def _paced(**kw) -> CalibrationSigma:
    """A report whose session held the FPA still, then sped up at once to a steady 1.5 °C/min:
    the rate jumped (its lagged value still 0), then the lagged rate caught up."""
    jump = [[i, 0] for i in range(16)]
    hold = [[15, j] for j in range(16)]
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": [[0, 0], *jump, *hold]}
    return CalibrationSigma(_report(paces=paces, fpa_rate_c_per_min=(-0.1, 1.55), **kw))


def test_paces_a_memoryless_calibration_never_held_are_outside():
    """A steady 1 °C/min lies between the paces held (still, 1.5 °C/min) but was never held
    itself: outside, named, with the remedy; the paces held are inside; without paces (a method
    with memory, an older report) nothing is."""
    model = _paced()
    t = np.arange(0.0, 3600.0, 10.0)
    for pace, unseen in ((0.0, False), (1.5, False), (1.0, True), (-1.0, True)):
        rate = np.full(t.size, pace)
        assert model.unseen_paces(rate, t).all() == unseen
        # the pace alone, as one burst's is judged (`pace_unseen`): where rate terms are
        # unverified, whether `correct` or `estimate` asks
        assert model.paces_never_held(rate, t).all() == unseen
        assert model.pace_unseen(pace, pace) == unseen
        why = model.outside(np.full((t.size, 2, 2), 25.0), np.full(t.size, 27.0),
                            rate_c_per_min=rate, time_s=t)
        assert bool(why) == unseen
    (why,) = model.outside(np.full((t.size, 2, 2), 25.0), np.full(t.size, 27.0),
                           rate_c_per_min=np.full(t.size, 1.0), time_s=t)
    assert "paces its chamber session never held (360 of 360 frames" in why
    assert "+1.00 °C/min after +1.00 over the last 8 min" in why and "lin-lag" in why
    # a jump from still to 1 °C/min: held at first (the session jumped through it), not once
    # the lagged rate has caught up
    jump = np.where(t >= 100.0, 1.0, 0.0)
    assert not model.unseen_paces(jump, t)[:12].any() and model.unseen_paces(jump, t)[-1]
    # the distance in °C/min from the nearest cell held, less half a cell
    d = model.pace_distance(np.full(t.size, 1.0), t)
    assert d[-1] == pytest.approx(0.45, abs=0.01)
    assert not CalibrationSigma(_report()).unseen_paces(np.full(t.size, 1.0), t).any()
    assert not model.unseen_paces(np.full(t.size, 1.0), t[::-1]).any()  # not one recording
    empty = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": []}  # a report that lists none
    assert not CalibrationSigma(_report(paces=empty)).unseen_paces(np.full(t.size, 1.0), t).any()
    # σ at an unseen pace: the worst rate bin's σ times the distance in cells; seen: as before
    steady = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5, rate_c_per_min=np.full(t.size, 1.0),
                         time_since_start_s=t)[-1, 0, 0]
    worst = G * 0.6  # the 0.5–1 °C/min bin's √(π/2)·MAE
    assert steady == pytest.approx(worst * 4.5, rel=0.05)
    held = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5, rate_c_per_min=np.zeros(t.size),
                       time_since_start_s=t)[-1, 0, 0]
    assert held == pytest.approx(G * 0.3 * 0.5, rel=1e-5)
    # one frame (a burst) has no pace history: no pace σ, as it is never refused for its pace
    one, bare = (model.sigma(np.full((1, 1), 25.0), 27.5, rate_c_per_min=[1.0], **kw)[0, 0]
                 for kw in ({"time_since_start_s": [3590.0]}, {}))
    assert one == pytest.approx(bare) and one < steady / 2


def test_a_method_with_memory_is_refused_only_beyond_its_wider_margin():
    """Margin 0.3 °C/min (a method with memory): a steady 1.2 °C/min, 0.25 from the 1.5 held,
    is inside; a steady 1.0, 0.45 away, outside, named as beyond the margin with what to
    record; forced, its σ grows from the worst bin's at the margin by one per cell beyond;
    a report made before margins keeps one cell."""
    base = _paced()
    model = CalibrationSigma(replace(base.report, paces=base.report.paces
                                     | {"margin_c_per_min": 0.3}))
    t = np.arange(0.0, 3600.0, 10.0)
    temps = np.full((t.size, 2, 2), 25.0)
    for pace, unseen in ((1.2, False), (1.5, False), (1.0, True), (0.0, False)):
        rate = np.full(t.size, pace)
        assert model.unseen_paces(rate, t)[-1] == unseen, pace
        assert base.unseen_paces(rate, t)[-1] == (pace not in (1.5, 0.0)), pace
    (why,) = model.outside(temps, np.full(t.size, 27.0), rate_c_per_min=np.full(t.size, 1.0),
                           time_s=t)
    assert "more than 0.3 °C/min from any pace its chamber session held" in why
    assert "+1.00 °C/min after +1.00" in why and "record a session" in why
    inside = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5,
                         rate_c_per_min=np.full(t.size, 1.2), time_since_start_s=t)[-1, 0, 0]
    assert inside == pytest.approx(base.rate_sigma([1.2])[0], rel=1e-5)  # shape 1 here
    forced = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5,
                         rate_c_per_min=np.full(t.size, 1.0), time_since_start_s=t)[-1, 0, 0]
    assert forced == pytest.approx(G * 0.6 * 2.5, rel=0.05)  # 1.5 cells past the margin, +1
    again = CalibrationReport.from_dict(json.loads(json.dumps(model.report.to_dict())))
    assert again.paces["margin_c_per_min"] == 0.3
    with pytest.raises(InvalidInputError, match="not a calibration report"):
        CalibrationReport.from_dict(model.report.to_dict() | {"fpa_paces": {
            **model.report.to_dict()["fpa_paces"], "margin_c_per_min": 0.05}})


def test_a_bursts_pace_sigma_grows_only_at_paces_never_held():
    from thermocal.estimation.base import FpaPace

    model = _paced()
    t = np.arange(0.0, 3600.0, 10.0)  # the same as the recording's σ at a steady 1 °C/min
    steady = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5, rate_c_per_min=np.full(t.size, 1.0),
                         time_since_start_s=t)[-1, 0, 0]
    one = model.sigma(np.full((1, 1), 25.0), 27.5, rate_c_per_min=[1.0],
                      lagged_rate_c_per_min=[1.0])[0, 0]
    assert one == pytest.approx(steady, rel=1e-3)
    x = np.full((1, 1), 25.0)
    assert model.burst_sigma(x, 27.5, FpaPace(1.0, 1.0))[0, 0] == pytest.approx(one)
    assert model.burst_sigma(x, 27.5, FpaPace(0.0, 0.0))[0, 0] < one  # held still
    assert model.burst_sigma(x, 27.5, FpaPace(1.0)) == pytest.approx(
        model.sigma(x, 27.5, rate_c_per_min=[1.0]))  # no history: its rate alone


def test_fpa_pace_keeps_a_change_after_the_rate_stops():
    from thermocal.calibration.dataset import fpa_pace

    t = np.arange(0.0, 3600.0, 10.0)
    rate = np.where(t < 1800.0, 1.5, 0.0)  # a 1.5 °C/min ramp, then held
    pace = fpa_pace(rate, t, 480.0)
    assert pace[0] == 1.5 and pace[179] == pytest.approx(1.5, rel=1e-3)
    # 2 min after the stop the rate is 0 but the pace is the lag's 1.5·e^(−120/480)
    assert pace[192] == pytest.approx(1.5 * np.exp(-130.0 / 480.0), rel=1e-6)
    assert pace[-1] < 0.05 and np.all(np.diff(pace[180:]) < 0)
    # a second recording (time starts again) starts from its own first rate
    both = fpa_pace(np.r_[rate, np.zeros(t.size)], np.r_[t, t], 480.0)
    np.testing.assert_array_equal(both[: t.size], pace)
    assert not both[t.size:].any()


def test_a_memoryless_sigma_is_binned_by_pace():
    """Bins of the pace: the minutes after a ramp stops take the σ of the pace they follow,
    not of a settled camera; a rate with no history, the largest σ at or above it."""
    cells = [[i, j] for i in range(17) for j in range(17)]  # every pace held: none refused
    bins = [{"pace_c_per_min": [0.0, 0.05], "frames": 5, "mae_c": 0.15},
            {"pace_c_per_min": [0.5, 1.0], "frames": 5, "mae_c": 0.6},
            {"pace_c_per_min": [1.0, 2.0], "frames": 5, "mae_c": 0.9}]
    model = CalibrationSigma(_report(
        by_rate=bins, fpa_rate_c_per_min=(-0.1, 1.55),
        paces={"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": cells}))
    assert model.by_pace and not CalibrationSigma(_report()).by_pace
    t = np.arange(0.0, 3600.0, 10.0)
    rate = np.where(t < 1800.0, 1.5, 0.0)
    sigma = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5, rate_c_per_min=rate,
                        time_since_start_s=t)[:, 0, 0]
    assert sigma[100] == pytest.approx(G * 0.9, rel=1e-5)  # on the ramp
    assert sigma[192] == pytest.approx(G * 0.9, rel=1e-5)  # stopped 2 min: still 1.14 °C/min
    assert sigma[-1] == pytest.approx(G * 0.15, rel=1e-5)  # 30 min on: settled
    # one frame: the lagged rate given, or not known (the pace is at least the rate)
    one = model.sigma(np.full((1, 1), 25.0), 27.5, rate_c_per_min=[0.0],
                      lagged_rate_c_per_min=[0.7])[0, 0]
    bare = model.sigma(np.full((1, 1), 25.0), 27.5, rate_c_per_min=[0.7])[0, 0]
    assert one == pytest.approx(G * 0.6, rel=1e-5) and bare == pytest.approx(G * 0.9, rel=1e-5)


def test_a_memoryless_report_bins_its_errors_by_pace(fitted):
    _, _, report = fitted
    assert report.by_rate and all("pace_c_per_min" in b for b in report.by_rate)
    again = CalibrationReport.from_dict(json.loads(json.dumps(report.to_dict())))
    assert CalibrationSigma(again).by_pace
    # and by how far the pace was from steady, bins of the same frames
    assert report.by_change and again.by_change == report.by_change
    assert sum(b["frames"] for b in report.by_change) == sum(b["frames"] for b in report.by_rate)
    assert [b["change_c_per_min"][0] for b in report.by_change][0] == 0.0


def test_fpa_change_is_the_rate_less_its_lagged_rate():
    from thermocal.calibration.dataset import fpa_change, lagged_rate

    t = np.arange(0.0, 3600.0, 10.0)
    rate = np.where(t < 1800.0, 0.0, 1.0)  # held, then a 1 °C/min ramp
    change = fpa_change(rate, t, 480.0)
    np.testing.assert_allclose(change, np.abs(rate - lagged_rate(rate, t, 480.0)))
    assert change[179] == 0.0 and change[180] > 0.9 and change[-1] < 0.05  # settles on the ramp
    both = fpa_change(np.r_[rate, rate], np.r_[t, t], 480.0)  # two recordings: each its own
    np.testing.assert_array_equal(both[t.size:], change)


def test_a_memoryless_sigma_grows_just_after_the_pace_changed():
    """A pace bin pools a steady ramp with the minutes after a step at the same pace: a frame's
    σ is at least its change bin's (|rate − lagged rate|, the bins above the steady one), given
    with the frame or from its recording; a report without change bins (a method with memory,
    an older file) keeps the pace bins alone."""
    cells = [[i, j] for i in range(-17, 17) for j in range(-17, 17)]
    bins = [{"pace_c_per_min": [0.0, 0.05], "frames": 5, "mae_c": 0.15},
            {"pace_c_per_min": [1.0, 2.0], "frames": 5, "mae_c": 0.5}]
    change = [{"change_c_per_min": [0.0, 0.5], "frames": 20, "mae_c": 0.2, "sigma_c": 0.3},
              {"change_c_per_min": [0.5, None], "frames": 20, "mae_c": 1.0, "sigma_c": 1.2}]
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": cells}
    model = CalibrationSigma(_report(by_rate=bins, fpa_rate_c_per_min=(-1.6, 1.6), paces=paces,
                                     by_change=change))
    plain = CalibrationSigma(_report(by_rate=bins, fpa_rate_c_per_min=(-1.6, 1.6), paces=paces))
    t = np.arange(0.0, 3600.0, 10.0)
    rate = np.where(t < 1800.0, 0.0, 1.5)  # held, then a 1.5 °C/min ramp
    temps = np.full((t.size, 1, 1), 25.0)
    sigma = model.sigma(temps, 27.5, rate_c_per_min=rate, time_since_start_s=t)[:, 0, 0]
    before = plain.sigma(temps, 27.5, rate_c_per_min=rate, time_since_start_s=t)[:, 0, 0]
    assert sigma[181] == pytest.approx(1.2, rel=1e-5) and before[181] == pytest.approx(G * 0.5)
    assert sigma[-1] == pytest.approx(G * 0.5, rel=1e-5) == before[-1]  # steady on the ramp
    # held: the pace bin's; the steady change bin (0.3) is not used, it pools plateaus and ramps
    assert sigma[100] == pytest.approx(G * 0.15, rel=1e-5)
    one = model.sigma(np.full((1, 1), 25.0), 27.5, rate_c_per_min=[1.5],
                      lagged_rate_c_per_min=[0.2])[0, 0]
    assert one == pytest.approx(1.2, rel=1e-5)
    again = CalibrationReport.from_dict(json.loads(json.dumps(model.report.to_dict())))
    assert again.by_change == change
    # a burst's pace (selfcal's level) and a rate not known take it too
    from thermocal.estimation.base import FpaPace

    x = np.full((1, 1), 25.0)
    assert model.burst_sigma(x, 27.5, FpaPace(1.5, 0.2, None))[0, 0] == pytest.approx(1.2)
    assert plain.burst_sigma(x, 27.5, FpaPace(1.5, 0.2, None))[0, 0] < 1.2
    assert model.change_sigma([np.nan, 0.1]).tolist() == [1.2, 0.0]


def test_a_change_near_a_bins_upper_edge_takes_some_of_the_larger_sigma_above():
    """The change bins sample an error that grows with the change: between a bin's centre and
    the next's, where that bin's σ is larger by no more than the centres' ratio, a frame's σ
    is never below the line between the two (the open last bin's centre half the width of the
    one below above its edge); where σ falls to the next bin (a settling regime's bin), or
    jumps beyond proportion (another regime), the bins stay as they are; the steady bin is not
    used, as before."""
    change = [{"change_c_per_min": [0.0, 0.05], "frames": 20, "sigma_c": 5.0},
              {"change_c_per_min": [0.05, 0.2], "frames": 20, "sigma_c": 1.0},
              {"change_c_per_min": [0.2, 0.5], "frames": 20, "sigma_c": 0.4},
              {"change_c_per_min": [0.5, 1.0], "frames": 20, "sigma_c": 0.8},
              {"change_c_per_min": [1.0, None], "frames": 20, "sigma_c": 1.2}]
    model = CalibrationSigma(_report(by_change=change))
    got = model.change_sigma([0.01, 0.1, 0.2, 0.35, 0.45, 0.6, 0.75, 0.875, 1.0, 1.25, 9.0,
                              np.nan])
    # 0.875 lies halfway from the 0.5–1 bin's centre (0.75) to the last's (1.25): 0.8 + 0.4 / 4
    # and 0.45 a quarter of the way from 0.35 (0.4) to 0.75 (0.8); 0.2, where σ fell: as was
    np.testing.assert_allclose(got, [0.0, 1.0, 0.4, 0.4, 0.5, 0.8, 0.8, 0.9, 1.2, 1.2, 1.2,
                                     1.2])
    jump = [dict(b) for b in change]
    jump[3]["sigma_c"] = 0.4 * 0.75 / 0.35 + 0.01  # beyond proportion to the change
    model = CalibrationSigma(_report(by_change=jump))
    assert model.change_sigma([0.45])[0] == pytest.approx(0.4)
    assert model.change_sigma([0.875])[0] > jump[3]["sigma_c"]  # 0.87 → 1.2: in proportion
    # bins with a gap, in any order: the open bin's centre half the width of the one below
    # (0.15) above its edge, 1.15; σ 1.0 → 3.5 is beyond 1.15 / 0.35: steps
    gap = [{"change_c_per_min": [1.0, None], "frames": 20, "sigma_c": 3.5},
           {"change_c_per_min": [0.2, 0.5], "frames": 20, "sigma_c": 1.0}]
    np.testing.assert_allclose(CalibrationSigma(_report(by_change=gap)).change_sigma(
        [0.45, 0.7, 1.1]), [1.0, 0.0, 3.5])


@pytest.mark.parametrize("bins, ok", [
    ([{"change_c_per_min": ["0.5", None], "frames": "7", "sigma_c": "1.2"}], True),
    ([{"change_c_per_min": [0.5, 0.2], "frames": 7, "sigma_c": 1.2}], False),
    ([{"change_c_per_min": [0.5, None], "frames": 7, "sigma_c": "nan"}], False),
    ([{"change_c_per_min": [0.5, None], "frames": 1e400, "sigma_c": 1.2}], False),
    ([{"change_c_per_min": [0.5, None], "frames": 7.5, "sigma_c": 1.2}], False),
    ([{"change_c_per_min": None, "frames": 7, "sigma_c": 1.2}], False),
    ([{"change_c_per_min": [-1, None], "frames": 7, "sigma_c": 1.2}], False),
    ([{"frames": 7, "sigma_c": 1.2}], False),
    ("a string", False),
])
def test_change_bins_are_read_back_checked_as_numbers(bins, ok):
    """A damaged report's change bins: refused in one line, or kept as the numbers they
    spell (never a string that σ then trips over)."""
    d = _report().to_dict() | {"mae_by_fpa_change_c": bins}
    if not ok:
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(d)
        return
    report = CalibrationReport.from_dict(d)
    assert report.by_change == [{"change_c_per_min": [0.5, None], "frames": 7, "sigma_c": 1.2}]
    assert CalibrationSigma(report).change_sigma([0.7]).tolist() == [1.2]


def _stilled() -> CalibrationSigma:
    """:func:`_paced`, from a session that had not settled, whose plateaus held the FPA still
    for 10 minutes (median of 4)."""
    model = _paced()
    still = {"band_c": 0.15, "held_s": 600.0, "plateaus": 4}
    from dataclasses import replace

    return CalibrationSigma(replace(model.report, paces=model.report.paces | {"still": still}))


def test_still_time_is_the_run_behind_each_frame_within_its_band():
    """Against the definition, frame by frame (a random walk, a recording gap)."""
    from thermocal.calibration.dataset import still_time

    def by_definition(f, t, band, gap):
        out = np.zeros(f.size)
        for i in range(f.size):
            j = i
            while j > 0 and abs(f[j - 1] - f[i]) <= band and t[j] - t[j - 1] <= gap:
                j -= 1
            out[i] = t[i] - t[j]
        return out

    rng = np.random.default_rng(1)
    for scale in (0.02, 0.05, 0.2):
        f = 30.0 + np.cumsum(rng.normal(0.0, scale, 400))
        t = np.cumsum(rng.uniform(0.5, 2.0, 400))
        t[200:] += 100.0  # a new recording
        np.testing.assert_allclose(still_time(f, t, band_c=0.15, max_gap_s=50.0),
                                   by_definition(f, t, 0.15, 50.0))
    assert still_time([], [], band_c=0.15, max_gap_s=50.0).shape == (0,)
    with pytest.raises(InvalidInputError, match="must be equal"):
        still_time([1.0, 2.0], [0.0], band_c=0.15, max_gap_s=50.0)


def test_a_camera_held_still_longer_than_an_unsettled_session_is_outside():
    """A recording held at 26.7 °C for a minute, stepped to 27 °C and held for 20 minutes (a
    quantised sensor flickering by 0.01 °C): after the step, inside for the 10 minutes the
    session's plateaus held, then outside, named with the remedy, σ grown with the excess;
    before it, still since the recording began, not known (below); nothing is judged by a
    report that lists no stillness (a session that settled)."""
    from thermocal.calibration.dataset import recording_fpa_rates
    from thermocal.estimation.base import FpaPace

    model = _stilled()
    t = np.arange(0.0, 1300.0, 10.0)
    fpa = np.where(t < 60.0, 26.7, 27.0) + 0.01 * (np.arange(t.size) % 2)
    rate, temps = recording_fpa_rates(fpa, t), np.full((t.size, 1, 1), 25.0)
    unseen = model.unseen_paces(rate, t, fpa_c=fpa)
    assert unseen[t < 25.0].all()  # still since it began: not known
    assert not unseen[(t > 25.0) & (t < 600.0)].any() and unseen[t > 720.0].all()
    assert not model.unseen_paces(rate, t).any()  # without the FPA: its pace only
    reasons = model.outside(temps, fpa, rate_c_per_min=rate, time_s=t)
    (why,) = [r for r in reasons if "longer than the plateaus" in r]
    assert "held its FPA still (" in why and "at 27.0 °C for 10." in why
    assert "record plateaus long enough" in why and "lin-lag" in why
    sigma = model.sigma(temps, fpa, rate_c_per_min=rate, time_since_start_s=t)[:, 0, 0]
    worst = G * 0.6
    assert sigma[-1] == pytest.approx(worst * 1210.0 / 600.0, rel=0.05)
    assert np.all(sigma[(t > 25.0) & (t < 600.0)] < worst)
    settled = _paced()
    assert settled.outside(temps, fpa, rate_c_per_min=rate, time_s=t) == ()
    # a burst: its stillness from its recording (FpaPace.still_s), with or without its FPA
    one = model.outside_burst(np.full((3, 1, 1), 25.0), 27.0, FpaPace(0.0, 0.0, 900.0))
    assert len(one) == 1 and "at 27.0 °C for 15.0 min), 1.50× longer" in one[0]
    (bare,) = model.outside_burst(np.full((3, 1, 1), 25.0), None, FpaPace(0.0, 0.0, 900.0))
    assert "(for 15.0 min), 1.50× longer" in bare
    assert model.outside_burst(np.full((3, 1, 1), 25.0), 27.0, FpaPace(0.0, 0.0, 500.0),
                               time_since_start_s=800.0) == ()
    x = np.full((1, 1), 25.0)
    assert model.burst_sigma(x, 27.0, FpaPace(0.0, 0.0, 900.0))[0, 0] == pytest.approx(
        worst * 1.5)
    assert model.burst_sigma(x, 27.0, FpaPace(0.0, 0.0, 500.0),
                             time_since_start_s=800.0)[0, 0] < worst
    np.testing.assert_allclose(model.still_excess([300.0, 1200.0]), [0.5, 2.0])
    np.testing.assert_array_equal(settled.still_excess([1200.0]), [0.0])


def test_a_stillness_its_recording_cannot_show_is_outside_an_unsettled_sessions():
    """Still since the recording began, or no FPA series at all (one value, --fpa-c; a burst
    without its recording's pace): how long before the camera was held still is not known, and
    a session whose plateaus ended before the camera settled cannot vouch for it (a settled
    `boson` camera through such a `lin-level`: 2.1 °C off, σ 0.9): outside, named with the
    remedy; σ as if held UNKNOWN_STILL_EXCESS times the plateaus. A session that settled lists
    no stillness and judges none of it."""
    from thermocal.calibration.uncertainty import UNKNOWN_STILL_EXCESS
    from thermocal.estimation.base import FpaPace

    model, settled = _stilled(), _paced()
    worst = G * 0.6
    t = np.arange(0.0, 300.0, 10.0)
    rate, temps = np.zeros(t.size), np.full((t.size, 1, 1), 25.0)
    fpa = 27.0 + 0.01 * (np.arange(t.size) % 2)
    assert model.unseen_paces(rate, t, fpa_c=fpa).all()
    (why,) = model.outside(temps, fpa, rate_c_per_min=rate, time_s=t)
    assert "its FPA was still throughout its recording (30 of 30 frames; first 0.0 min" in why
    assert "ended before the camera settled (10 min)" in why and "lin-lag" in why
    unknown = worst * UNKNOWN_STILL_EXCESS
    np.testing.assert_allclose(
        model.sigma(temps, fpa, rate_c_per_min=rate, time_since_start_s=t)[:, 0, 0], unknown,
        rtol=1e-6)
    for given in (np.full(t.size, 27.0), 27.0):  # one value for the whole recording
        (why,) = model.outside(temps, given, rate_c_per_min=rate, time_s=t)
        assert "no history of its FPA was given (30 of 30 frames" in why
        assert model.sigma(temps, given, rate_c_per_min=rate,
                           time_since_start_s=t)[-1, 0, 0] == pytest.approx(unknown)
        assert settled.outside(temps, given, rate_c_per_min=rate, time_s=t) == ()
    # a burst: without a pace, or still since its recording began
    burst = np.full((3, 1, 1), 25.0)
    for pace, since in ((None, None), (FpaPace(0.0, 0.0, None), 40.0),
                        (FpaPace(0.0, 0.0, 500.0), 500.0)):
        (why,) = model.outside_burst(burst, 27.0, pace, time_since_start_s=since)
        assert "how long the camera had held it still is not known" in why
        assert model.burst_sigma(burst[0], 27.0, pace, time_since_start_s=since)[0, 0] == \
            pytest.approx(unknown)
        assert settled.outside_burst(burst, 27.0, pace, time_since_start_s=since) == ()
    # the recording moved before: known, and inside
    assert model.outside_burst(burst, 27.0, FpaPace(0.0, 0.0, 500.0),
                               time_since_start_s=501.0) == ()
    # one stillness (not known) for frames with rates of their own: those the rate says were
    # moving are known not to be still
    moving = np.where(t < 150.0, 0.0, 1.0)
    (why,) = model.outside(temps, fpa, rate_c_per_min=moving, still_s=[np.nan])
    assert "(15 of 30 frames; a constant FPA temperature" in why
    sigma = model.sigma(temps, fpa, rate_c_per_min=moving, still_s=[np.nan])[:, 0, 0]
    assert np.all(sigma[t < 150.0] == pytest.approx(unknown)) and np.all(sigma[t > 150] < unknown)
    # and with each frame's time since its recording began: one held 500 s, known where the
    # recording had run longer
    (why,) = model.outside(temps, fpa, still_s=[500.0], time_since_start_s=t + 300.0)
    assert "(21 of 30 frames; first" in why
    with pytest.raises(InvalidInputError, match="still_s has 3 values and time_since_start_s"):
        model.outside(temps, fpa, still_s=[1.0, 2.0, 3.0], time_since_start_s=t)


def test_stillness_survives_json_and_is_checked():
    model = _stilled()
    again = CalibrationReport.from_dict(json.loads(json.dumps(model.report.to_dict())))
    assert again.paces == model.report.paces
    for bad in ({"band_c": 0.0}, {"held_s": -1.0}, {"held_s": math.inf}, {"plateaus": 0},
                {"plateaus": 1.5}, {"plateaus": True}):
        paces = model.report.to_dict()["fpa_paces"]
        paces = paces | {"still": paces["still"] | bad}
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(model.report.to_dict() | {"fpa_paces": paces})


def test_paces_survive_json_and_are_checked():
    model = _paced()
    again = CalibrationReport.from_dict(model.report.to_dict())
    assert again.paces == model.report.paces
    bad = model.report.to_dict() | {"fpa_paces": {"lag_s": 0.0, "cell_c_per_min": 0.1,
                                                  "cells": [[0, 0]]}}
    with pytest.raises(InvalidInputError, match="not a calibration report"):
        CalibrationReport.from_dict(bad)


def test_reports_list_their_paces_with_a_margin_by_memory(fitted):
    """The report of a method without memory of the FPA's pace lists the paces of its session
    (a 0.25 °C/min sawtooth: steady near ±0.25 and still at its turns), a frame inside within
    a cell of them; lin-lag's and wolf2016's (their models follow the pace's history or learn
    it) within MEMORY_PACE_MARGIN_C_PER_MIN."""
    from thermocal.calibration.report import MEMORY_PACE_MARGIN_C_PER_MIN

    _, _, report = fitted
    cells = np.array(report.paces["cells"])
    assert report.paces["lag_s"] == 480.0 and len(cells) >= 3
    assert report.paces["margin_c_per_min"] == report.paces["cell_c_per_min"] == 0.1
    assert MEMORY_PACE_MARGIN_C_PER_MIN == 0.3  # lin-lag's: test_calibration_report
    assert [2, 2] in cells.tolist() or [3, 3] in cells.tolist()
    assert not CALIBRATION_METHODS["lin-lag"].memoryless
    assert not CALIBRATION_METHODS["wolf2016"].memoryless
    assert all(CALIBRATION_METHODS[m].memoryless
               for m in ("two-point", "one-point", "polynomial", "lin", "lin-level"))


def test_correct_refuses_a_pace_its_calibration_never_held(fitted, tmp_path, capsys):
    """`thermocal correct`: a recording whose FPA climbs steadily at 1 °C/min, through a
    calibration whose session held only ±0.25 °C/min: exit 2, one line naming the paces and
    lin-lag; --force writes the temperatures with σ grown; the same recording held still is
    corrected."""
    from tests.cli_run import run
    from thermocal.io.recording import Recording, write_recording

    camera, cal, report = fitted
    cal_path = cal.save(tmp_path / "cal.h5")
    t = np.arange(0.0, 600.0, 10.0)
    lo = report.fpa_range_c[0] + 2.0
    paths = {}
    for name, fpa in (("climb", lo + t / 60.0), ("still", np.full(t.size, lo + 5.0))):
        frames = render(camera, np.full(t.size, 25.0), fpa, housing_c=fpa - 1.5,
                        rng=np.random.default_rng(0))
        paths[name], _ = write_recording(tmp_path / f"{name}.tiff",
                                         Recording(frames, fpa_c=fpa, time_s=t))
    args = ["correct", paths["climb"], "--calibration", cal_path, "--out", tmp_path / "t.tiff",
            "--sigma-out", tmp_path / "s.tiff"]
    code, _, err = run(args, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "paces its chamber session never held" in err and "lin-lag" in err
    assert not (tmp_path / "t.tiff").exists() and not (tmp_path / "s.tiff").exists()
    code, _, err = run(args + ["--force"], capsys)
    assert code == 0 and "corrected all the same (--force)" in err
    import tifffile

    forced = tifffile.imread(tmp_path / "s.tiff")
    code, _, err = run(["correct", paths["still"], "--calibration", cal_path, "--out",
                        tmp_path / "t2.tiff", "--sigma-out", tmp_path / "s2.tiff"], capsys)
    assert code == 0, err
    still = tifffile.imread(tmp_path / "s2.tiff")
    assert np.median(forced[-10:]) > 2.0 * np.median(still[-10:])
    for path, other in (("t2.tiff", {"sigma": "s2.tiff"}), ("s2.tiff", {"temperature": "t2.tiff"})):
        with tifffile.TiffFile(tmp_path / path) as tif:  # each says what it is, and whence
            about = json.loads(tif.pages[0].description)
        assert about | {"quantity": "", "shape": 0} == {
            "quantity": "", "shape": 0, "unit": "degC", "method": cal.method,
            "calibration": "cal.h5", "source": "still.tiff", **other}


def test_flight_refuses_the_groups_at_paces_its_calibration_never_held(fitted, tmp_path):
    """`thermocal flight` through a calibration judges each group by the recording's pace at
    its pivot: held still, then climbing steadily at 1 °C/min (the session held ±0.25): the
    climbing groups are refused with the reason; --force maps them with σ grown."""
    from thermocal.io.recording import Recording, read_temperature_tiff, write_recording
    from thermocal.pipeline.flight import FlightOptions, process_flight

    camera, cal, report = fitted
    cal_path = cal.save(tmp_path / "cal.h5")
    t = np.arange(0.0, 1800.0, 10.0)
    fpa = report.fpa_range_c[0] + 2.0 + np.maximum(t - 600.0, 0.0) / 60.0
    frames = render(camera, np.full(t.size, 25.0), fpa, housing_c=fpa - 1.5,
                    rng=np.random.default_rng(0))
    rec, _ = write_recording(tmp_path / "rec.tiff", Recording(frames, fpa_c=fpa, time_s=t))
    options = {"method": "calibration", "calibration": str(cal_path), "frames": 1,
               "stride": 30, "preview_every": 0}
    summary = process_flight(rec, tmp_path / "out", FlightOptions(**options))
    log = [json.loads(line) for line in (tmp_path / "out" / "log.jsonl").read_text().splitlines()]
    refused = [e["frame"] for e in log if "error" in e]
    assert refused and all(f * 10.0 >= 600.0 for f in refused)
    assert all("paces its chamber session never held" in e["error"] for e in log if "error" in e)
    assert summary["failed"] == len(refused) < len(log)
    forced = process_flight(rec, tmp_path / "forced", FlightOptions(**options, force=True))
    assert forced["failed"] == 0
    last = max(refused)
    sig = read_temperature_tiff(tmp_path / "forced" / "temps" / f"frame_{last:06d}_sigma.tiff")
    first = read_temperature_tiff(tmp_path / "forced" / "temps" / "frame_000000_sigma.tiff")
    assert np.median(sig) > 2.0 * np.median(first)


def test_the_pipeline_judges_a_bursts_pace_from_its_recording(fitted):
    """`estimate()` given a burst's FPA rate and its rate through the pace's lag (what a
    recording tells of the minutes before): a steady 1 °C/min the session never held is
    refused with the reason and the remedy; forced, its σ grows; a steady pace the session
    held, or no lagged rate (no history), passes as before."""
    camera, cal, report = fitted
    scene = 15.0 + 10.0 * np.random.default_rng(0).random((96, 96))
    fpa = 0.5 * sum(report.fpa_range_c)
    burst = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=fpa, seed=1)
    estimator = PivotCalibration(cal)
    args = {"fpa_c": burst.fpa_c, "time_since_start_s": 900.0}
    with pytest.raises(OutsideDomainError, match="paces its chamber session never held "
                                                 r"\(\+1\.00 °C/min after \+1\.00"):
        estimate(burst.frames, estimator, fpa_rate_c_per_min=1.0,
                 fpa_lagged_rate_c_per_min=1.0, **args)
    forced = estimate(burst.frames, estimator, fpa_rate_c_per_min=1.0,
                      fpa_lagged_rate_c_per_min=1.0, force=True, **args)
    pace, rate = forced.outside  # and faster than the session's fastest (0.31 °C/min)
    assert "lin-lag" in pace and "faster than the 0.31 °C/min" in rate
    held = estimate(burst.frames, estimator, fpa_rate_c_per_min=0.25,
                    fpa_lagged_rate_c_per_min=0.25, **args)
    assert held.outside == ()
    assert np.median(forced.sigma_c) > 2.0 * np.median(held.sigma_c)
    no_history = estimate(burst.frames, estimator, fpa_rate_c_per_min=0.25, **args)
    assert no_history.outside == ()
    np.testing.assert_array_equal(no_history.temperature_c, held.temperature_c)


def test_a_burst_late_in_its_recording_takes_the_sigma_of_frames_without_history(fitted):
    """A burst is calibrated without its recording's FPA history (a model remembering the
    FPA's rates starts steady at it): σ is that of frames taken alone however long the
    recording had run (it faded with the time since the flight began: σ 0.16 °C for
    1.7 °C errors of lin-lag bursts late in a flight)."""
    from dataclasses import replace

    camera, cal, report = fitted
    scene = 15.0 + 10.0 * np.random.default_rng(0).random((96, 96))
    burst = simulate_flight(scene, camera, n_frames=5, motion="walk",
                            fpa_c=0.5 * sum(report.fpa_range_c), seed=1)
    estimator = PivotCalibration(cal)
    plain = estimate(burst.frames, estimator, fpa_c=burst.fpa_c, time_since_start_s=3600.0)
    alone = {"sigma_c": 3.0, "mae_c": 2.5, "lag_s": 480.0, "frames": 10}
    estimator.sigma_model = CalibrationSigma(replace(report, without_history=alone))
    late = estimate(burst.frames, estimator, fpa_c=burst.fpa_c, time_since_start_s=3600.0)
    assert np.median(plain.sigma_c) < 1.0 <= 3.0 <= late.sigma_c.min()
    # given its recording's lagged rates (its history seen), σ fades with the time since
    seen = estimate(burst.frames, estimator, fpa_c=burst.fpa_c, time_since_start_s=3600.0,
                    fpa_rate_c_per_min=0.0, fpa_lag_rates_c_per_min=[0.0, 0.0])
    assert np.median(seen.sigma_c) < 1.0


def test_the_pipeline_judges_a_bursts_stillness_from_its_recording(fitted):
    """Given how long the FPA had held still (from its recording), a calibration whose session
    had not settled refuses a burst held still longer than the session was, and forced, grows
    its σ; shorter, as before."""
    from dataclasses import replace

    camera, cal, report = fitted
    scene = 15.0 + 10.0 * np.random.default_rng(0).random((96, 96))
    fpa = 0.5 * sum(report.fpa_range_c)
    burst = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=fpa, seed=1)
    estimator = PivotCalibration(cal)
    still = {"band_c": 0.15, "held_s": 600.0, "plateaus": 3}
    estimator.sigma_model = CalibrationSigma(replace(report, paces=report.paces | {
        "still": still}))
    args = {"fpa_c": burst.fpa_c, "fpa_rate_c_per_min": 0.0, "fpa_lagged_rate_c_per_min": 0.0}
    with pytest.raises(OutsideDomainError, match="held its FPA still .* 3.00× longer"):
        estimate(burst.frames, estimator, fpa_still_s=1800.0, **args)
    forced = estimate(burst.frames, estimator, fpa_still_s=1800.0, force=True, **args)
    held = estimate(burst.frames, estimator, fpa_still_s=300.0, **args)
    assert held.outside == () and len(forced.outside) == 1
    assert np.median(forced.sigma_c) > 2.0 * np.median(held.sigma_c)
    np.testing.assert_array_equal(forced.temperature_c, held.temperature_c)
    # held still since its recording began: how long before is not known
    with pytest.raises(OutsideDomainError, match="how long the camera had held it still is not"):
        estimate(burst.frames, estimator, fpa_still_s=300.0, time_since_start_s=300.0, **args)
    later = estimate(burst.frames, estimator, fpa_still_s=300.0, time_since_start_s=900.0,
                     **args)
    assert later.outside == () and np.array_equal(later.sigma_c, held.sigma_c)
    # without its rate a burst has no pace, nor a stillness: not known either
    with pytest.raises(OutsideDomainError, match="no history of its FPA was given"):
        estimate(burst.frames, estimator, fpa_c=burst.fpa_c, fpa_still_s=1800.0)
    bare = estimate(burst.frames, estimator, fpa_c=burst.fpa_c, force=True)
    assert np.median(bare.sigma_c) > 2.0 * np.median(held.sigma_c)


def test_a_flight_lags_the_rate_by_its_calibrations_own_pace_lag(fitted):
    """A recording's lagged rates (flight, estimate) use the lag the calibration's paces were
    binned at (its report's ``lag_s``), not a constant; none without a calibration's σ (a
    network); its stillness only where the report judges it (a session that had not
    settled)."""
    from dataclasses import replace

    from thermocal.calibration.dataset import lagged_rate
    from thermocal.estimation.paces import recording_paces

    _, cal, report = fitted
    t = np.arange(0.0, 1200.0, 10.0)
    fpa = 30.0 + np.maximum(t - 300.0, 0.0) / 120.0  # still, then 0.5 °C/min
    estimator = PivotCalibration(cal)
    history = recording_paces(fpa, t, estimator.fpa_paces)
    rates = history["fpa_rate_c_per_min"]
    assert rates[-1] == pytest.approx(0.5, abs=0.01) and rates[10] == pytest.approx(0.0)
    np.testing.assert_array_equal(history["fpa_lagged_rate_c_per_min"],
                                  lagged_rate(rates, t, report.paces["lag_s"]))
    assert history["fpa_still_s"] is None and "still" not in report.paces
    estimator.sigma_model = CalibrationSigma(replace(report, paces=report.paces | {
        "lag_s": 60.0, "still": {"band_c": 0.15, "held_s": 120.0, "plateaus": 2}}))
    history = recording_paces(fpa, t, estimator.fpa_paces)
    np.testing.assert_array_equal(history["fpa_lagged_rate_c_per_min"],
                                  lagged_rate(rates, t, 60.0))
    still = history["fpa_still_s"]
    assert still[30] == 300.0 and still[-10] == 10.0  # rising 0.083 °C a frame
    for none in (recording_paces(fpa, t, {}), recording_paces(fpa, t[::-1], estimator.fpa_paces)):
        assert none["fpa_lagged_rate_c_per_min"] is None and none["fpa_still_s"] is None


def test_the_unmeasured_growth_starts_where_each_end_fold_stopped():
    """Set points 10, 20, 30, 60 °C: the hot end's fold extrapolated 30 °C (60 left out, fitted
    on 10–30), the cold end's 10 °C; σ grows by the whole distance only past those."""
    folds = [f | {"held_out": 60.0} if f["kind"] == "setpoint" and f["held_out"] == 40.0 else f
             for f in _report().folds]
    model = CalibrationSigma(_report(folds=folds, scene_range_c=(10.0, 60.0)))
    _, _, k_scene, _, ends = model._curves
    assert ends == (10.0, 30.0)
    s = {t: float(model.sigma(np.array([[t]]), 27.5)[0, 0]) for t in (80.0, 100.0, -5.0, -10.0)}
    assert s[100.0] - s[80.0] == pytest.approx(G * k_scene * 20.0 + 10.0, rel=1e-4)
    assert s[-10.0] - s[-5.0] == pytest.approx(G * k_scene * 5.0 + 5.0, rel=1e-4)


def test_a_report_of_an_older_thermocal_says_what_it_lacks(fitted, tmp_path):
    """A report without paces (all methods), or a memoryless method's without change bins:
    said, with the remedy, when an estimator is made of it; one made now: nothing."""
    import warnings

    from thermocal.calibration.base import ThermocalWarning
    from thermocal.estimation.calibrated import PivotCalibration

    assert "no FPA paces" in CalibrationSigma(_report()).older_report()
    paced = _report(paces={"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": [[0, 0]]})
    assert "pace is from steady" in CalibrationSigma(paced).older_report()
    assert "FPA history" in CalibrationSigma(replace(paced, method="lin-lag")).older_report()
    alone = {"sigma_c": 0.2, "mae_c": 0.17, "lag_s": 480.0, "frames": 10}
    assert "ran one way" in CalibrationSigma(replace(paced, method="lin-lag",
                                                     without_history=alone)).older_report()
    swung = replace(paced, paces=paced.paces | {"swing": {
        "band_c_per_min": 0.1, "slack_c": 1.0, "rise_c": 5.0, "fall_c": 0.0}})
    assert CalibrationSigma(replace(swung, method="lin-lag",
                                    without_history=alone)).older_report() is None
    still = {"band_c": 0.15, "held_s": 240.0, "plateaus": 6}  # plateaus, but not their drift
    stilled = replace(swung, method="lin-lag", without_history=alone,
                      paces=swung.paces | {"still": still})
    assert "drifted at its plateaus' ends" in CalibrationSigma(stilled).older_report()
    settled = replace(stilled, paces=stilled.paces | {"settling": still | {
        "slope_c_per_min": 0.01, "window_s": 480.0}})
    assert CalibrationSigma(settled).older_report() is None
    _, cal, report = fitted
    assert CalibrationSigma(report).older_report() is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", ThermocalWarning)
        PivotCalibration(cal)  # made now: no warning
    old = replace(cal, info=cal.info | {"report": replace(report, by_change=[]).to_dict()})
    with pytest.warns(ThermocalWarning, match="older thermocal.*calibrate again"):
        PivotCalibration(old)


def test_frames_without_their_history_take_the_sigma_measured_so():
    """lin-lag's lags start steady at a short recording's rate: its report measures the error
    of frames taken alone (σ well above the interior folds'), and σ takes it at a recording's
    start (or for a burst, whose start is not known), fading with the longest lag."""
    from thermocal.calibration.report import CalibrationReport

    alone = {"sigma_c": 2.0, "mae_c": 1.7, "lag_s": 480.0, "frames": 10}
    model = CalibrationSigma(_report(method="lin-lag", without_history=alone))
    assert model.history_sigma(None, 2) == pytest.approx([2.0, 2.0])
    assert model.history_sigma([0.0, 480.0, 4800.0], 3) == pytest.approx(
        [2.0, 2.0 / math.e, 2.0 * math.exp(-10)])
    assert not CalibrationSigma(_report()).history_sigma(None, 3).any()
    temps = np.full((1, 4, 4), 25.0)
    without = CalibrationSigma(_report(method="lin-lag")).sigma(temps, [27.0])
    assert without.max() < 0.5  # the interior folds' level (shape 1 here)
    assert model.sigma(temps, [27.0]) == pytest.approx(np.full_like(without, 2.0))
    assert model.sigma(temps, [27.0], time_since_start_s=[0.0]) == pytest.approx(
        np.full_like(without, 2.0))
    assert model.sigma(temps, [27.0], time_since_start_s=[3600.0]) == pytest.approx(without)
    # a burst an hour into its recording, calibrated without that history: σ in full
    assert model.sigma(temps, [27.0], time_since_start_s=[3600.0],
                       history_seen=False) == pytest.approx(np.full_like(without, 2.0))
    back = CalibrationReport.from_dict(model.report.to_dict())
    assert back.without_history == alone
    for bad in ({"sigma_c": -1.0}, {"lag_s": 0.0}, {"frames": 2.5}, {"mae_c": math.inf}):
        with pytest.raises(InvalidInputError):
            CalibrationReport.from_dict(model.report.to_dict()
                                        | {"without_history": alone | bad})


def test_a_memoryless_fit_is_inside_only_at_paces_held_near_its_fpa():
    """A memoryless fit at each FPA temperature absorbs the lag bias of the paces it saw there:
    a session that held the FPA still only at 15 °C and ramped at 2 °C/min through 30 °C
    cannot vouch for a camera held still at 30 °C (a polynomial so fitted read 5.5 °C off,
    σ 0.6). Near 15 °C it can; a pace of unknown history (too short a recording) is taken as
    steady, as the calibration applies it; forced, σ grows with the distance."""
    from thermocal.calibration.report import CalibrationReport

    cells = [[0, 0, 15], [20, 20, 22], [20, 20, 30], [20, 20, 38]]
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "margin_c_per_min": 0.1,
             "cells": [[0, 0], [20, 20]], "fpa_cell_c": 1.0, "fpa_reach_c": 3.0,
             "fpa_cells": cells}
    model = CalibrationSigma(_report(paces=paces, fpa_range_c=(15.0, 40.0),
                                     fpa_rate_c_per_min=(-0.1, 2.0)))
    temps = np.full((1, 4, 4), 25.0)
    (why,) = model.outside(temps, [30.0], rate_c_per_min=[0.0], lagged_rate_c_per_min=[0.0])
    assert "held only more than 3 °C from 30.0 °C" in why and "lin-lag" in why
    assert model.outside(temps, [16.0], rate_c_per_min=[0.0], lagged_rate_c_per_min=[0.0]) == ()
    assert model.outside(temps, [30.0], rate_c_per_min=[2.0], lagged_rate_c_per_min=[2.0]) == ()
    (why,) = model.outside(np.full((3, 4, 4), 25.0), [30.0] * 3)  # no rate: a short recording
    assert "pace not known" in why and "3 of 3 frames" in why
    assert model.outside(temps, [16.0]) == ()
    # an FPA outside the session's range: that plainest cause first, the pace's after it
    far = model.outside(temps, [50.0])
    assert len(far) == 2 and far[0].startswith("the FPA temperature 50.0…50.0 °C is outside")
    steady = model.sigma(temps, [30.0])[0].min()
    assert steady > 10 * model.sigma(temps, [16.0])[0].max()  # forced: ~19 cells beyond
    # a pace held nowhere near in pace, but at this FPA: as before (the plane's distance)
    assert "never held" in model.outside(temps, [30.0], rate_c_per_min=[1.0],
                                         lagged_rate_c_per_min=[1.0])[0]
    # a burst's σ (calibrations and selfcal's level) judges its pace where it was held, as
    # the check does: a ramp at 30 °C inside and sharp, still at 30 °C refused and grown
    from thermocal.estimation.base import FpaPace

    ramp = model.burst_sigma(temps[0], 30.0, FpaPace(2.0, 2.0))
    still = model.burst_sigma(temps[0], 30.0, FpaPace(0.0, 0.0))
    assert model.outside_burst(temps, 30.0, FpaPace(2.0, 2.0)) == ()
    assert model.outside_burst(temps, 30.0, FpaPace(0.0, 0.0))
    assert ramp.max() < 1.0 and still.min() > 10 * ramp.max()
    with pytest.raises(InvalidInputError, match="one frame"):
        model.burst_sigma(temps, 30.0, FpaPace(2.0, 2.0))  # (N, H, W): a recording's frames
    # read back, checked
    again = CalibrationReport.from_dict(model.report.to_dict())
    assert again.paces == model.report.paces
    for bad in ({"fpa_cell_c": 0.0}, {"fpa_reach_c": -1.0}, {"fpa_cells": []}):
        with pytest.raises(InvalidInputError):
            CalibrationReport.from_dict(model.report.to_dict()
                                        | {"fpa_paces": paces | bad})


def test_sigma_outside_an_unmeasured_fpa_range_grows_by_the_distance():
    """A session at one FPA measured no growth with the FPA: σ grows by at least
    UNMEASURED_FPA_GROWTH_PER_C per °C outside (a two-point from a session at 30.5 °C erred
    0.26 °C at 30.0, σ 0.05). One with FPA folds grows as they measured up to one end segment
    beyond its range, and by that much per °C past it (lin-level forced at 80 °C, 35 °C above
    its session: 9.9 °C off where σ said 2.6)."""
    from thermocal.calibration.uncertainty import UNMEASURED_FPA_GROWTH_PER_C

    temps = np.full((1, 4, 4), 25.0)
    one_fpa = _report(folds=[f for f in _report().folds if f["kind"] == "setpoint"],
                      fpa_range_c=(30.5, 30.5))
    model = CalibrationSigma(one_fpa)
    inside = model.sigma(temps, [30.5]).max()
    assert model.sigma(temps, [30.0]).min() >= inside + G * 0.5 * UNMEASURED_FPA_GROWTH_PER_C - 1e-6
    model = CalibrationSigma(_report())  # FPA 20–35, end segments 5 °C wide, growth 0.4/°C
    near = model.sigma(temps, [38.0]).max()  # within one segment: the folds' growth alone
    far = model.sigma(temps, [50.0]).min()  # and 10 °C past the segment
    assert far - near == pytest.approx(G * 0.4 * 12.0 + 10.0 * UNMEASURED_FPA_GROWTH_PER_C,
                                       rel=1e-4)


def test_selfcal_judges_its_start_calibrations_stillness_with_the_bursts_start(monkeypatch):
    """selfcal started from a calibration whose session never settled: a burst still since its
    recording began (its time since the start given with the burst) is refused, and its
    level's σ taken as if held UNKNOWN_STILL_EXCESS times the plateaus; one whose recording
    moved before is not."""
    from thermocal.calibration.uncertainty import UNKNOWN_STILL_EXCESS
    from thermocal.estimation.base import FpaPace, PreparedBurst
    from thermocal.estimation.selfcal import SelfCalibration

    model = _stilled()
    monkeypatch.setattr(SelfCalibration, "sigma_model", property(lambda self: model))
    selfcal, temps, pace = SelfCalibration(), np.full((3, 1, 1), 25.0), FpaPace(0.0, 0.0, 500.0)

    def burst(since: float) -> PreparedBurst:
        return PreparedBurst(np.zeros((3, 1, 1)), temps, np.ones((3, 1, 1), dtype=bool),
                             np.repeat(np.eye(3)[None], 3, axis=0), 1, 27.0, 0.0, since, 0.0,
                             500.0)

    (why,) = selfcal.outside(temps, 27.0, pace=pace, burst=burst(500.0))
    assert "how long the camera had held it still is not known" in why
    assert selfcal.outside(temps, 27.0, pace=pace, burst=burst(900.0)) == ()
    worst = G * 0.6
    assert selfcal.level_sigma(temps[0], 27.0, pace=pace, time_since_start_s=500.0)[0, 0] == \
        pytest.approx(worst * UNKNOWN_STILL_EXCESS)
    assert selfcal.level_sigma(temps[0], 27.0, pace=pace, time_since_start_s=900.0)[0, 0] < worst


# ---------------------------------------------------------------------- forced, unseen paces


def test_the_report_states_what_an_fpa_degree_is_worth_in_scene_degrees(fitted):
    """The report's paces carry the camera's FPA sensitivity (scene °C per FPA °C in the
    counts, from the session: about 0.5 on `tau2`), read back as written; a damaged value is
    refused."""
    _, _, report = fitted
    sensitivity = report.paces["fpa_sensitivity_c_per_c"]
    assert 0.3 < sensitivity < 0.8
    back = CalibrationReport.from_dict(json.loads(json.dumps(report.to_dict())))
    assert back.paces["fpa_sensitivity_c_per_c"] == sensitivity
    for bad in (-1.0, math.inf):
        d = report.to_dict()
        d["fpa_paces"] = d["fpa_paces"] | {"fpa_sensitivity_c_per_c": bad}
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(d)
    # a frame at a pace far from every held one takes at least what that much more FPA
    # change over the lag is worth, uncorrected
    model = CalibrationSigma(report)
    d = np.array([2.0])
    assert model._pace_sigma(d)[0] >= sensitivity * 2.0 * report.paces["lag_s"] / 60.0


def test_a_forced_frame_at_an_unseen_pace_takes_its_rate_correction_into_sigma(tmp_path,
                                                                               capsys):
    """`lin-level` fitted on a session whose FPA only rose, forced on a recording whose FPA
    falls: its rate terms, fitted on rising paces alone, err by degrees there (a helper's
    audit: 8–14 °C where σ said 1.6–7.7, 362 of 720 frames silent). The correction they make
    at a pace no fold saw is unverified, and σ takes its size: the falling frames are
    covered."""
    import tifffile
    from cli_run import run

    from thermocal.calibration.dataset import prepare_chamber
    from thermocal.camera.presets import make_camera
    from thermocal.io.chamber import read_chamber
    from thermocal.io.recording import Recording, write_recording
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber

    camera = make_camera("boson", unit=101, size=(40, 32))
    points = (10.0, 30.0, 50.0, 70.0)
    write_simulated_chamber(tmp_path / "rising.h5", camera,
                            ChamberPlan(setpoints_c=points, interval_s=10.0), seed=1)
    write_simulated_chamber(tmp_path / "falling.h5", camera, ChamberPlan(
        setpoints_c=points, profile="ramp", ambient_c=(40.0, 10.0), interval_s=10.0,
        duration_s=3600.0), seed=7)
    held = read_chamber(tmp_path / "falling.h5")
    rec, _ = write_recording(tmp_path / "falling.tiff", Recording(
        held.frames, fpa_c=held.fpa_c, time_s=held.time_s))
    truth = prepare_chamber(tmp_path / "falling.h5").scene_c
    assert run(["calibrate", tmp_path / "rising.h5", "--method", "lin-level", "--out",
                tmp_path / "cal.h5"], capsys)[0] == 0
    code, _, err = run(["correct", rec, "--calibration", tmp_path / "cal.h5", "--force",
                        "--out", tmp_path / "t.tiff", "--sigma-out", tmp_path / "s.tiff"],
                       capsys)
    assert code == 0 and "paces its chamber session never held" in err, err
    error = np.abs(tifffile.imread(tmp_path / "t.tiff") - truth[:, None, None])
    sigma = tifffile.imread(tmp_path / "s.tiff")
    falling = held.fpa_c[-1] < held.fpa_c[0] - 10.0
    assert falling and float(error.mean()) > 1.0
    frame_error = error.reshape(len(error), -1).mean(axis=1)
    frame_sigma = np.median(sigma.reshape(len(sigma), -1), axis=1)
    silent = (frame_error > 1.0) & (frame_error > 2.0 * frame_sigma)
    assert silent.mean() < 0.05 and np.mean(error <= 2 * sigma) > 0.9


def test_a_memoryless_report_holds_only_the_paces_its_session_stayed_at():
    """A pace a session passed through in seconds (a step's steep rise) is not held for a
    memoryless method (PACE_DWELL_S): a camera staying there errs in ways no fold measured
    (lin-level on boson: 1.0–2.1 °C where σ said 0.2–0.3). A method with memory keeps every
    pace visited; a session too short to stay anywhere keeps what it visited."""
    from types import SimpleNamespace

    from thermocal.calibration.report import PACE_DWELL_S, paces_of

    t = np.arange(0.0, 2400.0, 10.0)
    rate = np.where(t < 600, 0.0, 1.0)
    rate[(t >= 600) & (t < 620)] = 0.5  # two frames (20 s) on the way up
    data = SimpleNamespace(usable=np.ones(t.size, bool), fpa_rate_c_per_min=rate, time_s=t,
                           fpa_c=20.0 + np.cumsum(rate) * 10.0 / 60.0)
    assert PACE_DWELL_S > 20.0
    held = {tuple(c) for c in paces_of(data, memoryless=True)["cells"]}
    visited = {tuple(c) for c in paces_of(data, memoryless=False)["cells"]}
    passed = {c for c in visited if c[0] == 5}
    assert passed and not passed & held and held < visited
    assert (0, 0) in held and (10, 10) in held
    fpa_cells = paces_of(data, memoryless=True)["fpa_cells"]
    assert not any(c[0] == 5 for c in fpa_cells)
    brief = SimpleNamespace(usable=np.ones(3, bool), fpa_rate_c_per_min=np.array([0.0, 0.5, 1.0]),
                            time_s=np.array([0.0, 10.0, 20.0]), fpa_c=np.array([20.0] * 3))
    assert len(paces_of(brief, memoryless=True)["cells"]) == 3
    # a review: one frame before a 200 s gap was a minute's stay, and passes on separate steps
    # added up; a stay is one run of frames, a gap ends it
    t2 = np.r_[np.arange(0, 600, 10), 600, np.arange(800, 1400, 10)].astype(float)
    r2 = np.r_[np.zeros(60), 0.5, np.ones(60)]
    gap = SimpleNamespace(usable=np.ones(t2.size, bool), fpa_rate_c_per_min=r2, time_s=t2,
                          fpa_c=np.full(t2.size, 20.0))
    assert not any(c[0] == 5 for c in paces_of(gap, memoryless=True)["cells"])
    passes = np.tile(np.r_[np.zeros(30), 0.5, 0.5, np.ones(30)], 4)  # four 20 s passes
    tp = np.arange(passes.size) * 10.0
    four = SimpleNamespace(usable=np.ones(tp.size, bool), fpa_rate_c_per_min=passes, time_s=tp,
                           fpa_c=np.full(tp.size, 20.0))
    assert not any(c[0] == 5 for c in paces_of(four, memoryless=True)["cells"])


def _sustained(held_s: list[list[float]], **kw) -> CalibrationSigma:
    """A memoryless report whose session visited every pace up to 1.5 °C/min (each with its
    lagged rate anywhere there), with the stays ``held_s`` (``[cell, s]``) its report
    records: only how long it held them can put a frame outside."""
    cells = [[i, j] for i in range(16) for j in range(16)]
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": cells,
             "fpa_sensitivity_c_per_c": 0.5,
             "sustained": {"band_c_per_min": 0.1, "slack_s": 120.0, "held_s": held_s}}
    return CalibrationSigma(_report(paces=paces, fpa_rate_c_per_min=(-0.1, 1.55), **kw))


def test_a_pace_held_longer_than_its_session_held_it_is_outside():
    """A memoryless calibration whose session passed 0.5 °C/min in 90 s (its steps' rises) is
    inside for the first 90 s + the slack of a recording that holds that pace, outside after
    (named, with what to record), σ grown by what the FPA ran on beyond the session's longest
    stay (× its FPA sensitivity, up to the lag); a pace the session held for an hour stays
    inside; at rest the stillness rule judges (not this one); an older report has no stays."""
    from thermocal.calibration.report import pace_stays

    model = _sustained([[0, 3600.0], [4, 90.0], [5, 90.0], [6, 60.0], [15, 3600.0]])
    t = np.arange(0.0, 1800.0, 10.0)
    rate = np.full(t.size, 0.5)
    rate[:3] = 0.0  # the recording starts still, then holds 0.5 °C/min
    stays = pace_stays(rate, t)
    assert stays[-1] == pytest.approx(t[-1] - t[3])
    excess = model.sustained_excess(rate, stays)
    assert excess[3] == 0 and excess[-1] == pytest.approx(stays[-1] - 90.0)
    unseen = model.unseen_paces(rate, t)
    first = int(np.argmax(unseen))
    assert stays[first] > 90.0 + 120.0 >= stays[first - 1]
    why = model.outside(np.full((t.size, 2, 2), 25.0), np.full(t.size, 27.0),
                        rate_c_per_min=rate, time_s=t)
    said = " ".join(why)
    assert "the FPA held a pace for longer than its chamber session held it" in said
    assert "+0.50 °C/min for 3.7 min, the session at most 1.5 min near it" in said
    assert "a ramp or sawtooth at this rate" in said
    sigma = model.sigma(np.full((t.size, 1, 1), 25.0), 27.5, rate_c_per_min=rate,
                        time_since_start_s=t)[:, 0, 0]
    assert sigma[-1] == pytest.approx(0.5 * 0.5 * 480.0 / 60.0, rel=1e-5)  # up to the lag
    assert sigma[first - 1] == pytest.approx(G * 0.6, rel=1e-5)  # its rate bin's, inside
    assert sigma[first - 1] <= sigma[first] < sigma[first + 30]  # then grows with the excess
    # a burst given its stay from its recording is judged alike
    from thermocal.estimation.base import FpaPace

    long_, short = (model.outside_burst(np.full((1, 2, 2), 25.0), 27.0,
                                        FpaPace(0.5, 0.5, None, None, s)) for s in (600.0, 60.0))
    assert any("held a pace for longer" in w for w in long_)
    assert not any("held a pace for longer" in w for w in short)
    # a pace the session held for an hour: inside however long; at rest: not this rule
    assert not model.sustained_excess(np.full(t.size, 1.5), pace_stays(np.full(t.size, 1.5),
                                                                       t)).any()
    assert not model.sustained_excess(np.zeros(t.size), t - t[0]).any()
    # an older report, or a method with memory: no stays, nothing outside for them
    assert not CalibrationSigma(_report()).sustained_excess(rate, stays).any()


def test_stays_survive_json_and_are_checked():
    model = _sustained([[0, 3600.0], [5, 90.0]])
    again = CalibrationReport.from_dict(json.loads(json.dumps(model.report.to_dict())))
    assert again.paces == model.report.paces
    for bad in ({"band_c_per_min": 0.0}, {"slack_s": -1.0}, {"slack_s": math.inf},
                {"held_s": []}, {"held_s": [[0.5, 10.0]]}, {"held_s": [[1, -5.0]]},
                {"held_s": [[1, math.nan]]}):
        paces = model.report.to_dict()["fpa_paces"]
        paces = paces | {"sustained": paces["sustained"] | bad}
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(model.report.to_dict() | {"fpa_paces": paces})


def test_a_memoryless_report_records_how_long_its_session_held_each_pace():
    """``sustained_of``: per pace cell, the longest the session's usable frames had stayed
    within a cell of their rate; only a memoryless method's report holds it."""
    from types import SimpleNamespace

    from thermocal.calibration.report import paces_of

    t = np.arange(0.0, 3000.0, 10.0)
    rate = np.where(t < 600, 0.0, np.where(t < 900, 0.5, 0.0))  # 5 min at 0.5 °C/min
    data = SimpleNamespace(usable=np.ones(t.size, bool), fpa_rate_c_per_min=rate, time_s=t,
                           fpa_c=20.0 + np.cumsum(rate) * 10.0 / 60.0)
    held = dict((c, s) for c, s in paces_of(data, memoryless=True)["sustained"]["held_s"])
    assert held[5] == pytest.approx(290.0) and held[0] == pytest.approx(t[-1] - 900.0)
    assert "sustained" not in paces_of(data, memoryless=False)


def test_a_method_that_learns_online_is_held_to_the_directions_its_session_changed():
    """wolf2016 (it learns its FPA terms online) fitted on a session whose FPA only rose: a
    recording falling by more than a cell below the session's paces is outside, named ("fell
    … never did"), with what to record, though within its 0.3 °C/min margin (a helper's map:
    −2.6…−4.4 °C where σ said 0.5–2.1 over a slow sawtooth's falls, unrefused); a fall within a
    cell is the session's rest; lin-lag, whose lag terms are linear in the rate, keeps its
    margin."""
    cells = [[i, j] for i in range(0, 11) for j in range(0, 11)]  # rest and rises only
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": cells, "margin_c_per_min": 0.3}
    t = np.arange(0.0, 1800.0, 10.0)
    temps = np.full((t.size, 2, 2), 25.0)
    fpa = np.full(t.size, 27.0)
    for method, rate, outside in (("wolf2016", -0.25, True), ("wolf2016", -0.08, False),
                                  ("wolf2016", 0.5, False), ("lin-lag", -0.25, False)):
        model = CalibrationSigma(_report(method=method, paces=paces,
                                         fpa_rate_c_per_min=(-0.05, 1.05)))
        r = np.full(t.size, rate)
        why = model.outside(temps, fpa, rate_c_per_min=r, time_s=t)
        assert bool(why) == outside, (method, rate, why)
        assert model.unseen_paces(r, t).all() == outside
        if outside:
            assert "the FPA fell at a pace its chamber session never did" in why[0]
            assert "-0.25 °C/min" in why[0] and "a sawtooth at this rate" in why[0]


def test_a_method_with_memory_is_judged_settled_on_the_history_that_led_to_each_plateau():
    """``settling_slope`` for a method with memory applies the session in time order, so
    each plateau's end has the history before it; applied alone, an online estimate still
    converging at each end (a decaying start error) would read as a camera still settling. Its
    threshold is the memory one: an error drifting 0.01 °C/min at every end is unsettled for
    it, settled for a memoryless method."""
    from types import SimpleNamespace

    from thermocal.calibration.report import settling_slope, settling_warning

    def settling(calibration, data, ends, method, *, memoryless):
        slope = settling_slope(calibration, data, ends, memoryless=memoryless)
        return settling_warning(slope, len(ends), method, memoryless=memoryless)

    t = np.arange(0.0, 6 * 1200.0, 10.0)
    scene = np.full(t.size, 30.0)

    def stub(drift_c_per_min: float, start_error_c: float):
        def apply(frames, *, fpa_c=None, time_s=None):
            since = (np.asarray(time_s) - time_s[0]) / 60.0  # its state starts at frame 0
            err = start_error_c * np.exp(-since / 5.0) + drift_c_per_min * (since % 20.0)
            return np.asarray(frames, dtype=np.float64) + err[:, None, None]
        return SimpleNamespace(apply=apply)

    data = SimpleNamespace(n_frames=t.size, usable=np.ones(t.size, bool), time_s=t,
                           scene_c=scene, fpa_c=np.full(t.size, 27.0),
                           session=SimpleNamespace(frames=np.full((t.size, 2, 2), 30.0)))
    ends = [np.flatnonzero((t >= k * 1200.0 + 720.0) & (t < (k + 1) * 1200.0))
            for k in range(1, 6)]
    converging = stub(0.0, 1.0)
    assert settling(converging, data, ends, "m", memoryless=True) is not None
    assert settling(converging, data, ends, "m", memoryless=False) is None
    drifting = stub(0.01, 0.0)
    assert settling(drifting, data, ends, "m", memoryless=True) is None
    said = settling(drifting, data, ends, "lin-lag", memoryless=False)
    assert "lin-lag's error was still changing by +0.010 °C/min" in said
    assert "terms for the FPA's history never saw the camera settle" in said
    assert "use lin-lag" not in said


def test_a_method_with_memory_is_refused_a_stillness_in_its_own_words():
    """A method with memory whose session did not settle (``lin-lag``) is refused a camera held
    still longer than its session's plateaus in words that fit it: its terms for the FPA's
    history, not "no memory"; and no advice to use lin-lag."""
    from dataclasses import replace

    t = np.arange(0.0, 1800.0, 10.0)
    lag = CalibrationSigma(replace(_stilled().report, method="lin-lag"))
    said = " ".join(lag.outside(np.full((t.size, 1, 1), 25.0), np.full(t.size, 27.0),
                                rate_c_per_min=np.zeros(t.size), time_s=t))
    assert "its terms for the FPA's history never saw the camera settle" in said
    assert "no memory" not in said and "use lin-lag" not in said


def test_fpa_swings_are_how_far_the_fpa_ran_one_way_since_its_run_began():
    """A run starts where the rate leaves the band and goes on through frames beyond it on that
    side, NaN rates and pauses within the band of up to a minute (a slow ramp's flicker); a
    longer pause, a turn or a recording gap ends it."""
    from thermocal.calibration.report import PACE_LAG_S, SWING_PAUSE_S, fpa_swings

    t = np.arange(0.0, 3600.0, 10.0)
    rate = np.full(t.size, 0.25)
    rate[:6] = 0.0  # still, then a steady rise
    fpa = 20.0 + np.cumsum(rate) * 10.0 / 60.0
    steady = fpa_swings(fpa, rate, t)
    np.testing.assert_allclose(steady[6:], fpa[6:] - fpa[6])
    assert not steady[:6].any()
    flicker = rate.copy()
    flicker[30::90], flicker[75::90] = 0.09, np.nan  # a frame in the band, a rate not known
    np.testing.assert_allclose(fpa_swings(fpa, flicker, t), steady)
    paused = rate.copy()
    paused[100:100 + int(SWING_PAUSE_S / 10) + 2] = 0.0  # longer than a pause: a new run
    again = fpa_swings(fpa, paused, t)
    k = 100 + int(SWING_PAUSE_S / 10) + 2
    assert again[k] == 0.0 and again[-1] == pytest.approx(fpa[-1] - fpa[k])
    turned = rate.copy()
    turned[200:] = -0.25
    down = fpa_swings(20.0 + np.cumsum(turned) * 10.0 / 60.0, turned, t)
    assert down[199] > 0 and down[200] == 0.0 and np.all(down[201:] < 0)
    gap = t.copy()
    gap[150:] += 2 * PACE_LAG_S  # another recording: the run starts anew
    split = fpa_swings(fpa, rate, gap)
    assert split[150] == 0.0 and split[-1] == pytest.approx(fpa[-1] - fpa[150])
    assert fpa_swings([], [], []).shape == (0,)
    with pytest.raises(InvalidInputError, match="must be equal"):
        fpa_swings([1.0, 2.0], [0.0], [0.0, 1.0])


def _swung(rise_c: float = 5.0, fall_c: float = 0.0) -> CalibrationSigma:
    """A lin-lag report whose session visited every pace up to ±1.5 °C/min, and whose FPA ran
    at most ``rise_c`` up and ``fall_c`` down without pause."""
    cells = [[i, j] for i in range(-15, 16) for j in range(-15, 16)]
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": cells, "margin_c_per_min": 0.3,
             "swing": {"band_c_per_min": 0.1, "slack_c": 1.0, "rise_c": rise_c,
                       "fall_c": fall_c}}
    return CalibrationSigma(_report(method="lin-lag", paces=paces,
                                    fpa_rate_c_per_min=(-1.55, 1.55)))


def test_a_longer_run_of_the_fpa_than_its_session_ran_is_outside_a_method_with_memory():
    """lin-lag fitted on 5 °C ambient steps (its FPA ran at most 5 °C up, never down): a steady
    0.25 °C/min rise is inside for its first 6 °C (the run and the slack), outside after, named
    with what to record, σ grown by how many times the session's run the frame's is; a fall of
    more than the slack is outside at once; a session with a sawtooth over the range (a 35 °C
    run) takes the rise; a report without runs (memoryless, older) judges none."""
    t = np.arange(0.0, 3600.0, 10.0)
    rate = np.full(t.size, 0.25)
    rate[:3] = 0.0
    fpa = 20.0 + np.r_[np.zeros(3), np.arange(1, t.size - 2) * 0.25 * 10.0 / 60.0]
    temps = np.full((t.size, 2, 2), 25.0)
    model = _swung()
    swings, excess = model._swings(fpa, rate, t)
    assert swings[-1] == pytest.approx(fpa[-1] - fpa[3])
    np.testing.assert_allclose(excess, np.maximum(swings - 5.0, 0.0))
    said = " ".join(model.outside(temps, fpa, rate_c_per_min=rate, time_s=t))
    assert "the FPA rose" in said and "without pause" in said
    assert "further than its chamber session's longest rise (5.0 °C)" in said
    assert "a ramp or sawtooth over this range" in said
    sigma = model.sigma(temps[:, :1, :1], fpa, rate_c_per_min=rate,
                        time_since_start_s=t)[:, 0, 0]
    first = int(np.argmax(swings > 6.0))
    assert sigma[-1] == pytest.approx(model._worst_sigma() * swings[-1] / 6.0, rel=1e-4)
    assert sigma[first - 1] < sigma[first + 1] < sigma[-1]
    falling = model.outside(temps, fpa[::-1], rate_c_per_min=-rate[::-1], time_s=t)
    assert any("the FPA fell" in w and "longest fall (0.0 °C)" in w for w in falling)
    assert not any("without pause" in w for w in _swung(rise_c=35.0, fall_c=35.0).outside(
        temps, fpa, rate_c_per_min=rate, time_s=t))
    assert not _paced().swing_excess(swings).any()
    # a report's runs survive JSON and are checked
    again = CalibrationReport.from_dict(json.loads(json.dumps(model.report.to_dict())))
    assert again.paces == model.report.paces
    for bad in ({"band_c_per_min": 0.0}, {"slack_c": -1.0}, {"rise_c": math.inf},
                {"fall_c": math.nan}):
        paces = model.report.to_dict()["fpa_paces"]
        paces = paces | {"swing": paces["swing"] | bad}
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(model.report.to_dict() | {"fpa_paces": paces})


def test_a_report_of_a_method_with_memory_records_its_sessions_runs():
    """``swing_of``: the farthest the usable frames' FPA ran up and down without pause; only a
    method with memory's report holds it (a memoryless one holds its stays instead)."""
    from types import SimpleNamespace

    from thermocal.calibration.report import paces_of

    t = np.arange(0.0, 3000.0, 10.0)
    rate = np.where(t < 600, 0.0, np.where(t < 900, 0.5, np.where(t < 1200, -0.3, 0.0)))
    fpa = 20.0 + np.cumsum(rate) * 10.0 / 60.0
    data = SimpleNamespace(usable=np.ones(t.size, bool), fpa_rate_c_per_min=rate, time_s=t,
                           fpa_c=fpa)
    swing = paces_of(data, memoryless=False)["swing"]
    assert swing["rise_c"] == pytest.approx(0.5 * 290.0 / 60.0)
    assert swing["fall_c"] == pytest.approx(0.3 * 290.0 / 60.0)
    assert "swing" not in paces_of(data, memoryless=True)
    assert "sustained" not in paces_of(data, memoryless=False)


def test_an_online_estimate_begun_while_the_fpa_changes_takes_the_error_of_a_frame_alone():
    """wolf2016 learns its FPA terms online; its session began settled, so its start-up bins
    never saw an estimate begun mid-change. A recording begun while its FPA changes takes the
    report's σ of frames alone over its first minute (fading); one begun settled does not;
    lin-lag's applies to every recording's start, as before."""
    from dataclasses import replace

    alone = {"sigma_c": 3.0, "mae_c": 2.5, "lag_s": 60.0, "frames": 100}
    t = np.arange(0.0, 300.0, 10.0)
    temps = np.full((t.size, 1, 1), 25.0)

    def sigmas(method, rate0, history):
        report = replace(_paced().report, method=method,
                         without_history=alone if history else {})
        rate = np.full(t.size, rate0)
        return CalibrationSigma(report).sigma(temps, 27.0 + rate * t / 60.0,
                                              rate_c_per_min=rate, time_since_start_s=t)[:, 0, 0]

    for method, rate0, grown in (("wolf2016", 1.5, True), ("wolf2016", 0.0, False),
                                 ("lin-lag", 0.0, True)):
        with_, without = sigmas(method, rate0, True), sigmas(method, rate0, False)
        assert bool(with_[0] > without[0]) is grown, (method, rate0)
        if grown:
            assert with_[0] == pytest.approx(max(3.0, without[0]), rel=1e-5)
            np.testing.assert_allclose(with_[-1], without[-1], rtol=1e-4)  # faded
    wolf = CalibrationSigma(replace(_paced().report, method="wolf2016", without_history=alone))
    # its cold starts measured (the estimate begun afresh at each of its session's steps): σ by
    # the time since the recording began, once its FPA has changed; settled, none
    cold = alone | {"by_time": [{"time_s": [0.0, 60.0], "frames": 20, "mae_c": 3.0,
                                 "sigma_c": 3.5},
                                {"time_s": [60.0, 900.0], "frames": 50, "mae_c": 4.0,
                                 "sigma_c": 5.0}]}
    measured = CalibrationSigma(replace(wolf.report, without_history=cold))
    moved = t >= 30.0
    got = measured.history_sigma(t, t.size, moved=moved)
    assert np.all(got[~moved] == 0.0) and got[3] == pytest.approx(3.5)
    assert got[10] == pytest.approx(5.0)  # 100 s in: its measured bin, above the fade
    again = CalibrationReport.from_dict(json.loads(json.dumps(measured.report.to_dict())))
    assert again.without_history == cold
    overlapping = [cold["by_time"][1], cold["by_time"][0]]
    for broken in [cold | {"by_time": [cold["by_time"][0] | bad]}
                   for bad in ({"time_s": [60.0, 10.0]}, {"sigma_c": math.nan}, {"frames": 0},
                               {"time_s": [0.0, None]}, {"mae_c": -1.0})] + [
                       cold | {"by_time": overlapping}]:
        with pytest.raises(InvalidInputError, match="not a calibration report"):
            CalibrationReport.from_dict(measured.report.to_dict()
                                        | {"without_history": broken})
    # a burst (history not seen) takes it in full, whatever its rate
    assert wolf.sigma(temps[0], 27.0, rate_c_per_min=[0.0], history_seen=False)[0, 0] >= 3.0


def test_the_pipeline_judges_a_bursts_run_of_fpa_change_from_its_recording(fitted):
    """Given how far the FPA had run one way (from its recording: ``recording_paces``'
    ``fpa_swing_c``), a calibration with memory refuses a burst whose FPA ran further than its
    session's did, and forced, grows its σ; a shorter run, as before; a report without runs
    gives none."""
    from dataclasses import replace

    from thermocal.estimation.paces import pace_at, recording_paces

    camera, cal, report = fitted
    scene = 15.0 + 10.0 * np.random.default_rng(0).random((96, 96))
    fpa = 0.5 * sum(report.fpa_range_c)
    burst = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=fpa, seed=1)
    estimator = PivotCalibration(cal)
    cells = [[i, j] for i in range(-20, 21) for j in range(-20, 21)]
    swing = {"band_c_per_min": 0.1, "slack_c": 1.0, "rise_c": 5.0, "fall_c": 0.0}
    estimator.sigma_model = CalibrationSigma(replace(report, paces={
        "lag_s": 480.0, "cell_c_per_min": 0.1, "cells": cells, "margin_c_per_min": 0.3,
        "swing": swing}))
    t = np.arange(0.0, 1800.0, 10.0)
    ramp = fpa - 5.0 + 0.3 * t / 60.0  # 9 °C in 30 min
    history = recording_paces(ramp, t, estimator.fpa_paces)
    assert history["fpa_swing_c"][-1] == pytest.approx(ramp[-1] - ramp[1], abs=0.1)
    late, early = (pace_at(history, t, k) for k in (t.size - 1, 60))
    assert late["fpa_swing_c"] > 6.0 > early["fpa_swing_c"]
    with pytest.raises(OutsideDomainError, match="the FPA rose .* without pause"):
        estimate(burst.frames, estimator, fpa_c=burst.fpa_c, **late)
    forced = estimate(burst.frames, estimator, fpa_c=burst.fpa_c, force=True, **late)
    inside = estimate(burst.frames, estimator, fpa_c=burst.fpa_c, **early)
    assert inside.outside == () and any("without pause" in w for w in forced.outside)
    assert np.median(forced.sigma_c) > np.median(inside.sigma_c)
    assert recording_paces(ramp, t, {})["fpa_swing_c"] is None


def test_a_method_that_learns_online_is_scored_alone_frame_by_frame_and_its_bursts_alike():
    """Frames alone, for a method that learns online, are each applied in a call of their own
    (its estimate carries its state from frame to frame of one call, whatever their times); a
    burst of it begins its estimate afresh: settled (its pace known, 0), the start-up σ of its
    session; changing, the σ of frames alone; an older report without its cold starts or runs
    is said to be older."""
    from dataclasses import replace
    from types import SimpleNamespace

    from thermocal.calibration.report import frame_errors_alone

    def apply(frames, *, fpa_c=None, time_s=None):  # an estimate that learns frame by frame
        return np.asarray(frames, np.float32) + np.arange(len(frames), dtype=np.float32)[
            :, None, None]

    stub = SimpleNamespace(apply=apply)
    n = 6
    data = SimpleNamespace(session=SimpleNamespace(frames=np.full((n, 2, 2), 30.0)),
                           fpa_c=np.full(n, 27.0), fpa_rate_c_per_min=np.zeros(n),
                           scene_c=np.full(n, 30.0))
    scored = np.ones(n, bool)
    assert not frame_errors_alone(stub, data, scored, learns_online=True).any()
    np.testing.assert_array_equal(frame_errors_alone(stub, data, scored)[:, 0], np.arange(n))
    alone = {"sigma_c": 3.0, "mae_c": 2.5, "lag_s": 480.0, "frames": 100,
             "by_time": [{"time_s": [0.0, 60.0], "frames": 20, "mae_c": 3.0, "sigma_c": 3.5}]}
    wolf = CalibrationSigma(replace(_paced().report, method="wolf2016", without_history=alone,
                                    by_time=[{"time_s": [0.0, 300.0], "frames": 20,
                                              "mae_c": 0.4, "sigma_c": 0.5}]))
    x = np.full((1, 1), 25.0)
    settled = wolf.sigma(x, 27.0, rate_c_per_min=[0.0], lagged_rate_c_per_min=[0.0],
                         time_since_start_s=[1800.0], history_seen=False)[0, 0]
    moving = wolf.sigma(x, 27.0, rate_c_per_min=[0.0], lagged_rate_c_per_min=[0.5],
                        time_since_start_s=[1800.0], history_seen=False)[0, 0]
    assert settled == pytest.approx(0.5, rel=1e-5)  # its start-up bin, 0 s into its estimate
    assert moving == pytest.approx(3.5, rel=1e-5)  # its cold start's
    assert "no record of how far" in CalibrationSigma(replace(
        _paced().report, method="lin-lag", without_history=alone)).older_report()
    assert "estimate begun afresh" in CalibrationSigma(replace(
        _paced().report, method="wolf2016", paces=_paced().report.paces | {
            "swing": {"band_c_per_min": 0.1, "slack_c": 1.0, "rise_c": 5.0,
                      "fall_c": 0.0}})).older_report()


def test_the_curves_say_where_sigma_is_larger_not_how_large():
    """Two interior FPA segments erring 0.2 and 0.4 °C: σ at the worse one's centre is the
    level times (1 + 0.4 / 0.3 − 1), at the better one's times (1 + 0.2 / 0.3 − 1), whatever
    the set points' folds erred on the whole; and a report whose folds measured their error
    over their frames' level (``relative_mae``) is read by that, not by the MAE."""
    folds = [f for f in _report().folds if f["kind"] == "setpoint"] + [
        {"kind": "fpa", "held_out": [20.0, 25.0], "extrapolation": False, "frames": 5,
         "mae_c": 0.2},
        {"kind": "fpa", "held_out": [25.0, 30.0], "extrapolation": False, "frames": 5,
         "mae_c": 0.4}]
    model = CalibrationSigma(_report(folds=folds))
    s = model.sigma(np.full((2, 1, 1), 25.0), [22.5, 27.5])[:, 0, 0]
    np.testing.assert_allclose(s, G * 0.3 * np.array([0.2, 0.4]) / 0.3, rtol=1e-6)
    # the worse segment was the one the session crossed fast: over their frames' level the
    # two erred alike, and σ is the level at both
    relative = [f | {"relative_mae": 0.8} for f in folds]
    flat = CalibrationSigma(_report(folds=relative))
    np.testing.assert_allclose(flat.sigma(np.full((2, 1, 1), 25.0), [22.5, 27.5])[:, 0, 0],
                               G * 0.3, rtol=1e-6)
    # the centre is the interior folds' mean (weighted by their frames), not the ends': an
    # end's own error, large where the fit is poor there, would put the interior below it
    weights = {20.0: 15, 25.0: 20}  # the two interior FPA segments' frames, by their start
    ends = [f | {"frames": weights[f["held_out"][0]]} if f["kind"] == "fpa" else f
            for f in folds] + [
        {"kind": "fpa", "held_out": [15.0, 20.0], "extrapolation": True, "frames": 10,
         "mae_c": 2.0, "own_mae_c": 0.7}]
    x, v, mean = CalibrationSigma(_report(folds=ends))._curves[1]
    np.testing.assert_allclose(v, [0.7, 0.2, 0.4])
    assert mean == pytest.approx((0.2 * 15 + 0.4 * 20) / 35)
    # one fold without it (a report whose folds did not all measure it): the MAE
    mixed = CalibrationSigma(_report(folds=relative[:-1] + folds[-1:]))
    np.testing.assert_allclose(mixed.sigma(np.full((2, 1, 1), 25.0), [22.5, 27.5])[:, 0, 0], s,
                               rtol=1e-6)


def test_a_camera_held_still_longer_than_the_plateaus_takes_their_last_drift():
    """A session whose error still changed at its plateaus' ends by less than refuses
    (−0.025 °C/min over 8 min: 0.2 °C) answers a camera held still longer than its plateaus
    held the FPA (4 min) with that drift in quadrature; a moving camera, one held still for
    less, and a calibration whose report lists no settling keep σ as it was. A frame whose
    stillness is not known (a burst, or still since its recording began) may have been held
    still for hours: it takes it too."""
    settling = {"band_c": 0.15, "held_s": 240.0, "plateaus": 6, "slope_c_per_min": -0.025,
                "window_s": 480.0}
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": [[0, 0]], "settling": settling}
    plain = CalibrationSigma(_report(paces={k: v for k, v in paces.items() if k != "settling"}))
    model = CalibrationSigma(_report(paces=paces))
    drift = 0.025 * 8.0
    np.testing.assert_allclose(model.settling_drift([100.0, 600.0, np.nan], [False, False, True]),
                               [0.0, drift, drift])
    np.testing.assert_allclose(plain.settling_drift([600.0]), [0.0])
    t = np.arange(0.0, 1800.0, 10.0)
    temps = np.full((t.size, 1, 1), 25.0)
    still = np.full(t.size, 27.5)
    moving = 27.5 + 0.5 * (t - t[0]) / 60.0
    before = plain.sigma(temps, still, rate_c_per_min=np.zeros(t.size),
                         time_since_start_s=t)[:, 0, 0]
    after = model.sigma(temps, still, rate_c_per_min=np.zeros(t.size),
                        time_since_start_s=t)[:, 0, 0]
    # still since the recording began: how long before it is not known, so every frame
    np.testing.assert_allclose(after, np.hypot(before, drift), rtol=1e-6)
    rate = np.full(t.size, 0.5)
    np.testing.assert_allclose(model.sigma(temps, moving, rate_c_per_min=rate,
                                           time_since_start_s=t),
                               plain.sigma(temps, moving, rate_c_per_min=rate,
                                           time_since_start_s=t))
    # the FPA moved, then held: the drift only once it had held longer than the plateaus
    fpa = np.where(t < 600.0, 20.0 + 0.75 * t / 60.0, 27.5)
    r = np.where(t < 600.0, 0.75, 0.0)
    got = model.sigma(temps, fpa, rate_c_per_min=r, time_since_start_s=t)[:, 0, 0]
    ref = plain.sigma(temps, fpa, rate_c_per_min=r, time_since_start_s=t)[:, 0, 0]
    late = t >= 600.0 + 240.0 + 60.0
    np.testing.assert_allclose(got[late], np.hypot(ref[late], drift), rtol=1e-6)
    np.testing.assert_allclose(got[t < 600.0], ref[t < 600.0])
    # a burst: its stillness given, or not known
    burst = dict(rate_c_per_min=[0.0], lagged_rate_c_per_min=[0.0])
    assert model.sigma(temps[:1], [27.5], still_s=[60.0], **burst)[0, 0, 0] == pytest.approx(
        plain.sigma(temps[:1], [27.5], **burst)[0, 0, 0], rel=1e-6)
    assert model.sigma(temps[:1], [27.5], still_s=[np.nan], **burst)[0, 0, 0] == pytest.approx(
        np.hypot(plain.sigma(temps[:1], [27.5], **burst)[0, 0, 0], drift), rel=1e-6)


def test_a_burst_takes_the_drift_by_its_recording_s_stillness():
    """A burst of a recording (``thermocal flight``, ``estimate``) is judged still from its
    recording, for a report that lists settling alone as for one that lists stillness: a burst
    whose FPA had held still for a minute keeps σ; one held for ten, longer than the plateaus,
    takes the drift (before, every steady burst took it: its stillness was not measured)."""
    from thermocal.estimation.base import FpaPace
    from thermocal.estimation.paces import pace_at, recording_paces

    settling = {"band_c": 0.15, "held_s": 240.0, "plateaus": 6, "slope_c_per_min": -0.025,
                "window_s": 480.0}
    paces = {"lag_s": 480.0, "cell_c_per_min": 0.1, "cells": [[0, 0]], "settling": settling}
    model = CalibrationSigma(_report(paces=paces))
    plain = CalibrationSigma(_report(paces={k: v for k, v in paces.items() if k != "settling"}))
    t = np.arange(0.0, 1800.0, 10.0)
    fpa = np.where(t < 600.0, 20.0 + 0.75 * t / 60.0, 27.5)
    series = recording_paces(fpa, t, paces)
    assert series["fpa_still_s"] is not None
    x = np.full((1, 1), 25.0)
    for k, drifts in ((66, False), (120, True)):  # 60 s and 600 s after the FPA stopped
        at = pace_at(series, t, k)
        pace = FpaPace(at["fpa_rate_c_per_min"], at["fpa_lagged_rate_c_per_min"],
                       at["fpa_still_s"])
        got = model.burst_sigma(x, 27.5, pace)[0, 0]
        ref = plain.burst_sigma(x, 27.5, pace)[0, 0]
        assert got == pytest.approx(np.hypot(ref, 0.2) if drifts else ref, rel=1e-6)


def test_a_curve_without_an_interior_fold_keeps_its_ends_and_damaged_folds_are_refused():
    """Every interior FPA fold failed to refit: the FPA curve's ends (the fit's own error
    there) still shape σ, centred on the set points' interior (before, the curve was dropped:
    σ at an FPA end its fit erred 1 °C at fell to a third); a fold's NaN or negative error in
    a report read back is refused (it would make σ NaN everywhere)."""
    folds = [f for f in _report().folds if f["kind"] == "setpoint"] + [
        {"kind": "fpa", "held_out": [20.0, 25.0], "extrapolation": True, "frames": 5,
         "mae_c": 2.0, "own_mae_c": 0.9},
        {"kind": "fpa", "held_out": [25.0, 30.0], "extrapolation": False, "frames": 5,
         "mae_c": None, "error": "no settled frame"},
        {"kind": "fpa", "held_out": [30.0, 35.0], "extrapolation": True, "frames": 5,
         "mae_c": 0.4, "own_mae_c": 0.3}]
    model = CalibrationSigma(_report(folds=folds))
    s = model.sigma(np.full((2, 1, 1), 25.0), [22.5, 32.5])[:, 0, 0]
    # the set points' interior mean is 0.3 °C: the cold end (0.9) triples σ, the warm end
    # (0.3, at least its nearest interior point's: none) keeps it
    np.testing.assert_allclose(s, G * 0.3 * np.array([0.9 / 0.3, 1.0]), rtol=1e-6)
    d = _report(folds=folds).to_dict()
    d["mae_by_fpa_c"][0]["own_mae_c"] = float("nan")
    with pytest.raises(InvalidInputError, match="own_mae_c must be >= 0 and finite"):
        CalibrationReport.from_dict(json.loads(json.dumps(d)))
    d["mae_by_fpa_c"][0]["own_mae_c"] = 0.9
    d["mae_by_scene_c"][1]["relative_mae"] = -1.0
    with pytest.raises(InvalidInputError, match="relative_mae must be >= 0"):
        CalibrationReport.from_dict(json.loads(json.dumps(d)))
