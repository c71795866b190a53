"""Registering a burst of raw frames to its pivot frame, with the fixed pattern estimated jointly.

Why not plain feature matching: on a Tau2-class core the per-pixel offset FPN (tens of counts)
is as strong as the scene's fine texture, and it sits at the same sensor position in every
frame, so SIFT/ORB matches and correlation peaks vote for the identity. What moves with the scene
is the scene; what stays is the fixed pattern. :func:`register_burst` therefore alternates

1. **fixed-pattern estimate** ``F`` (counts, ``(H, W)``): first the temporal median of the frames
   (3 frames or more; for a pair the column pattern and the radial quadratic surface), then, once
   the frames are aligned, the mean over frames of ``frame_i − scene`` where the scene is the
   average of the aligned, corrected frames warped back into frame ``i`` (the offset part of
   Hardie et al. 2000 restricted to registration);
2. **alignment** of every corrected, lightly blurred frame to the pivot: a coarse translation
   by phase correlation (the zero-shift peak, left by any FPN that remains, suppressed), then
   ECC (``cv2.findTransformECC``, Evangelidis & Psarakis 2008), affine in the loop and a full
   homography in the last pass; the previous estimate is kept when it correlates better.

Feature-based variants (``method="sift"`` / ``"orb"``, RANSAC, optional ECC) work on the same
FPN-corrected frames.

Failures raise :class:`~thermocal.errors.RegistrationError` naming the frame: a uniform frame, an
ECC correlation too low to trust (no common scene), too few RANSAC inliers, or a degenerate
homography (see :func:`thermocal.registration.features.check_homography`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from thermocal.errors import InvalidInputError, RegistrationError
from thermocal.registration.features import (
    MIN_INLIERS,
    _as_frame,
    _column_pattern,
    _match,
    _quadratic_surface,
    _ransac,
    _stretch,
    check_homography,
)

__all__ = ["BURST_METHODS", "BurstRegistration", "register_burst"]

#: Methods of :func:`register_burst`: the dense default and the feature-based alternatives.
BURST_METHODS = ("auto", "ecc", "sift", "sift-ecc", "orb", "orb-ecc")

#: Fewest pixels of the pivot that a frame must cover (fraction of the frame).
MIN_OVERLAP = 0.2
#: Lowest ECC correlation coefficient accepted between a frame and the pivot.
MIN_CORRELATION = 0.5

_BLUR_SIGMA = 1.0  # px, damps the residual per-pixel FPN and noise before alignment
_SUPPRESS_PX = 8  # half-width of the zero-shift window suppressed in phase correlation
_ITERATIONS = 5  # fixed-pattern / alignment rounds
_FINAL_HOMOGRAPHY = False  # a full-homography ECC pass at the end (measured: no gain on walks)


@dataclass(frozen=True, eq=False)
class BurstRegistration:
    """Homographies of a burst to its pivot frame.

    Attributes
    ----------
    homographies : numpy.ndarray, shape (N, 3, 3), float64
        Pixel ``(x, y)`` of frame ``i`` → pixel of the pivot frame, ``h33 = 1``; the pivot's own
        is exactly the identity.
    pivot : int
        Index of the pivot frame.
    inliers : numpy.ndarray, shape (N,), int
        Support of each frame's homography: RANSAC inliers for the feature methods, pivot pixels
        covered by the frame (those ECC used) for ``"auto"``/``"ecc"``; 0 for the pivot.
    method : str
        Registration method used.
    fixed_pattern : numpy.ndarray, shape (H, W), float32
        The fixed pattern (offset FPN, counts) estimated along the way, mean zero. A by-product:
        an offset-only estimate, not a calibration.
    """

    homographies: np.ndarray
    pivot: int
    inliers: np.ndarray
    method: str
    fixed_pattern: np.ndarray | None = None

    def warp(self, frames: Any, *, interpolation: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """Warp ``frames`` (N, H, W) onto the pivot grid: ``(warped float32, valid bool)``.

        See :func:`thermocal.registration.warp.warp_to_pivot`.
        """
        from thermocal.registration.warp import warp_to_pivot

        return warp_to_pivot(frames, self.homographies, interpolation=interpolation)


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------


def _as_burst(frames: Any) -> np.ndarray:
    arr = np.asarray(frames)
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"frames: expected raw counts or floats, got dtype {arr.dtype}")
    if arr.ndim != 3:
        raise InvalidInputError(f"frames: expected a (N, H, W) burst, got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise InvalidInputError("frames: the burst is empty")
    _as_frame(arr[0], "frame 0")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr).reshape(len(arr), -1).all(axis=1))[0])
        raise InvalidInputError(f"frames: frame {bad} contains NaN or infinite values")
    return arr


def _check_pivot(pivot: Any, n: int) -> int:
    if isinstance(pivot, bool) or not isinstance(pivot, int | np.integer):
        raise InvalidInputError(f"pivot: expected a frame index, got {pivot!r}")
    if not 0 <= int(pivot) < n:
        raise InvalidInputError(f"pivot: {pivot} is not a frame index (0..{n - 1})")
    return int(pivot)


# --------------------------------------------------------------------------------------------
# the pieces
# --------------------------------------------------------------------------------------------


def _phase_shift(a: np.ndarray, b: np.ndarray, window: np.ndarray) -> tuple[float, float]:
    """Translation ``(dx, dy)`` taking ``a`` onto ``b``, the zero-shift peak suppressed.

    Hand-written rather than ``cv2.phaseCorrelate`` because that returns only the highest peak,
    which is often the fixed pattern's zero shift.
    """
    fa = np.fft.rfft2(a * window)
    fb = np.fft.rfft2(b * window)
    cross = fb * np.conj(fa)
    cross /= np.sqrt(np.abs(cross)) + 1e-6  # half-way to phase correlation: robust, not noisy
    corr = np.fft.fftshift(np.fft.irfft2(cross, s=a.shape))
    h, w = a.shape
    cy, cx = h // 2, w // 2
    s = _SUPPRESS_PX
    corr[cy - s : cy + s + 1, cx - s : cx + s + 1] = corr.min()
    iy, ix = np.unravel_index(int(np.argmax(corr)), corr.shape)
    return float(ix - cx), float(iy - cy)


def _ecc(
    moving: np.ndarray, fixed: np.ndarray, h0: np.ndarray, *, motion: int, iterations: int
) -> tuple[np.ndarray, float]:
    """ECC from ``h0`` (moving → fixed); ``(H, correlation)``, correlation −1 on failure."""
    warp = np.linalg.inv(h0)
    warp = (warp / warp[2, 2]).astype(np.float32)
    if motion != cv2.MOTION_HOMOGRAPHY:
        warp = np.ascontiguousarray(warp[:2])
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, iterations, 1e-5)
    try:
        cc, warp = cv2.findTransformECC(fixed, moving, warp, motion, criteria, None, 1)
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


def _coverage(h: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Pivot pixels that frame ``h`` covers, float32 0/1 ``(H, W)``."""
    hh, w = shape
    ones = np.ones(shape, np.float32)
    return cv2.warpPerspective(ones, h, (w, hh), flags=cv2.INTER_NEAREST)


