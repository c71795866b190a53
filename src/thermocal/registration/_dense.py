"""Dense alignment pieces shared by burst and sequence registration (private).

* image pyramids (``cv2.pyrDown``) and homographies between pyramid levels;
* :func:`prepare`: a frame with its fixed pattern removed, band-limited and made zero-mean for
  ECC (``cv2.findTransformECC`` mixes the zero fill of its border into the correlation, so a
  frame with a large mean -- raw counts around 7000 with a few counts of contrast -- makes it
  diverge even from the true warp);
* :func:`phase_peaks`: the strongest peaks of a (half-whitened) phase correlation;
* :func:`ecc`: ECC refinement (Evangelidis & Psarakis 2008) from an initial homography;
* :func:`corner_shift`: how far two homographies move the frame corners apart;
* :func:`run_parallel`: a map over frames on a few threads (OpenCV releases the GIL).

Homographies map pixel ``(x, y)`` of the moving frame to pixel ``(x, y)`` of the fixed frame
(:mod:`thermocal.registration.warp`). A pixel ``(x, y)`` of pyramid level ``L`` sits at
``(2^L x, 2^L y)`` of the full-resolution frame (``cv2.pyrDown`` centres its kernel on the even
pixels).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import cv2
import numpy as np

T = TypeVar("T")

#: Default number of threads used to align frames in parallel.
DEFAULT_WORKERS = min(2, os.cpu_count() or 1)


def pyr_down(img: np.ndarray, levels: int) -> np.ndarray:
    """``img`` reduced ``levels`` times by ``cv2.pyrDown`` (Gaussian 5×5 and decimation by 2)."""
    for _ in range(levels):
        img = cv2.pyrDown(img)
    return img


def to_level(h: np.ndarray, levels: int) -> np.ndarray:
    """A full-resolution homography expressed at pyramid level ``levels``."""
    if levels == 0:
        return h
    s = float(2**levels)
    out = np.diag([1.0 / s, 1.0 / s, 1.0]) @ h @ np.diag([s, s, 1.0])
    return out / out[2, 2]


def from_level(h: np.ndarray, levels: int) -> np.ndarray:
    """A homography found at pyramid level ``levels`` expressed at full resolution."""
    if levels == 0:
        return h
    s = float(2**levels)
    out = np.diag([s, s, 1.0]) @ h @ np.diag([1.0 / s, 1.0 / s, 1.0])
    return out / out[2, 2]


def prepare(img: np.ndarray, *, highpass: float = 0.0, blur: float = 0.0) -> np.ndarray:
    """Band-limit a frame (pixels of its own level) and remove its mean, float32.

    ``blur`` (Gaussian sigma) damps noise and the per-pixel residual of the fixed pattern;
    ``highpass`` (sigma of the Gaussian that is subtracted) removes smooth shading that the
    scene does not carry (self-radiation, vignetting, the smooth part of the column pattern).
    """
    y = img
    if blur > 0:
        y = cv2.GaussianBlur(y, (0, 0), blur)
    if highpass > 0:
        y = y - cv2.GaussianBlur(y, (0, 0), highpass)
    return (y - np.float32(y.mean())).astype(np.float32, copy=False)


def hanning(shape: tuple[int, int]) -> np.ndarray:
    """Hanning window ``(H, W)`` float32 for phase correlation."""
    return cv2.createHanningWindow((shape[1], shape[0]), cv2.CV_32F)


def phase_peaks(
    moving: np.ndarray, fixed: np.ndarray, window: np.ndarray, *, count: int = 3,
    exclude_px: int = 0,
) -> list[tuple[float, float]]:
    """The ``count`` strongest translations ``(dx, dy)`` taking ``moving`` onto ``fixed``.

    Hand-written rather than ``cv2.phaseCorrelate``, which returns only the single highest
    peak: with fixed-pattern noise or periodic texture the true shift is often the second or
    third peak, and every candidate is checked by ECC afterwards. The cross-power spectrum is
    whitened half-way (divided by the square root of its magnitude), which keeps the peaks sharp
    without amplifying the noise of weak frequencies. Peaks closer than 2 pixels to a stronger
    one, and (``exclude_px > 0``) those within ``exclude_px`` of zero shift, are skipped.
    """
    fa = np.fft.rfft2(moving * window)
    fb = np.fft.rfft2(fixed * window)
    cross = fb * np.conj(fa)
    cross /= np.sqrt(np.abs(cross)) + 1e-6
    corr = np.fft.fftshift(np.fft.irfft2(cross, s=moving.shape))
    h, w = corr.shape
    cy, cx = h // 2, w // 2
    low = corr.min()
    if exclude_px > 0:
        e = exclude_px
        corr[max(0, cy - e + 1) : cy + e, max(0, cx - e + 1) : cx + e] = low
    out = []
    for _ in range(count):
        iy, ix = np.unravel_index(int(np.argmax(corr)), corr.shape)
        out.append((float(ix - cx), float(iy - cy)))
        corr[max(0, iy - 2) : iy + 3, max(0, ix - 2) : ix + 3] = low
    return out


def shift_correlation(moving: np.ndarray, fixed: np.ndarray, dx: float, dy: float) -> float:
    """Correlation coefficient of ``moving`` and ``fixed`` where they overlap after shifting
    ``moving`` by the integer translation ``(dx, dy)`` (−1 when they overlap by under 10 %)."""
    h, w = moving.shape
    ix, iy = int(round(dx)), int(round(dy))
    x0, x1 = max(0, -ix), min(w, w - ix)
    y0, y1 = max(0, -iy), min(h, h - iy)
    if (x1 - x0) * (y1 - y0) < 0.1 * w * h:
        return -1.0
    a = moving[y0:y1, x0:x1].ravel()
    b = fixed[y0 + iy : y1 + iy, x0 + ix : x1 + ix].ravel()
    a = a - a.mean()
    b = b - b.mean()
    den = float(np.sqrt(np.dot(a, a) * np.dot(b, b)))
    return float(np.dot(a, b)) / den if den > 0 else -1.0


def ecc(
    moving: np.ndarray,
    fixed: np.ndarray,
    h0: np.ndarray,
    *,
    motion: int = cv2.MOTION_AFFINE,
    iterations: int = 30,
    eps: float = 1e-4,
    mask: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Refine ``h0`` (moving → fixed) by ECC; ``(h, correlation)``, correlation −1 on failure.

    Both images must be zero-mean float32 of one size (:func:`prepare`). ``mask`` (uint8, the
    size of ``moving``) marks the moving image's valid pixels.
    """
    try:
        warp = np.linalg.inv(h0)
    except np.linalg.LinAlgError:
        return h0, -1.0
    warp = (warp / warp[2, 2]).astype(np.float32)
    if motion != cv2.MOTION_HOMOGRAPHY:
        warp = np.ascontiguousarray(warp[:2])
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, int(iterations), float(eps))
    try:
        cc, warp = cv2.findTransformECC(fixed, moving, warp, motion, criteria, mask, 1)
    except cv2.error:
        return h0, -1.0
    if motion != cv2.MOTION_HOMOGRAPHY:
        warp = np.vstack([warp, [0.0, 0.0, 1.0]])
    try:
        h = np.linalg.inv(warp.astype(np.float64))
    except np.linalg.LinAlgError:
        return h0, -1.0
    if not np.all(np.isfinite(h)) or abs(h[2, 2]) < 1e-12:
        return h0, -1.0
    return h / h[2, 2], float(cc)


