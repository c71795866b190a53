"""thermocal demo: runs end to end on built-in data and writes its report."""

from __future__ import annotations

import json

from thermocal.demo import DEMO_UNIT, run_demo


def test_demo_runs_small_and_writes_its_report(tmp_path):
    results = run_demo(tmp_path, size=(160, 120))  # the smallest the network checks
    names = {p.name for p in tmp_path.iterdir()}
    assert {"report.png", "error_cdf.png", "results.json"} <= names
    rows = {r["method"].split(" (")[0]: r for r in results["rows"]}
    # the per-pixel, FPA-dependent calibration is at the noise floor; two-point drifts away
    assert rows["polynomial"]["mae_c"] < 0.2
    assert rows["two-point"]["mae_c"] > 1.0
    assert rows["true camera model"]["mae_c"] < 0.1
    assert json.loads((tmp_path / "results.json").read_text())["camera"]["unit"] == DEMO_UNIT
