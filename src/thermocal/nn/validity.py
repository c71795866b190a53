"""Whether a burst lies inside what a network was trained on (numpy only).

A network trained on synthetic bursts of one camera family is a model of that family, not of
microbolometers in general: on another family it can be wrong by several °C with nothing in its
output to show it (issue 18: 1.1–11.4 °C per burst on the ``boson`` family for the ``tau2``-trained
shipped network). Before it runs, the burst is checked against the network's domain, read from
its weights file:

- the **FPA temperature** within the training range (``BurstConfig.fpa_range_c``);
- the **scene**: the burst's median, through the network's own nominal calibration, within the
  range of training scene levels, and its 1st–99th percentiles within the clip range;
- the **family's fixed pattern**: the line pattern that the nominal calibration leaves must run
  the way the family's does (``tau2``: columns, Oz et al. eq. 19). A camera whose lines run the
  other way is not of the family, however plausible its counts. Frames smaller than
  :data:`LINE_CHECK_MIN_PX` a side are refused: on them no line statistic tells the families
  apart, so the family cannot be vouched for. A burst that moved is read without its scene
  (each frame less the burst's registered mean: what stays on the sensor), since a scene's own
  lines along the flight (crop rows, roads) pass for a fixed pattern in any one frame; a still
  burst, frame by frame.

What no check at one FPA temperature can see (a family with the same line pattern but another
response to the FPA temperature) is what the network's uncertainty must cover.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from thermocal.camera.presets import CameraPreset
from thermocal.metrics import line_patterns

__all__ = ["FIXED_RATIO_MAX", "LINE_CHECK_MIN_PX", "LINE_RATIO_MAX", "REMEDY",
           "SEPARATING_MOTION_PX", "UNCROSSED_LINE_PX", "UNCROSSED_RATIO_MAX", "Domain",
           "beyond_training_c", "family_lines", "family_pattern_reason", "fixed_line_patterns",
           "motion_extent_px", "outside_domain"]

#: What to do about a burst outside the network's domain.
REMEDY = ("train from a chamber session of this camera: `thermocal train --chamber`, or "
          "calibrate it (`thermocal calibrate`); --force gives the estimate with its "
          "uncertainty inflated")

#: Largest ratio of the cross-line pattern to the family's own line pattern (°C / °C) of a
#: burst of the family. ``tau2`` bursts through the shipped network's nominal calibration
#: stayed at or below 0.21 on the quick held-out set (0.34 over procedural towns), ``boson``
#: bursts at or above 1.28 (measured while choosing it); ``benchmarks/coverage.py`` shows the
#: outcome: no ``tau2`` burst refused for its pattern, every ``boson`` burst refused.
LINE_RATIO_MAX = 0.6
#: Smallest frame side, px, on which the fixed pattern's direction tells the families apart
#: (RESULTS.md, "The network's family check on small frames": over 12 units × 7-frame bursts,
#: from 160×120 up ``tau2`` ratios stayed at or below 0.57 and ``boson`` ratios at or above
#: 0.96; at 96×72 and below they overlap, a line's median over so few pixels keeps the scene).
LINE_CHECK_MIN_PX = 120
#: Least extent of a burst's motion, px, that tells a line pattern fixed on the sensor from
#: the scene's lines across it (a pattern's line moved by 2 px or more meets other lines).
SEPARATING_MOTION_PX = 2.0
#: Largest ratio of the cross-line to the family's own line pattern once the scene is removed
#: (:func:`family_lines`) of a burst of the family whose motion crossed both directions' lines
#: (a walk; ``python benchmarks/family_check.py``, through the shipped network's nominal
#: calibration): ``tau2`` walks at most 0.12, ``boson`` at least 0.49 (seeds 10–13 and 50–53);
#: chosen first for UAV passes (seeds 10–49: ``tau2`` at most 0.18, ``boson`` at least 0.30),
#: which :data:`UNCROSSED_RATIO_MAX` now judges.
FIXED_RATIO_MAX = 0.24
#: The same limit where the motion crossed only the family's own lines (a straight UAV pass
#: along the rows of a ``tau2``), for own lines of :data:`UNCROSSED_LINE_PX` pixels, and
#: ``√(UNCROSSED_LINE_PX / L)`` times it for lines of ``L`` (the pixels' scatter in a line's
#: median falls as ``1/√L``): a cross pattern then cancels as the scene's lines do, and what is
#: read in its place is that scatter (with what a jitter across left of it), so the family is
#: vouched for by its own lines' strength against it alone. Gimbal-steady passes (no attitude
#: jitter; ``python benchmarks/family_check.py --seeds 50-129``, 400 bursts of each family at
#: 160×120): ``tau2`` at most 0.15, ``boson`` at least 0.16; at 336×256 (40 bursts, a scratch
#: run) 0.06 and 0.145. Set low, where an error is a refusal, not a silent answer.
UNCROSSED_RATIO_MAX = 0.14
UNCROSSED_LINE_PX = 120
#: The scene's level and spread are read from every ``PERCENTILE_STRIDE``-th row and column.
PERCENTILE_STRIDE = 2


@dataclass(frozen=True)
class Domain:
    """What a network was trained on.

    Attributes
    ----------
    fpa_range_c : (float, float)
        FPA temperatures of the training bursts, °C.
    scene_level_c : (float, float)
        Range of the training scenes' mean temperatures, °C.
    scene_clip_c : (float, float)
        Range of every training pixel's temperature, °C.
    family : str or None
        The camera family (preset name) of the training units; None for a network trained on
        one unit's chamber fit.
    line_fpn : str or None
        The family's line pattern: ``"column"`` or ``"row"`` (None: not checked).
    """

    fpa_range_c: tuple[float, float]
    scene_level_c: tuple[float, float]
    scene_clip_c: tuple[float, float]
    family: str | None = None
    line_fpn: str | None = None

    @classmethod
    def of_network(cls, data: dict[str, Any], nominal_info: dict[str, Any] | None) -> Domain:
        """The domain of a network from its weights file's training ``data`` (the
        :class:`~thermocal.nn.data.BurstConfig` stored there) and its nominal camera's
        ``info`` (the family's preset parameters, when it is a preset's average)."""
        params = (nominal_info or {}).get("preset_parameters")
        family = line = None
        if params:
            preset = CameraPreset.from_dict(params)
            family, line = preset.name, preset.fpn.split("-")[0]
        return cls(tuple(data["fpa_range_c"]), tuple(data["temp_mean_range_c"]),
                   tuple(data["temp_clip_c"]), family, line)


def outside_domain(domain: Domain, frames_c: np.ndarray | None, fpa_c: float, *,
                   warped_c: np.ndarray | None = None, valid: np.ndarray | None = None,
                   homographies: np.ndarray | None = None) -> tuple[str, ...]:
    """Why a burst lies outside ``domain``: ``()`` when it lies inside.

    Parameters
    ----------
    domain : Domain
    frames_c : (N, H, W) float32 or None
        The burst's raw frames through the network's nominal calibration, °C (where each frame
        lies on the sensor, before warping); None (a network of raw counts): the FPA alone.
    fpa_c : float
        The burst's FPA temperature, °C.
    warped_c, valid, homographies : (N, H, W) float32, (N, H, W) bool, (N, 3, 3), optional
        The same frames warped onto the pivot, where each covers it, and their frame → pivot
        homographies (for the family's fixed pattern of a burst that moved).

    Returns
    -------
    tuple of str
        One clause per failed check, e.g. ``"the FPA temperature 55.0 °C is outside the 10–50 °C
        the network was trained on"``.
    """
    reasons = []
    lo, hi = domain.fpa_range_c
    if not lo <= fpa_c <= hi:
        reasons.append(f"the FPA temperature {fpa_c:.1f} °C is outside the {lo:g}–{hi:g} °C "
                       "the network was trained on")
    if frames_c is None:
        return tuple(reasons)
    # the median and the 1st and 99th percentiles in one pass, over every other row and column
    # (a quarter of the pixels, 150,000 of a 336×256 burst of 7: 12 → 3 ms, of a flight
    # pivot's ~150 ms; on a burst of Gaussian noise of σ = 10 °C the 1st, 50th and 99th
    # percentiles move by 0.08, 0.00 and 0.23 °C, against training ranges tens of °C wide)
    sample = frames_c[..., ::PERCENTILE_STRIDE, ::PERCENTILE_STRIDE]
    p1, level, p99 = (float(v) for v in np.percentile(sample, [1, 50, 99]))
    lo, hi = domain.scene_level_c
    if not lo <= level <= hi:
        reasons.append(f"the scene's median {level:.1f} °C is outside the {lo:g}–{hi:g} °C of "
                       "its training scenes")
    lo, hi = domain.scene_clip_c
    if p1 < lo or p99 > hi:
        reasons.append(f"the scene spans {p1:.0f}…{p99:.0f} °C, beyond the {lo:g}…{hi:g} °C of "
                       "its training scenes")
    reason = family_pattern_reason(frames_c, domain.family, domain.line_fpn,
                                   of="the network was trained on", warped_c=warped_c,
                                   valid=valid, homographies=homographies)
    return (*reasons, reason) if reason else tuple(reasons)


def beyond_training_c(domain: Domain, frame_c: np.ndarray | None, temperature_c: np.ndarray
                      ) -> np.ndarray:
    """How far beyond its training scenes a forced estimate lies, ``(H, W)`` float32, °C.

    The distance of the scene's median (``frame_c``, the pivot's raw frame ``(H, W)`` through
    the network's nominal calibration, °C; None for a network of raw counts) beyond the range
    of training scene levels, plus each pixel's distance (``temperature_c``, the estimate
    ``(H, W)``, °C) beyond the range of training pixel temperatures; 0 inside. No training
    burst measured the error there, so it may be the whole distance, as a calibration's σ
    beyond its last set point (:mod:`thermocal.calibration.uncertainty`): the shipped network
    forced on a FLIR T1030sc CSQ read 101 °C where the camera's own calibration reads 19 °C,
    from counts whose median through the ``tau2`` nominal lies 45 °C above the training levels.
    """
    t = np.asarray(temperature_c, dtype=np.float64)
    lo, hi = domain.scene_clip_c
    out = np.maximum(lo - t, 0.0) + np.maximum(t - hi, 0.0)
    if frame_c is not None:
        level = float(np.median(np.asarray(frame_c)[::PERCENTILE_STRIDE, ::PERCENTILE_STRIDE]))
        lo, hi = domain.scene_level_c
        out += max(lo - level, 0.0) + max(level - hi, 0.0)
    return out.astype(np.float32)


def family_pattern_reason(frames_c: np.ndarray, family: str | None, line_fpn: str | None, *,
                          of: str, warped_c: np.ndarray | None = None,
                          valid: np.ndarray | None = None,
                          homographies: np.ndarray | None = None) -> str | None:
    """Why frames ``(N, H, W)`` (°C through the family's average unit) are not of ``family``,
    whose fixed pattern runs along ``line_fpn`` (``"column"`` or ``"row"``; otherwise not
    checked): their pattern runs the other way more than a burst of the family's does
    (:func:`family_lines`), or they are smaller than :data:`LINE_CHECK_MIN_PX` a side, too
    small to tell. None when they are.
    ``of`` ends the sentence: what was made for the family ("the network was trained on");
    ``warped_c``, ``valid``, ``homographies``: the frames registered onto the pivot."""
    if line_fpn not in ("column", "row"):
        return None
    h, w = frames_c.shape[-2:]
    if min(h, w) < LINE_CHECK_MIN_PX:
        return (f"its frames, {w}×{h}, are too small to check that the camera is of the "
                f"{family} family {of} (the fixed pattern's direction needs at least "
                f"{LINE_CHECK_MIN_PX} px a side)")
    own, cross, limit, what = family_lines(frames_c, line_fpn, warped_c=warped_c, valid=valid,
                                           homographies=homographies)
    if own > 0 and cross <= limit * own:
        return None
    other = "column" if line_fpn == "row" else "row"
    if own <= 0 and cross <= 0:
        return (f"its {what} has no {line_fpn} pattern beyond the pixels' noise (a {family} "
                f"camera's runs along {line_fpn}s): not a camera of the {family} family {of}")
    if own <= 0:
        return (f"its {what} runs along {other}s ({cross:.2f} °C) and not along {line_fpn}s: "
                f"not a camera of the {family} family {of}")
    return (f"its {what} runs along {other}s too much for a {family} camera "
            f"({cross:.2f} °C against {own:.2f} °C along {line_fpn}s, {cross / own:.3f} of it "
            f"where a {family} burst's stays below {limit:.3f}): not a camera of the {family} "
            f"family {of}")


def family_lines(frames_c: np.ndarray, line_fpn: str, *, warped_c: np.ndarray | None = None,
                 valid: np.ndarray | None = None, homographies: np.ndarray | None = None
                 ) -> tuple[float, float, float, str]:
    """The family's own line pattern and the cross one (°C) of frames ``(N, H, W)`` whose
    family's lines run along ``line_fpn``, the largest ratio of the two a burst of the family
    shows, and what was read, in words: ``(own, cross, limit, what)``.

    With the frames registered onto the pivot (``warped_c``, ``valid``, ``homographies``) and a
    motion of at least :data:`SEPARATING_MOTION_PX`, without the scene
    (:func:`fixed_line_patterns`, limit :data:`FIXED_RATIO_MAX`): a direction's lines are
    told from the scene's, and from the pixels' own scatter, only where the motion crossed
    them (columns by a motion along x). The family's own lines not crossed stay in the mean:
    read frame by frame. A cross pattern not crossed cancels as the scene's lines do (a row
    pattern under a motion along x): it cannot be seen in the burst, and what is read in its
    place is the pixels' scatter, with what a jitter across left of it; the family is then
    vouched for by the strength of its own lines against that scatter, to the stricter
    :data:`UNCROSSED_RATIO_MAX` (scaled with the lines' length). Otherwise frame by frame
    (:func:`~thermocal.metrics.line_patterns`, limit :data:`LINE_RATIO_MAX`)."""
    column = line_fpn == "column"

    def own_cross(rows: Any, cols: Any) -> tuple[Any, Any]:
        return (cols, rows) if column else (rows, cols)

    fixed, crossed = None, (False, False)  # (rows, columns)
    if warped_c is not None and valid is not None and homographies is not None:
        ex, ey = motion_extent_px(homographies, frames_c.shape[-2:])
        crossed = (ey >= SEPARATING_MOTION_PX, ex >= SEPARATING_MOTION_PX)
        if any(crossed):
            fixed = fixed_line_patterns(warped_c, valid, beyond_noise=crossed)
    if fixed is None:
        own, cross = own_cross(*line_patterns(frames_c))
        return own, cross, LINE_RATIO_MAX, "fixed pattern"
    own, cross = own_cross(*fixed)
    own_crossed, cross_crossed = own_cross(*crossed)
    what = "fixed pattern (each frame less the burst's scene)"
    if not own_crossed:
        own = own_cross(*line_patterns(frames_c))[0]
    if own_crossed and not cross_crossed:
        length = frames_c.shape[-2] if column else frames_c.shape[-1]
        limit = UNCROSSED_RATIO_MAX * math.sqrt(UNCROSSED_LINE_PX / length)
        other = "row" if column else "column"
        return own, cross, limit, f"{what[:-1]}; its {other}s not crossed by the motion)"
    return own, cross, FIXED_RATIO_MAX, what


def motion_extent_px(homographies: np.ndarray, shape: tuple[int, int]) -> tuple[float, float]:
    """How far a burst moved: the spread (max − min), px, of where its frames' centres land on
    the pivot under their frame → pivot ``homographies`` ``(N, 3, 3)``, along x and along y;
    ``shape`` is ``(H, W)``."""
    h, w = shape
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0, 1.0])
    p = np.asarray(homographies, dtype=np.float64) @ centre
    xy = p[:, :2] / p[:, 2:3]
    return float(np.ptp(xy[:, 0])), float(np.ptp(xy[:, 1]))


#: Least side, px, of the region every frame of a burst covers on which
#: :func:`fixed_line_patterns` is read (below it, a line's median over so few pixels is noise).
FIXED_MIN_SIDE_PX = LINE_CHECK_MIN_PX // 2


def fixed_line_patterns(warped_c: np.ndarray, valid: np.ndarray, *,
                        beyond_noise: tuple[bool, bool] = (True, True)
                        ) -> tuple[float, float] | None:
    """The row and the column pattern (°C, :func:`~thermocal.metrics.line_patterns`) of what
    stays on the sensor of a burst registered onto its pivot: each frame ``(N, H, W)`` °C less
    the frames' mean, where ``valid`` every frame sees the pixel. The scene, registered, cancels;
    a fixed pattern moved with each frame does not (save along the motion: a line pattern whose
    lines the frames slid along cancels too). None when the region all frames cover is smaller
    than :data:`FIXED_MIN_SIDE_PX` a side. ``beyond_noise`` (rows, columns): that pattern as
    what its lines share beyond the pixels' own scatter
    (:func:`~thermocal.metrics.line_patterns`): with the scene gone, that scatter is most of a
    line pattern the sensor does not have."""
    common = np.asarray(valid).all(axis=0)
    by_row, by_col = common.mean(axis=1), common.mean(axis=0)
    rows = np.flatnonzero(by_row >= 0.9 * by_row.max())
    cols = np.flatnonzero(by_col >= 0.9 * by_col.max())
    if rows.size < FIXED_MIN_SIDE_PX or cols.size < FIXED_MIN_SIDE_PX:
        return None
    box = (slice(None), slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    frames = np.asarray(warped_c, dtype=np.float32)[box]
    inside = common[box[1:]]
    residual = np.where(inside, frames - frames.mean(axis=0), np.float32(0))
    return line_patterns(residual.astype(np.float32), beyond_noise=beyond_noise)