def _fixed_pattern(x: np.ndarray, hs: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Offset FPN from aligned frames: mean over frames of ``x_i − scene seen by frame i``."""
    n, hh, w = x.shape
    acc = np.zeros((hh, w), np.float32)
    cnt = np.zeros((hh, w), np.float32)
    for i in range(n):
        cov = _coverage(hs[i], (hh, w))
        acc += cv2.warpPerspective(
            x[i] - f, hs[i], (w, hh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        ) * cov
        cnt += cov
    scene = acc / np.maximum(cnt, 1.0)
    seen = (cnt > 0).astype(np.float32)
    facc = np.zeros((hh, w), np.float32)
    fcnt = np.zeros((hh, w), np.float32)
    back_flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    for i in range(n):
        back = cv2.warpPerspective(
            scene, hs[i], (w, hh), flags=back_flags, borderMode=cv2.BORDER_REPLICATE
        )
        ok = cv2.warpPerspective(
            seen, hs[i], (w, hh), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
        )
        facc += (x[i] - back) * ok
        fcnt += ok
    out = np.where(fcnt > 0, facc / np.maximum(fcnt, 1.0), f).astype(np.float32)
    return out - np.float32(out.mean())


def _initial_pattern(x: np.ndarray) -> np.ndarray:
    if len(x) >= 3:
        f = np.median(x, axis=0).astype(np.float32)
    else:
        f = np.mean([_column_pattern(xi) + _quadratic_surface(xi) for xi in x], axis=0)
    return (f - f.mean()).astype(np.float32)


def _prepared(x: np.ndarray, f: np.ndarray) -> list[np.ndarray]:
    out = []
    for xi in x:
        y = xi - f
        y = cv2.GaussianBlur(y - np.float32(y.mean()), (0, 0), _BLUR_SIGMA)
        out.append(y)
    return out


def _features_h(
    moving: np.ndarray, fixed: np.ndarray, detector: str, name: str
) -> tuple[np.ndarray, int]:
    from thermocal.registration.features import FrameFeatures, _detector

    def feats(img: np.ndarray) -> FrameFeatures:
        u8 = _stretch(img, 0.0)
        kps, desc = _detector(detector).detectAndCompute(u8, None)
        pts = np.array([k.pt for k in kps], dtype=np.float32).reshape(-1, 2)
        return FrameFeatures(u8, pts, desc, detector)

    p_mov, p_fix = _match(feats(moving), feats(fixed))
    h, inliers = _ransac(p_mov, p_fix)
    if h is None or inliers < MIN_INLIERS:
        raise RegistrationError(
            f"{name}: too few inliers ({inliers} of {len(p_mov)} matches, need {MIN_INLIERS}); "
            "the frames may not overlap or lack texture"
        )
    return h / h[2, 2], inliers


# --------------------------------------------------------------------------------------------
# public
# --------------------------------------------------------------------------------------------


def register_burst(
    frames: Any, *, pivot: int | None = None, method: str = "auto"
) -> BurstRegistration:
    """Register every frame of a burst to its pivot frame.

    Parameters
    ----------
    frames : array_like, shape (N, H, W)
        Raw frames (uint16 14-bit counts, or float), at least 16×16 pixels. Never modified.
    pivot : int, optional
        Index of the pivot frame. None chooses the frame with the largest total overlap with
        the others (:func:`thermocal.scenes.trajectory.choose_pivot`; the middle one, ``N // 2``,
        on a tie).
    method : {"auto", "ecc", "sift", "sift-ecc", "orb", "orb-ecc"}
        ``"auto"``/``"ecc"``: phase correlation + ECC with the fixed pattern estimated jointly
        (see the module notes). ``"sift"``/``"orb"``: OpenCV features + RANSAC on the
        FPN-corrected frames, ``-ecc`` refining them by ECC.

    Returns
    -------
    BurstRegistration

    Raises
    ------
    RegistrationError
        A frame that cannot be registered to the pivot: uniform, too little correlation with
        the pivot (no common scene), too few inliers, or a degenerate homography; the message
        names the frame and the reason.
    InvalidInputError
        Not a numeric ``(N, H, W)`` burst, NaN, a bad pivot index or an unknown method.
    """
    if method not in BURST_METHODS:
        raise InvalidInputError(
            f"registration method {method!r}: choose from {', '.join(BURST_METHODS)}"
        )
    arr = _as_burst(frames)
    n, hh, w = arr.shape
    if pivot is not None:
        pivot = _check_pivot(pivot, n)
    if n == 1:
        return BurstRegistration(np.eye(3)[None], 0, np.zeros(1, int), method,
                                 np.zeros((hh, w), np.float32))
    x = np.stack([cv2.medianBlur(arr[i].astype(np.float32), 3) for i in range(n)])
    for i in range(n):
        if float(np.ptp(x[i])) <= 1e-6 * max(1.0, float(np.abs(x[i]).max())):
            raise RegistrationError(
                f"frame {i}: the frame is uniform; there is no scene structure to align"
            )
    ref = n // 2 if pivot is None else pivot
    detector = None if method in ("auto", "ecc") else method.split("-")[0]
    refine = method in ("auto", "ecc") or method.endswith("-ecc")

    f = _initial_pattern(x)
    window = cv2.createHanningWindow((w, hh), cv2.CV_32F)
    hs = np.repeat(np.eye(3)[None], n, axis=0)
    cc = np.ones(n)
    inliers = np.zeros(n, dtype=int)

    def align(target: int, rounds: int, init: np.ndarray | None, final: bool) -> None:
        nonlocal f
        for k in range(rounds):
            y = _prepared(x, f)
            last = final and k == rounds - 1
            for i in range(n):
                if i == target:
                    continue
                name = f"frame {i} (to pivot {target})"
                if init is not None and k == 0:
                    candidates = [init[i]]
                elif detector is not None:
                    h_new, inliers[i] = _features_h(y[i], y[target], detector, name)
                    candidates = [h_new] + ([hs[i]] if k > 0 and refine else [])
                else:
                    dx, dy = _phase_shift(y[i], y[target], window)
                    candidates = [np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])]
                    if k > 0:
                        candidates.append(hs[i])
                if not refine:
                    hs[i], cc[i] = candidates[0], 1.0
                    continue
                best = (candidates[0], -1.0)
                for h0 in candidates:
                    got = _ecc(y[i], y[target], h0, motion=cv2.MOTION_AFFINE, iterations=50)
                    if got[1] > best[1]:
                        best = got
                if last and _FINAL_HOMOGRAPHY:
                    got = _ecc(y[i], y[target], best[0], motion=cv2.MOTION_HOMOGRAPHY,
                               iterations=30)
                    if got[1] >= best[1] - 1e-3:
                        best = got
                hs[i], cc[i] = best
            if k < rounds - 1:
                f = _fixed_pattern(x, hs, f)
            hs[target] = np.eye(3)

    align(ref, _ITERATIONS, None, final=True)
    if pivot is None and n > 2:
        from thermocal.scenes.trajectory import choose_pivot

        best = choose_pivot(hs, (w, hh))
        if best != ref:
            composed = np.linalg.inv(hs[best])[None] @ hs
            composed /= composed[:, 2:3, 2:3]
            hs = composed
            ref = best
            align(ref, 1, composed.copy(), final=True)
    hs[ref] = np.eye(3)

    for i in range(n):
        if i == ref:
            continue
        name = f"frame {i} (to pivot {ref})"
        hs[i] = check_homography(hs[i], (w, hh), name)
        cover = int(_coverage(hs[i], (hh, w)).sum())
        if cover < MIN_OVERLAP * w * hh:
            raise RegistrationError(
                f"{name}: degenerate homography (it covers only {cover / (w * hh):.0%} of the "
                f"pivot, need {MIN_OVERLAP:.0%})"
            )
        if refine and cc[i] < MIN_CORRELATION:
            raise RegistrationError(
                f"{name}: no common scene found (ECC correlation {cc[i]:.2f} < "
                f"{MIN_CORRELATION}); a uniform frame or frames that do not overlap"
            )
        if detector is None:
            inliers[i] = cover
    inliers[ref] = 0
    return BurstRegistration(
        homographies=hs, pivot=int(ref), inliers=inliers, method=method, fixed_pattern=f
    )
