"""Figures: Fig. 7 (MAE against N), with and without the family model's floor, and the
shipped Fig. 7 results the demo draws."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from importlib.resources import files
from pathlib import Path

import pytest

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
    uneven = {"n": [1, 3], "mae_c": {"kpn": [0.7, 0.6]}, "mae_sd_c": {"kpn": [0.05, None]},
              "seeds": {"kpn": [2, 1]}}
    ax = mae_vs_frames_figure(uneven).axes[0]
    assert ax.get_legend_handles_labels()[1] == ["kpn (mean ± SD of 1–2 seeds)"]
    no_counts = {k: v for k, v in res.items() if k != "seeds"}  # SD without the seed counts
    assert "kpn (mean ± SD of several seeds)" in (
        mae_vs_frames_figure(no_counts).axes[0].get_legend_handles_labels()[1])


@pytest.fixture
def fig7(monkeypatch):
    """benchmarks/kpn_fig7.py as a module (it needs torch, and benchmarks/ on the path)."""
    pytest.importorskip("torch")
    bench = Path(__file__).resolve().parents[1] / "benchmarks"
    monkeypatch.syspath_prepend(str(bench))
    for name in ("kpn", "kpn_fig7"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    spec = importlib.util.spec_from_file_location("kpn_fig7", bench / "kpn_fig7.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    for name in ("kpn", "kpn_fig7"):
        sys.modules.pop(name, None)


def _rows(fig7, runs):
    keys = dict.fromkeys(("mae_c", "bias_free_mae_c", "within_0_5"), 0.0)
    return [{**keys, "variant": "kpn", "n": n, "seed": s, "mae_c": m, "bias_free_mae_c": m / 2}
            for n, s, m in runs]


def test_fig7_merge_averages_seeds_and_gives_their_sd(fig7):
    rows = _rows(fig7, [(1, 42, 0.8), (1, 43, 0.6), (3, 42, 0.5), (3, 43, 0.5)])
    floor = {"variant": fig7.FLOOR, "n": 1, "mae_c": 1.8, "bias_free_mae_c": 1.7}
    res = fig7.to_figure_json(rows + [floor, dict(floor)], "note")  # one floor row per run
    assert res["mae_c"]["kpn"] == [0.7, 0.5] and res["seeds"]["kpn"] == [2, 2]
    assert math.isclose(res["mae_sd_c"]["kpn"][0], math.sqrt(0.02))
    assert res["mae_sd_c"]["kpn"][1] == 0
    assert res["floor"]["mae_c"] == [1.8, None]
    one = fig7.to_figure_json(rows[::2], "note")  # one seed: no SD keys
    assert "mae_sd_c" not in one and one["mae_c"]["kpn"] == [0.8, 0.5]


def test_fig7_merge_refuses_a_run_given_twice_and_unlike_floors(fig7):
    rows = _rows(fig7, [(1, 42, 0.8), (1, 43, 0.6)])
    with pytest.raises(SystemExit, match="seed 43 is given twice"):
        fig7.to_figure_json(rows + rows[1:], "note")
    floor = {"variant": fig7.FLOOR, "n": 1, "mae_c": 1.8, "bias_free_mae_c": 1.7}
    with pytest.raises(SystemExit, match="differ between the files"):
        fig7.to_figure_json(rows + [floor, {**floor, "mae_c": 1.5}], "note")


def test_previews_on_one_figure_are_the_bytes_of_a_new_figure_each(tmp_path):
    """The reused figure (image, colour range and title updated) writes the same PNG as a new
    figure per map; a map of another size gets a figure of its own."""
    import numpy as np

    from thermocal.plotting import TemperaturePreviews, save_figure, temperature_figure

    rng = np.random.default_rng(0)
    maps = [rng.normal(20, 3, (48, 64)), rng.normal(-5, 10, (48, 64)),
            rng.normal(40, 1, (30, 40))]
    with TemperaturePreviews(dpi=80) as previews:
        for i, m in enumerate(maps):
            previews.save(tmp_path / f"r{i}.png", m, title=f"pivot {i}")
    for i, m in enumerate(maps):
        save_figure(temperature_figure(m, title=f"pivot {i}"), tmp_path / f"n{i}.png", dpi=80,
                    tight=False, fast=True)
        assert (tmp_path / f"r{i}.png").read_bytes() == (tmp_path / f"n{i}.png").read_bytes()
    assert previews._fig is None  # closed on leaving the block
