"""Whether frames come from the camera a calibration was made for: the imprint of its pattern.

A per-pixel calibration removes its own camera's fixed pattern. On that camera's frames the
pattern cancels, and what comes out (the scene) is independent of the correction; on another
camera's frames (another unit of the family, another family) nothing cancels, and the
correction itself is printed on the output, where it stays as a pattern the scene does not
have — and with it an error no report measured (a ``tau2`` unit's ``polynomial`` on another
unit: 2.5–3.2 °C; any method on another unit or family 2.2–27.9 °C;
`benchmarks/another_camera.py`). So does the calibration's own camera when it has flat-field
corrected its frames itself (a Tau2's FFC on, where the chamber session was recorded with it
off): the pattern the calibration removes is no longer in them, and removing it prints it
(``polynomial`` 1.4–3.1 °C off, any method up to 18 °C). Pixels stuck in the raw frame (dead
at 0 counts or full scale) are filled from their neighbours before the high-pass and left out.

The calibration's pattern ``P``: its output for a uniform frame at the frame's median count
and FPA temperature (all of the correction, none of the scene). The *imprint*: the
least-squares slope of the output's high-pass on ``P``'s high-pass (a Gaussian blur of
:data:`HIGH_PASS_PX` removed, which keeps the pixel-scale pattern and drops most of the
scene): about 0 on the calibration's own camera, about 1 on any other. Its standard error is a
jackknife's over tiles of the frame (leaving one out at a time: pixels a high-pass or a
scene's edges correlate are not taken for independent ones); frames
are another camera's when the slope less twice that exceeds :data:`IMPRINT_MAX`, so a
calibration that removes too little pattern for the slope to tell (a camera whose pattern lies
below its noise and scene) is never taken for another camera's.

A check with no library behind it (by hand: a few numpy reductions over ``cv2``'s blur); the
line patterns of the output alone were tried first and could not tell straight streets from
another unit's columns (RESULTS.md, "Another camera's frames").
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from thermocal.calibration.base import Calibration
from thermocal.threads import caught_warnings

__all__ = ["IMPRINT_MAX", "OTHER_CAMERA_SIGMA_C", "Imprint", "imprint", "imprint_reason"]

#: σ of the Gaussian blur a high-pass removes, px.
HIGH_PASS_PX = 2.0
#: Pixels left out at each edge (where the blur's border replicates), px.
EDGE_PX = 6
#: The scatters (MAD) that set the clips are read from every SCATTER_STRIDE-th row and column.
SCATTER_STRIDE = 3
#: The frame is cut into TILES × TILES tiles for the slope's standard error (a jackknife).
TILES = 4
#: Pixels of the pattern more than this many of its scatters (MAD) from 0 are left out: the
#: calibration's bad pixels, filled from their neighbours in the output, and its outliers.
PATTERN_CLIP = 6.0
#: Raw pixels whose high-pass is more than this many of its scatters (MAD) from 0 are stuck:
#: their output is replaced by its neighbours' median before the high-pass, and left out.
STUCK_CLIP = 20.0
#: Pixels of the output more than this many of its scatters (MAD) from 0 are left out: pixels
#: the calibration cannot invert (another camera's dead ones), the scene's sharpest edges.
OUTPUT_CLIP = 10.0
#: The imprint above which frames are another camera's: the slope's lower bound (less twice
#: its standard error) above this. On the simulator's cameras, every method: own unit
#: −0.72…+0.37 (``one-point``; the others −0.17…+0.13), any other unit or family 0.95…1.13
#: (`benchmarks/another_camera.py`).
IMPRINT_MAX = 0.5
#: σ added (in quadrature) to the temperatures of frames forced through another camera's
#: calibration, °C: the report measured nothing of that camera (another unit's `polynomial`
#: 2.5–3.2 °C off, any method on another unit or family 2.2–27.9 °C, within 2σ; the same as
#: `selfcal`'s for another family).
OTHER_CAMERA_SIGMA_C = 15.0


class Imprint(NamedTuple):
    """The share of a calibration's correction left in its output: ``slope`` (0: its own
    camera, 1: another) and its standard error ``se``."""

    slope: float
    se: float

    @property
    def foreign(self) -> bool:
        """Whether the frames are, beyond doubt, another camera's: the slope less twice its
        standard error above :data:`IMPRINT_MAX` (a pattern too weak to measure never is)."""
        return self.slope - 2.0 * self.se > IMPRINT_MAX


def _high_pass(image: np.ndarray, *, crop: bool = True) -> np.ndarray:
    """``image`` less its Gaussian blur of :data:`HIGH_PASS_PX`, float32, without
    :data:`EDGE_PX` at each edge (``(H − 2·EDGE_PX, W − 2·EDGE_PX)``) unless not ``crop``."""
    import cv2  # its Gaussian blur: the line-pattern checks' too

    x = np.asarray(image, dtype=np.float32)
    hp = x - cv2.GaussianBlur(x, (0, 0), HIGH_PASS_PX, borderType=cv2.BORDER_REPLICATE)
    return hp[EDGE_PX:-EDGE_PX, EDGE_PX:-EDGE_PX] if crop else hp


def _stuck(raw: np.ndarray) -> np.ndarray:
    """The raw frame's pixels that stand out of their neighbourhood by more than
    :data:`STUCK_CLIP` of its high-pass's scatters (dead pixels at 0 counts or full scale,
    another camera's hot ones), bool ``(H, W)``, its edges too (a dead pixel there rings into
    the pixels judged)."""
    hp = _high_pass(raw, crop=False)
    return np.abs(hp) > STUCK_CLIP * _scatter(hp, np.ones(hp.shape, dtype=bool))


def _filled(temps: np.ndarray, stuck: np.ndarray) -> np.ndarray:
    """``temps`` (°C ``(H, W)``) with its ``stuck`` pixels replaced by their 5×5 median (of
    the finite ones' values, NaN taken as 0 there), float32 (a new array where any pixel is
    stuck; never changed in place): a dead pixel's output
    (the coldest or hottest the calibration reads) would otherwise ring through the high-pass
    around it. Other pixels as they were, NaN included (left out after)."""
    import cv2

    x = np.asarray(temps, dtype=np.float32)
    if not stuck.any():
        return x
    return np.where(stuck, cv2.medianBlur(np.nan_to_num(x), 5), x)


def _scatter(x: np.ndarray, keep: np.ndarray) -> float:
    """1.4826 × the median absolute value of the kept ``x`` (its MAD about 0), from every
    :data:`SCATTER_STRIDE`-th row and column (a scale, to a few per cent; 0 if none kept)."""
    sample = x[::SCATTER_STRIDE, ::SCATTER_STRIDE][keep[::SCATTER_STRIDE, ::SCATTER_STRIDE]]
    return 1.4826 * float(np.median(np.abs(sample))) if sample.size else 0.0


def _tile_sums(t: np.ndarray, p: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Σ t·p and Σ p² over the kept pixels of each of :data:`TILES` × :data:`TILES` tiles of
    the frame ``(h, w)`` each, float64 ``(TILES²,)`` each."""
    rows = [int(r[0]) for r in np.array_split(np.arange(t.shape[0]), TILES)]
    cols = [int(c[0]) for c in np.array_split(np.arange(t.shape[1]), TILES)]

    def tiles(x: np.ndarray) -> np.ndarray:
        by_row = np.add.reduceat(np.where(keep, x, 0.0), rows, axis=0, dtype=np.float64)
        return np.add.reduceat(by_row, cols, axis=1).ravel()

    return tiles(t * p), tiles(p * p)


