"""thermocal.evaluation: the held-out set, the scores and their split, the tables."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.evaluation.heldout import eval_bursts, other_unit_calibration
from thermocal.evaluation.references import FAMILY_ROW, ExactModel, reference_scores
from thermocal.evaluation.scoring import scores, split_error, summarise
from thermocal.evaluation.tables import accuracy_table, markdown_table
from thermocal.nn.data import EVAL_SCENES, EVAL_UNITS


def _burst(truth, mask=None):
    return {"truth": truth, "mask": np.ones(truth.shape, bool) if mask is None else mask}


def test_scores_split_a_known_error():
    rng = np.random.default_rng(0)
    truth = rng.uniform(10.0, 30.0, (96, 128))
    b = _burst(truth)
    s = scores(truth + 0.4, b)  # the unit's offset alone
    assert s["mae"] == pytest.approx(0.4) and s["bias"] == pytest.approx(0.4)
    assert s["bias_free"] < 1e-9 and s["smooth"] < 1e-9 and s["fine"] < 1e-9
    assert s["within_0_5"] == 1.0 and s["affine_free"] < 1e-9
    checker = 0.3 * ((np.indices(truth.shape).sum(axis=0) % 2) * 2 - 1)  # pixel FPN
    smooth, fine = split_error(checker, b["mask"])
    assert smooth < 0.02 and fine == pytest.approx(0.3, abs=0.02)
    ramp = np.linspace(-1.0, 1.0, truth.shape[1])[None].repeat(truth.shape[0], 0)
    smooth, fine = split_error(ramp, b["mask"])
    assert smooth > 0.45 and fine < 0.05  # a radial-like pattern is smooth
    rows, cols = np.indices(truth.shape)
    corners = np.hypot(rows - 47.5, cols - 63.5) > 60  # in the last fifth of the pixels
    by_r = scores(truth + 2.0 * corners, b)["bias_by_radius"]
    assert by_r[0] == pytest.approx(0.0) and by_r[3] < 1.0 < by_r[-1] <= 2.0


def test_summarise_and_tables():
    rows = summarise({"a": [{"mae": 1.0, "bias_free": 0.5, "affine_free": 0.4,
                             "within_0_5": 0.2, "bias": -0.5, "smooth": 0.3, "fine": 0.2},
                            {"mae": 3.0, "bias_free": 1.5, "affine_free": 0.6,
                             "within_0_5": 0.4, "bias": 1.5, "smooth": 0.5, "fine": 0.4}]})
    r = rows[0]
    assert r["mae_c"] == 2.0 and r["median_mae_c"] == 2.0 and r["mean_abs_bias_c"] == 1.0
    assert r["within_0_5"] == pytest.approx(0.3)
    text = accuracy_table(rows)
    assert text.splitlines()[2] == ("| a | 2.00 | 2.00 | 30 % | 1.00 | 1.00 | 0.40 | 0.30 | "
                                    "0.50 |")
    assert markdown_table(("x", "y"), [(1, 2)]) == "| x | y |\n|---|---|\n| 1 | 2 |"


def test_held_out_set_and_references():
    bursts = eval_bursts(7, quick=True)
    assert len(bursts) == len(EVAL_SCENES)
    assert {b["unit"] for b in bursts} <= set(EVAL_UNITS)
    assert {b["scene"] for b in bursts} == set(EVAL_SCENES)
    again = eval_bursts(7, quick=True)
    assert all(np.array_equal(a["frames"], b["frames"]) for a, b in zip(bursts, again,
                                                                         strict=True))
    # one unit per burst (a population of units' levels), as many bursts per scene as asked
    each = eval_bursts(7, quick=True, units=tuple(range(300, 330)), per_scene=2,
                       unit_per_burst=True)
    assert len(each) == 2 * len(EVAL_SCENES) == len({b["unit"] for b in each})
    # one camera (fitted on a chamber file) for every burst, within the FPA range it covers
    from dataclasses import replace

    from thermocal.camera.presets import make_camera

    cam = make_camera("tau2", unit=3, size=(64, 48))
    fitted = replace(cam, info={**cam.info, "fpa_range_c": [20.0, 35.0]})
    own = eval_bursts(7, quick=True, camera=fitted)
    assert all(b["unit"] is None and 20.0 <= b["fpa_c"] <= 35.0 for b in own)
    assert own[0]["frames"].shape[1:] == (48, 64)
    b = bursts[0]
    refs = {FAMILY_ROW: ExactModel.family((0, 1))}
    from thermocal.burst import fill_stuck_pixels

    frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
    out = reference_scores(b, frames, refs, other_unit_calibration())
    assert list(out)[0] == FAMILY_ROW
    own = out["(reference) own two-point at the burst FPA (eq. 9 mean)"]
    other = out["two-point, other unit, FPA 30 °C (pivot frame)"]
    assert own["mae"] < 0.3 < other["mae"]  # the unit's own calibration is the best reference


def test_level_rows_recover_a_known_spread_of_units_levels():
    """Levels drawn from the stated Gaussian cover it as a Gaussian does; levels twice as wide
    are told (RMS twice the stated, fewer within 1σ); the interval resamples whole units."""
    from thermocal.evaluation.suites.level_contrast import level_rows

    rng = np.random.default_rng(3)
    n = 4000
    contrast = rng.uniform(-80.0, 20.0, n)
    unit = np.arange(n)
    stated = np.sqrt(0.5**2 + (0.01 * contrast) ** 2)
    rows = level_rows(rng.normal(0.0, stated), contrast, unit, floor_c=0.5, contrast_per_c=0.01)
    assert [r["bin"] for r in rows] == [(-90.0, -40.0), (-40.0, -20.0), (-20.0, 0.0),
                                        (0.0, 60.0), None]
    assert sum(r["bursts"] for r in rows[:-1]) == rows[-1]["bursts"] == n
    for r in rows:
        assert r["rms_c"] == pytest.approx(r["stated_c"], rel=0.12)
        assert r["interval_c"][0] < r["rms_c"] < r["interval_c"][1]
        assert 0.60 < r["within_1sigma"] < 0.76 and 0.90 < r["within_2sigma"] < 0.99
    cold = rows[0]  # the stated level grows with the contrast
    assert cold["stated_c"] > rows[3]["stated_c"] + 0.15
    wide = level_rows(rng.normal(0.0, 2 * stated), contrast, unit, floor_c=0.5,
                      contrast_per_c=0.01)[-1]
    assert wide["rms_c"] == pytest.approx(2 * wide["stated_c"], rel=0.1)
    assert wide["within_1sigma"] < 0.45
    # twenty units of twenty bursts each, every burst its unit's level: twenty draws, not 400,
    # and the interval over units says so
    levels = np.repeat(rng.normal(0.0, 0.5, 20), 20)
    grouped = level_rows(levels, np.full(400, -10.0), np.repeat(np.arange(20), 20),
                         floor_c=0.5, contrast_per_c=None)[-1]["interval_c"]
    apart = level_rows(levels, np.full(400, -10.0), np.arange(400), floor_c=0.5,
                       contrast_per_c=None)[-1]["interval_c"]
    assert grouped[1] - grouped[0] > 2.5 * (apart[1] - apart[0])
    # one unit's many bursts are one draw: no interval over one unit
    one = level_rows(np.full(5, 0.3), np.full(5, -10.0), np.zeros(5), floor_c=0.5,
                     contrast_per_c=None)
    assert one[0]["interval_c"] is None and one[0]["stated_c"] == pytest.approx(0.5)
    with pytest.raises(InvalidInputError):
        level_rows(np.array([np.nan]), np.zeros(1), np.zeros(1), floor_c=0.5,
                   contrast_per_c=None)
