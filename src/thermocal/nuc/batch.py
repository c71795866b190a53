"""NUC methods that work on a whole burst (registration-based) or on one frame at a time.

* :func:`hardie2000` [``hardie2000``] — registration-based NUC (Hardie, Hayat, Armstrong, Yasuda,
  Appl. Opt. 2000): with the frames registered, every scene point is seen by several detectors;
  the scene is estimated by averaging the registered, corrected frames, and each detector's
  gain and offset by a least-squares line between its readings and the scene it saw; a few
  rounds.
* :func:`tendero2012` [``admire``] — single-frame correction in the spirit of ADMIRE (Tendero &
  Gilles 2012): midway column equalisation (each column's sorted values replaced by a
  Gaussian-weighted average of the neighbouring columns' sorted values, removing column FPN)
  followed by DCT denoising (hard thresholding of sliding 8×8 block DCTs, ``scipy.fft``,
  averaged over the overlapping blocks).

Outputs are float32 counts-like frames, not radiometric.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import fft as sfft
from scipy.ndimage import gaussian_filter1d

from thermocal.errors import InvalidInputError, RegistrationError
from thermocal.nuc._common import GAIN_RANGE, as_nuc_frames, check_int, check_positive

__all__ = ["column_midway", "dct_denoise", "hardie2000", "tendero2012"]


# --------------------------------------------------------------------------------------------
# Hardie et al. 2000
# --------------------------------------------------------------------------------------------


def _registered(frames: np.ndarray) -> np.ndarray:
    """Frame → pivot homographies of ``frames`` ``(N, H, W)``: each frame registered onto the
    pivot (:func:`~thermocal.registration.register_burst`); where a frame cannot be (a pass
    whose ends do not overlap its pivot), every frame onto the one before it
    (:func:`~thermocal.registration.sequence.register_sequence`, as ``thermocal flight``
    registers) chained to the middle frame. A frame that shares no scene with the pivot then
    maps outside it and adds nothing to the scene estimate.

    Raises
    ------
    RegistrationError
        Neither way registers: the burst's error, and where the chain broke.
    """
    from thermocal.registration import register_burst
    from thermocal.registration.sequence import register_sequence

    try:
        return register_burst(frames).homographies
    except RegistrationError as direct:
        if len(frames) < 3:
            raise
        seq = register_sequence(frames)
        hs, reachable = seq.chained_to(len(frames) // 2)
        if not reachable.all():
            broken = int(np.flatnonzero(~np.asarray(seq.ok, bool))[0])
            raise RegistrationError(f"{direct}; frame to frame, frame {broken} does not "
                                    f"register onto frame {broken - 1} either") from None
        return hs


def hardie2000(
    frames: Any,
    *,
    homographies: Any = None,
    rounds: int = 3,
    estimate_gain: bool = True,
    min_views: int = 3,
) -> np.ndarray:
    """Registration-based NUC (Hardie et al. 2000).

    Parameters
    ----------
    frames : array_like, shape (N, H, W)
        Raw frames (counts), N ≥ 2. Never modified.
    homographies : array_like, shape (N, 3, 3), optional
        Frame → pivot homographies; when None they are estimated (:func:`_registered`: each
        frame onto the pivot, or, for a pass whose ends do not overlap it, frame to frame and
        chained), which may raise :class:`~thermocal.errors.RegistrationError`.
    rounds : int
        Scene / parameter rounds (default 3).
    estimate_gain : bool
        Fit gain and offset per detector (True) or the offset only.
    min_views : int
        Fewest frames in which a detector must see the estimated scene for its gain to be
        fitted (otherwise the mean gain is kept).

    Returns
    -------
    numpy.ndarray, float32, shape (N, H, W)
        Corrected frames ``(x − o)/g``, rescaled to the mean gain and offset.
    """
    x = as_nuc_frames(frames, min_frames=2)
    n, hh, w = x.shape
    rounds = check_int(rounds, "rounds")
    min_views = check_int(min_views, "min_views", minimum=2)
    if homographies is None:
        hs = _registered(x)
    else:
        from thermocal.registration.warp import as_homographies

        hs = as_homographies(homographies, "homographies", n=n)
    gain = np.ones((hh, w), np.float32)
    offset = np.zeros((hh, w), np.float32)
    ones = np.ones((hh, w), np.float32)
    back_flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    cover = [cv2.warpPerspective(ones, hs[i], (w, hh), flags=cv2.INTER_NEAREST) for i in range(n)]
    for _ in range(rounds):
        y = (x - offset) / gain
        acc = np.zeros((hh, w), np.float32)
        cnt = np.zeros((hh, w), np.float32)
        for i in range(n):
            acc += cv2.warpPerspective(
                y[i], hs[i], (w, hh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
            ) * cover[i]
            cnt += cover[i]
        scene = acc / np.maximum(cnt, 1.0)
        seen = (cnt > 0).astype(np.float32)
        # per-detector sums for the least-squares line x = g·s + o over the frames it saw
        s1 = np.zeros((hh, w), np.float32)
        sx = np.zeros_like(s1)
        ss = np.zeros_like(s1)
        sxx = np.zeros_like(s1)
        sxs = np.zeros_like(s1)
        for i in range(n):
            s_i = cv2.warpPerspective(scene, hs[i], (w, hh), flags=back_flags,
                                      borderMode=cv2.BORDER_REPLICATE)
            v = cv2.warpPerspective(seen, hs[i], (w, hh),
                                    flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP)
            s1 += v
            sx += v * x[i]
            ss += v * s_i
            sxx += v * s_i * s_i
            sxs += v * s_i * x[i]
        m_s = ss / np.maximum(s1, 1.0)
        m_x = sx / np.maximum(s1, 1.0)
        var_s = sxx / np.maximum(s1, 1.0) - m_s * m_s
        cov = sxs / np.maximum(s1, 1.0) - m_s * m_x
        if estimate_gain:
            # a gain needs enough views and a scene that changed at that detector, and must
            # lie in the physical GAIN_RANGE (else the mean gain is kept: dividing by a fit
            # of 0.2 made 40-frame walks diverge, issue 18)
            floor = np.float32(1e-2 * max(float(np.median(var_s)), 1e-6))
            fit = (s1 >= min_views) & (var_s > floor)
            g = np.where(fit, cov / np.maximum(var_s, floor), np.nan)
            g = np.where(np.isfinite(g) & (g > GAIN_RANGE[0]) & (g < GAIN_RANGE[1]), g, np.nan)
            g_mean = float(np.nanmean(g)) if np.isfinite(g).any() else 1.0
            g = np.where(np.isfinite(g), g / g_mean, 1.0).astype(np.float32)
        else:
            g = np.ones((hh, w), np.float32)
        o = np.where(s1 > 0, m_x - g * m_s, 0.0).astype(np.float32)
        # the scene was made with the previous parameters: compose them
        offset = o
        gain = g
    y = (x - offset) / gain
    return (y * np.float32(gain.mean()) + np.float32(offset.mean())).astype(np.float32)


# --------------------------------------------------------------------------------------------
# Tendero & Gilles 2012 (ADMIRE-style)
# --------------------------------------------------------------------------------------------


def column_midway(frame: np.ndarray, *, sigma: float = 8.0) -> np.ndarray:
    """Midway column equalisation (MIRE, Tendero, Landeau & Gilles 2012) of one frame.

    Each column's sorted values (its empirical quantile function) are replaced by the
    Gaussian-weighted (σ columns) average of the sorted values of the neighbouring columns, and
    put back in the column's own rank order. Column FPN, an offset or gain per column, is then
    equal across columns while the scene's column-to-column structure is kept.

    Parameters
    ----------
    frame : numpy.ndarray, shape (H, W), float32
    sigma : float
        Width of the column neighbourhood, columns.

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
    """
    order = np.argsort(frame, axis=0, kind="stable")
    sorted_cols = np.take_along_axis(frame, order, axis=0)
    target = gaussian_filter1d(sorted_cols, sigma, axis=1, mode="reflect").astype(np.float32)
    out = np.empty_like(frame)
    np.put_along_axis(out, order, target, axis=0)
    return out


def dct_denoise(frame: np.ndarray, *, sigma: float, block: int = 8, step: int = 2) -> np.ndarray:
    """DCT denoising: hard thresholding at ``3σ`` of sliding ``block²`` DCTs, averaged.

    Written by hand on ``scipy.fft.dctn`` over a strided window view (no maintained library
    offers block-DCT denoising); every block is processed at once, no loop over pixels.

    Parameters
    ----------
    frame : numpy.ndarray, shape (H, W), float32
    sigma : float
        Noise standard deviation, units of ``frame``.
    block, step : int
        Block side and stride, pixels.
    """
    hh, w = frame.shape
    pad_h = (-(hh - block)) % step
    pad_w = (-(w - block)) % step
    padded = np.pad(frame, ((0, pad_h), (0, pad_w)), mode="reflect")
    win = sliding_window_view(padded, (block, block))[::step, ::step]  # (by, bx, b, b)
    coef = sfft.dctn(win, axes=(-2, -1), norm="ortho", workers=2)
    keep = np.abs(coef) >= 3.0 * sigma
    keep[..., 0, 0] = True
    rec = sfft.idctn(np.where(keep, coef, 0.0), axes=(-2, -1), norm="ortho", workers=2)
    rec = rec.astype(np.float32)
    out = np.zeros(padded.shape, np.float32)
    weight = np.zeros(padded.shape, np.float32)
    by, bx = rec.shape[:2]
    for dy in range(block):  # loop over the block offsets (block² steps), not over pixels
        for dx in range(block):
            out[dy : dy + by * step : step, dx : dx + bx * step : step] += rec[:, :, dy, dx]
            weight[dy : dy + by * step : step, dx : dx + bx * step : step] += 1.0
    return (out / np.maximum(weight, 1.0))[:hh, :w]


def _noise_sigma(frame: np.ndarray) -> float:
    """Robust noise σ: MAD of the diagonal second difference, / 0.6745, / 2 (its gain)."""
    d = frame[1:, 1:] - frame[:-1, 1:] - frame[1:, :-1] + frame[:-1, :-1]
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / 2.0)


def tendero2012(
    frames: Any, *, column_sigma: float = 8.0, denoise: bool = True, block: int = 8
) -> np.ndarray:
    """Single-frame NUC in the spirit of ADMIRE (Tendero & Gilles 2012), frame by frame.

    Dead and hot pixels are replaced by their 3×3 median first (a single-frame method cannot
    learn them), then :func:`column_midway` and, when ``denoise``, :func:`dct_denoise` with the
    noise σ measured robustly on the equalised frame.

    Parameters
    ----------
    frames : array_like, shape (N, H, W) or (H, W)
        Raw frames; each is corrected on its own.
    column_sigma : float
        Column neighbourhood of the equalisation, columns (default 8).
    denoise : bool
        Apply the DCT denoising step (default True).
    block : int
        DCT block side, pixels (default 8).

    Returns
    -------
    numpy.ndarray, float32, shape (N, H, W)
    """
    x = as_nuc_frames(frames, min_frames=1)
    sig = check_positive(column_sigma, "column_sigma")
    block = check_int(block, "block", minimum=2)
    if min(x.shape[1:]) < block:
        raise InvalidInputError(f"frames: smaller than the {block}x{block} DCT block")
    out = np.empty_like(x)
    for k in range(x.shape[0]):
        f = x[k]
        med = cv2.medianBlur(f, 3)
        resid = f - med
        spread = float(np.median(np.abs(resid))) / 0.6745
        f = np.where(np.abs(resid) > 6.0 * max(spread, 1e-6), med, f)
        f = column_midway(f, sigma=sig)
        if denoise:
            f = dct_denoise(f, sigma=max(_noise_sigma(f), 1e-6), block=block)
        out[k] = f
    return out