def pattern_of(calibration: Calibration, raw: np.ndarray, *, fpa_c: float | None = None,
               time_s: float | None = None) -> np.ndarray | None:
    """The calibration's pattern at a raw frame ``(H, W)``: its output, °C ``(H, W)``, for a
    uniform frame at the frame's median count, FPA temperature ``fpa_c`` (°C) and time
    ``time_s`` (s; a shutter calibration's offsets are those of the closure before it), at a
    steady FPA. None where it cannot be made (shutter offsets without the frame's time)."""
    if getattr(calibration, "event_offset", None) is not None and time_s is None:
        return None
    uniform = np.full((1, *np.shape(raw)), np.median(raw), dtype=np.asarray(raw).dtype)
    kwargs: dict[str, Any] = {}
    if fpa_c is not None:
        kwargs["fpa_c"] = [float(fpa_c)]
    if time_s is not None:
        kwargs["time_s"] = [float(time_s)]
    with caught_warnings():  # dropped: the frames' own application has said it (this
        # thread's alone where pivots run at once: catch_warnings would silence the others')
        return np.asarray(calibration.apply(uniform, **kwargs)[0], dtype=np.float32)


def imprint(calibration: Calibration, raw: Any, temps_c: Any, *, fpa_c: float | None = None,
            time_s: float | None = None) -> Imprint | None:
    """The :class:`Imprint` of ``calibration`` on one frame: raw counts ``(H, W)`` and their
    temperatures through it, °C ``(H, W)``, at FPA temperature ``fpa_c`` (°C, where the method
    takes one) and time ``time_s`` (s). None where it cannot be told: no pattern
    (:func:`pattern_of`), a frame too small, or a pattern too weak to measure."""
    raw = np.asarray(raw)
    temps = np.asarray(temps_c)
    if raw.ndim != 2 or temps.shape != raw.shape or min(raw.shape) <= 4 * EDGE_PX:
        return None
    pattern = pattern_of(calibration, raw, fpa_c=fpa_c, time_s=time_s)
    if pattern is None:
        return None
    stuck = _stuck(raw)
    p, t = _high_pass(pattern), _high_pass(_filled(temps, stuck))
    keep = np.isfinite(p) & np.isfinite(t) & ~stuck[EDGE_PX:-EDGE_PX, EDGE_PX:-EDGE_PX]
    keep &= np.abs(p) <= PATTERN_CLIP * _scatter(p, keep)
    keep &= np.abs(t) <= OUTPUT_CLIP * _scatter(t, keep)
    num, den = _tile_sums(t, p, keep)
    if keep.sum() < 100 or np.any(den <= 0.0):
        return None
    slope = float(num.sum() / den.sum())
    # delete-a-tile jackknife: the pattern's and the scene's own spatial correlation in it
    # (pixel-scale for another camera's fixed pattern, the blur's scale for a scene's edges)
    left = (num.sum() - num) / (den.sum() - den)
    k = left.size
    se = math.sqrt((k - 1) / k * float(np.sum((left - left.mean()) ** 2)))
    return Imprint(slope, se)


