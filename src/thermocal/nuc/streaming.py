"""Per-frame (streaming) scene-based NUC: each method keeps per-pixel parameters that it updates
with every new frame and applies to it.

Every corrector is a :class:`~thermocal.calibration.base.StreamingCorrector`: ``update(frame)``
learns from one ``(H, W)`` frame, ``correct_frame(frame)`` corrects one frame with the current
parameters (float32), ``process(frame)`` does both (update, then correct) and ``correct(frames)``
processes a stack ``(N, H, W)`` in order.
The outputs are in counts-like units around the raw level: **not radiometric** (no method here
knows the scene temperature); compare them with the truth only after an affine fit.

Methods (CLI names in brackets):

* :class:`Harris1999` [``harris1999``] — constant statistics (Harris & Chiang, IEEE TIP 1999): the
  per-pixel temporal mean and mean absolute deviation estimate offset and gain.
* :class:`Scribner` [``scribner``] — retina-like LMS network (Scribner et al. 1991/1993): gain and
  offset descend the error between a pixel and the mean of its ``(2W+1)²`` neighbourhood.
* :class:`Pezoa2004` [``ecr``] — enhanced constant range (Pezoa, Torres et al. 2004): the per-pixel
  range of the signal, tracked by exponentially relaxed maxima and minima, estimates gain and
  offset.
* :class:`TorresKalman` [``torres-kalman``] — Kalman filter NUC (Torres & Hayat, JOSA A 2003):
  gain and offset as slowly drifting (Gauss-Markov) states, measured once per block of frames
  from the block's per-pixel mean and spread (constant-statistics observation).
* :class:`Zuo2011` [``zuo2011``] — interframe-registration LMS (Zuo et al., JOSA A 2011): the error
  between a corrected frame and the previous corrected frame registered onto it drives the
  offset (and gain) by LMS; large errors (moving objects, misregistration) are not learned from.

All work is vectorised float32 numpy / OpenCV on whole frames; no Python loop over pixels.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from thermocal.errors import InvalidInputError
from thermocal.nuc._common import (
    GAIN_RANGE,
    as_nuc_frames,
    as_one_frame,
    check_int,
    check_positive,
)

__all__ = [
    "Harris1999",
    "Pezoa2004",
    "Scribner",
    "StreamingNUC",
    "TorresKalman",
    "Zuo2011",
    "harris1999",
    "pezoa2004",
    "scribner",
    "torres_kalman",
    "zuo2011",
]

_EPS = np.float32(1e-3)


class StreamingNUC:
    """Base of the streaming correctors: shape bookkeeping, ``correct_frame``, ``process`` and
    ``correct`` of a stack.

    A method states only its own rule: ``_start(x)`` (state from the first frame),
    ``_update(x)`` (learn from one checked float32 frame), ``_correct(x)`` (correct one) and, when
    the estimate needs a few frames first, ``_ready()`` (False: frames pass through unchanged).
    """

    #: Frames needed before the estimate means anything (batch use checks it).
    min_frames = 2

    def __init__(self) -> None:
        self.shape: tuple[int, int] | None = None
        self.n_seen = 0

    def _frame(self, frame: Any) -> np.ndarray:
        x = as_one_frame(frame, self.shape)
        if self.shape is None:
            self.shape = x.shape
            self._start(x)
        return x

    def _start(self, x: np.ndarray) -> None:  # pragma: no cover - each method overrides it
        raise NotImplementedError

    def update(self, frame: Any) -> None:
        """Learn from one frame ``(H, W)`` (raw counts or float)."""
        self._learn(self._frame(frame))

    def _learn(self, x: np.ndarray) -> None:
        """Learn from a checked frame and count it."""
        self._update(x)
        self.n_seen += 1

    def _update(self, x: np.ndarray) -> None:  # pragma: no cover
        raise NotImplementedError

    def _ready(self) -> bool:
        """Whether the parameters are estimated yet (until then ``correct_frame`` copies the
        frame)."""
        return True

    def correct_frame(self, frame: Any) -> np.ndarray:
        """Correct one frame ``(H, W)`` with the current parameters (learning nothing); float32
        ``(H, W)``."""
        x = self._frame(frame)
        if not self._ready():
            return x.copy()
        return self._correct(x)

    def _correct(self, x: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def process(self, frame: Any) -> np.ndarray:
        """Update with a frame, then correct it; float32 ``(H, W)``."""
        self.update(frame)
        return self.correct_frame(frame)

    def correct(self, frames: Any) -> np.ndarray:
        """Run over a sequence ``(N, H, W)`` (causal: frame k is corrected with frames ≤ k).

        Returns
        -------
        numpy.ndarray, float32, shape (N, H, W)
        """
        arr = as_nuc_frames(frames, min_frames=self.min_frames)
        self._warn_short(arr.shape[0])
        return self._run(arr)

    def _warn_short(self, n: int) -> None:
        """Warn when ``n`` frames are too few for the method's estimate to settle (none by
        default)."""

    def _run(
        self, arr: np.ndarray, per_frame: Callable[[int], dict[str, Any]] | None = None
    ) -> np.ndarray:
        """``process`` every frame of checked ``(N, H, W)`` float32 frames in order, with the
        keyword arguments ``per_frame(k)`` for frame k when given; float32 ``(N, H, W)``."""
        out = np.empty(arr.shape, dtype=np.float32)
        for k in range(arr.shape[0]):
            out[k] = self.process(arr[k], **({} if per_frame is None else per_frame(k)))
        return out


class _ExponentialWindow(StreamingNUC):
    """Per-pixel temporal mean ``self.mean`` and one spread statistic, both recursive means with
    weight ``max(1/n, 1/window)`` (cumulative at first, then an exponential window of ``window``
    frames); ready after 2 frames. A method states its spread by ``_start`` (state after
    ``super()._start``) and ``_update_spread``, and keeps its own keyword-only ``__init__`` (so
    that an unknown option's ``TypeError`` names the method's class)."""

    def __init__(self, *, window: int = 200) -> None:
        super().__init__()
        self.window = check_int(window, "window", minimum=2)

    def _start(self, x: np.ndarray) -> None:
        self.mean = x.copy()

    def _ready(self) -> bool:
        return self.n_seen >= 2

    def _warn_short(self, n: int) -> None:
        """A stack shorter than the window: the statistics come from few views (a helper's
        audit: on a 21-frame walk Harris's frames 1–10 correlated 0.28–0.70 with the truth
        against 0.90–0.96 raw)."""
        if n < self.window:
            from thermocal.calibration.base import ThermocalWarning  # here: not at import

            warnings.warn(
                f"{n} frames, fewer than the {self.window}-frame window of this "
                "constant-statistics method: its per-pixel statistics come from few views of "
                "the scene, whose own pattern they take for the sensor's, so its first frames "
                "may come out worse than the raw ones", ThermocalWarning, stacklevel=3)

    def _update(self, x: np.ndarray) -> None:
        a = np.float32(max(1.0 / (self.n_seen + 1), 1.0 / self.window))
        d = x - self.mean
        self.mean += a * d
        self._update_spread(a, x, d)

    def _update_spread(self, a: np.float32, x: np.ndarray, d: np.ndarray) -> None:
        """Update the spread with weight ``a`` from frame ``x``; ``d`` is ``x`` minus the mean
        before this frame, ``self.mean`` is already updated."""
        raise NotImplementedError  # pragma: no cover


class _LinearLMS(StreamingNUC):
    """``y = g·x + o`` per pixel, learned by LMS steps ``o ← o − μ·e``, ``g ← g − μ_g·e·x/x̄²``
    on an error ``e`` that each method defines (``_update`` calls :meth:`_descend`)."""

    def __init__(self, *, learning_rate: float, gain_rate: float) -> None:
        super().__init__()
        self.mu = np.float32(check_positive(learning_rate, "learning_rate", upper=1.0))
        if not 0 <= float(gain_rate) < 10:
            raise InvalidInputError(f"gain_rate: expected 0 <= gain_rate < 10, got {gain_rate!r}")
        self.mu_g = np.float32(self.mu * float(gain_rate))

    def _start(self, x: np.ndarray) -> None:
        self.gain = np.ones_like(x)
        self.offset = np.zeros_like(x)

    def _descend(self, x: np.ndarray, e: np.ndarray) -> None:
        """One LMS step on the error ``e`` ``(H, W)`` of frame ``x``."""
        self.offset -= self.mu * e
        if self.mu_g:
            xbar = np.float32(max(float(x.mean()), 1e-6))
            self.gain -= (self.mu_g / xbar) * e * (x / xbar)

    def _correct(self, x: np.ndarray) -> np.ndarray:
        return self.gain * x + self.offset


class _BlockMoments:
    """Per-pixel mean and standard deviation of consecutive, non-overlapping blocks of ``size``
    frames (running sums, reset after each block)."""

    def __init__(self, like: np.ndarray, size: int) -> None:
        self.size = size
        self._sum = np.zeros_like(like)
        self._sum2 = np.zeros_like(like)
        self.count = 0

    def add(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Add a frame; the block's ``(mean, std)`` (each ``(H, W)``) when it completes one."""
        self._sum += x
        self._sum2 += x * x
        self.count += 1
        if self.count < self.size:
            return None
        n = np.float32(self.count)
        m = self._sum / n
        s = np.sqrt(np.maximum(self._sum2 / n - m * m, 0.0))
        self._sum[:] = 0.0
        self._sum2[:] = 0.0
        self.count = 0
        return m, s


