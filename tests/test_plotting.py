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