def imprint_reason(calibration: Calibration, raw: Any, temps_c: Any, *,
                   fpa_c: Any = None, time_s: Any = None, frames: int = 5) -> str | None:
    """Why frames are not raw frames of the camera ``calibration`` was made for, in words, or
    None.
    ``raw`` ``(N, H, W)`` or ``(H, W)`` counts and their temperatures through it (same shape),
    at ``fpa_c`` and ``time_s`` (one or one per frame, or None): up to ``frames`` of them,
    evenly spaced, each judged by :func:`imprint`; their median imprint decides."""
    raw = np.asarray(raw)
    temps = np.asarray(temps_c)
    if raw.ndim == 2:
        raw, temps = raw[None], temps[None]
    n = raw.shape[0]
    fpa = None if fpa_c is None or np.size(fpa_c) == 0 else np.broadcast_to(
        np.asarray(fpa_c, dtype=np.float64).reshape(-1), (n,))
    times = None if time_s is None else np.broadcast_to(
        np.asarray(time_s, dtype=np.float64).reshape(-1), (n,))
    found = []
    for k in np.unique(np.linspace(0, n - 1, min(frames, n)).round().astype(int)):
        got = imprint(calibration, raw[k], temps[k],
                      fpa_c=None if fpa is None else float(fpa[k]),
                      time_s=None if times is None else float(times[k]))
        if got is not None:
            found.append(got)
    if not found:
        return None
    slope = float(np.median([f.slope for f in found]))
    se = float(np.median([f.se for f in found]))
    if not Imprint(slope, se).foreign:
        return None
    return (f"the frames are not raw frames of the camera the {calibration.method} "
            f"calibration was made for: {100 * slope:.0f} % of the fixed pattern it removes is "
            "left printed on its output (0 % on its own camera's raw frames; another unit or "
            "camera family leaves it whole, and so do frames the camera has flat-field "
            "corrected itself), so its error there is unknown (use this camera's own "
            "calibration, `thermocal calibrate` its chamber session, on frames recorded as "
            "those were: the camera's flat-field correction (FFC) off)")
