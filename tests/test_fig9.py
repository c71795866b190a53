"""thermocal.evaluation.suites.fig9: Oz et al.'s Fig. 9 comparison (its pure parts; the run
itself is a benchmark)."""

from __future__ import annotations

import numpy as np

from thermocal.evaluation.suites import fig9


def test_pivots_lie_on_the_flights_grid_and_spread_over_the_pass():
    piv = fig9._pivots(301, 2, fig9.N)
    assert len(piv) == 2 and all((p - fig9.N // 2) % fig9.N == 0 for p in piv)
    assert fig9.N // 2 < piv[0] < 150 < piv[1] < 301 - fig9.N // 2


def test_scores_are_after_the_best_affine_map():
    rng = np.random.default_rng(0)
    truth = rng.normal(20, 3, (32, 40))
    good = np.ones_like(truth, bool)
    exact = fig9._score(3.0 * truth + 100.0, truth, good)  # counts-like but exact
    assert exact["affine_free_mae_c"] < 1e-9 and exact["column_bands_c"] < 1e-9
    stripes = truth + np.tile(rng.normal(0, 0.5, 40), (32, 1))
    s = fig9._score(stripes, truth, good)
    assert s["column_bands_c"] > 0.3 and s["affine_free_mae_c"] > 0.2


def test_summary_means_per_method_and_report(tmp_path):
    rows = [{"method": m, "affine_free_mae_c": v, "roughness": 0.1, "column_bands_c": v / 2,
             "seconds": 1.0} for m, v in (("a", 1.0), ("a", 3.0), ("b", 0.5))]
    summary = fig9.summarise(rows)
    assert [s["method"] for s in summary] == ["a", "b"]
    assert summary[0]["affine_free_mae_c"] == 2.0 and summary[0]["bursts"] == 2
    text = fig9.report(summary, {"machine": "m", "wall_s": 1.0, "command": "c", "data": "d"})
    assert "| a | 2 | 2.000 |" in text
    fig9.figure(summary, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 1000