def _bounded_gain(v: np.ndarray) -> np.ndarray:
    """A gain-like map ``v`` (a spread per pixel) clipped to ``GAIN_RANGE`` (2/3…3/2) times its
    spatial mean: safe to divide by, and a detector's gain, not the scene's spread."""
    m = max(float(v.mean()), 1e-6)
    return np.clip(v, np.float32(GAIN_RANGE[0] * m), np.float32(GAIN_RANGE[1] * m))


def _gain_offset_output(x: np.ndarray, gain: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``(x − offset) / gain`` rescaled to the mean gain and offset (counts-like output)."""
    g = np.maximum(gain, _EPS)
    y = (x - offset) / g
    return y * np.float32(g.mean()) + np.float32(offset.mean())


# --------------------------------------------------------------------------------------------
# Harris & Chiang 1999
# --------------------------------------------------------------------------------------------


class Harris1999(_ExponentialWindow):
    """Constant-statistics NUC (Harris & Chiang 1999).

    Each pixel sees, over time, a scene of the same mean and spread; its temporal mean ``m`` is
    then the offset and its mean absolute deviation ``d`` the gain (up to one global constant).
    Both are recursive means with weight ``max(1/n, 1/window)`` (cumulative at first, then an
    exponential window of ``window`` frames so that drift is followed). Safeguard: the gain is
    kept within ``GAIN_RANGE`` (2/3…3/2) of its spatial mean (a pixel that saw little change has
    a small ``d`` that is the scene's, not its gain).

    Parameters
    ----------
    window : int
        Length of the exponential window, frames (default 200).
    """

    def __init__(self, *, window: int = 200) -> None:
        super().__init__(window=window)

    def _start(self, x: np.ndarray) -> None:
        super()._start(x)
        self.mad = np.zeros_like(x)

    def _update_spread(self, a: np.float32, x: np.ndarray, d: np.ndarray) -> None:
        self.mad += a * (np.abs(x - self.mean) - self.mad)

    def _correct(self, x: np.ndarray) -> np.ndarray:
        d = _bounded_gain(self.mad)
        return (x - self.mean) / d * np.float32(d.mean()) + np.float32(self.mean.mean())


# --------------------------------------------------------------------------------------------
# Scribner et al. 1991
# --------------------------------------------------------------------------------------------


class Scribner(_LinearLMS):
    """Retina-like LMS neural network NUC (Scribner et al. 1991, 1993).

    ``y = g·x + o``; the desired output of a pixel is the mean of its ``(2W+1)²`` neighbourhood
    of ``y`` (a "retina-like" horizontal cell); gradient descent on ``(y − desired)²`` gives
    ``o ← o − μ·e`` and ``g ← g − μ_g·e·x/x̄²`` (the gain step normalised by the mean signal
    ``x̄`` so that ``μ`` is dimensionless).

    Parameters
    ----------
    learning_rate : float
        ``μ`` for the offset, 0 < μ < 1 (default 0.05).
    gain_rate : float
        Relative rate of the gain (``μ_g = gain_rate·μ``, default 0.1; 0 for offset only).
    window : int
        ``W`` of the neighbourhood, pixels (default 1: 3×3).
    """

    def __init__(
        self, *, learning_rate: float = 0.05, gain_rate: float = 0.1, window: int = 1
    ) -> None:
        super().__init__(learning_rate=learning_rate, gain_rate=gain_rate)
        self.ksize = 2 * check_int(window, "window") + 1

    def _update(self, x: np.ndarray) -> None:
        y = self._correct(x)
        desired = cv2.blur(y, (self.ksize, self.ksize), borderType=cv2.BORDER_REFLECT)
        self._descend(x, y - desired)


# --------------------------------------------------------------------------------------------
# Pezoa et al. 2004: enhanced constant range
# --------------------------------------------------------------------------------------------


class Pezoa2004(_ExponentialWindow):
    """Enhanced constant-range NUC, ECR (Pezoa, Torres, Córdova, Reeves 2004).

    Constant range: every pixel sees, over time, irradiances spread uniformly over the same range
    ``[a, b]``, so its signal range ``[x_min, x_max]`` gives gain ``x_max − x_min`` and offset
    ``x_min``. Raw extremes are noisy and outlier-driven; the enhancement estimates the bounds of
    the uniform model from its first two moments, ``x_min, x_max = m ∓ √3·s`` with ``m`` and
    ``s`` the recursive (exponentially windowed) temporal mean and standard deviation of the
    pixel — this is our reading of the enhancement, stated here because the estimator matters.
    Output ``(x − x_min)/(x_max − x_min)`` rescaled to the mean range and minimum; the range is
    kept within ``GAIN_RANGE`` (2/3…3/2) of its spatial mean.

    Parameters
    ----------
    window : int
        Length of the exponential window, frames (default 200).
    """

    def __init__(self, *, window: int = 200) -> None:
        super().__init__(window=window)

    def _start(self, x: np.ndarray) -> None:
        super()._start(x)
        self.var = np.zeros_like(x)

    def _update_spread(self, a: np.float32, x: np.ndarray, d: np.ndarray) -> None:
        self.var += a * (d * (x - self.mean) - self.var)

    def _half_range(self) -> np.ndarray:
        """``√3·s``, half the range of the uniform model, counts ``(H, W)``."""
        return np.float32(np.sqrt(3.0)) * np.sqrt(np.maximum(self.var, 0.0))

    @property
    def low(self) -> np.ndarray:
        """Lower bound of each pixel's range, counts ``(H, W)``."""
        return self.mean - self._half_range()

    @property
    def high(self) -> np.ndarray:
        """Upper bound of each pixel's range, counts ``(H, W)``."""
        return self.mean + self._half_range()

    def _correct(self, x: np.ndarray) -> np.ndarray:
        low = self.low
        return _gain_offset_output(x, _bounded_gain(self.high - low), low)


# --------------------------------------------------------------------------------------------
# Torres & Hayat 2003: Kalman filter
# --------------------------------------------------------------------------------------------


class TorresKalman(StreamingNUC):
    """Kalman-filter NUC (Torres & Hayat 2003).

    Gain ``g`` and offset ``o`` of each pixel are states that drift slowly between blocks of
    ``block`` frames (a random walk with variances ``drift_gain``, ``drift_offset`` per block).
    Within a block the scene is assumed to have the same temporal mean ``μ`` and spread ``σ`` at
    every pixel (the constant-statistics observation of the paper, its "spatiotemporal
    diversity" condition), so the block's per-pixel mean ``m`` and standard deviation ``s``
    measure ``g = s/σ`` and ``o = m − g·μ`` with ``μ``, ``σ`` set to the spatial means of ``m``
    and ``s`` (which fixes the arbitrary global scale). One scalar Kalman filter per pixel and
    state fuses the block measurements; the measurement variance is taken from the spread of the
    measurements themselves across the frame.

    Numerical safeguards (not in the paper's equations, which assume the diversity condition
    holds at every pixel; the filter's form is unchanged): a gain measurement is bounded to
    ``GAIN_RANGE`` (2/3…3/2) of the mean (where a pixel saw little change during a block,
    ``s/σ`` is the scene's, not the detector's, and dividing by it made the output diverge);
    the measurement variances are floored; and the covariance update is written
    ``P⁺ = P⁻·R/(P⁻ + R)`` (equal to ``(1 − K)·P⁻``), positive whatever the rounding, so
    ``0 < K < 1`` and the estimates stay convex combinations of bounded measurements.

    Parameters
    ----------
    block : int
        Frames per block (default 10).
    drift_gain, drift_offset : float
        Process-noise variances per block, relative to the measurement variance (defaults 0.02).
    """

    #: Floors of the measurement variances: gain (dimensionless) and offset (counts²).
    R_FLOOR_GAIN = 1e-6
    R_FLOOR_OFFSET = 1e-4

    def __init__(
        self, *, block: int = 10, drift_gain: float = 0.02, drift_offset: float = 0.02
    ) -> None:
        super().__init__()
        self.block = check_int(block, "block", minimum=2)
        # before its first block ends no estimate exists and frames pass through unchanged:
        # a shorter stack would come back raw (a helper's audit: 7 frames, 'corrected')
        self.min_frames = self.block
        self.q_g = np.float32(check_positive(drift_gain, "drift_gain"))
        self.q_o = np.float32(check_positive(drift_offset, "drift_offset"))

    def _start(self, x: np.ndarray) -> None:
        self.gain = np.ones_like(x)
        self.offset = np.zeros_like(x)
        self.p_gain = np.float32(np.inf)
        self.p_offset = np.float32(np.inf)
        self._moments = _BlockMoments(x, self.block)
        self.n_blocks = 0

    def _ready(self) -> bool:
        return self.n_blocks > 0

    def _warn_short(self, n: int) -> None:
        """Its first ``block − 1`` frames pass through unchanged (no estimate before its first
        block ends): said where they are more than a tenth of the stack, not left to look
        corrected (a helper's review)."""
        if self.block - 1 <= 0.1 * n:
            return
        from thermocal.calibration.base import ThermocalWarning  # here: not at import

        warnings.warn(f"torres-kalman: its first {self.block - 1} of {n} frames pass through "
                      f"uncorrected (no estimate before its first block of {self.block} ends)",
                      ThermocalWarning, stacklevel=3)

    def _update(self, x: np.ndarray) -> None:
        block = self._moments.add(x)
        if block is None:
            return
        m, s = block
        # safeguard: a gain measurement is a detector's gain, within GAIN_RANGE of the mean
        sigma = np.float32(max(float(s.mean()), 1e-6))
        g_meas = _bounded_gain(s) / sigma
        o_meas = m - g_meas * np.float32(m.mean())
        # Scalar filters, one per pixel and state; every pixel shares the same variances
        # (a spatially uniform prior), so P and K are scalars per state.
        r_g = np.float32(max(float(g_meas.var()), self.R_FLOOR_GAIN))
        r_o = np.float32(max(float(o_meas.var()), self.R_FLOOR_OFFSET))
        if self.n_blocks == 0:
            self.gain, self.offset = g_meas, o_meas
            self.p_gain, self.p_offset = r_g, r_o
        else:
            pg = self.p_gain + self.q_g * r_g
            po = self.p_offset + self.q_o * r_o
            kg, ko = pg / (pg + r_g), po / (po + r_o)
            self.gain += kg * (g_meas - self.gain)
            self.offset += ko * (o_meas - self.offset)
            # (1 − K)·P⁻ written so that it stays positive: P⁻·R/(P⁻ + R)
            self.p_gain, self.p_offset = pg * r_g / (pg + r_g), po * r_o / (po + r_o)
        self.n_blocks += 1

    def _correct(self, x: np.ndarray) -> np.ndarray:
        return _gain_offset_output(x, self.gain, self.offset)


# --------------------------------------------------------------------------------------------
# Zuo et al. 2011: interframe registration LMS
# --------------------------------------------------------------------------------------------


def _translation(prev: np.ndarray, cur: np.ndarray) -> tuple[float, float] | None:
    """Sub-pixel shift taking ``cur`` onto ``prev`` (phase correlation), None if unreliable."""
    (dx, dy), response = cv2.phaseCorrelate(prev, cur)
    if not np.isfinite(response) or response < 0.05:
        return None
    return -dx, -dy


class Zuo2011(_LinearLMS):
    """Interframe-registration LMS NUC (Zuo, Chen, Gu, Sui 2011).

    ``y = g·x + o``. Frame ``k`` and the previous frame are registered (a homography given with
    each frame, or else a translation by phase correlation of the corrected, high-passed frames);
    where they overlap, the same scene point should give the same corrected value, so the error
    ``e = y_k(p) − y_{k−1}(H p)`` drives ``o ← o − μ·e`` and ``g ← g − μ_g·e·x/x̄²``. Pixels
    whose error exceeds ``threshold`` times the median absolute error are not updated once the
    first ``warmup`` frames have been learned (moving objects and misregistration: the paper's
    ghosting guard; before that the FPN itself makes the large errors).

    Parameters
    ----------
    learning_rate : float
        ``μ`` (default 0.5).
    gain_rate : float
        ``μ_g / μ`` (default 0: offset only, as measured best on simulated flights).
    threshold : float
        Error guard, multiples of the median absolute error (default 6).
    warmup : int
        Frames learned without the guard (default 30).
    """

    def __init__(
        self,
        *,
        learning_rate: float = 0.5,
        gain_rate: float = 0.0,
        threshold: float = 6.0,
        warmup: int = 30,
    ) -> None:
        super().__init__(learning_rate=learning_rate, gain_rate=gain_rate)
        self.threshold = np.float32(check_positive(threshold, "threshold"))
        self.warmup = check_int(warmup, "warmup", minimum=0)

    def _start(self, x: np.ndarray) -> None:
        super()._start(x)
        self._prev: np.ndarray | None = None
        self._pending: np.ndarray | None = None
        self.skipped = 0

    def update(self, frame: Any, *, homography: Any = None) -> None:
        """Learn from one frame; ``homography`` (3, 3) maps this frame's pixels to the previous
        frame's (estimated by phase correlation when None)."""
        x = self._frame(frame)
        self._pending = None if homography is None else np.asarray(homography, dtype=np.float64)
        self._learn(x)

    def process(self, frame: Any, *, homography: Any = None) -> np.ndarray:
        """Update with a frame (and its homography to the previous frame), then correct it."""
        self.update(frame, homography=homography)
        return self.correct_frame(frame)

    def correct(self, frames: Any, *, homographies: Any = None) -> np.ndarray:
        """Run over ``(N, H, W)`` frames; ``homographies`` (N, 3, 3) map each frame to a common
        pivot (as :func:`thermocal.registration.register_burst` gives) when known."""
        arr = as_nuc_frames(frames, min_frames=self.min_frames)
        if homographies is None:
            return self._run(arr)
        from thermocal.registration.warp import as_homographies

        hs = as_homographies(homographies, "homographies", n=arr.shape[0])
        return self._run(
            arr, lambda k: {"homography": np.linalg.inv(hs[k - 1]) @ hs[k] if k > 0 else None}
        )

    def _shift_matrix(self, prev_y: np.ndarray, y: np.ndarray) -> np.ndarray | None:
        a = prev_y - cv2.GaussianBlur(prev_y, (0, 0), 8.0)
        b = y - cv2.GaussianBlur(y, (0, 0), 8.0)
        t = _translation(a, b)
        if t is None:
            return None
        return np.array([[1.0, 0.0, t[0]], [0.0, 1.0, t[1]], [0.0, 0.0, 1.0]])

    def _update(self, x: np.ndarray) -> None:
        y = self._correct(x)
        prev = self._prev
        self._prev = x
        if prev is None:
            return
        prev_y = self._correct(prev)
        h = self._pending if self._pending is not None else self._shift_matrix(prev_y, y)
        if h is None:
            self.skipped += 1
            return
        hh, w = x.shape
        flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
        # previous corrected frame sampled at H p for every pixel p of this frame
        warped = cv2.warpPerspective(prev_y, h, (w, hh), flags=flags,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
        e = y - warped
        ok = np.isfinite(e)
        if not ok.any():
            self.skipped += 1
            return
        e = np.where(ok, e, np.float32(0.0))
        if self.n_seen >= self.warmup:
            mad = float(np.median(np.abs(e[ok])))
            e[np.abs(e) > self.threshold * max(mad, 1e-6)] = 0.0
        self._descend(x, e)


# --------------------------------------------------------------------------------------------
# the methods as functions of a stack: f(frames, **options) -> (N, H, W) float32
# --------------------------------------------------------------------------------------------


def harris1999(frames: Any, **options: Any) -> np.ndarray:
    """Constant statistics (Harris & Chiang 1999) over ``(N, H, W)`` frames; see
    :class:`Harris1999` for the options. Returns float32 ``(N, H, W)``."""
    return Harris1999(**options).correct(frames)


def scribner(frames: Any, **options: Any) -> np.ndarray:
    """Retina-like LMS (Scribner et al. 1991); see :class:`Scribner`. float32 ``(N, H, W)``."""
    return Scribner(**options).correct(frames)


def pezoa2004(frames: Any, **options: Any) -> np.ndarray:
    """Enhanced constant range (Pezoa et al. 2004); see :class:`Pezoa2004`."""
    return Pezoa2004(**options).correct(frames)


def torres_kalman(frames: Any, **options: Any) -> np.ndarray:
    """Kalman-filter NUC (Torres & Hayat 2003); see :class:`TorresKalman`."""
    return TorresKalman(**options).correct(frames)


def zuo2011(frames: Any, *, homographies: Any = None, **options: Any) -> np.ndarray:
    """Interframe-registration LMS (Zuo et al. 2011); see :class:`Zuo2011`.

    ``homographies`` (N, 3, 3), frame → pivot, when known (else phase correlation per pair).
    """
    return Zuo2011(**options).correct(frames, homographies=homographies)
