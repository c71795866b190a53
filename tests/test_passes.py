"""thermocal.evaluation.passes: whole UAV passes through ``thermocal flight``, scored map by map."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.evaluation.passes import (
    SCORES,
    PassMethod,
    PassSpec,
    evaluate_pass,
    load_pass_scene,
    map_scores,
    own_polynomial,
    score_flight,
    simulate_pass,
    summarise_maps,
    summarise_passes,
)
from thermocal.io.recording import read_temperature_tiff, write_temperature_tiff

SPEC = PassSpec(scene="builtin:aerial", unit=100, n_frames=28, size=(64, 48), fpa_c=30.0, seed=3)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A 28-frame 64×48 pass (4 groups of 7) through the unit's own polynomial, per frame and
    registered mean, and (with torch) the shipped network."""
    work = tmp_path_factory.mktemp("passes")
    methods = [PassMethod("own, pivot alone", "calibration", own_polynomial, force=True),
               PassMethod("own, mean", "mean", own_polynomial, force=True)]
    try:
        import torch  # noqa: F401

        # 64×48 frames are too small for the network's family check: forced, σ inflated
        methods.append(PassMethod("kpn", "kpn", force=True))
    except ImportError:
        pass
    return work, evaluate_pass(SPEC, methods, work)


def test_tiny_pass_scores_every_map(tiny):
    work, res = tiny
    assert res["pass"]["unit"] == 100 and res["pass"]["n_frames"] == 28
    for label, r in res["methods"].items():
        assert r["failed"] == [], label
        assert [m["frame"] for m in r["maps"]] == [3, 10, 17, 24]
        s = r["summary"]
        assert s["maps"] == 4
        assert all(math.isfinite(s[k]) for k in SCORES), label
        assert s["mae_c"] >= s["bias_free_mae_c"] - 1e-9 or s["mean_abs_bias_c"] < 1e-3
    # the recording and the maps are removed; the calibration made for the unit is kept
    assert [p.name for p in work.iterdir()] == ["polynomial_tau2_100_64x48.h5"]


def test_own_calibration_is_near_oracle(tiny):
    """The unit's own chamber polynomial is the truth up to its fit: near-zero scores."""
    _, res = tiny
    for label in ("own, pivot alone", "own, mean"):
        s = res["methods"][label]["summary"]
        assert s["mae_c"] < 0.1, label
        assert s["bias_free_mae_c"] < 0.1 and s["column_bands_c"] < 0.05, label
        assert s["row_bands_c"] < 0.05 and s["affine_free_mae_c"] < 0.1, label


def test_network_is_scored_without_a_calibration(tiny):
    _, res = tiny
    if "kpn" not in res["methods"]:
        pytest.skip("torch is not installed")
    r = res["methods"]["kpn"]
    assert r["calibration"] is None
    assert 0.0 < r["summary"]["mae_c"] < 5.0


def test_truth_as_estimate_scores_zero_and_failures_are_listed(tmp_path):
    """The truth of each pivot frame, written as a flight's maps, scores exactly zero: the
    maps are compared with their own pivot frame's truth, not another's."""
    rec = simulate_pass(SPEC, tmp_path / "pass")
    truth = read_temperature_tiff(tmp_path / "pass" / "truth.tiff")
    assert truth.shape == (28, 48, 64)
    out = tmp_path / "out"
    (out / "temps").mkdir(parents=True)
    lines = []
    for pivot in (3, 10, 17):
        write_temperature_tiff(out / "temps" / f"frame_{pivot:06d}.tiff", truth[pivot])
        lines.append({"frame": pivot, "mean_c": float(truth[pivot].mean())})
    lines.append({"frame": 24, "error": "registration failed"})
    (out / "log.jsonl").write_text("".join(json.dumps(e) + "\n" for e in lines))
    scored = score_flight(out, tmp_path / "pass" / "truth.tiff")
    assert rec.name == "frames.tiff"
    assert [m["frame"] for m in scored["maps"]] == [3, 10, 17]
    assert scored["failed"] == [{"frame": 24, "error": "registration failed"}]
    for m in scored["maps"]:
        assert all(m[k] == pytest.approx(0.0, abs=1e-9) for k in SCORES)
    # another frame's truth is not zero: the pass moves
    write_temperature_tiff(out / "temps" / "frame_000010.tiff", truth[11])
    again = score_flight(out, tmp_path / "pass" / "truth.tiff")
    assert again["maps"][1]["mae_c"] > 0.01


def test_map_scores_known_answers():
    truth = np.random.default_rng(4).normal(20.0, 2.0, (6, 8))
    stripes = np.array([0.2, -0.2] * 4)
    est = truth + 0.5 + stripes[None, :]
    s = map_scores(est, truth)
    assert s["bias_c"] == pytest.approx(0.5)
    assert s["mae_c"] == pytest.approx(np.mean(np.abs(0.5 + stripes)))
    assert s["bias_free_mae_c"] == pytest.approx(0.2)
    assert s["column_bands_c"] == pytest.approx(0.2)
    assert s["row_bands_c"] == pytest.approx(0.0, abs=1e-12)
    valid = np.ones((6, 8), bool)
    valid[:, 1::2] = False  # only the +0.2 columns: no bands left
    assert map_scores(est, truth, valid=valid)["column_bands_c"] == pytest.approx(0.0, abs=1e-12)


