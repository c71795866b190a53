"""The stages of a burst that no estimator owns (numpy and OpenCV only).

Validation of a raw burst (:func:`check_burst`, :func:`pivot_index`, :func:`fpa_value`), its
homographies onto the pivot frame (:func:`find_homographies`), its stuck pixels
(:func:`stuck_pixels`, :func:`fill_stuck_pixels`) and the overlap check (:func:`check_overlap`).
:mod:`thermocal.estimation.pipeline` runs them in order.
"""

from __future__ import annotations

import math
from statistics import NormalDist
from typing import Any

import numpy as np

from thermocal._validate import (
    SATURATED_FRACTION,
    as_frames,
    check_fpa_c,
    check_not_constant,
    check_not_saturated,
    pivot_index,
)
from thermocal.calibration.base import fill_bad_pixels
from thermocal.errors import InvalidInputError, RegistrationError
from thermocal.registration.burst import register_burst
from thermocal.registration.warp import as_homographies

__all__ = [
    "FROZEN_FALSE_ALARMS",
    "FROZEN_MIN_FRAMES",
    "MAX_FILLED_CLIP_PX",
    "MIN_OVERLAP",
    "SATURATED_FRACTION",
    "burst_window",
    "check_burst",
    "check_overlap",
    "fill_stuck_pixels",
    "find_homographies",
    "fpa_value",
    "frozen_pixels",
    "pivot_index",
    "scene_motion_at",
    "scene_motion_px",
    "stuck_pixels",
]

#: Every frame must see at least this fraction of the pivot frame.
MIN_OVERLAP = 0.1


