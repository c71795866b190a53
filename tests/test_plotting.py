"""Figures: Fig. 7 (MAE against N), with and without the family model's floor."""

from __future__ import annotations

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
