"""Registering a burst of raw frames to its pivot frame, with the fixed pattern estimated jointly.

Why not plain feature matching: on a Tau2-class core the per-pixel offset FPN (tens of counts)
and the column pattern are as strong as the scene's texture, and they sit at the same sensor
position in every frame, so SIFT/ORB matches and correlation peaks vote for the identity. What
moves with the scene is the scene; what stays is the fixed pattern. :func:`register_burst`:

1. **two starting patterns** (:func:`~thermocal.registration.fixed_pattern.initial_patterns`):
   the temporal median, whose ghost of the scene is weak on low-contrast scenes, and its column
   and fine-scale part, which has no coarse ghost and suits high-contrast scenes (plus a known
   pattern when one is given). Each is tried on a coarse alignment at half resolution -- the
   three strongest phase-correlation peaks, the two that correlate best refined by affine ECC
   (``cv2.findTransformECC``, Evangelidis & Psarakis 2008), the best correlation kept -- and the
   one whose alignment explains the burst best (one scene plus one pattern,
   :func:`~thermocal.registration.fixed_pattern.joint_residual`, scored at half resolution) is
   kept;
2. **alternation**: the pattern is re-estimated for the current homographies by back-projection
   (:func:`~thermocal.registration.fixed_pattern.back_projected_pattern`, the offset part of
   Hardie et al. 2000), then the frames are aligned again: at half resolution with the phase
   peaks as fresh candidates, then twice at full resolution, stopping early once an update moves
   no corner by more than 0.05 px.

The frames are used raw (no median filter: dead and hot pixels are fixed and the pattern takes
them; a median filter would mix the pattern with the scene and leave a residue that differs from
frame to frame). Frames are aligned in parallel threads (OpenCV releases the GIL). Measured and
not kept (``benchmarks/registration.py`` data): a final full-homography ECC pass where it
raises the correlation (median 0.25 px, p95 1.39 px against 0.22 / 1.00 for affine on the walks),
ranking the phase candidates at quarter resolution (faster, 1.3 % more failures), removing each
frame's column medians (that leaves a sensor-fixed pattern of its own).

Feature-based variants (``method="sift"`` / ``"orb"``, RANSAC, optionally refined as above with
``-ecc``) replace the coarse alignment and work on the same FPN-corrected frames.

Failures raise :class:`~thermocal.errors.RegistrationError` naming the frame: a uniform frame, an
ECC correlation too low to trust (no common scene), too few RANSAC inliers, a degenerate
homography (:func:`thermocal.registration.features.check_homography`) or too little overlap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

import thermocal.registration._dense as dense
from thermocal._validate import as_frames, check_frame_index, is_constant
from thermocal.errors import InvalidInputError, RegistrationError, ResolutionMismatchError
from thermocal.registration.features import (
    MIN_FRAME_PX,
    MIN_INLIERS,
    FrameFeatures,
    as_frame,
    check_homography,
    make_detector,
    match_features,
    ransac_homography,
    stretch_u8,
)
from thermocal.registration.fixed_pattern import (
    as_fixed_pattern,
    back_projected_pattern,
    initial_patterns,
    joint_residual,
)
from thermocal.registration.warp import translation, warp_to_pivot

__all__ = ["BURST_METHODS", "BurstRegistration", "register_burst", "register_pair"]

#: Methods of :func:`register_burst`: the dense default and the feature-based alternatives.
BURST_METHODS = ("auto", "ecc", "sift", "sift-ecc", "orb", "orb-ecc")

#: Fewest pixels of the pivot that a frame must cover (fraction of the frame).
MIN_OVERLAP = 0.2
#: Lowest ECC correlation coefficient accepted between a frame and the pivot.
MIN_CORRELATION = 0.5
#: An alignment round that moves no frame corner by more than this (pixels) ends the rounds.
CONVERGED_PX = 0.05

_COARSE_LEVEL = 1  # pyramid level of the coarse rounds (half resolution)
_COARSE_HIGHPASS = 12.0  # px of that level: removes shading the scene does not carry
_PEAKS = 3  # phase-correlation candidates per frame
_KEEP = 2  # of the phase peaks, the ones with the best direct correlation go on to ECC
_RACE = 5  # ECC iterations every candidate gets before only the best one continues
_FINE_BLUR = 1.0  # px, damps the residual per-pixel pattern at full resolution
# (sweeps of the pattern before the round, ECC iterations, level, phase candidates?)
_ROUNDS = ((3, 20, _COARSE_LEVEL, True), (2, 10, 0, False), (2, 10, 0, False))


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
        covered by the frame for ``"auto"``/``"ecc"``; 0 for the pivot.
    method : str
        Registration method used.
    fixed_pattern : numpy.ndarray, shape (H, W), float32
        The fixed pattern (offset FPN, counts) estimated along the way, mean zero. A by-product:
        an offset-only estimate, not a calibration.
    correlation : numpy.ndarray, shape (N,), float64
        ECC correlation of each FPN-corrected frame with the pivot in the last round (1 for the
        pivot; NaN for the feature methods without ``-ecc``).
    """

    homographies: np.ndarray
    pivot: int
    inliers: np.ndarray
    method: str
    fixed_pattern: np.ndarray | None = None
    correlation: np.ndarray | None = None

    def warp(self, frames: Any, *, interpolation: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """Warp ``frames`` (N, H, W) onto the pivot grid: ``(warped float32, valid bool)``.

        See :func:`thermocal.registration.warp.warp_to_pivot`.
        """
        return warp_to_pivot(frames, self.homographies, interpolation=interpolation)


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------


def _as_burst(frames: Any) -> np.ndarray:
    """A ``(N, H, W)`` burst of numbers, frames at least :data:`MIN_FRAME_PX` on a side, finite."""
    return as_frames(frames, ndim=3, min_size=MIN_FRAME_PX, bit_depth=None)


def _as_float(arr: np.ndarray) -> np.ndarray:
    """Frames as float32 (raw: dead and hot pixels are fixed, the pattern takes them); uniform
    frames refused."""
    x = arr.astype(np.float32)
    for i in range(len(x)):
        if is_constant(x[i]):
            raise RegistrationError(
                f"frame {i}: the frame is uniform; there is no scene structure to align"
            )
    return x


# --------------------------------------------------------------------------------------------
# the pieces
# --------------------------------------------------------------------------------------------


def _prepared(x: np.ndarray, f: np.ndarray, level: int) -> list[np.ndarray]:
    if level == 0:
        return [dense.prepare(xi - f, blur=_FINE_BLUR) for xi in x]
    return [dense.prepare(dense.pyr_down(xi - f, level), highpass=_COARSE_HIGHPASS) for xi in x]


def _align(
    y: list[np.ndarray],
    target: int,
    hs: np.ndarray,
    *,
    level: int,
    iterations: int,
    peaks: bool,
    current: bool,
    workers: int,
    race: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Align every frame of ``y`` (images of pyramid ``level``) to ``y[target]`` by ECC.

    Candidates: the current homographies ``hs`` (full resolution) when ``current``, the
    strongest phase-correlation peaks when ``peaks``. Returns full-resolution homographies and
    correlations (the old homography and −1 where ECC failed from every candidate).
    """
    window = dense.hanning(y[0].shape) if peaks else None
    n = len(y)

    def one(i: int) -> tuple[np.ndarray, float]:
        cands = [dense.to_level(hs[i], level)] if current else []
        if peaks:
            shifts = dense.phase_peaks(y[i], y[target], window, count=_PEAKS)
            if _KEEP < len(shifts):
                score = [dense.shift_correlation(y[i], y[target], dx, dy) for dx, dy in shifts]
                shifts = [shifts[k] for k in np.argsort(score)[::-1][:_KEEP]]
            cands += [translation(dx, dy) for dx, dy in shifts]
        h, cc = dense.best_of(y[i], y[target], cands, iterations=iterations, race=race)
        if h is None or cc <= -1.0:
            return hs[i], -1.0
        return dense.from_level(h, level), cc

    others = [i for i in range(n) if i != target]
    got = dense.run_parallel(one, others, workers)
    out = hs.copy()
    cc = np.ones(n)
    for i, (h, c) in zip(others, got, strict=True):
        out[i], cc[i] = h, c
    out[target] = np.eye(3)
    return out, cc


def _features_h(
    moving: np.ndarray, fixed: np.ndarray, detector: str, name: str
) -> tuple[np.ndarray, int]:
    def feats(img: np.ndarray) -> FrameFeatures:
        u8 = stretch_u8(img, 0.0)
        kps, desc = make_detector(detector).detectAndCompute(u8, None)
        pts = np.array([k.pt for k in kps], dtype=np.float32).reshape(-1, 2)
        return FrameFeatures(u8, pts, desc, detector)

    p_mov, p_fix = match_features(feats(moving), feats(fixed))
    h, inliers = ransac_homography(p_mov, p_fix)
    if h is None or inliers < MIN_INLIERS:
        raise RegistrationError(
            f"{name}: too few inliers ({inliers} of {len(p_mov)} matches, need {MIN_INLIERS}); "
            "the frames may not overlap or lack texture"
        )
    return h / h[2, 2], inliers


def _coarse_dense(
    x: np.ndarray, patterns: dict[str, np.ndarray], ref: int, workers: int
) -> tuple[str, np.ndarray, np.ndarray]:
    """Coarse alignment from every starting pattern; the one that explains the burst best."""
    n = len(x)
    xl = np.stack([dense.pyr_down(xi, _COARSE_LEVEL) for xi in x])
    best: tuple[float, str, np.ndarray, np.ndarray] | None = None
    for name, f in patterns.items():
        y = _prepared(x, f, _COARSE_LEVEL)
        hs, cc = _align(y, ref, np.repeat(np.eye(3)[None], n, axis=0), level=_COARSE_LEVEL,
                        iterations=30, peaks=True, current=False, workers=workers, race=_RACE)
        if len(patterns) == 1:
            return name, hs, cc
        # scored at half resolution: the same choice as at full resolution, at a quarter the cost
        hl = np.stack([dense.to_level(h, _COARSE_LEVEL) for h in hs])
        fl = dense.pyr_down(f, _COARSE_LEVEL)
        score = joint_residual(xl, hl, back_projected_pattern(xl, hl, fl, sweeps=2),
                               highpass=8.0 / 2**_COARSE_LEVEL)
        if best is None or score < best[0]:
            best = (score, name, hs, cc)
    assert best is not None
    return best[1], best[2], best[3]


def _coarse_features(
    x: np.ndarray, f: np.ndarray, ref: int, detector: str, inliers: np.ndarray
) -> np.ndarray:
    y = _prepared(x, f, 0)
    hs = np.repeat(np.eye(3)[None], len(x), axis=0)
    for i in range(len(x)):
        if i != ref:
            hs[i], inliers[i] = _features_h(y[i], y[ref], detector,
                                            f"frame {i} (to pivot {ref})")
    return hs


def _refine(
    x: np.ndarray, f: np.ndarray, hs: np.ndarray, cc: np.ndarray, ref: int, *,
    rounds: tuple[tuple[int, int, int, bool], ...], peaks: bool, workers: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Alternate pattern sweeps and alignment rounds; ``(hs, cc, f)``."""
    size = (x.shape[2], x.shape[1])
    for sweeps, iterations, level, with_peaks in rounds:
        f = back_projected_pattern(x, hs, f, sweeps=sweeps)
        y = _prepared(x, f, level)
        new, new_cc = _align(y, ref, hs, level=level, iterations=iterations,
                             peaks=with_peaks and peaks, current=True, workers=workers,
                             race=_RACE)
        moved = max(dense.corner_shift(new[i], hs[i], size) for i in range(len(x)))
        ok = new_cc > -1.0
        hs = np.where(ok[:, None, None], new, hs)
        cc = np.where(ok, new_cc, cc)
        if level == 0 and moved < CONVERGED_PX:
            break
    return hs, cc, f


# --------------------------------------------------------------------------------------------
# public
# --------------------------------------------------------------------------------------------


def register_burst(
    frames: Any,
    *,
    pivot: int | None = None,
    method: str = "auto",
    fixed_pattern: Any = None,
    workers: int | None = None,
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
        FPN-corrected frames, ``-ecc`` refining them as ``"auto"`` does.
    fixed_pattern : FixedPattern or array_like (H, W), optional
        A known fixed pattern (counts), e.g. from
        :func:`~thermocal.registration.fixed_pattern.estimate_fixed_pattern` on the recording
        the burst comes from (same camera state and scene level: the gain part of the pattern
        scales with the scene): one more starting pattern, tried with the burst's own.
    workers : int, optional
        Threads that align frames in parallel (default: up to 4, the CPU count).

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
        Not a numeric ``(N, H, W)`` burst, NaN, a bad pivot index, an unknown method, a bad
        fixed pattern or number of workers (a pattern of another size:
        :class:`~thermocal.errors.ResolutionMismatchError`).
    """
    if method not in BURST_METHODS:
        raise InvalidInputError(
            f"registration method {method!r}: choose from {', '.join(BURST_METHODS)}"
        )
    n_workers = dense.check_workers(workers)
    arr = _as_burst(frames)
    n, hh, w = arr.shape
    if pivot is not None:
        pivot = check_frame_index(pivot, n)
    if n == 1:
        return BurstRegistration(np.eye(3)[None], 0, np.zeros(1, int), method,
                                 np.zeros((hh, w), np.float32), np.ones(1))
    x = _as_float(arr)
    ref = n // 2 if pivot is None else pivot
    detector = None if method in ("auto", "ecc") else method.split("-")[0]
    refine = method in ("auto", "ecc") or method.endswith("-ecc")
    patterns = initial_patterns(x)
    if fixed_pattern is not None:
        given = as_fixed_pattern(fixed_pattern, (hh, w)).pattern
        patterns = {"given": given - np.float32(given.mean()), **patterns}
    inliers = np.zeros(n, dtype=int)

    if detector is None:
        start, hs, cc = _coarse_dense(x, patterns, ref, n_workers)
    else:
        start = "fine" if "fine" in patterns else next(iter(patterns))  # no coarse ghost
        hs = _coarse_features(x, patterns[start], ref, detector, inliers)
        cc = np.full(n, np.nan)
    f = patterns[start]
    if refine:
        hs, cc, f = _refine(x, f, hs, cc, ref, rounds=_ROUNDS, peaks=detector is None,
                            workers=n_workers)
    if pivot is None and n > 2:
        from thermocal.scenes.trajectory import choose_pivot

        best = choose_pivot(hs, (w, hh))
        if best != ref:
            hs = np.linalg.inv(hs[best])[None] @ hs
            hs /= hs[:, 2:3, 2:3]
            ref = best
            if refine:
                hs, cc, f = _refine(x, f, hs, cc, ref, rounds=((2, 10, 0, False),), peaks=False,
                                    workers=n_workers)
    hs[ref] = np.eye(3)
    cc[ref] = 1.0

    for i in range(n):
        if i == ref:
            continue
        name = f"frame {i} (to pivot {ref})"
        hs[i] = check_homography(hs[i], (w, hh), name)
        cover = int(cv2.warpPerspective(np.ones((hh, w), np.float32), hs[i], (w, hh),
                                        flags=cv2.INTER_NEAREST).sum())
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
        homographies=hs, pivot=int(ref), inliers=inliers, method=method, fixed_pattern=f,
        correlation=cc.astype(np.float64),
    )


def register_pair(
    moving: Any, fixed: Any, *, method: str = "auto", fixed_pattern: Any = None
) -> tuple[np.ndarray, int]:
    """Homography that maps pixels of ``moving`` onto ``fixed``.

    The pair is registered as a two-frame burst (:func:`thermocal.registration.register_burst`
    with ``pivot=1``). Without ``fixed_pattern`` the pattern is estimated from the two frames
    only, which fails on low-contrast scenes (see ``benchmarks/registration.py``); with the
    pattern of the recording the frames come from
    (:func:`thermocal.registration.estimate_fixed_pattern`) a pair is as easy as a burst.

    Parameters
    ----------
    moving, fixed : array_like, shape (H, W)
        Raw frames (uint16 14-bit counts or float), same size. Never modified.
    method : {"auto", "ecc", "sift", "sift-ecc", "orb", "orb-ecc"}
        See :func:`thermocal.registration.register_burst`.
    fixed_pattern : FixedPattern or array_like (H, W), optional
        The known fixed pattern (counts) of the camera.

    Returns
    -------
    h : numpy.ndarray, shape (3, 3), float64
        Pixel ``(x, y)`` of ``moving`` → pixel of ``fixed``; ``h[2, 2] = 1``.
    inliers : int
        Support of the estimate (RANSAC inliers, or covered pixels for the dense methods).

    Raises
    ------
    RegistrationError
        Too few inliers, a degenerate homography or a uniform frame.
    InvalidInputError, ResolutionMismatchError
        Frames that are not 2-D numeric, hold NaN, or differ in size.
    """
    a = as_frame(moving, "moving")
    b = as_frame(fixed, "fixed")
    if a.shape != b.shape:
        raise ResolutionMismatchError(
            f"moving is {a.shape[1]}x{a.shape[0]} but fixed is {b.shape[1]}x{b.shape[0]}"
        )
    reg = register_burst(np.stack([a, b]), pivot=1, method=method, fixed_pattern=fixed_pattern)
    return reg.homographies[0], int(reg.inliers[0])
