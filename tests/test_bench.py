"""thermocal bench: finds the benchmarks, runs them, reports with the machine."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thermocal.bench import BENCHMARKS, machine, markdown_report
from thermocal.cli import main


def test_every_suite_is_a_package_module_with_a_script_beside_it():
    import importlib
    from pathlib import Path

    scripts = Path(__file__).resolve().parents[1] / "benchmarks"
    for name in BENCHMARKS:
        assert callable(importlib.import_module(f"thermocal.evaluation.suites.{name}").main)
        assert f"thermocal.evaluation.suites.{name}" in (scripts / f"{name}.py").read_text()


def test_the_nuc_suite_scores_every_method_or_says_where_it_is_scored():
    """Every NUC method is in the nuc suite, or is a method of one short burst that Fig. 9's
    suite scores (deepir, added later, ran on the suite's 120-frame walks and failed to
    register them: `thermocal bench` failed, unnoticed)."""
    from thermocal.evaluation.suites import fig9, nuc
    from thermocal.nuc import NUC_METHODS

    scored = {method for _, method in nuc.VARIANTS}
    for name in NUC_METHODS:
        assert (name in scored) != (name in nuc.BURST_ONLY), name
    assert set(nuc.BURST_ONLY) <= set(fig9.METHODS)


def test_bench_refuses_a_missing_output_folder_before_running(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "--quick", "--json", str(tmp_path / "no" / "r.json")])
    assert exc.value.code == 2 and "does not exist" in capsys.readouterr().err


def test_a_benchmark_named_twice_runs_once(monkeypatch, capsys):
    import thermocal.bench as bench

    asked = []
    monkeypatch.setattr(bench, "run_benchmarks",
                        lambda names, *, quick: asked.append(names) or {})
    main(["bench", "--quick", "--only", "simulator", "--only", "nuc", "--only", "simulator"])
    assert asked == [("simulator", "nuc")]


def test_report_names_the_machine_and_failures():
    runs = {"simulator": {"markdown": "| a |", "results": {}, "seconds": 3.0, "rc": 0,
                          "stderr_tail": []},
            "nuc": {"markdown": "", "results": None, "seconds": 1.0, "rc": 2,
                    "stderr_tail": ["boom"]}}
    text = markdown_report(runs, quick=True, host=machine())
    assert "cores" in text and "| a |" in text
    assert "nuc (1 s) — FAILED (exit 2)" in text and "boom" in text
    assert "- command: `thermocal bench --quick`" in text
    # the command that reruns it: the suites --only chose (the audit: `--only` was dropped)
    text = markdown_report(runs, quick=False, host=machine(), only=("simulator", "nuc"))
    assert "- command: `thermocal bench --only simulator --only nuc`" in text


@pytest.mark.slow
def test_bench_runs_the_simulator_benchmark(tmp_path):
    out = tmp_path / "r.json"
    md = tmp_path / "r.md"
    main(["bench", "--quick", "--only", "simulator", "--json", str(out), "--markdown", str(md)])
    data = json.loads(out.read_text())
    assert data["benchmarks"]["simulator"]["rc"] == 0
    assert "640x512" in md.read_text()


def test_coverage_tables_say_whether_any_level_of_sigma_meets_the_bands():
    from thermocal.evaluation.suites.coverage import report, unit_spread
    from thermocal.metrics import rescaled_coverage, sigma_coverage

    rng = np.random.default_rng(0)
    gauss, rect = rng.normal(0.0, 1.0, 4000), rng.uniform(-1.0, 1.0, 4000)
    sigma = np.full(4000, 0.5)
    rows = []
    for unit in (101, 102):
        for method, err in (("lin", gauss), ("two-point", rect)):
            rows.append({"method": method, "data": f"tau2 unit {unit}", "preset": "tau2",
                         "unit": unit, "frames": 10, "refused": 0, "silent_over_1c": 0,
                         "mae_c": float(np.abs(err).mean()), "accepted": sigma_coverage(err, sigma),
                         "forced": None, "accepted_rescaled": rescaled_coverage(err, sigma)})
    text = report(rows, {"machine": "test", "wall_s": 1.0})
    lines = {ln.split("|")[1].strip(): ln for ln in text.splitlines() if "tau2 unit 101" in ln}
    assert "×2.0" in lines["lin"] and "no k in band" not in lines["lin"]
    assert "no k in band" in lines["two-point"]
    spread = unit_spread(rows)
    assert "(2 of 2)" in spread and "(0 of 2)" in spread


def test_one_factor_per_method_is_found_only_where_every_cases_factors_meet():
    from thermocal.evaluation.suites.coverage import method_factors
    from thermocal.metrics import rescaled_coverage

    rng = np.random.default_rng(2)
    sigma = np.full(20_000, 0.5)

    def row(method, preset, held_out, err):
        return {"method": method, "preset": preset, "unit": 101, "held_out": held_out,
                "accepted_rescaled": rescaled_coverage(err, sigma)}

    # lin: every case's errors Gaussian of σ 1 under a stated 0.5 (each needs ×2);
    # wolf2016: one case needs ×2, the other ×3; two-point: a rectangle in one case
    rows = [row("lin", p, h, rng.normal(0.0, 1.0, sigma.size))
            for p in ("tau2", "boson") for h in ("ramp", "other")]
    rows += [row("wolf2016", "tau2", "ramp", rng.normal(0.0, 1.0, sigma.size)),
             row("wolf2016", "boson", "ramp", rng.normal(0.0, 1.5, sigma.size)),
             row("two-point", "tau2", "ramp", rng.normal(0.0, 1.0, sigma.size)),
             row("two-point", "boson", "ramp", rng.uniform(-1.0, 1.0, sigma.size))]
    lines = {ln.split("|")[1].strip(): ln for ln in method_factors(rows).splitlines()
             if ln.startswith("| ") and "method" not in ln}
    lo, hi = (float(v) for v in lines["lin"].split("|")[6].strip(" ×").split("–"))
    assert lo < 2.0 < hi and hi / lo < 1.3
    assert "none: tau2 101 ramp needs ≤" in lines["wolf2016"]
    needs = float(lines["wolf2016"].split("boson 101 ramp ≥ ")[1].split()[0])
    assert 2.5 < needs < 3.0  # a Gaussian of 1.5 °C under a stated 0.5
    # each family alone has one case: its own interval
    assert lines["wolf2016"].split("|")[7].strip().startswith("×")
    assert "no factor in band for 1 of 2 (boson 101 ramp" in lines["two-point"]
    rect = rescaled_coverage(rng.uniform(-1.0, 1.0, sigma.size), sigma)
    assert rect["band_factors"] is None
    assert method_factors(rows[:1]) == ""


def test_the_networks_coverage_is_told_by_condition():
    from thermocal.evaluation.suites.coverage import _conditions, condition_table

    assert _conditions(40.0, -50.0) == ["FPA 35…45 °C", "scene − FPA -90…-40 °C"]
    assert _conditions(10.0, 70.0) == []  # outside every bin
    row = {"data": "tau2 units", "accepted_by_condition": {
        "FPA 35…45 °C": {"bursts": 3, "within_1sigma": 0.5, "within_2sigma": 0.9,
                         "median_sigma_c": 0.8, "pixels": 10}}}
    text = condition_table([row, {"data": "calibration row"}])
    assert "| tau2 units | FPA 35…45 °C | 3 | 50.0 % | 90.0 % | 0.80 |" in text
    assert condition_table([{"data": "calibration row"}]) == ""
    # bursts of several units: the share with its interval over units, which spans it
    from thermocal.evaluation.suites.coverage import _condition_cell

    rng = np.random.default_rng(0)
    sigma = np.full(100, 1.0)
    cell = _condition_cell({u: [(rng.normal(rng.normal(0.0, 0.7), 0.7, 100), sigma)]
                            for u in range(30)})
    assert cell["bursts"] == 30 and cell["units"] == 30
    lo, hi = cell["interval"]["within_1sigma"]
    assert lo < cell["within_1sigma"] < hi and hi - lo > 0.03
    text = condition_table([{"data": "u", "accepted_by_condition": {"FPA 15…25 °C": cell}}])
    assert f"{100 * cell['within_1sigma']:.1f} % ({100 * lo:.0f}–{100 * hi:.0f})" in text
    assert _condition_cell({1: [(np.zeros(3), np.ones(3))]})["interval"] is None


def test_the_networks_pixels_are_told_by_their_temperature():
    """A σ right on the whole but wrong on the cold pixels: the pixel bins show it."""
    from thermocal.evaluation.suites.coverage import (
        _condition_keys,
        _pixel_conditions,
        condition_table,
    )

    temps = np.array([-30.0, -10.0, 0.0, 10.0, 40.0, 200.0])
    bins = _pixel_conditions(temps)
    assert [k for k, _ in bins] == ["pixels at -90…-20 °C", "pixels at -20…-5 °C",
                                    "pixels at -5…5 °C", "pixels at 5…15 °C",
                                    "pixels at 15…60 °C"]
    assert all(sel.sum() == 1 for _, sel in bins) and not any(sel[-1] for _, sel in bins)
    keys = _condition_keys()  # the table's order: FPA, scene − FPA, then the pixels, rising
    assert keys.index("FPA 35…45 °C") < keys.index("scene − FPA -90…-40 °C") < keys.index(
        "scene − FPA 0…60 °C") < keys.index("pixels at -90…-20 °C")
    from thermocal.evaluation.suites.coverage import _condition_cell

    rng = np.random.default_rng(2)
    t = rng.uniform(-40.0, 30.0, 20000)
    err = rng.normal(0.0, np.where(t < -5.0, 3.0, 0.5))  # cold pixels err 6 times more
    sigma = np.full(t.size, 1.0)
    cells = {k: _condition_cell({0: [(err[sel], sigma[sel])]}) for k, sel in _pixel_conditions(t)}
    assert cells["pixels at -90…-20 °C"]["within_1sigma"] < 0.35
    assert cells["pixels at 5…15 °C"]["within_1sigma"] > 0.9
    text = condition_table([{"data": "u", "accepted_by_condition": cells}])
    assert "| u | pixels at -20…-5 °C | 1 |" in text


def test_the_suites_pixel_bins_pair_each_pixels_error_with_its_own_sigma():
    """The shipped network on three quick bursts through the suite (`_run`): the pixel bins
    hold every accepted pixel once, each with its own error and σ (the coverage of a bin
    computed again from the estimates, by hand)."""
    from thermocal.burst import fill_stuck_pixels
    from thermocal.estimation.pipeline import estimate
    from thermocal.evaluation.heldout import eval_bursts
    from thermocal.evaluation.suites.coverage import _pixel_conditions, _run
    from thermocal.nn.infer import NetworkEstimator

    net = NetworkEstimator.from_file("kpn")
    bursts = eval_bursts(7, quick=True, units=(300, 301), per_scene=1, unit_per_burst=True)[:3]
    res = _run(net, bursts)
    pixel_cells = {k: c for k, c in res["accepted_by_condition"].items()
                   if k.startswith("pixels at")}
    assert sum(c["pixels"] for c in pixel_cells.values()) == res["accepted"]["pixels"]
    errors, sigmas, temps = [], [], []
    for b in bursts:
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        est = estimate(frames, net, fpa_c=b["fpa_read"], homographies=b["hs"],
                       pivot=b["pivot"], fill_defects=False)
        assert not est.outside
        errors.append((est.temperature_c - b["truth"])[b["mask"]])
        sigmas.append(est.sigma_c[b["mask"]])
        temps.append(est.temperature_c[b["mask"]])
    e, s, t = (np.concatenate(a) for a in (errors, sigmas, temps))
    for key, sel in _pixel_conditions(t):
        assert pixel_cells[key]["within_1sigma"] == pytest.approx(
            np.mean(np.abs(e[sel]) <= s[sel]), abs=1e-12)


def test_coverage_says_what_sharpening_sigma_would_silence():
    from thermocal.evaluation.suites.coverage import _rescaled

    rng = np.random.default_rng(1)
    # 200 frames of small Gaussian errors under a σ twice too large, and one frame off by 3 °C
    # whose σ of 2 °C covers it at 1σ × 2: silent once σ is scaled below 3 / (2·2) = 0.75
    pairs = [(rng.normal(0.0, 0.3, 50), np.full(50, 0.6)) for _ in range(200)]
    pairs.append((np.full(50, 3.0), np.full(50, 2.0)))
    res = _rescaled(pairs)
    assert 0.4 < res["factor"] < 0.6  # the level the small errors want
    assert res["silent_at_factor"] == 1
    assert res["safe_factor"] == pytest.approx(0.75)
    assert res["safe_within_1sigma"] > 0.68
    # nothing to silence: the safe factor is the best one
    calm = _rescaled(pairs[:-1])
    assert calm["silent_at_factor"] == 0 and calm["safe_factor"] == calm["factor"]
    assert _rescaled([]) is None


def test_the_fits_accumulation_rate_is_measured_on_its_own_code():
    """The chamber suite's ceiling of the numpy fit: bytes of frames per second that
    `polynomial._accumulate` reads on one core, finite and positive on a small block."""
    from thermocal.evaluation.suites.chamber_io import accumulate_rate

    rate = accumulate_rate((16, 32), frames=8, rounds=2)
    assert np.isfinite(rate) and rate > 0


def test_a_frames_silent_share_is_a_gaussians_beyond_both_1c_and_2_sigma():
    from scipy import stats

    from thermocal.evaluation.suites.coverage import silent_share

    assert silent_share(np.full(5, 1.0)) == pytest.approx(2 * stats.norm.sf(2.0))  # 2σ binds
    assert silent_share(np.full(5, 0.25)) == pytest.approx(2 * stats.norm.sf(4.0))  # 1 °C binds
    assert silent_share(np.zeros(3)) == 0.0
