"""Figures for reports (matplotlib, headless)."""

from __future__ import annotations

import textwrap
import threading
from pathlib import Path

import numpy as np


def pyplot():
    """matplotlib's ``pyplot`` on the Agg backend (files only, no display), imported when
    first needed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str | Path, *, dpi: int = 110, tight: bool = True,
                fast: bool = False) -> None:
    """Save ``fig`` to ``path`` atomically and close it (``tight``: cropped to what is drawn,
    at the cost of drawing it twice; ``fast``: a PNG compressed at zlib's level 1, not 6)."""
    try:
        _write_figure(fig, path, dpi, tight=tight, fast=fast)
    finally:
        pyplot().close(fig)


def _write_figure(fig, path: str | Path, dpi: int, *, tight: bool = True,
                  fast: bool = False) -> None:
    """Save ``fig`` to ``path`` atomically (its format by the suffix), keeping it open."""
    from thermocal.io.atomic import atomic_path

    fmt = Path(path).suffix.lstrip(".")
    extra = {"pil_kwargs": {"compress_level": 1}} if fast and fmt == "png" else {}
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight" if tight else None, format=fmt, **extra)


def burst_report_figure(
    raw: np.ndarray,
    truth_c: np.ndarray,
    estimates_c: dict[str, np.ndarray],
    *,
    title: str = "",
    error_range_c: float = 3.0,
    valid: np.ndarray | None = None,
):
    """Raw frame, truth and, per method, the estimate and its error map (°C). Returns the figure.

    All images ``(H, W)``; estimates share the truth's colour scale; errors use a diverging map
    clipped at ``±error_range_c``; the MAE in each title is over ``valid`` pixels (all if None).
    """
    plt = pyplot()
    n = len(estimates_c)
    fig, axes = plt.subplots(2, n + 1, figsize=(3.6 * (n + 1), 5.8), squeeze=False)
    lo, hi = np.percentile(truth_c, [1, 99])
    raw_lo, raw_hi = np.percentile(raw, [1, 99])
    im = axes[0, 0].imshow(raw, cmap="gray", vmin=raw_lo, vmax=raw_hi)
    axes[0, 0].set_title("raw frame (counts)")
    fig.colorbar(im, ax=axes[0, 0], fraction=0.046)
    im = axes[1, 0].imshow(truth_c, cmap="inferno", vmin=lo, vmax=hi)
    axes[1, 0].set_title("truth (°C)")
    fig.colorbar(im, ax=axes[1, 0], fraction=0.046)
    for j, (name, est) in enumerate(estimates_c.items(), start=1):
        im = axes[0, j].imshow(est, cmap="inferno", vmin=lo, vmax=hi)
        axes[0, j].set_title(f"{name} (°C)")
        fig.colorbar(im, ax=axes[0, j], fraction=0.046)
        err = est - truth_c
        im = axes[1, j].imshow(err, cmap="RdBu_r", vmin=-error_range_c, vmax=error_range_c)
        mae = np.mean(np.abs(err if valid is None else err[valid]))
        axes[1, j].set_title(f"{name} error, MAE {mae:.2f} °C")
        fig.colorbar(im, ax=axes[1, j], fraction=0.046)
    for ax in axes.flat:
        ax.set_xticks([])
        ax.set_yticks([])
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def temperature_figure(temp_c: np.ndarray, *, title: str = ""):
    """One temperature map ``(H, W)`` in °C with a colour bar (1–99 % range). Returns the figure."""
    plt = pyplot()
    h, w = temp_c.shape
    fig, ax = plt.subplots(figsize=(4.5 * w / max(h, w) + 1.2, 4.5 * h / max(h, w)))
    lo, hi = _temperature_range(temp_c)
    im = ax.imshow(temp_c, cmap="inferno", vmin=lo, vmax=hi)
    fig.colorbar(im, ax=ax, fraction=0.046, label="°C")
    ax.set_xticks([])
    ax.set_yticks([])
    if title:
        ax.set_title(title, fontsize=9)
    # fixed margins, room for a title and six-character colour-bar labels: the figure can be
    # saved whole (not cropped, which draws it twice) whatever the map's values
    fig.subplots_adjust(left=0.01, right=0.83, bottom=0.01, top=0.93)
    return fig


def _temperature_range(temp_c: np.ndarray) -> tuple[float, float]:
    """The colour range of a temperature map, °C: its 1st–99th percentile, at least 0.1 °C."""
    lo, hi = np.percentile(temp_c, [1, 99])
    return lo, max(hi, lo + 0.1)


class TemperaturePreviews:
    """PNG previews of temperature maps (as :func:`temperature_figure` draws them, at ``dpi``,
    saved whole and compressed fast) drawn on one figure, kept between maps of one size: its
    image, colour range and title are updated in place. A new figure per map costs about 1.7×
    as much (0.12 against 0.07 s for a 336×256 map, cropped); cropping (it draws twice) and
    zlib's level 6 cost about as much again as the preview (:func:`save_figure`'s defaults);
    the files are the same bytes as a new figure's saved so. Threads may share one: it draws
    for one at a time (matplotlib figures are not thread-safe); :meth:`close` (or ``with``)
    frees the figure."""

    def __init__(self, *, dpi: int = 80) -> None:
        self.dpi = dpi
        self._fig = None
        self._lock = threading.Lock()

    def save(self, path: str | Path, temp_c: np.ndarray, *, title: str = "") -> None:
        """Write the preview of ``temp_c`` ``(H, W)`` °C to ``path`` (PNG, atomically)."""
        temp_c = np.asarray(temp_c)
        with self._lock:
            if (self._fig is None
                    or self._fig.axes[0].images[0].get_array().shape != temp_c.shape):
                self._close()
                self._fig = temperature_figure(temp_c, title=title)
            else:
                ax = self._fig.axes[0]
                image = ax.images[0]
                image.set_data(temp_c)
                image.set_clim(*_temperature_range(temp_c))
                ax.set_title(title, fontsize=9)
            _write_figure(self._fig, path, self.dpi, tight=False, fast=True)

    def close(self) -> None:
        """Free the figure (a later :meth:`save` makes a new one)."""
        with self._lock:
            self._close()

    def _close(self) -> None:
        if self._fig is not None:
            pyplot().close(self._fig)
            self._fig = None

    def __enter__(self) -> TemperaturePreviews:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def error_cdf_figure(estimates_c: dict[str, np.ndarray], truth_c: np.ndarray, *,
                     valid: np.ndarray | None = None, max_error_c: float = 3.0):
    """Fraction of pixels within an absolute error, per method, with the 0.5 °C line
    (Oz et al. Fig. 12). Returns the figure."""
    from thermocal.metrics import error_cdf

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    for name, est in estimates_c.items():
        thresholds, fraction = error_cdf(est, truth_c, valid=valid, max_error=max_error_c)
        ax.plot(thresholds, 100 * fraction, label=name)
    ax.axvline(0.5, color="k", linestyle="--", linewidth=1)
    ax.set_xlabel("absolute error (°C)")
    ax.set_ylabel("pixels within (%)")
    ax.set_xlim(0, max_error_c)
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def uncertainty_figure(temp_c: np.ndarray, sigma_c: np.ndarray, truth_c: np.ndarray, *,
                       valid: np.ndarray | None = None, title: str = ""):
    """An estimate's temperature, its 1σ map and its absolute error on the σ colour scale, °C
    (each ``(H, W)``), with the share of pixels within 1σ and 2σ. Returns the figure."""
    from thermocal.metrics import sigma_coverage

    plt = pyplot()
    error = np.abs(np.asarray(temp_c, np.float64) - truth_c)
    mask = np.ones(error.shape, bool) if valid is None else np.asarray(valid, bool)
    cov = sigma_coverage(error[mask], np.asarray(sigma_c)[mask])
    top = float(np.percentile(np.concatenate([sigma_c[mask], error[mask]]), 99))
    fig, axes = plt.subplots(1, 3, figsize=(12.0, 3.6))
    panels = ((temp_c, "temperature (°C)", None, None),
              (sigma_c, "uncertainty 1σ (°C)", 0.0, top),
              (np.where(mask, error, np.nan), f"|error| (°C): {100 * cov['within_1sigma']:.0f} % "
               f"within 1σ, {100 * cov['within_2sigma']:.0f} % within 2σ", 0.0, top))
    for ax, (img, label, lo, hi) in zip(axes, panels, strict=True):
        shown = ax.imshow(img, cmap="inferno", vmin=lo, vmax=hi)
        ax.set_title(label, fontsize=9)
        ax.axis("off")
        fig.colorbar(shown, ax=ax, fraction=0.046)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def mae_vs_frames_figure(results: dict):
    """MAE against the number of frames N per network variant (Oz et al. Fig. 7).

    ``results = {"n": [1, 3, …], "mae_c": {variant: [...]}, "note": "..."}``, optionally with
    ``"floor": {"mae_c": [...]}`` (the eq. 9 mean through the exact average training unit),
    drawn dashed, and ``"mae_sd_c": {variant: [...]}`` (the SD over training seeds of mean
    values), drawn as error bars.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    values_all = []
    sds = results.get("mae_sd_c") or {}
    for name, values in results["mae_c"].items():
        sd = sds.get(name)
        if sd and any(v is not None for v in sd):  # None: a single seed at that N
            counts = sorted(set((results.get("seeds") or {}).get(name) or []))
            of = ("several" if not counts else str(counts[0]) if len(counts) == 1
                  else f"{counts[0]}–{counts[-1]}")
            label = f"{name} (mean ± SD of {of} seeds)"
            ax.errorbar(results["n"], values, yerr=[0.0 if v is None else v for v in sd],
                        marker="o", capsize=3, label=label)
        else:
            ax.plot(results["n"], values, marker="o", label=name)
        values_all.extend(values)
    floor = (results.get("floor") or {}).get("mae_c")
    if floor and all(v is not None for v in floor):
        ax.plot(results["n"], floor, "k--", marker=".", label="exact family model (eq. 9)")
        values_all.extend(floor)
    if values_all and min(values_all) > 0 and max(values_all) > 4 * min(values_all):
        from matplotlib.ticker import FormatStrFormatter

        ax.set_yscale("log")  # one unstable variant would otherwise flatten the others
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
    ax.set_xlabel("frames N")
    ax.set_ylabel("MAE (°C)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    if results.get("note"):
        ax.set_title(textwrap.fill(results["note"], 90), fontsize=7)
    fig.tight_layout()
    return fig


def figure_png(fig, *, dpi: int = 110) -> bytes:
    """``fig`` as PNG bytes (to embed in a page), and close it."""
    import io

    plt = pyplot()
    try:
        buffer = io.BytesIO()
        fig.savefig(buffer, dpi=dpi, bbox_inches="tight", format="png")
    finally:
        plt.close(fig)
    return buffer.getvalue()