def burst_window(n_frames: int, n: int | None, pivot: int | None) -> tuple[slice, int | None]:
    """The frames of a recording of ``n_frames`` an estimator of bursts of ``n`` takes.

    ``n`` None (any length) or ``n_frames <= n``: every frame, ``pivot`` as given (checked
    later, with the burst). Otherwise the ``n`` frames centred on ``pivot`` (default the
    recording's middle frame, :func:`pivot_index`), moved inside the recording at its ends;
    the pivot's index within them is returned. Raises :class:`InvalidInputError` for a pivot
    outside the recording.
    """
    if n is None or n_frames <= n:
        return slice(0, n_frames), pivot
    p = pivot_index(pivot, n_frames)
    start = min(max(p - n // 2, 0), n_frames - n)
    return slice(start, start + n), p - start


def check_burst(
    frames: Any, *, bit_depth: int = 14, name: str = "frames", registered: bool = False
) -> np.ndarray:
    """Validate a raw burst: ``(N, H, W)`` counts, no saturated or constant (dead) frames.

    The rules are :mod:`thermocal._validate`'s: :func:`~thermocal._validate.as_frames`,
    :func:`~thermocal._validate.check_not_saturated` (more than
    :data:`~thermocal._validate.SATURATED_FRACTION` of the pixels at 0 or at
    ``2**bit_depth − 1``) and :func:`~thermocal._validate.check_not_constant`. For
    ``registered`` frames, 0 marks pixels a frame does not cover: they are not counted.
    Raises :class:`InvalidInputError`.
    """
    arr = as_frames(frames, name, bit_depth=bit_depth)
    check_not_saturated(arr, name, bit_depth=bit_depth, registered=registered)
    check_not_constant(arr, name, registered=registered)
    return arr


def scene_motion_px(homographies: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """How far the scene moves under each sensor pixel during a burst, px, ``(H, W)`` float32.

    ``homographies`` map each frame's pixels onto the pivot frame: pixel ``p`` of frame ``k`` sees
    the scene point the pivot sees at ``H_k p``, so the largest ``|H_k p − p|`` over the frames is
    how far the scene slid under ``p``.
    """
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w]
    return scene_motion_at(homographies, ys.ravel(), xs.ravel()).reshape(h, w)


def scene_motion_at(homographies: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """:func:`scene_motion_px` at the pixels ``(rows, cols)`` (each ``(P,)``), px ``(P,)``
    float32."""
    pts = np.stack([np.asarray(cols, np.float64), np.asarray(rows, np.float64),
                    np.ones(np.size(rows))])
    out = np.zeros(pts.shape[1])
    for hk in np.asarray(homographies, dtype=np.float64):
        q = hk @ pts
        out = np.maximum(out, np.hypot(q[0] / q[2] - pts[0], q[1] / q[2] - pts[1]))
    return out.astype(np.float32)


def stuck_pixels(
    frames: Any,
    homographies: Any = None,
    *,
    min_counts: float = 100.0,
    k: float = 10.0,
    min_motion_px: float = 2.0,
) -> np.ndarray:
    """Defective pixels of a raw burst, ``(H, W)`` bool.

    A stuck hot or dead pixel stays at its place on the sensor while the scene moves under it,
    so it differs from the median of its 3×3 neighbours in every frame, where a small hot object
    moves away. A pixel is flagged when, in every frame, it differs from that median by more than
    ``min_counts`` and ``k`` robust standard deviations of the frame's differences, and (given
    the frame → pivot ``homographies``) the scene slid at least ``min_motion_px`` under it
    (:func:`scene_motion_px`): a static scene's point sources and thin lines are not defects.
    Without homographies the scene is taken to move. Bursts of fewer than 3 frames give none.

    Each frame's robust deviation (the median of its differences) is taken only while some
    pixel is still a candidate and only when it can raise the frame's threshold above
    ``min_counts``; the scene's motion only at the candidates: the same answer as the rule with
    every median and the whole frame's motion.
    """
    import cv2  # a 3×3 median of float32 frames

    arr = np.asarray(frames)
    out = np.zeros(arr.shape[1:], dtype=bool)
    if arr.shape[0] < 3:
        return out
    scale = k * 1.4826
    # the median raises the threshold only if at least half the frame lies above
    # min_counts / scale (an O(pixels) count in place of the median, in most frames); a hair
    # below it, so that rounding cannot skip a median that matters
    gate = min_counts / scale * (1.0 - 1e-6) if scale > 0 else np.inf
    rows = cols = None
    median = _count_median if np.issubdtype(arr.dtype, np.integer) else np.median
    for f in arr:
        f = f.astype(np.float32)
        d = np.abs(f - cv2.medianBlur(f, 3))
        if rows is None:
            rows, cols = np.nonzero(d > min_counts)
        else:
            keep = d[rows, cols] > min_counts
            rows, cols = rows[keep], cols[keep]
        if rows.size and np.count_nonzero(d > gate) * 2 >= d.size:
            keep = d[rows, cols] > max(min_counts, scale * float(median(d)))
            rows, cols = rows[keep], cols[keep]
        if rows.size == 0:
            return out
    if homographies is not None:
        moved = scene_motion_at(homographies, rows, cols) >= min_motion_px
        rows, cols = rows[moved], cols[moved]
    out[rows, cols] = True
    return out


def _count_median(d: np.ndarray) -> float:
    """``np.median`` of whole, non-negative numbers (float32 differences of integer counts),
    the same number: from their histogram below 2**16 (one pass, 5× faster than the
    partition; a 14- or 16-bit camera's), by ``np.median`` otherwise (a histogram that large
    would cost more than it saves, and float32's mean of the middle two is inexact from
    2**23)."""
    if d.size == 0 or d.max() >= 2**16:
        return float(np.median(d))
    cum = np.cumsum(np.bincount(d.astype(np.intp).ravel()))
    n = d.size
    return float(np.searchsorted(cum, (n - 1) // 2, side="right")
                 + np.searchsorted(cum, n // 2, side="right")) / 2.0


#: A burst's pixel is frozen when its counts do not change over at least this many frames…
FROZEN_MIN_FRAMES = 5
#: …and live pixels would stay at one count by chance so rarely, at the burst's temporal
#: noise, that at most this many of its pixels are expected to (:func:`frozen_pixels`; a live
#: pixel so flagged takes its neighbours' median: 7 still frames of the simulator's units,
#: 2.3–2.6 counts of noise, expect 0.5–0.9 of 86,000).
FROZEN_FALSE_ALARMS = 1.0


def frozen_pixels(low: np.ndarray, high: np.ndarray, n_frames: int) -> np.ndarray:
    """Pixels whose counts never change over a burst, ``(H, W)`` bool, from its per-pixel
    minimum and maximum over ``n_frames`` frames.

    A live microbolometer's readout always carries temporal noise: over 7 frames of a static
    scene the simulator's ``tau2`` and ``boson`` units span 6–7 counts at the median pixel, and
    0–1 live pixels of 86,000 stayed at one count, where every one of their 17 dead pixels did.
    So a frozen pixel is dead or stuck, whether or not the scene moved (which
    :func:`stuck_pixels` needs: a burst of a camera held still hid them), provided the noise
    makes a live pixel frozen by chance rare enough: σ from the median pixel's span (a normal
    sample's expected range), and the chance that ``n_frames`` rounded draws share one count,
    ``(1 / (σ √(2π)))^(N−1) / √N``, times the pixels, at most :data:`FROZEN_FALSE_ALARMS`
    (5 frames of 1.6 counts of noise: 140 of 86,000 live pixels were flagged by a fixed
    span). Bursts of fewer than :data:`FROZEN_MIN_FRAMES` frames, or too quiet (a noiseless
    or averaged recording), give none. In a burst that moved, the median pixel's span holds
    the scene's motion too: a quiet camera's live pixels over a uniform area (a sky) may then
    be flagged (14 of 86,000 for 1.2 counts of noise under 40 % of sky), and take their
    neighbours' median."""
    span = np.asarray(high, dtype=np.float64) - np.asarray(low, dtype=np.float64)
    if n_frames < FROZEN_MIN_FRAMES or span.size == 0:
        return np.zeros(span.shape, dtype=bool)
    # the expected range of N normal draws, in σ (Blom's approximation: 2.36 for 5, 2.73 for 7)
    spread = 2.0 * NormalDist().inv_cdf((n_frames - 0.375) / (n_frames + 0.25))
    sigma = float(np.median(span)) / spread
    same = min(1.0, 1.0 / (sigma * math.sqrt(2.0 * math.pi))) if sigma > 0 else 1.0
    if span.size * same ** (n_frames - 1) / math.sqrt(n_frames) > FROZEN_FALSE_ALARMS:
        return np.zeros(span.shape, dtype=bool)
    return span == 0


#: The largest group of touching clipped pixels (8-connected) a frame alone fills from its
#: neighbours, px: a hot or dead pixel, or two. A larger one is a scene beyond the sensor's range
#: (a saturated object), whose count says only that it is hotter than the top's temperature:
#: filled, it had read as its surroundings with the calibration's σ (a review).
MAX_FILLED_CLIP_PX = 2


def clipped_parts(clipped: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A frame's clipped pixels ``(H, W)`` bool (:func:`~thermocal._validate.clipped_mask`) as
    two masks: ``(isolated, clusters)``, groups of at most :data:`MAX_FILLED_CLIP_PX` touching
    pixels (8 neighbours: defects, filled from their neighbours) and larger ones (a saturated
    scene: a lower bound, left for the domain check)."""
    from scipy.ndimage import label

    clipped = np.asarray(clipped, dtype=bool)
    if not clipped.any():
        return clipped, np.zeros_like(clipped)
    labels, n = label(clipped, structure=np.ones((3, 3), dtype=bool))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    isolated = clipped & (sizes[labels] <= MAX_FILLED_CLIP_PX)
    return isolated, clipped & ~isolated


def fill_stuck_pixels(frames: Any, homographies: Any = None, *, top: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """A copy of a raw burst ``(N, H, W)`` with its :func:`stuck_pixels` and
    :func:`frozen_pixels` replaced by the median of their good 3×3 neighbours (rounded for
    integer frames), and their mask ``(H, W)``. Every other pixel and the dtype are kept. Given
    ``top`` (the largest count, ``2**bit_depth − 1``), integer pixels at 0 or at ``top`` in any
    frame are filled too, whether or not the scene moved, where they form groups of at most
    :data:`MAX_FILLED_CLIP_PX` (:func:`clipped_parts`): a clipped defect says nothing of the
    scene (a saturated pixel of a hovering burst read 80 °C where the scene was 17 °C, with
    σ 1 °C); a larger group is a saturated object, left as it is."""
    arr = np.asarray(frames)
    out = arr.copy()
    bad = stuck_pixels(arr, homographies)
    if arr.ndim == 3 and arr.size:
        low, high = arr.min(axis=0), arr.max(axis=0)
        bad |= frozen_pixels(low, high, arr.shape[0])
        if top is not None and np.issubdtype(arr.dtype, np.integer):
            # defects: a pixel or two; a larger group is a saturated object, kept for the
            # domain check (filled, it read as its surroundings: a review)
            bad |= clipped_parts((low <= 0) | (high >= top))[0]
    if bad.any():
        filled = fill_bad_pixels(arr.astype(np.float32), bad)[:, bad]
        if np.issubdtype(arr.dtype, np.integer):
            filled = np.rint(filled)
        out[:, bad] = filled.astype(arr.dtype)
    return out, bad


def find_homographies(frames: np.ndarray, pivot: int, homographies: Any = None) -> np.ndarray:
    """Frame → pivot homographies ``(N, 3, 3)``: ``homographies`` checked, or found by
    :func:`thermocal.registration.register_burst` onto frame ``pivot``."""
    n = frames.shape[0]
    if homographies is not None:
        return as_homographies(homographies, n=n)
    reg = register_burst(frames, pivot=pivot)
    return as_homographies(reg.homographies, n=n)


def check_overlap(valid: np.ndarray, pivot: int) -> None:
    """Every frame must see at least :data:`MIN_OVERLAP` of the pivot frame (``valid`` is
    ``(N, H, W)``); raises :class:`RegistrationError` otherwise."""
    frac = valid.reshape(valid.shape[0], -1).mean(axis=1)
    for k, f in enumerate(frac):
        if k != pivot and f < MIN_OVERLAP:
            raise RegistrationError(
                f"frame {k} overlaps the pivot frame {pivot} by only {100 * f:.0f} %; a burst "
                f"needs overlapping views (at least {100 * MIN_OVERLAP:.0f} %)"
            )


def fpa_value(fpa_c: Any, n: int) -> float:
    """One FPA temperature for a burst, °C: the mean of one value or one per frame."""
    if fpa_c is None:
        raise InvalidInputError(
            "no FPA temperature: give --fpa-c or a sidecar JSON with fpa_c (the network needs it)"
        )
    arr = np.asarray(fpa_c, dtype=np.float64).ravel()
    if arr.size not in (1, n) or not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"fpa_c: expected one finite value or {n}, got {arr.size}")
    return check_fpa_c(float(arr.mean()))


