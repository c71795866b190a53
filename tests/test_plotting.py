"""Figures: Fig. 7 (MAE against N), with and without the family model's floor, and the
shipped Fig. 7 results the demo draws."""

from __future__ import annotations

import json
import math
from importlib.resources import files

from thermocal.plotting import mae_vs_frames_figure


def test_mae_vs_frames_figure_draws_each_variant_and_the_floor():
    base = {"n": [1, 3, 7], "mae_c": {"kpn": [2.0, 1.2, 0.9], "e2e": [3.0, 2.9, 3.1]}}
    fig = mae_vs_frames_figure(base)
    assert [ln.get_label() for ln in fig.axes[0].get_lines()] == ["kpn", "e2e"]
    fig = mae_vs_frames_figure(base | {"floor": {"mae_c": [1.5, 0.9, 0.8]}, "note": "n"})
    lines = fig.axes[0].get_lines()
    assert len(lines) == 3 and lines[-1].get_linestyle() == "--"
    assert list(lines[-1].get_ydata()) == [1.5, 0.9, 0.8]
    fig = mae_vs_frames_figure(base | {"floor": {"mae_c": [None, 0.9, 0.8]}})
    assert len(fig.axes[0].get_lines()) == 2  # an incomplete floor is not drawn


def test_shipped_fig7_results_have_the_layout_the_demo_draws():
    res = json.loads((files("thermocal.nn") / "weights" / "fig7.json").read_text())
    assert res["n"] == [1, 3, 5, 7, 9, 11]
    assert set(res["mae_c"]) == {"kpn", "kpn-no-offset", "e2e"}
    for key in ("mae_c", "bias_free_mae_c", "within_0_5"):
        for values in res[key].values():
            assert len(values) == len(res["n"]) and all(math.isfinite(v) and v >= 0 for v in values)
    assert len(res["floor"]["mae_c"]) == len(res["n"]) and res["note"]
    fig = mae_vs_frames_figure(res)
    assert len(fig.axes[0].lines) == 4  # three variants and the family model


def test_mae_vs_frames_figure_draws_error_bars_over_seeds():
    res = {"n": [1, 3], "mae_c": {"kpn": [0.7, 0.6], "e2e": [2.0, 2.1]},
           "mae_sd_c": {"kpn": [0.05, 0.02], "e2e": [None, None]},
           "seeds": {"kpn": [3, 3], "e2e": [1, 1]}}
    ax = mae_vs_frames_figure(res).axes[0]
    assert len(ax.containers) == 1  # kpn's error bars; e2e, of one seed, a plain line
    assert [ln.get_label() for ln in ax.get_lines()][-1] == "e2e"
    assert set(ax.get_legend_handles_labels()[1]) == {"kpn (mean ± SD of 3 seeds)", "e2e"}


def test_fig7_merge_averages_seeds_and_gives_their_sd():
    import importlib.util
    import sys
    from pathlib import Path

    bench = Path(__file__).resolve().parents[1] / "benchmarks"
    sys.path.insert(0, str(bench))
    try:
        spec = importlib.util.spec_from_file_location("kpn_fig7", bench / "kpn_fig7.py")
        fig7 = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(fig7)
    finally:
        sys.path.remove(str(bench))
    keys = dict.fromkeys(("mae_c", "bias_free_mae_c", "within_0_5"), 0.0)
    rows = [{**keys, "variant": "kpn", "n": n, "seed": s, "mae_c": m, "bias_free_mae_c": m / 2}
            for n, s, m in [(1, 42, 0.8), (1, 43, 0.6), (3, 42, 0.5), (3, 43, 0.5)]]
    rows.append({**keys, "variant": fig7.FLOOR, "n": 1, "mae_c": 1.8})
    res = fig7.to_figure_json(rows, "note")
    assert res["mae_c"]["kpn"] == [0.7, 0.5] and res["seeds"]["kpn"] == [2, 2]
    assert math.isclose(res["mae_sd_c"]["kpn"][0], math.sqrt(0.02))
    assert res["mae_sd_c"]["kpn"][1] == 0
    assert res["floor"]["mae_c"] == [1.8, None]
    one = fig7.to_figure_json(rows[::2], "note")  # one seed: no SD keys
    assert "mae_sd_c" not in one and one["mae_c"]["kpn"] == [0.8, 0.5]
