"""Markdown tables of evaluation results (plain strings; the suites print them)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from thermocal.evaluation.scoring import SPLIT_SIGMA_PX

__all__ = ["accuracy_table", "markdown_table", "per_burst_table", "radius_table",
           "trajectory_table"]


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """A Markdown table: one ``|``-separated line per row, cells as given (already formatted)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def accuracy_table(rows: list[dict]) -> str:
    """The accuracy table of :func:`~thermocal.evaluation.scoring.summarise`'s rows, with a
    note on what each column means."""
    table = markdown_table(
        ("method", "MAE °C", "median MAE °C", "within 0.5 °C", "mean abs bias °C",
         "bias-free MAE °C", "smooth part °C", "fine part °C", "affine-free MAE °C"),
        ((r["method"], f"{r['mae_c']:.2f}", f"{r['median_mae_c']:.2f}",
          f"{100 * r['within_0_5']:.0f} %", f"{r['mean_abs_bias_c']:.2f}",
          f"{r['bias_free_mae_c']:.2f}", f"{r['smooth_mae_c']:.2f}", f"{r['fine_mae_c']:.2f}",
          f"{r['affine_free_mae_c']:.2f}") for r in rows))
    note = (
        "(bias-free: after removing each burst's mean error; its smooth part: a Gaussian of "
        f"σ = {SPLIT_SIGMA_PX:.0f} px of it (radial patterns, low frequencies), its fine part: "
        "the rest (pixel FPN left, noise, blurred detail), each as an MAE; affine-free: after "
        "the best affine map onto the truth (an oracle): what is left of non-uniformity and "
        "noise once the unit's unknown global offset / gain are set aside)"
    )
    return f"{table}\n\n{note}"


def trajectory_table(bursts: list[dict], res: dict[str, list[dict]]) -> str:
    """Each method's MAE °C on the walks and on the hovers."""
    rows = []
    for name, lst in res.items():
        by = {m: [s["mae"] for b, s in zip(bursts, lst, strict=True) if b["motion"] == m]
              for m in ("walk", "hover")}
        rows.append((name, f"{np.mean(by['walk']):.2f}", f"{np.mean(by['hover']):.2f}"))
    return markdown_table(("method", "walk (60-80 % overlap)", "hover (±3 px jitter)"), rows)


def radius_table(res: dict[str, list[dict]]) -> str:
    """Each method's mean error °C by fifths of the pixels from the sensor's centre."""
    rows = [(name, *(f"{v:+.2f}" for v in np.nanmean([s["bias_by_radius"] for s in lst],
                                                      axis=0)))
            for name, lst in res.items()]
    return markdown_table(("method", "1st", "2nd", "3rd", "4th", "5th (corners)"), rows)


def per_burst_table(bursts: list[dict], scores: list[dict]) -> str:
    """One method's scores burst by burst."""
    return markdown_table(
        ("scene", "unit", "FPA °C", "MAE °C", "bias °C", "bias-free °C", "affine-free °C"),
        ((f"{b['scene']} ({b['motion']})", b["unit"], f"{b['fpa_c']:.1f}", f"{s['mae']:.2f}",
          f"{s['bias']:+.2f}", f"{s['bias_free']:.2f}", f"{s['affine_free']:.2f}")
         for b, s in zip(bursts, scores, strict=True)))