def test_summaries_are_means_over_maps_then_passes():
    def maps(value, n):
        return [dict.fromkeys(SCORES, value) | {"bias_c": -value} for _ in range(n)]

    a, b = summarise_maps(maps(0.2, 3)), summarise_maps(maps(0.4, 5))
    assert a["maps"] == 3 and a["mae_c"] == pytest.approx(0.2)
    assert a["mean_abs_bias_c"] == pytest.approx(0.2)
    empty = summarise_maps([])
    assert empty["maps"] == 0 and math.isnan(empty["mae_c"])
    results = [{"methods": {"x": {"summary": a}, "y": {"summary": empty}}},
               {"methods": {"x": {"summary": b}, "y": {"summary": b}}}]
    rows = {r["method"]: r for r in summarise_passes(results)}
    assert rows["x"]["passes"] == 2 and rows["x"]["maps"] == 8
    assert rows["x"]["mae_c"] == pytest.approx(0.3)  # the mean of the passes' means
    assert rows["x"]["pass_mae_range_c"] == pytest.approx([0.2, 0.4])
    assert rows["y"]["passes"] == 1 and rows["y"]["passes_without_maps"] == 1
    assert rows["x"]["within_1sigma_interval"] is None  # no units named


def test_the_sigma_shares_carry_an_interval_over_units():
    """Passes of six units, each unit's maps covering its own share: the interval is the
    bootstrap's over the units' means, and spans the mean."""
    results = [{"pass": {"unit": u},
                "methods": {"x": {"summary": {"maps": 3, **dict.fromkeys(SCORES, 0.1),
                                              "mean_abs_bias_c": 0.1, "within_1sigma": share,
                                              "within_2sigma": 0.95, "median_sigma_c": 0.2}}}}
               for u, share in zip((1, 1, 2, 3, 4, 5, 6), (0.5, 0.5, 0.6, 0.7, 0.8, 0.9, 0.6),
                                   strict=True)]
    row = summarise_passes(results)[0]
    lo, hi = row["within_1sigma_interval"]
    assert lo < 0.65 < hi and hi - lo > 0.05
    assert row["within_2sigma_interval"] is None  # the same in every unit


def test_only_held_out_scenes():
    assert load_pass_scene("builtin:aerial").ndim == 2
    with pytest.raises(InvalidInputError, match="not held out"):
        load_pass_scene("builtin:floor")


def test_fixed_part_of_a_pass_is_found(tmp_path):
    """Maps = truth + a per-map level + a pattern fixed in the sensor: the fixed part is the
    pattern (less its mean), and nothing is left once it is removed."""
    simulate_pass(SPEC, tmp_path / "pass")
    truth = read_temperature_tiff(tmp_path / "pass" / "truth.tiff")
    stripes = np.tile([0.3, -0.3, 0.1, -0.1], 16)  # 64 columns, mean 0, SD sqrt(0.05)
    rows = np.linspace(-0.2, 0.2, 48)[:, None]  # a ramp down the rows, mean 0
    pattern = stripes[None, :] + rows
    out = tmp_path / "out"
    (out / "temps").mkdir(parents=True)
    lines = []
    for k, pivot in enumerate((3, 10, 17, 24)):
        est = truth[pivot] + pattern + 0.5 * k  # a different level per map
        write_temperature_tiff(out / "temps" / f"frame_{pivot:06d}.tiff", est)
        lines.append(json.dumps({"frame": pivot}) + "\n")
    (out / "log.jsonl").write_text("".join(lines))
    scored = score_flight(out, tmp_path / "pass" / "truth.tiff")
    fixed = scored["fixed"]
    assert fixed["fixed_sd_c"] == pytest.approx(float(np.std(pattern)), abs=1e-5)
    assert fixed["fixed_column_bands_c"] == pytest.approx(math.sqrt(0.05), abs=1e-5)
    assert fixed["fixed_row_bands_c"] == pytest.approx(float(np.std(rows)), abs=1e-5)
    for key in ("moving_bias_free_mae_c", "moving_column_bands_c", "moving_row_bands_c"):
        assert fixed[key] == pytest.approx(0.0, abs=1e-5)
    assert [m["bias_c"] for m in scored["maps"]] == pytest.approx([0.0, 0.5, 1.0, 1.5], abs=1e-5)
    # one map: no fixed part to tell from the scene
    (out / "log.jsonl").write_text(lines[0])
    assert score_flight(out, tmp_path / "pass" / "truth.tiff")["fixed"] is None


def test_benchmark_main_writes_its_report(tmp_path, capsys):
    from thermocal.evaluation.passes import main

    md, js = tmp_path / "r.md", tmp_path / "r.json"
    main(["--units", "100", "--frames", "14", "--size", "64x48", "--methods",
          "mean-own,calibration-own", "--markdown", str(md), "--json", str(js)])
    text = md.read_text()
    assert "## Whole UAV passes" in text and "unit 100, builtin:aerial" in text
    assert "mean + own polynomial (reference)" in text and "fixed part SD" in text
    data = json.loads(js.read_text())
    (res,) = data["results"]
    assert res["pass"]["seed"] == 100 and res["pass"]["size"] == [64, 48]
    assert all(r["summary"]["maps"] == 2 for r in res["methods"].values())
    with pytest.raises(InvalidInputError, match="unknown method"):
        main(["--methods", "no-such-method"])
