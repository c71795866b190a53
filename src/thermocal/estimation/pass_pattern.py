"""A camera's residual fixed pattern from a whole pass: the scene and the pattern jointly.

Hardie et al. 2000 (Appl. Opt. 39:1241) estimate each detector's gain and offset from a few
registered frames: the scene is the average of the corrected frames, each detector's gain and
offset a least-squares line between what it read and the scene it saw. Here the same idea runs
over a whole pass (hundreds of frames, every ground point seen by every column it crosses) and
radiometrically: the frames come in as band radiance through a start model (the camera family's
average unit, or the unit's own chamber calibration), and what is fitted is what that model
gets wrong for this unit::

    L_k(p) = a(p) · x(H_k p) + b(p) + c(p) · (t_k − t_ref) + noise

with ``L_k`` frame ``k``'s radiance through the start model, ``x`` the scene on a canvas (a
mosaic), ``H_k`` frame ``k`` → canvas, ``a`` the per-pixel gain, ``b`` the per-pixel offset (the
column and row pattern and the smooth radial part included), ``c`` the offset's change with
the FPA temperature ``t_k`` (fitted only when the FPA spans :data:`MIN_FPA_SPAN_C`). The rounds
alternate the mosaic (a weighted average of the corrected frames) and the per-pixel regression
(weighted least squares), with robust weights (Huber, on the residual's MAD) that leave out
moving objects and parallax.

What motion identifies, and what the start model keeps:

* the global level and gain (the mean of ``b`` and of ``a``): never; the unit's own level
  against its family's cannot be told from an unknown scene. ``mean(b) = 0`` and
  ``mean(a) = 1``: the start model's level stays (a ground reference fixes it);
* a pattern along the lines the scene does not cross: a pass moving along the rows keeps each
  ground line on one sensor row, so a row's offset cannot be told from what that row's strip of
  ground radiates. Each row's median gain and offset are held at the start model's (1 and 0) in
  the fit — a scene whose temperature changes mostly across the rows (a sky gradient) would
  otherwise trade a row's gain against its offset — and then two priors give back what they can
  (:func:`unseen_line_profile`):

  - *fine stripes* (a row's own offset, the mean of its pixels' offsets, a row FPN): the
    constant-statistics assumption (Harris & Chiang 1999; Tendero et al. 2012's midway
    equalisation works on the same one) over the whole pass: the strips of ground seen by two
    neighbouring rows, each hundreds of pixels long, differ little, so the median of the
    corrected frames' differences between neighbouring rows is the rows' offset difference.
    Kept only for stripes narrower than about :data:`FINE_LINES` lines (a Gaussian high-pass):
    slower changes across the rows are the ground's (a field beside a wood) as much as the
    sensor's. A ground line that runs along the whole pass (a long road) looks like a stripe;
  - *a radially symmetric offset* (``radial=True``: families whose smooth offset pattern is
    radial, Oz et al. eq. 16–17): its quadratic along the seen lines is the same along the
    unseen ones, about the start model's centre. What stays unseen is the part of the unit's
    radial pattern that is odd about that centre (an optical centre a little off: a ramp across
    the rows), and slow non-radial patterns;
* a linear ramp of ``b`` along the motion trades, under pure translation, with a level that
  drifts frame by frame; the model has no free per-frame level (the level is the start model's
  at each frame's FPA temperature), so the ramp is seen.

Written by hand: no maintained library fits a scene-based fixed pattern over a registered pass
(OpenCV and kornia give the warps, which this uses).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d

from thermocal.errors import InvalidInputError

__all__ = [
    "FINE_LINES",
    "MIN_FPA_SPAN_C",
    "MIN_FRAMES",
    "MIN_MOTION_FRACTION",
    "ResidualPattern",
    "fine_part",
    "fit_residual_pattern",
    "motion_span",
    "radial_line_profile",
    "unseen_line_profile",
]

#: Fewest frames a pass needs.
MIN_FRAMES = 30
#: Fewest frame extents (along the motion) the scene must move across the sensor over the pass.
MIN_MOTION_FRACTION = 0.5
#: FPA temperature span (°C) over the pass from which the pattern's FPA dependence is fitted.
MIN_FPA_SPAN_C = 1.0
#: Motion (px) across the lines below which that line direction's pattern is not identified.
LINE_MOTION_PX = 8.0
#: Huber threshold, in robust SDs of the residuals.
HUBER_K = 3.0
#: Views of a canvas point below which it does not enter the regression.
MIN_CANVAS_WEIGHT = 3.0
#: The prior SD of a pixel's gain against the start model's (the ``tau2`` family's column gains
#: spread ±5 % around their average).
GAIN_PRIOR_SD = 0.05
#: Plausible per-pixel gains; a pixel fitted outside (a stuck or dead pixel) is flagged bad.
GAIN_BOUNDS = (0.5, 1.5)
#: σ, lines, of the Gaussian trend left out of the constant-statistics line profile: stripes
#: narrower than this along the unseen lines are estimated, slower changes are the ground's.
FINE_LINES = 6.0
#: Most frames (evenly spaced over the pass) whose line statistics estimate the fine stripes.
STAT_FRAMES = 64


@dataclass(frozen=True, eq=False)
class ResidualPattern:
    """What the start model gets wrong for one camera unit, in band radiance (W·m⁻²·sr⁻¹).

    Attributes
    ----------
    gain, offset, offset_per_c : (H, W) float32
        ``a``, ``b`` and ``c`` of the module's model (``c`` per °C of FPA from ``fpa_ref_c``;
        zeros when not fitted).
    offset_se : (H, W) float32
        Standard error of ``b`` (radiance): the residuals' robust SD over √views.
    bad : (H, W) bool
        Pixels the fit flags (implausible gain, too few views): filled from their neighbours.
    fpa_ref_c : float
        FPA temperature of ``b``, °C (the pass's mean).
    residual_sd : float
        Robust SD of the residuals of the last round (radiance).
    views : (H, W) int32
        Frames whose view of each pixel entered the regression.
    motion_px : (float, float)
        The scene's motion across the sensor over the pass, along x and along y, px.
    rounds : int
        Rounds run.
    fitted_fpa : bool
        Whether ``c`` was fitted.
    """

    gain: np.ndarray
    offset: np.ndarray
    offset_per_c: np.ndarray
    offset_se: np.ndarray
    bad: np.ndarray
    fpa_ref_c: float
    residual_sd: float
    views: np.ndarray
    motion_px: tuple[float, float]
    rounds: int
    fitted_fpa: bool

    @property
    def shape(self) -> tuple[int, int]:
        return self.gain.shape  # type: ignore[return-value]

    def correct(self, radiance: np.ndarray, fpa_c: np.ndarray) -> np.ndarray:
        """Radiance through the start model ``(N, H, W)`` at FPA temperatures ``fpa_c``
        ``(N,)`` °C → corrected radiance ``(N, H, W)`` float32 (a new array)."""
        dt = (np.asarray(fpa_c, np.float64).reshape(-1, 1, 1) - self.fpa_ref_c).astype(np.float32)
        return ((radiance - self.offset - self.offset_per_c * dt) / self.gain).astype(np.float32)

    def lines_not_identified(self) -> dict[str, str]:
        """The line directions (``"rows"``, ``"columns"``) whose pattern the pass's motion did
        not wholly show: ``"all"`` where the scene moved less than :data:`LINE_MOTION_PX`
        across them (the module's priors give back fine stripes and a radial quadratic),
        ``"slow"`` where it moved less than :data:`MIN_MOTION_FRACTION` of the frame across
        them (stripes are seen; a pattern as wide as the frame, a ramp across it, is not: the
        fit's rounds carry it no further than the motion; holding its slow part at the start
        model's there, as for unseen lines, was tried and made crabbed passes worse: the fit
        trades a partly seen line's gain against its offset)."""
        mx, my = self.motion_px
        h, w = self.shape
        out = {}
        for lines, moved, extent in (("rows", my, h), ("columns", mx, w)):
            if moved < LINE_MOTION_PX:
                out[lines] = "all"
            elif moved < MIN_MOTION_FRACTION * extent:
                out[lines] = "slow"
        return out

    def unidentified(self) -> list[str]:
        """What this pass could not show, in words (kept from the start model)."""
        out = ["the global level and gain (the start model's; a ground reference fixes them)"]
        moved = dict(zip(("rows", "columns"), self.motion_px[::-1], strict=True))
        for lines, kind in self.lines_not_identified().items():
            why = (f"; only stripes narrower than {FINE_LINES:g} {lines}, and a radial quadratic "
                   "where the family has one, were estimated" if kind == "all" else
                   f", under {MIN_MOTION_FRACTION:g} of the frame: stripes are seen, a ramp "
                   "across the frame is not")
            out.append(f"the {lines[:-1]} pattern's slow part (the scene moved "
                       f"{moved[lines]:.0f} px across the {lines}{why})")
        if not self.fitted_fpa:
            out.append("the pattern's change with the FPA temperature (FPA span below "
                       f"{MIN_FPA_SPAN_C:g} °C)")
        return out


def motion_span(homographies: np.ndarray, shape: tuple[int, int]) -> tuple[float, float]:
    """How far the frame centre's image moves over the pass, along x and y (px): the ranges of
    ``homographies`` ``(N, 3, 3)`` (frame → canvas) applied to the centre of a frame of
    ``shape`` ``(H, W)``."""
    h, w = shape
    c = np.array([(w - 1) / 2.0, (h - 1) / 2.0, 1.0])
    p = homographies @ c
    xy = p[:, :2] / p[:, 2:]
    return float(np.ptp(xy[:, 0])), float(np.ptp(xy[:, 1]))


def check_motion(homographies: np.ndarray, shape: tuple[int, int]) -> tuple[float, float]:
    """The pass's motion (:func:`motion_span`), refused when too short or too still.

    Raises
    ------
    InvalidInputError
        Fewer than :data:`MIN_FRAMES` frames, or motion below :data:`MIN_MOTION_FRACTION` of
        the frame's extent along it.
    """
    n = len(homographies)
    if n < MIN_FRAMES:
        raise InvalidInputError(
            f"selfcal needs a pass of at least {MIN_FRAMES} frames; this one has {n}")
    mx, my = motion_span(homographies, shape)
    h, w = shape
    need = MIN_MOTION_FRACTION * (w if mx / w >= my / h else h)
    if max(mx, my) < need:
        raise InvalidInputError(
            f"selfcal: the scene moved {max(mx, my):.0f} px across the sensor over these {n} "
            f"frames; it needs at least {need:.0f} px ({MIN_MOTION_FRACTION:g} of the frame) so "
            "that each pixel sees what its neighbours saw: fly on, or use --method kpn|mean")
    return mx, my


def _canvas(homographies: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, tuple]:
    """Frame → canvas homographies (the frames' footprint shifted to start at 0) and, per frame,
    its footprint box ``(x0, y0, x1, y1)`` on the canvas; the canvas size ``(W, H)``."""
    h, w = shape
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float).T
    pts = homographies @ corners
    xy = pts[:, :2] / pts[:, 2:]
    lo = np.floor(xy.min(axis=(0, 2))) - 1
    shift = np.array([[1.0, 0, -lo[0]], [0, 1.0, -lo[1]], [0, 0, 1]])
    to_canvas = shift @ homographies
    xy = xy - lo[None, :, None]
    boxes = np.stack([np.floor(xy[:, 0].min(1)) - 1, np.floor(xy[:, 1].min(1)) - 1,
                      np.ceil(xy[:, 0].max(1)) + 2, np.ceil(xy[:, 1].max(1)) + 2], 1)
    boxes = np.maximum(boxes, 0).astype(int)
    size = (int(boxes[:, 2].max()), int(boxes[:, 3].max()))
    return to_canvas, (boxes, size)


def _splat(values: np.ndarray, weights: np.ndarray, to_canvas: np.ndarray, boxes: np.ndarray,
           size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Σ warp(w·v) and Σ warp(w) on the canvas, each frame warped into its own box only."""
    num = np.zeros(size[::-1], np.float32)
    den = np.zeros(size[::-1], np.float32)
    for k in range(len(values)):
        x0, y0, x1, y1 = boxes[k]
        m = np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1]]) @ to_canvas[k]
        box = (int(x1 - x0), int(y1 - y0))
        num[y0:y1, x0:x1] += cv2.warpPerspective(values[k] * weights[k], m, box,
                                                 flags=cv2.INTER_LINEAR)
        den[y0:y1, x0:x1] += cv2.warpPerspective(weights[k], m, box, flags=cv2.INTER_LINEAR)
    return num, den


def _sample(canvas: np.ndarray, to_canvas: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The canvas seen by each frame: ``(N, H, W)`` float32."""
    h, w = shape
    return np.stack([cv2.warpPerspective(canvas, m, (w, h),
                                         flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                         borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
                     for m in to_canvas])


def fit_residual_pattern(
    radiance: np.ndarray,
    homographies: np.ndarray,
    *,
    fpa_c: np.ndarray,
    good: np.ndarray | None = None,
    use: np.ndarray | None = None,
    rounds: int = 8,
    tol: float = 2e-3,
    fit_gain: bool = True,
    radial: bool = False,
) -> ResidualPattern:
    """Fit the residual pattern of a pass (see the module).

    Parameters
    ----------
    radiance : (N, H, W) float32
        Each frame through the start model, band radiance W·m⁻²·sr⁻¹. Never modified.
    homographies : (N, 3, 3) float64
        Frame → a common reference frame (any one frame of the pass).
    fpa_c : (N,) float
        FPA temperature of each frame, °C.
    good : (H, W) bool, optional
        Pixels to fit (default all); the others are flagged ``bad``.
    use : (N,) bool, optional
        Frames to fit on (default all: frames that did not register are left out).
    rounds : int
        Most mosaic / regression rounds.
    tol : float
        Stop once the offset changes by less than ``tol`` of the residual SD between rounds.
    fit_gain : bool
        Fit the per-pixel gain (else 1).
    radial : bool
        The start model's family has a radially symmetric smooth offset (Oz et al. eq. 16–17):
        along lines the pass did not cross, take its quadratic from the lines it did.

    Returns
    -------
    ResidualPattern

    Raises
    ------
    InvalidInputError
        A pass too short or too still (:func:`check_motion`), or shapes that disagree.
    """
    L = np.asarray(radiance, np.float32)
    n, h, w = L.shape
    hs = np.asarray(homographies, np.float64)
    fpa = np.asarray(fpa_c, np.float64).reshape(-1)
    if hs.shape != (n, 3, 3) or fpa.shape != (n,):
        raise InvalidInputError("fit_residual_pattern: one homography and FPA value per frame")
    use = np.ones(n, bool) if use is None else np.asarray(use, bool)
    L, hs, fpa = L[use], hs[use], fpa[use]
    n = len(L)
    motion = check_motion(hs, (h, w))
    # the lines the scene never crossed: their pattern stays the start model's (axis of the
    # line means: rows → 1, columns → 0)
    unseen = tuple(axis for axis, moved in ((1, motion[1]), (0, motion[0]))
                   if moved < LINE_MOTION_PX)
    good = np.ones((h, w), bool) if good is None else np.asarray(good, bool)
    fpa_ref = float(fpa.mean())
    fitted_fpa = bool(np.ptp(fpa) >= MIN_FPA_SPAN_C)
    dt = (fpa - fpa_ref).astype(np.float32)[:, None, None]
    to_canvas, (boxes, size) = _canvas(hs, (h, w))
    a = np.ones((h, w), np.float32)
    b = np.zeros((h, w), np.float32)
    c = np.zeros((h, w), np.float32)
    weights = np.broadcast_to(good.astype(np.float32), L.shape).copy()
    sd = np.inf
    done = 0
    for done in range(1, rounds + 1):
        corrected = (L - b - c * dt) / a
        num, den = _splat(corrected, weights, to_canvas, boxes, size)
        scene = num / np.maximum(den, 1e-6)
        seen = _sample(scene, to_canvas, (h, w))
        inside = _sample(den, to_canvas, (h, w)) >= MIN_CANVAS_WEIGHT
        wk = weights * inside
        a_new, b_new, c_new = _regress(L, seen, dt if fitted_fpa else None, wk, fit_gain,
                                       gain_weight=(sd / GAIN_PRIOR_SD) ** 2
                                       if np.isfinite(sd) else 0.0)
        a_new, b_new, c_new = _normalise(a_new, b_new, c_new, good, unseen)
        resid = L - (a_new * seen + b_new + c_new * dt)
        sd = _robust_sd(resid[inside & good[None]])
        change = float(np.abs(b_new - b)[good].max()) if done > 1 else np.inf
        a, b, c = a_new, b_new, c_new
        # Huber weights: moving objects, parallax and misregistered frames weigh little
        weights = good * np.minimum(1.0, HUBER_K * sd / np.maximum(np.abs(resid), 1e-12))
        weights = weights.astype(np.float32)
        if change < tol * sd:
            break
    for axis in unseen:  # what the priors give back along the unseen lines (see the module)
        sub = slice(None, None, max(1, n // STAT_FRAMES))
        corrected = (L[sub] - b - c * dt[sub]) / a
        line = np.expand_dims(unseen_line_profile(corrected, b, good, axis, radial=radial), axis)
        b = b + a * line
        if radial and fitted_fpa:
            c = c + np.expand_dims(radial_line_profile(c, good, axis), axis)
    if unseen:
        b = (b - np.median(b[good])).astype(np.float32)
        c = (c - np.median(c[good])).astype(np.float32)
    views = inside.sum(axis=0).astype(np.int32)
    wsum = np.maximum((wk > 0.5).sum(axis=0), 1)
    bad = ~good | (a < GAIN_BOUNDS[0]) | (a > GAIN_BOUNDS[1]) | (views < MIN_FRAMES // 2)
    se = (sd / np.sqrt(wsum)).astype(np.float32)
    return ResidualPattern(a, b, c, se, bad, fpa_ref, float(sd), views, motion, done, fitted_fpa)


def unseen_line_profile(corrected: np.ndarray, offset: np.ndarray, good: np.ndarray, axis: int,
                        *, radial: bool = False) -> np.ndarray:
    """The offset profile across lines the pass did not cross (radiance; one value per such
    line, median 0), from the module's two priors.

    Parameters
    ----------
    corrected : (N, H, W) float32
        Frames of the pass corrected with the fitted pattern (radiance).
    offset : (H, W) float32
        The fitted offset ``b`` (its profile along the seen lines gives the radial quadratic).
    good : (H, W) bool
        Pixels to use.
    axis : int
        The unseen lines, as the axis of their means: 1 rows (the profile is ``(H,)``), 0
        columns (``(W,)``).
    radial : bool
        Add the radial quadratic (:func:`radial_line_profile`).
    """
    across = 2 - axis  # the frames' axis that runs across the unseen lines
    x = np.where(good, corrected, np.nan)
    with warnings.catch_warnings():  # a line of bad pixels only: no step there (0 below)
        warnings.simplefilter("ignore", RuntimeWarning)
        step = np.nanmedian(np.diff(x, axis=across), axis=(0, 3 - across))
    fine = fine_part(np.concatenate([[0.0], np.cumsum(np.nan_to_num(step))]))
    if radial:
        fine = fine + radial_line_profile(offset, good, axis)
    return (fine - np.median(fine)).astype(np.float32)


def fine_part(profile: np.ndarray) -> np.ndarray:
    """The stripes of a line profile ``(K,)``: less its Gaussian trend of :data:`FINE_LINES`."""
    profile = np.asarray(profile, np.float64)
    return profile - gaussian_filter1d(profile, FINE_LINES, mode="nearest")


def radial_line_profile(x: np.ndarray, good: np.ndarray, axis: int) -> np.ndarray:
    """A radially symmetric pattern's quadratic along the unseen lines (``axis`` as in
    :func:`unseen_line_profile`), from its profile along the seen ones: the mean of ``x``
    ``(H, W)`` over each seen line, least-squares quadratic in the coordinate running −0.5 … 0.5
    across the frame (:func:`thermocal.camera.presets.radial_map`'s), its ``u²`` term put on
    ``v²`` about the centre (median 0)."""
    seen = np.ma.masked_array(x, ~good).mean(axis=1 - axis).filled(np.nan)
    u = np.linspace(-0.5, 0.5, seen.size)
    ok = np.isfinite(seen)
    beta = np.polyfit(u[ok], seen[ok], 2)[0] if ok.sum() > 3 else 0.0
    v = np.linspace(-0.5, 0.5, x.shape[1 - axis])
    q = beta * v**2
    return (q - np.median(q)).astype(np.float32)


def _regress(L: np.ndarray, s: np.ndarray, dt: np.ndarray | None, w: np.ndarray,
             fit_gain: bool, *, gain_weight: float = 0.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-pixel weighted least squares of ``L`` on ``[s, 1, dt]`` (``a``, ``b``, ``c``), the
    gain held to 1 by a Gaussian prior of weight ``gain_weight`` (the residual variance over
    the prior's, :data:`GAIN_PRIOR_SD`): a pixel whose scene barely changed over the pass (a
    row along a sky gradient) cannot tell its gain from its offset, and keeps the start
    model's gain."""
    cols = [s] if fit_gain else []
    cols.append(np.ones_like(s))
    if dt is not None:
        cols.append(np.broadcast_to(dt, s.shape))
    k = len(cols)
    h, wd = s.shape[1:]
    A = np.empty((h, wd, k, k), np.float64)
    y = np.empty((h, wd, k), np.float64)
    target = L if fit_gain else L - s
    for i in range(k):
        wi = w * cols[i]
        y[..., i] = (wi * target).sum(axis=0)
        for j in range(i, k):
            A[..., i, j] = A[..., j, i] = (wi * cols[j]).sum(axis=0)
    # a pixel that saw too little keeps the start model: a small ridge towards (1, 0, 0), and
    # the gain's prior
    ridge = 1e-6 * np.maximum(A[..., 0, 0], 1e-12)[..., None]
    prior = np.zeros(k)
    A = A + np.eye(k) * ridge[..., None]
    if fit_gain:
        prior[0] = 1.0
        A[..., 0, 0] += gain_weight
        y[..., 0] += gain_weight
    y = y + ridge * prior
    x = np.linalg.solve(A, y[..., None])[..., 0]
    a = x[..., 0] if fit_gain else np.ones((h, wd))
    b = x[..., 1 if fit_gain else 0]
    c = x[..., -1] if dt is not None else np.zeros((h, wd))
    return a.astype(np.float32), b.astype(np.float32), c.astype(np.float32)


def _normalise(a: np.ndarray, b: np.ndarray, c: np.ndarray, good: np.ndarray,
               unseen: tuple[int, ...] = ()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The start model's global level, gain and FPA dependence: ``median(a) = 1``,
    ``median(b) = median(c) = 0`` over the good pixels with a plausible gain; and along the
    ``unseen`` lines (axes of their means: 1 rows, 0 columns) the start model's line pattern:
    each line's median gain 1, median offset 0 (what motion cannot show is not invented)."""
    ok = good & (a > GAIN_BOUNDS[0]) & (a < GAIN_BOUNDS[1])
    a = np.where(ok, a, 1.0).astype(np.float32)
    for axis in unseen:
        masked = np.ma.masked_array
        a = a / np.ma.median(masked(a, ~ok), axis=axis, keepdims=True).filled(1.0)
        b = b - np.ma.median(masked(b, ~ok), axis=axis, keepdims=True).filled(0.0)
        c = c - np.ma.median(masked(c, ~ok), axis=axis, keepdims=True).filled(0.0)
    mean_a = float(np.median(a[ok]))  # robust: a few ill-conditioned lines cannot scale all
    return (a / mean_a).astype(np.float32), (b - np.median(b[ok])).astype(np.float32), \
        (c - np.median(c[ok])).astype(np.float32)


def _robust_sd(values: np.ndarray) -> float:
    """1.4826 × the median absolute deviation (a few hundred thousand values suffice)."""
    v = values[:: max(1, values.size // 400_000)]
    return float(1.4826 * np.median(np.abs(v - np.median(v)))) + 1e-12
