"""Scoring an estimate against the truth: MAE, the bias / smooth / fine split of the error,
the affine-free MAE, the fraction within 0.5 °C, the error by distance from the sensor's centre,
and the summary of a method over many bursts (numpy and scipy only)."""

from __future__ import annotations

import functools

import numpy as np
from scipy.ndimage import gaussian_filter

from thermocal.metrics import best_affine_fit, fraction_within, mae
from thermocal.nn.inputs import sensor_r2

__all__ = ["SPLIT_SIGMA_PX", "masked_smooth", "radial_bins", "scores", "split_error",
           "summarise"]


@functools.lru_cache(maxsize=2)
def radial_bins(shape: tuple[int, int], n: int = 5) -> np.ndarray:
    """Each pixel's quintile (``n``-tile) of distance from the sensor's centre, ``(H, W)`` int."""
    r2 = sensor_r2(shape)
    return np.searchsorted(np.quantile(r2, np.linspace(0, 1, n + 1)[1:-1]), r2)


#: Gaussian σ, px, that splits the bias-free error into a smooth and a fine part.
SPLIT_SIGMA_PX = 6.0


def masked_smooth(x: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian of ``sigma`` px of ``x (H, W)`` over the pixels of ``mask (H, W) bool`` only
    (normalised by the mask's own Gaussian), ``(H, W)`` float."""
    return gaussian_filter(np.where(mask, x, 0.0), sigma) / np.maximum(
        gaussian_filter(mask.astype(float), sigma), 1e-9)


def split_error(err: np.ndarray, mask: np.ndarray,
                sigma: float = SPLIT_SIGMA_PX) -> tuple[float, float]:
    """``(smooth, fine)`` MAE, °C, of the error ``err (H, W)`` °C less its mean over ``mask
    (H, W) bool``: the smooth part is a Gaussian of ``sigma`` px of it, normalised over the mask
    (radial patterns, the scene's low frequencies; not zero-mean in general), the fine part the
    rest (pixel FPN left, noise, blurred detail). MAEs do not add up to the bias-free MAE."""
    e = np.where(mask, err - err[mask].mean(), 0.0)
    smooth = masked_smooth(e, mask, sigma)
    return float(np.mean(np.abs(smooth[mask]))), float(np.mean(np.abs((e - smooth)[mask])))


def scores(est: np.ndarray, b: dict) -> dict:
    """Scores of an estimate ``est (H, W)`` °C of the burst ``b`` (a held-out burst: its
    ``truth`` and ``mask``): ``mae``, ``bias``, ``bias_free``, ``smooth``, ``fine``,
    ``affine_free`` (°C), ``within_0_5`` (fraction) and ``bias_by_radius`` (5 values, °C)."""
    m = b["mask"]
    err = est - b["truth"]
    bias = float(err[m].mean())
    fit = best_affine_fit(est, b["truth"], m)
    bins = radial_bins(est.shape)
    smooth, fine = split_error(err, m)
    return {
        "mae": mae(est, b["truth"], valid=m),
        "bias_free": float(np.mean(np.abs(err[m] - bias))),
        "smooth": smooth,
        "fine": fine,
        "affine_free": mae(fit, b["truth"], valid=m),
        "within_0_5": fraction_within(est, b["truth"], 0.5, valid=m),
        "bias": bias,
        "bias_by_radius": [
            float(err[sel].mean()) if sel.any() else float("nan")
            for sel in (m & (bins == k) for k in range(5))
        ],
    }


def summarise(res: dict[str, list[dict]]) -> list[dict]:
    """One row per method of ``res`` (method → per-burst :func:`scores`): the means over the
    bursts (``mae_c``, ``median_mae_c``, ``bias_free_mae_c``, ``affine_free_mae_c``,
    ``within_0_5``, ``mean_abs_bias_c``, ``smooth_mae_c``, ``fine_mae_c``)."""
    rows = []
    for name, lst in res.items():
        maes = [r["mae"] for r in lst]
        rows.append(
            {
                "method": name,
                "mae_c": float(np.mean(maes)),
                "median_mae_c": float(np.median(maes)),
                "bias_free_mae_c": float(np.mean([r["bias_free"] for r in lst])),
                "affine_free_mae_c": float(np.mean([r["affine_free"] for r in lst])),
                "within_0_5": float(np.mean([r["within_0_5"] for r in lst])),
                "mean_abs_bias_c": float(np.mean([abs(r["bias"]) for r in lst])),
                "smooth_mae_c": float(np.mean([r["smooth"] for r in lst])),
                "fine_mae_c": float(np.mean([r["fine"] for r in lst])),
            }
        )
    return rows