def best_of(
    moving: np.ndarray, fixed: np.ndarray, candidates: Iterable[np.ndarray], *, iterations: int,
    race: int = 0, motion: int = cv2.MOTION_AFFINE,
) -> tuple[np.ndarray | None, float]:
    """ECC from every candidate; the result with the highest correlation ``(h, cc)``.

    With ``race > 0`` and several candidates, each gets ``race`` iterations first and only the
    best one continues for the rest.
    """
    cands = list(candidates)
    first = race if 0 < race < iterations and len(cands) > 1 else iterations
    best: tuple[np.ndarray | None, float] = (None, -2.0)
    for h0 in cands:
        got = ecc(moving, fixed, h0, iterations=first, motion=motion)
        if got[1] > best[1]:
            best = got
    if first < iterations and best[0] is not None and best[1] > -1.0:
        got = ecc(moving, fixed, best[0], iterations=iterations - first, motion=motion)
        if got[1] > -1.0:
            best = got
    return best


def corner_shift(a: np.ndarray, b: np.ndarray, size: tuple[int, int]) -> float:
    """Mean distance (pixels) between the frame corners mapped by ``a`` and by ``b``."""
    w, h = size
    c = np.array([[0.0, w - 1.0, w - 1.0, 0.0], [0.0, 0.0, h - 1.0, h - 1.0], [1, 1, 1, 1]])
    pa, pb = a @ c, b @ c
    return float(np.linalg.norm(pa[:2] / pa[2] - pb[:2] / pb[2], axis=0).mean())


def run_parallel(fn: Callable[[int], T], items: Iterable[int], workers: int) -> list[T]:
    """``[fn(i) for i in items]``, on ``workers`` threads when more than one."""
    items = list(items)
    if workers <= 1 or len(items) <= 1:
        return [fn(i) for i in items]
    with ThreadPoolExecutor(max_workers=min(workers, len(items))) as pool:
        return list(pool.map(fn, items))


def check_workers(workers: Any) -> int:
    """``workers`` as a positive int (None: :data:`DEFAULT_WORKERS`)."""
    from thermocal.errors import InvalidInputError

    if workers is None:
        return DEFAULT_WORKERS
    if isinstance(workers, bool) or not isinstance(workers, int | np.integer) or workers < 1:
        raise InvalidInputError(f"workers: expected a positive number of threads, got {workers!r}")
    return int(workers)
