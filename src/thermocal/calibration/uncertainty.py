"""A calibration's uncertainty and domain, from its cross-validation report (numpy only).

For a temperature ``T`` (°C) measured at FPA temperature ``t`` (°C)::

    σ(T, t, r) = s(r) · max(1 + [v_scene(T) / v̄_scene − 1] + [v_fpa(t) / v̄_fpa − 1], v_least)
                 + √(π/2) · [k_scene · d_scene(T) + k_fpa · d_fpa(t)]

- ``v_scene``, ``v_fpa``: the cross-validated error of the report's interior folds (set points
  left out; FPA segments left out), each over the level of its frames' FPA rates (the folds'
  ``relative_mae``: a segment the session crossed at fast paces errs more for its paces, which
  ``s(r)`` already tells; a report made before: their MAE), interpolated at ``T`` and ``t``
  (:class:`CalibrationReport`), and at its end folds the fit's own error there where it exceeds
  the nearest interior fold's (a refit without an end extrapolates, the fit did not: `lin` on
  `boson` unit 105 errs 2.2 and 2.6 °C at its session's FPA ends, 0.8–1.1 inside; a
  two-point's refit without an FPA end is the fit itself, far from its reference FPA). The
  folds score single frames, so the noise (NETD) and the unmodelled drift are in them;
- ``v̄_scene``, ``v̄_fpa``: the mean of each curve's interior folds (weighted by their frames;
  with its end points too, the ends' own errors, large where a fit is poor at an end, put the
  interior below 1: `wolf2016` and `lin` on `boson` left 688 and 338 frames silent over five
  units). A set point left out and
  an FPA segment left out are gaps of their own sizes, and one kind errs more than the other
  throughout (``lin-lag`` on ``tau2``: FPA segments 0.09–0.11 °C, set points 0.05–0.07): each
  curve tells *where* σ is larger, relative to its own mean, and the rate bins how large (taken
  against the mean of all folds, the FPA folds' excess raised σ by 5–53 % at every FPA, where
  the held-out runs erred as the folds did on the whole). The two excesses add (a cold scene
  at an FPA end errs by both; taking half of each, as before, missed `lin`'s cold scenes at the
  FPA ends of `tau2`'s held-out runs by over 2σ), never below ``v_least``, the least of either
  curve over its mean (and 1);
- ``s(r)``: the σ that covers the interior
  folds' pixel errors at the FPA rate ``r`` (°C/min; its bin of ``mae_by_fpa_rate_c``) as a
  Gaussian's would (:func:`~thermocal.calibration.report.coverage_sigma`): a method without a
  rate term errs most while the FPA changes. For a memoryless method ``r`` is the FPA's *pace*
  (:func:`~thermocal.calibration.dataset.fpa_pace`: the larger of the rate and the rate through
  the report's 8-min lag), in the report's bins and here alike: the minutes after a change,
  rate 0 but optics still catching up, are not taken for settled ones (binned by the present
  rate, `polynomial`'s σ on `tau2`'s held-out runs covered 91 % of errors at 1σ, 71–76 % by
  pace). A rate whose history is not known takes the largest σ of the bins at or above it. A
  memoryless method's frame of a recording (or given its lagged rate) also takes at least the σ
  of how far its pace is from steady (:meth:`CalibrationSigma.change_sigma`, the report's
  ``mae_by_fpa_change_c``): a pace bin pools a steady ramp with the minutes just after a step
  at the same pace, and those err more (``lin-level`` on ``boson`` just after 5 °C ambient
  steps: 4–17 frames per unit erred beyond 2σ, 0–4 with it).
  Where the rate is not known (a burst of a fraction of a second) ``s`` is that of all the
  interior folds' errors (``expected_sigma_c``). A report made before it stored σ:
  ``s = √(π/2)·MAE``;
- ``d_scene``, ``d_fpa``: how far ``T`` and ``t`` lie outside the ranges the session covers, °C
  (0 inside);
- ``k_scene``, ``k_fpa``: how fast the error grew on the report's extrapolation folds (its end
  set points and end FPA segments, left out in turn): their excess MAE over the interior's per
  °C of extrapolation, never below :data:`MIN_GROWTH_PER_C`. Outside the ranges σ keeps growing
  with the distance: it is not clipped. Beyond the step to the next set point outside the
  scene range (as far as that end's fold extrapolated) no fold measured anything: σ also grows
  by the whole distance past it (a pixel whose counts the calibration cannot invert, clipped at
  −123 °C, is not given a few degrees);
- ``√(π/2)``: a Gaussian's σ from its MAE.

:meth:`CalibrationSigma.outside` says why frames lie outside what a calibration was fitted on
(FPA temperature, scene temperature, FPA rate, and for a memoryless method the FPA's pace
history); the product refuses them unless ``--force``. Faster FPA rates than the session's
fastest grow σ in proportion to the rate.

**Paces a memoryless method never held.** A method with no memory of how the FPA changed (a rate
term, if any, sees the present rate only;
:attr:`~thermocal.calibration.registry.CalibrationInfo.memoryless`) errs, on a camera whose optics
lag the FPA, by what the rate's history leaves: 3–4 °C on the ``boson`` preset's held-out
1 °C/min sawtooth for ``lin-level`` and ``polynomial``, whose sessions held only 1.5 °C/min
steadily. Its cross-validation sees only the paces of its session, which its report lists
(:attr:`~thermocal.calibration.report.CalibrationReport.paces`: cells of the plane of the FPA
rate and the same through a lag of 8 min). A frame whose pace lies more than one cell from
every cell the session held (:meth:`CalibrationSigma.pace_distance`) is outside; forced, its
``s`` becomes at least the report's largest rate-bin σ times its distance in cells: how large
its error is no session measured. A method *with* memory (``lin-lag``, ``wolf2016``) is held to
the same paces with a wider margin (the report's ``margin_c_per_min``,
:data:`~thermocal.calibration.report.MEMORY_PACE_MARGIN_C_PER_MIN`): its lag terms follow a
pace's history, but their form was fitted on the session's paces alone, and on a camera whose
lag has another form its error grows with the distance from them where no fold can show it.
Nor does it vouch for a longer run of the FPA in one direction than its session's longest
(the report's ``swing``, :meth:`CalibrationSigma.swing_excess`): what lags the FPA more slowly
than its lags or its online estimate follow falls behind by about as far as the FPA ran, and a
session of ambient steps runs a few °C at a time. Fitted on 5 °C steps, ``lin-lag`` on ``tau2``
read a steady 0.5 °C/min rise 0.1–0.2 °C off where σ said 0.06 from 7 °C on (54 % within 2σ),
and ``wolf2016`` on ``boson`` +2 °C where σ said 0.9–1.0; a frame whose FPA ran more than
:data:`~thermocal.calibration.report.SWING_SLACK_C` further is outside, and forced, its ``s``
becomes at least the report's largest rate-bin σ times how many times the session's run (and
the slack) the frame's is. A session with a sawtooth over its range runs as far as a ramp does.

**Stillness a session never reached.** Where the session's plateaus ended before the camera
settled (:func:`~thermocal.calibration.report.settling_warning`: the method's error was still
changing at their ends; for a method with memory, at a tenth of the memoryless threshold, its
σ being that much smaller), a camera held still for longer than they lasted is in a state
the session never showed: on the ``boson`` preset, the 30-minute hold at the top of a held-out
ramp drifts on to +1.0…+1.25 °C for ``polynomial`` where σ said 0.5; after 19-min plateaus,
``lin-lag`` on ``tau2`` read a 2-h hold −0.12 °C off where σ said 0.07, and ``wolf2016`` on
``boson`` −1.4…−2.2 °C where σ said 0.9. The report then states
how long the session's plateaus held the FPA still (its ``paces["still"]``,
:func:`~thermocal.calibration.report.stillness_of`); a frame held still for longer
(:meth:`CalibrationSigma.still_excess` > 1) is outside, and forced, its ``s`` becomes at least
the report's largest rate-bin σ times that excess. Below the threshold the report still states
how far the error drifted over the plateaus' last 8 minutes (``paces["settling"]``), and a frame
held still longer than they held the FPA, or for a time not known, takes that drift in
quadrature (:meth:`CalibrationSigma.settling_drift`: `polynomial` on `tau2`, −0.025 °C/min at
the ends of 19-min steps, read a camera held still for 1–2 h −0.08…−0.13 °C off where σ said
0.03–0.05; 0.21 with it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from thermocal.calibration.base import Calibration
from thermocal.calibration.dataset import RATE_SMOOTH_S, lagged_rate, recording_still_time
from thermocal.calibration.report import (
    MIN_BIN_FRAMES,
    PACE_LAG_S,
    SWING_BAND_C_PER_MIN,
    CalibrationReport,
    bins_sigma,
    fpa_swings,
    pace_stays,
    rate_bin_range,
    report_of,
    settling_alternative,
    settling_cause,
    stillness_band,
)
from thermocal.errors import InvalidInputError

__all__ = ["FPA_MARGIN_C", "MIN_GROWTH_PER_C", "NO_REPORT", "NO_REPORTED_ERROR",
           "NO_REPORT_REMEDY", "RATE_MARGIN", "REMEDY", "SCENE_MARGIN_C", "CalibrationSigma",
           "no_sigma_reason", "older_report_warning"]

#: The least growth of the error outside the calibrated ranges, °C of MAE per °C outside.
MIN_GROWTH_PER_C = 0.02
#: The growth of the error outside the FPA range of a session that measured none (held at one
#: FPA temperature: no FPA segment could be left out), °C of MAE per °C outside. A two-point
#: from a session held at 30.5 °C erred 0.26 °C on frames at 30.0 °C, σ 0.05; on a steps
#: session its cross-validation's FPA folds err 6–14 °C 8–30 °C from its reference: about
#: 0.5 °C per °C, which this covers at 1σ.
UNMEASURED_FPA_GROWTH_PER_C = 1.0
#: FPA temperatures this close outside the session's range are inside (the sensor's noise), °C.
FPA_MARGIN_C = 0.5
#: Scene temperatures this close outside the blackbody's range are inside, °C: a blackbody at
#: an end set point reads within the noise and the fit's own error of it (a recording of the
#: session's 10 °C plateau through its polynomial: 1st percentile 9.9x °C, refused); σ grows
#: from the range's end all the same.
SCENE_MARGIN_C = 0.5
#: Frames this far from the FPA temperatures a fit used, °C, may read their scene out of range
#: because of their FPA, which the refusal then says (a two-point at 15.5 °C reads a 20 °C
#: scene as 7…42 °C at an FPA of 45 °C).
FITTED_FPA_NOTE_C = 5.0
#: How far from the paces held near its FPA temperature (``fpa_cells``) a memoryless method's
#: frame is still inside, °C/min: wider than the margin of the paces held anywhere (a cell),
#: since a fit at one FPA temperature is held by its neighbours' too (a 0.2 °C/min sawtooth's
#: polynomial reads a camera held still at 28 °C within 0.15 °C), narrow enough for a pace
#: met only far away (a 2 °C/min ramp's: 5.5 °C off at a still 30 °C).
LOCAL_PACE_MARGIN_C_PER_MIN = 0.3
#: FPA rates up to this many times the session's fastest are inside (the rate estimate's noise).
RATE_MARGIN = 1.25
#: How many times longer than the session's plateaus a camera is taken to have held its FPA
#: still where its recording cannot show how long (still throughout it, or no FPA series), for
#: σ when forced: a state beyond any the session measured, as after the plateaus' length
#: twice over (a settled `boson` camera through a 20-min-plateau `lin-level`: 2.1 °C off where
#: σ said 0.9; the largest rate-bin σ of such reports is 1.5–1.9 °C).
UNKNOWN_STILL_EXCESS = 2.0
#: Frames whose stillness reaches back this close to their recording's start (s) were still
#: throughout it: how long before it began is not known.
SINCE_START_TOL_S = 1e-6
#: What to do about frames outside a calibration's ranges.
REMEDY = ("calibrate over these conditions (a chamber session that covers them: `thermocal "
          "calibrate`); --force gives the temperatures with their uncertainty grown")

#: Why frames cannot be checked against a calibration without a cross-validation report.
NO_REPORT = ("the calibration has no cross-validation report (made by an older thermocal), so "
             "neither the ranges it was fitted on nor its error can be checked")
#: Why a calibration whose report measured no error has no σ (written with ``--force``).
NO_REPORTED_ERROR = ("the calibration's cross-validation report measured no error (no set point "
                     "or FPA segment of its session could be left out and refitted: too few of "
                     "them, or every refit failed), so its temperatures would have no "
                     "uncertainty")
#: What to do about either.
NO_REPORT_REMEDY = ("calibrate again (`thermocal calibrate`) from a session of at least 3 set "
                    "points; --force gives the temperatures without an uncertainty")


def no_sigma_reason(calibration: Any) -> str:
    """Why :meth:`CalibrationSigma.of` gives ``calibration`` no σ: it has no report
    (:data:`NO_REPORT`), or its report measured no error (:data:`NO_REPORTED_ERROR`; its
    ranges were stated but never tested)."""
    return NO_REPORT if report_of(calibration) is None else NO_REPORTED_ERROR


_GAUSS = math.sqrt(math.pi / 2)


def _curve(folds: list[dict[str, Any]], where: Any, key: str = "mae_c"
           ) -> tuple[np.ndarray, np.ndarray, float | None]:
    """``(x, v, mean)`` of σ's curve along ``x = where(fold)``, sorted: the interior folds'
    cross-validated error ``v`` (``key``: ``mae_c``, °C, or ``relative_mae``, that over the
    level of its frames' FPA rates), and at each end fold the fit's own error there
    (``own_`` + ``key``; the refit's where the refit was the fit itself, ``fit_unchanged``)
    where that exceeds the nearest interior point's (an own error is the least to expect
    there; a refit without that end extrapolates, the fit did not); and the mean of the
    interior folds' (weighted by their frames; None without one), what the curve is centred
    on. A report made before end folds scored the fit has interior points alone."""
    inner = sorted((where(f), f[key], f.get("frames") or 1) for f in folds
                   if not f["extrapolation"] and f.get(key) is not None)
    pts = [p[:2] for p in inner]
    for f in (f for f in folds if f["extrapolation"]):
        own = f.get(key) if f.get("fit_unchanged") else f.get(f"own_{key}")
        if own is None:
            continue
        x = where(f)
        near = min(inner, key=lambda p: abs(p[0] - x))[1] if inner else own
        pts.append((x, max(own, near)))
    pts.sort()
    x, v = (np.array([p[k] for p in pts], dtype=np.float64) for k in range(2))
    mean = (sum(p[1] * p[2] for p in inner) / sum(p[2] for p in inner)) if inner else None
    return x, v, mean


def _growth(folds: list[dict[str, Any]], interior: float, distance: Any) -> float:
    """Excess MAE per °C of the extrapolation folds (their MAE above ``interior``, over how far
    each extrapolates, ``distance(fold)`` °C), at least :data:`MIN_GROWTH_PER_C`."""
    rates = [max(0.0, f["mae_c"] - interior) / max(distance(f), 1e-6) for f in folds
             if f["extrapolation"] and f.get("mae_c") is not None]
    return max([MIN_GROWTH_PER_C, *rates])


def _common_shape(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str
                  ) -> tuple[int, ...]:
    """The shape ``(N,)`` two series broadcast to (one value for each of the other's, or as
    many); :class:`InvalidInputError` naming both otherwise."""
    try:
        return np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise InvalidInputError(f"{name_a} has {a.size} values and {name_b} {b.size}: give "
                                "one, or one per frame") from None


def _rising_bins_sigma(values: np.ndarray, bins: list[dict[str, Any]], key: str
                       ) -> np.ndarray:
    """:func:`~thermocal.calibration.report.bins_sigma` of an error that grows with ``values``,
    read as the continuous curve its bins sample: between the centres of a bin and of the next
    above it, never below the line between their σ (the open last bin's centre half the width of
    the one below it above its edge), where σ grows to the next bin by no more than the centres'
    ratio. A lag's error grows with how far the pace changed, at most in proportion, and a bin's
    σ is its frames' average, so near its upper edge a frame errs as the bin above (`lin` and
    `lin-level` on `boson`: up to 1.07 × 2σ of the 0.5–1 °C/min bin at 0.85–0.88, where the bin
    above said 40 % more). Where σ falls to the next bin, or jumps by more than proportion, the
    bins part regimes, not a curve (a plateau's unsettled start from a steady pace; `polynomial`
    on `boson`, 1.3 → 6.3 °C from 0.05–0.2 to 0.2–0.5 °C/min, its sawtooth's fast paces in the
    second: read as a line, its median σ grew by half for no frame), and stay as they are."""
    out = bins_sigma(values, bins, key)
    bins = sorted(bins, key=lambda b: float(b[key][0]))

    def centre(k: int) -> float:
        lo, hi = bins[k][key]
        if hi is None:  # the open last bin: half the width of the one below, above its edge
            below = bins[k - 1][key] if k else (lo, lo)
            hi = lo + (float(below[1]) - float(below[0]))
        return 0.5 * (float(lo) + float(hi))

    centres = [centre(k) for k in range(len(bins))]
    for k in range(len(bins) - 1):
        (c0, c1), (s0, s1) = centres[k : k + 2], (bins[k]["sigma_c"], bins[k + 1]["sigma_c"])
        between = (values >= c0) & (values < c1)
        if s0 < s1 <= s0 * c1 / max(c0, 1e-9) and between.any():
            out[between] = np.maximum(out[between],
                                      s0 + (s1 - s0) * (values[between] - c0) / (c1 - c0))
    return out


def _count(outside: np.ndarray) -> str:
    """``"K of N frames; "`` of the frames ``outside`` (bool ``(N,)``) a refusal names, or
    ``""`` for one frame."""
    return f"{int(np.sum(outside))} of {outside.size} frames; " if outside.size > 1 else ""


def older_report_warning(what: str) -> str:
    """The warning for a calibration whose report lacks ``what``
    (:meth:`CalibrationSigma.older_report`)."""
    return (f"the calibration was made by an older thermocal: its report holds {what}; "
            "calibrate again (`thermocal calibrate`) to have it")


@dataclass(frozen=True)
class CalibrationSigma:
    """σ of a calibration's temperatures and the ranges it covers (see the module docstring)."""

    report: CalibrationReport
    #: The FPA temperatures the fit itself used, °C (a two-point's one reference; None: not
    #: known): frames far from them may read a scene out of range because of their FPA.
    fitted_fpa_c: tuple[float, float] | None = None

    @classmethod
    def of(cls, calibration: Calibration) -> CalibrationSigma | None:
        """From the report stored in ``calibration``; None without one (an older file) or when
        the report measured no error."""
        report = report_of(calibration)
        if report is None or report.expected_mae_c is None:
            return None
        fitted = getattr(calibration, "fpa_range", None) or getattr(calibration, "fpa_range_c",
                                                                    None)
        return cls(report, None if fitted is None else (float(fitted[0]), float(fitted[1])))

    def older_report(self) -> str | None:
        """What the report lacks that one made now records (a file made by an older
        thermocal), in words, or None: the FPA paces its session held (frames are then not
        checked against them), or, for a memoryless method, σ by how far the pace is from
        steady (:meth:`change_sigma`), σ of frames without their history, its session's runs,
        its cold starts, or the drift at its plateaus' ends (``paces["settling"]``, where it
        lists ``still``: a report with plateaus)."""
        info = self._method_info
        if not self.report.paces:
            return ("no FPA paces, so frames are not checked against the paces its session "
                    "held")
        if info is not None and info.memoryless and not self.report.by_change:
            return ("no σ by how far the FPA's pace is from steady, so σ just after the FPA "
                    "starts or stops changing may be too small")
        if self.report.method == "lin-lag" and not self.report.without_history:
            return ("no σ of frames whose FPA history it cannot see, so σ of a recording "
                    "shorter than its lags may be too small")
        if info is not None and not info.memoryless and "swing" not in self.report.paces:
            return ("no record of how far its session's FPA ran one way without pause, so a "
                    "longer run (a long ramp) is not refused")
        if info is not None and info.learns_online and not (
                self.report.without_history or {}).get("by_time"):
            return ("no σ of its estimate begun afresh, so σ of a recording whose FPA changes "
                    "soon after it began may be too small")
        if "still" in self.report.paces and "settling" not in self.report.paces:
            return ("no record of how far its error still drifted at its plateaus' ends, so σ "
                    "of a camera held still longer than they lasted may be too small")
        return None

    @cached_property
    def _curves(self) -> tuple:
        """The report's interior MAE curves by scene level and by FPA temperature, and the
        growth rates outside them (derived from the report once: σ is asked per frame)."""
        r = self.report
        # a report whose folds measured their error over their frames' level: the curves
        # of that (a set point or FPA segment that the session visited at fast paces errs
        # more at the same scene and FPA: the rate bins say so already); else of the MAE
        scored = [f for f in r.folds if f.get("mae_c") is not None]
        key = ("relative_mae" if scored and all(f.get("relative_mae") is not None
                                                for f in scored) else "mae_c")
        scene = _curve(r.by_scene(), lambda f: float(f["held_out"]), key)
        fpa = _curve(r.by_fpa(), lambda f: 0.5 * sum(f["held_out"]), key)
        points = sorted(float(f["held_out"]) for f in r.by_scene())
        step = float(np.min(np.diff(points))) if len(points) > 1 else 10.0
        k_scene = _growth(r.by_scene(), r.expected_mae_c, lambda f: step)
        k_fpa = _growth(r.by_fpa(), r.expected_mae_c,
                        lambda f: 0.5 * (f["held_out"][1] - f["held_out"][0]))
        if not any(f.get("mae_c") is not None for f in r.by_fpa()):
            k_fpa = max(k_fpa, UNMEASURED_FPA_GROWTH_PER_C)  # a session at one FPA
        # how far the end folds extrapolated, below and above: one step to the next set point
        ends = ((points[1] - points[0], points[-1] - points[-2]) if len(points) > 1
                else (step, step))
        return scene, fpa, k_scene, k_fpa, ends

    def _shape(self, frames: np.ndarray, fpa: np.ndarray) -> np.ndarray:
        """σ's shape ``(N, H, W)`` at temperatures ``frames`` (°C ``(N, H, W)``) and FPA
        temperatures ``fpa`` (°C ``(N,)``): 1, plus each curve's excess there over its
        interior folds' mean, relative to that mean (the scene and FPA parts add: a
        cold scene at an FPA end errs by both), never below the least of either curve so
        taken. Each curve is centred on its own: a set point left out and an FPA segment left
        out are gaps of their own size, and one kind errs more than the other throughout
        (`lin-lag` on `tau2`: FPA folds 0.09–0.11 °C, set points 0.05–0.07): they tell where
        σ is larger, the rate bins how large."""
        (sx, sv, c_scene), (fx, fv, c_fpa), *_ = self._curves
        # a curve without a scored interior fold (all refits failed, or two set points) keeps
        # its ends, centred on the other curve's interior: how its ends compare with the rest
        c_scene, c_fpa = c_scene or c_fpa, c_fpa or c_scene
        shape = np.ones(frames.shape)
        least = 1.0
        if sx.size and c_scene:
            shape += np.interp(frames, sx, sv) / c_scene - 1.0
            least = min(least, float(sv.min()) / c_scene)
        if fx.size and c_fpa:
            shape += (np.interp(fpa, fx, fv) / c_fpa - 1.0)[:, None, None]
            least = min(least, float(fv.min()) / c_fpa)
        return np.maximum(shape, least)

    @cached_property
    def _fpa_ends(self) -> tuple[float, float]:
        """How far the end FPA folds extrapolated, below and above, °C: the widths of the end
        segments (inf without FPA folds: the growth outside is then unmeasured from the
        range itself, :data:`UNMEASURED_FPA_GROWTH_PER_C`)."""
        spans = sorted((float(f["held_out"][0]), float(f["held_out"][1]))
                       for f in self.report.by_fpa())
        if not spans:
            return math.inf, math.inf
        return spans[0][1] - spans[0][0], spans[-1][1] - spans[-1][0]

    def _overall_sigma(self) -> float:
        r = self.report
        return r.sigma_c if r.sigma_c is not None else _GAUSS * r.expected_mae_c

    @staticmethod
    def _bin_sigma(b: dict[str, Any]) -> float:
        """A rate bin's σ (``√(π/2)·MAE`` in a report made before bins had σ)."""
        return b["sigma_c"] if b.get("sigma_c") is not None else _GAUSS * b["mae_c"]

    @property
    def by_pace(self) -> bool:
        """Whether the report's rate bins are of the FPA's pace (a memoryless method's:
        :func:`~thermocal.calibration.dataset.fpa_pace`), not of its present rate."""
        return any("pace_c_per_min" in b for b in self.report.by_rate)

    def rate_sigma(self, rate_c_per_min: Any, *, at_least: bool = False) -> np.ndarray:
        """``s(r)`` of each rate (°C/min; ``(N,)``; the pace for a report binned by pace), °C:
        its bin's σ (the overall σ for a rate the session never had; ``√(π/2)·MAE`` of its bin
        in a report without bin σ). ``at_least``: the rates are lower bounds (a pace whose
        history is not known is at least the present rate): the largest σ of the bins at or
        above each."""
        rate = np.abs(np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1))
        top = self.max_rate_c_per_min
        out = np.full(rate.shape, self._overall_sigma())
        bins = sorted(self.report.by_rate, key=lambda b: rate_bin_range(b)[0])
        for i, b in enumerate(bins):
            lo, hi = rate_bin_range(b)
            sel = (np.minimum(rate, top) >= lo) & (np.minimum(rate, top) < (
                math.inf if hi is None else hi))
            out[sel] = (max(self._bin_sigma(c) for c in bins[i:]) if at_least
                        else self._bin_sigma(b))
        # faster than the session ever changed: the error of a rate term left out grows with
        # the rate, so σ grows in proportion beyond the fastest rate it covered
        faster = rate > top
        out[faster] *= rate[faster] / max(top, 1e-3)
        return out

    def start_sigma(self, time_since_start_s: Any) -> np.ndarray:
        """σ of each frame's time since its recording began (s; ``(N,)``), °C: its bin of the
        report's ``mae_by_time_since_start_c`` where that bin holds at least
        :data:`~thermocal.calibration.report.MIN_BIN_FRAMES` frames (a report made before
        sparse bins were pooled), 0 elsewhere (no start-up seen)."""
        t = np.asarray(time_since_start_s, dtype=np.float64).reshape(-1)
        return bins_sigma(t, [b for b in self.report.by_time if b["frames"] >= MIN_BIN_FRAMES
                               and b.get("sigma_c") is not None], "time_s")

    def change_sigma(self, change_c_per_min: Any) -> np.ndarray:
        """σ of how far each frame's pace was from steady (°C/min, ``|r − y|``; ``(N,)``), °C:
        its bin of the report's ``mae_by_fpa_change_c`` (a memoryless method's) above the steady
        one; 0 in the steady bin and where the report has none (a method with memory, an older
        report): the pace bins alone.

        The steady bin pools plateaus with steady ramps, which the pace bins tell apart: taking
        it too left no frame silent on the first held-out run but over-covered every memoryless
        method (``polynomial`` on ``tau2`` 100 % within 2σ; RESULTS.md, 2026-11-28)."""
        d = np.asarray(change_c_per_min, dtype=np.float64).reshape(-1)
        used = [b for b in self.report.by_change if b["change_c_per_min"][0] > 0]
        out = _rising_bins_sigma(d, used, "change_c_per_min")
        if used:  # a rate not known (NaN): how it changed is not known either, the worst bin
            out[np.isnan(d)] = max(b["sigma_c"] for b in used)
        return out

    def history_sigma(self, time_since_start_s: Any, n: int, *, moved: Any = None
                      ) -> np.ndarray:
        """σ of ``n`` frames taken ``time_since_start_s`` after their recording began (s, one
        or one per frame; None: not known, or not seen, as a burst's) that a model remembering
        the FPA's rates cannot see the history of: the report's σ of frames taken alone
        (``without_history``), fading as ``exp(−t / τ)`` with the model's longest lag ``τ``
        (a first-order lag forgets its start so); 0 for the other methods. ``lin-lag`` on a
        5-frame recording of a camera long settled: −0.14 °C where σ said 0.07, 55 % of the
        pixels beyond 2σ; σ without history covers it (0.16 °C MAE on its session's frames).
        For a method that learns online, only at frames whose recording's FPA had changed since
        it began (``moved``, bool ``(n,)``; None: not known, taken as changed) or whose history
        was not seen: a recording that stays settled is what its session's start-up bins
        (:meth:`start_sigma`) measured, its session having begun settled; a change early in
        it, before the estimate learned anything, no fold saw."""
        alone = self.report.without_history
        if not alone:
            return np.zeros(n)
        since = (np.zeros(n) if time_since_start_s is None else np.broadcast_to(
            np.asarray(time_since_start_s, dtype=np.float64).reshape(-1), (n,)))
        faded = alone["sigma_c"] * np.exp(-np.maximum(since, 0.0) / alone["lag_s"])
        if not (self._learns_online and moved is not None):
            return faded
        if alone.get("by_time"):  # its cold starts, measured: their σ by time since
            faded = np.maximum(faded, bins_sigma(since, alone["by_time"], "time_s"))
        return np.where(np.broadcast_to(np.asarray(moved, dtype=bool).reshape(-1), (n,)),
                        faded, 0.0)

    def pace_distance(self, rate_c_per_min: Any, time_s: Any, *, fpa_c: Any = None
                      ) -> np.ndarray:
        """How far each frame's pace lies from the paces the session held, °C/min ``(N,)``: the
        Chebyshev distance in the plane (FPA rate, the same through the report's lag) from the
        nearest held cell's centre, less half a cell, at least 0; given the frames' FPA
        temperatures ``fpa_c`` (°C), of the cells held near them (:meth:`_distance`).
        ``rate_c_per_min`` and ``time_s`` (s) are one recording's, ``(N,)`` in time order.
        Zeros where the report lists no paces (a method with memory, or an older report) and
        for times out of order (not one recording: no pace history)."""
        return self._pace(rate_c_per_min, time_s, None, fpa_c)[2]

    def _pace(self, rate_c_per_min: Any, time_s: Any, lagged_rate_c_per_min: Any = None,
              fpa_c: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each frame's rate and lagged rate, °C/min, and its :meth:`pace_distance` (all
        ``(N,)``; at its FPA temperature ``fpa_c``, °C, where given): the lagged rate given
        (``lagged_rate_c_per_min``, one or one per frame, taken from the frames' recording),
        or made from the rates of one recording at ``time_s`` (the rate itself where there is
        no pace history)."""
        rate = np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1)
        if lagged_rate_c_per_min is not None:
            lagged = np.broadcast_to(
                np.asarray(lagged_rate_c_per_min, dtype=np.float64).reshape(-1), rate.shape)
            return rate, lagged, self._distance(rate, lagged, fpa_c)
        t = np.asarray(time_s, dtype=np.float64).reshape(-1)
        paces = self.report.paces
        if (not paces or not paces["cells"] or rate.size == 0 or t.shape != rate.shape
                or np.any(np.diff(t) <= 0)):
            return rate, rate, np.zeros(rate.shape)
        lagged = lagged_rate(rate, t, paces["lag_s"])
        return rate, lagged, self._distance(rate, lagged, fpa_c)

    def _distance(self, rate: np.ndarray, lagged: np.ndarray, fpa: Any = None) -> np.ndarray:
        """:meth:`pace_distance` of points (rate, lagged rate), °C/min ``(N,)`` each; zeros
        where the report lists no paces. Given their FPA temperatures ``fpa`` (°C, one or one
        per point) and a report that says where each pace was held (a memoryless method's
        ``fpa_cells``), the distance from the paces held within ``fpa_reach_c`` of a point's
        FPA also counts, less :data:`LOCAL_PACE_MARGIN_C_PER_MIN` beyond the margin: a pace
        held only at other FPA temperatures (none within reach: a cell beyond that margin)."""
        paces = self.report.paces
        if not paces or not paces["cells"]:
            return np.zeros(rate.shape)
        cell = paces["cell_c_per_min"]
        held = np.asarray(paces["cells"], dtype=np.float64).reshape(-1, 2) * cell
        point = np.stack([rate, lagged], axis=1)
        out = self._nearest(point, held) - 0.5 * cell
        if fpa is not None and np.size(fpa) and paces.get("fpa_cells"):
            where = np.asarray(paces["fpa_cells"], dtype=np.float64).reshape(-1, 3)
            centre = (where[:, 2] + 0.5) * paces["fpa_cell_c"]
            reach = paces["fpa_reach_c"] + 0.5 * paces["fpa_cell_c"]
            at = np.broadcast_to(np.asarray(fpa, dtype=np.float64).reshape(-1), rate.shape)
            local = self._nearest(point, where[:, :2] * cell, at, centre, reach) - 0.5 * cell
            local[np.isinf(local)] = LOCAL_PACE_MARGIN_C_PER_MIN + cell  # none within reach
            out = np.maximum(out, local - (LOCAL_PACE_MARGIN_C_PER_MIN - self._pace_margin))
        if self._learns_online:  # a direction of change its session never held: outside
            out = np.maximum(out, self._pace_margin + self._beyond_rates(rate))
        return np.maximum(out, 0.0)

    @cached_property
    def _method_info(self) -> Any:
        """The report's method's :class:`~thermocal.calibration.registry.CalibrationInfo`, or
        None for a method the registry does not know."""
        from thermocal.calibration.registry import CALIBRATION_METHODS  # here: no cycle

        return CALIBRATION_METHODS.get(self.report.method)

    @property
    def _memoryless(self) -> bool:
        """Whether the report's method has no memory of how the FPA changed (True for a method
        the registry does not know: the stricter words)."""
        return bool(self._method_info is None or self._method_info.memoryless)

    @property
    def _learns_online(self) -> bool:
        """Whether the report's method learns as frames stream by (``wolf2016``'s LMS)."""
        return bool(self._method_info is not None and self._method_info.learns_online)

    def _beyond_rates(self, rate: np.ndarray) -> np.ndarray:
        """How far each FPA rate (°C/min ``(N,)``) lies more than a cell beyond the rates of
        the paces the session held (below the lowest or above the highest cell's), °C/min;
        negative within. A method that learns online (``wolf2016``) is held to the directions
        of change its session showed: on `boson` fitted on ambient steps (an FPA that only
        rose) it went unrefused over a slow sawtooth's falls at −0.25 °C/min, within its
        margin of the session's rest, erring −2.6…−4.4 °C where σ said 0.5–2.1 (250 frames, a
        helper's map of silent frames)."""
        paces = self.report.paces
        cell = paces["cell_c_per_min"]
        rates = np.asarray(paces["cells"], dtype=np.float64).reshape(-1, 2)[:, 0] * cell
        return np.maximum(rates.min() - rate, rate - rates.max()) - cell

    @staticmethod
    def _nearest(point: np.ndarray, held: np.ndarray, at: np.ndarray | None = None,
                 centre: np.ndarray | None = None, reach: float = 0.0) -> np.ndarray:
        """The Chebyshev distance of each point ``(N, 2)`` to the nearest ``held`` ``(M, 2)``,
        °C/min (given the points' FPA temperatures ``at`` ``(N,)`` and the cells'
        ``centre`` ``(M,)``, of the cells within ``reach`` °C alone; inf where none is)."""
        out = np.empty(point.shape[0])
        for i in range(0, point.shape[0], 4096):  # (frames × cells) at a time, bounded
            d = np.abs(point[i:i + 4096, None, :] - held[None]).max(axis=2)
            if at is not None:
                d = np.where(np.abs(at[i:i + 4096, None] - centre[None]) > reach, np.inf, d)
            out[i:i + 4096] = d.min(axis=1) if d.shape[1] else np.inf
        return out

    def pace_unseen(self, rate_c_per_min: float, lagged_c_per_min: float | None,
                    fpa_c: float | None = None) -> bool:
        """Whether one frame's pace (its FPA rate and the same through the report's lag,
        °C/min, taken from its recording; at FPA temperature ``fpa_c``, °C, where known) lies
        more than the margin from every pace the session held; False where the lagged rate
        is not known or the report lists no paces."""
        if lagged_c_per_min is None:
            return False
        d = self._distance(np.array([float(rate_c_per_min)]),
                           np.array([float(lagged_c_per_min)]),
                           None if fpa_c is None else [float(fpa_c)])
        return bool(d[0] > self._pace_margin)

    def paces_never_held(self, rate_c_per_min: Any, time_s: Any, *, fpa_c: Any = None
                         ) -> np.ndarray:
        """Which frames ``(N,)`` bool of one recording changed at a pace more than the margin
        from every pace the session held (:meth:`pace_distance`; the pace alone, as
        :meth:`pace_unseen` judges one burst's): where a method's rate terms were never
        verified."""
        return self.pace_distance(rate_c_per_min, time_s, fpa_c=fpa_c) > self._pace_margin

    def unseen_paces(self, rate_c_per_min: Any, time_s: Any, *, fpa_c: Any = None
                     ) -> np.ndarray:
        """Which frames ``(N,)`` bool of one recording changed at a pace the session never
        held: more than one cell from every held one (:meth:`pace_distance`), or, given their
        FPA temperatures ``fpa_c`` (°C ``(N,)``), held it still longer than the session's
        plateaus did (:meth:`still_excess`); or held a pace longer than the session held it
        by more than its slack (:meth:`sustained_excess`)."""
        unseen = self.pace_distance(rate_c_per_min, time_s, fpa_c=fpa_c) > self._pace_margin
        _, excess = self._sustained(rate_c_per_min, time_s)
        unseen |= self._held_too_long(excess)
        if fpa_c is not None:
            _, excess, unknown, _ = self._still(fpa_c, time_s, rate_c_per_min=rate_c_per_min)
            unseen |= (excess > 1.0) | unknown
        return unseen

    def still_excess(self, still_s: Any) -> np.ndarray:
        """How many times longer each frame had held its FPA still than the session's plateaus
        did ``(N,)``: ``still_s`` (s; :func:`~thermocal.calibration.dataset.recording_still_time`
        of its recording) over the report's ``paces["still"]["held_s"]``. Zeros where the report
        lists no stillness (a session that settled, a method with memory, an older report)."""
        s = np.asarray(still_s, dtype=np.float64).reshape(-1)
        still = (self.report.paces or {}).get("still")
        return s / still["held_s"] if still else np.zeros(s.shape)

    def sustained_excess(self, rate_c_per_min: Any, stays_s: Any) -> np.ndarray:
        """How much longer each frame had held its pace than its chamber session held any pace
        within a cell of it, s ``(N,)`` (0 where no longer, where the report lists no stays —
        a method with memory, an older report — and at rest, the stillness's part): its stay
        ``stays_s`` (s, :func:`~thermocal.calibration.report.pace_stays` of its recording, one
        or one per frame) at its FPA rate ``rate_c_per_min`` (°C/min) less the longest the
        session stayed there (its report's ``sustained``). Frames with an excess above the
        report's ``slack_s`` are outside: what lags the FPA has run on to a state the session
        never showed."""
        sus = (self.report.paces or {}).get("sustained")
        rate = np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1)
        stays = np.asarray(stays_s, dtype=np.float64).reshape(-1)
        shape = _common_shape(rate, stays, "rate_c_per_min", "the stays")
        if not sus or not sus["held_s"]:
            return np.zeros(shape)
        cell = self.report.paces["cell_c_per_min"]
        held = dict((int(c), s) for c, s in sus["held_s"])
        lo, hi = min(held), max(held)
        table = np.zeros(hi - lo + 3)  # cells lo−1 … hi+1: the longest stay within one cell
        for c, s in held.items():
            table[c - lo : c - lo + 3] = np.maximum(table[c - lo : c - lo + 3], s)
        at = np.round(np.nan_to_num(np.broadcast_to(rate, shape)) / cell).astype(np.int64)
        inside = (at >= lo - 1) & (at <= hi + 1)
        longest = np.where(inside, table[np.clip(at - lo + 1, 0, table.size - 1)], 0.0)
        excess = np.maximum(np.broadcast_to(stays, shape) - longest, 0.0)
        return np.where((at != 0) & np.isfinite(np.broadcast_to(rate, shape)), excess, 0.0)

    def _sustained(self, rate_c_per_min: Any, time_s: Any = None, stays_s: Any = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Frames' stays at their pace (s) and :meth:`sustained_excess` (s), both ``(N,)``: the
        stays given (``stays_s``, one or one per frame, taken from their recording), or those
        of the frames of one recording at ``time_s`` (s, in time order); zeros where neither
        (no history: a burst alone) or the report lists no stays."""
        rate = np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1)
        if not (self.report.paces or {}).get("sustained"):
            return np.zeros(rate.shape), np.zeros(rate.shape)
        if stays_s is None:
            t = None if time_s is None else np.asarray(time_s, dtype=np.float64).reshape(-1)
            if t is None or t.shape != rate.shape or np.any(np.diff(t) <= 0):
                return np.zeros(rate.shape), np.zeros(rate.shape)
            stays_s = pace_stays(rate, t, band_c_per_min=self.report.paces["sustained"][
                "band_c_per_min"])
        stays = np.nan_to_num(np.asarray(stays_s, dtype=np.float64).reshape(-1))
        excess = self.sustained_excess(rate, stays)
        return np.broadcast_to(stays, excess.shape), excess

    def _sustained_sigma(self, rate_c_per_min: np.ndarray, excess: np.ndarray) -> np.ndarray:
        """``s`` of frames that held their pace longer than the session did by more than its
        slack (:meth:`sustained_excess`, s): what the FPA ran on by at that rate beyond the
        session's longest stay, up to the report's lag, is worth in the counts (its
        ``fpa_sensitivity_c_per_c``; 1 where absent), and at least the report's largest
        rate-bin σ: how far what lags it fell behind no fold measured (0 elsewhere)."""
        paces = self.report.paces or {}
        sus = paces.get("sustained")
        if not sus:
            return np.zeros(np.shape(excess))
        sensitivity = paces.get("fpa_sensitivity_c_per_c")
        sensitivity = 1.0 if sensitivity is None else sensitivity
        ran = np.abs(np.nan_to_num(rate_c_per_min)) * np.minimum(excess, paces["lag_s"]) / 60.0
        return np.where(self._held_too_long(excess),
                        np.maximum(self._worst_sigma(), sensitivity * ran), 0.0)

    def _held_too_long(self, excess: np.ndarray) -> np.ndarray:
        """Whether frames' :meth:`sustained_excess` (s) exceeds the report's ``slack_s`` (never
        where the report lists no stays): outside."""
        sus = (self.report.paces or {}).get("sustained")
        return np.asarray(excess) > (sus["slack_s"] if sus else math.inf)

    def swing_excess(self, swings_c: Any) -> np.ndarray:
        """How much further each frame's FPA had run in one direction without pause than its
        chamber session's ever did that way, °C ``(N,)``: ``|swing|`` less the report's
        ``rise_c`` (a rise) or ``fall_c`` (a fall), ``swings_c`` (°C, signed:
        :func:`~thermocal.calibration.report.fpa_swings` of its recording); 0 where not
        further, and where the report lists no runs (a memoryless method, an older report).
        Frames beyond the report's ``slack_c`` are outside: what lags the FPA more slowly than
        a model with memory follows has fallen further behind than any fold saw."""
        swings = np.nan_to_num(np.asarray(swings_c, dtype=np.float64).reshape(-1))
        if not (self.report.paces or {}).get("swing"):
            return np.zeros(swings.shape)
        return np.maximum(np.abs(swings) - self._session_run(swings), 0.0)

    def _session_run(self, swings: np.ndarray) -> np.ndarray:
        """The session's longest run in each of ``swings``' directions (its report's
        ``rise_c`` for a rise, ``fall_c`` for a fall), °C."""
        swing = self.report.paces["swing"]
        return np.where(swings > 0, swing["rise_c"], swing["fall_c"])

    def _swings(self, fpa_c: np.ndarray, rate: np.ndarray, time_s: Any, swing_c: Any = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """Frames' runs in one direction (°C, signed) and :meth:`swing_excess` (°C), both
        ``(N,)``: the runs given (``swing_c``, one or one per frame, taken from their
        recording), or those of the frames of one recording at FPA ``fpa_c`` (°C), rate
        ``rate`` (°C/min) and ``time_s`` (s, in time order); zeros without them (a burst alone,
        a constant FPA) or where the report lists no runs."""
        n = rate.shape[0]
        swing = (self.report.paces or {}).get("swing")
        if swing and swing_c is not None:
            given = np.broadcast_to(np.nan_to_num(np.asarray(swing_c, dtype=np.float64)
                                                  .reshape(-1)), (n,))
            return given, self.swing_excess(given)
        t = None if time_s is None else np.asarray(time_s, dtype=np.float64).reshape(-1)
        if (not swing or t is None or fpa_c.shape != rate.shape or t.shape != rate.shape
                or np.any(np.diff(t) <= 0)):
            return np.zeros(n), np.zeros(n)
        swings = fpa_swings(fpa_c, rate, t, band_c_per_min=swing["band_c_per_min"])
        return swings, self.swing_excess(swings)

    def _ran_too_far(self, excess: np.ndarray) -> np.ndarray:
        """Whether frames' :meth:`swing_excess` (°C) exceeds the report's ``slack_c`` (never
        where the report lists no runs): outside."""
        swing = (self.report.paces or {}).get("swing")
        return np.asarray(excess) > (swing["slack_c"] if swing else math.inf)

    def _swing_sigma(self, swings: np.ndarray, excess: np.ndarray) -> np.ndarray:
        """``s`` of frames whose FPA ran further in one direction than the session's did by more
        than its slack: the report's largest rate-bin σ times how many times its longest run
        that way (and the slack) the frame's run is: how far behind what lags the FPA fell, no
        fold measured (0 elsewhere)."""
        swing = (self.report.paces or {}).get("swing")
        if not swing:
            return np.zeros(np.shape(excess))
        held = self._session_run(swings) + swing["slack_c"]
        return np.where(self._ran_too_far(excess),
                        self._worst_sigma() * np.abs(swings) / held, 0.0)

    def _swing_reason(self, swing: float, excess: float, count: str = "") -> str:
        """The refusal's text for a frame whose FPA ran ``swing`` °C (signed) in one direction,
        ``excess`` °C further than its session's longest run that way."""
        way, run = ("rose", "rise") if swing > 0 else ("fell", "fall")
        held = abs(swing) - excess
        frames = f" ({count.rstrip('; ')} beyond)" if count else ""
        return (f"the FPA {way} {abs(swing):.1f} °C without pause{frames}, {excess:.1f} °C "
                f"further than its chamber session's longest {run} ({held:.1f} °C): the "
                f"{self.report.method} "
                "calibration's terms for the FPA's history were fitted on shorter runs, and what "
                "lags the FPA more slowly falls further behind on a longer one (record a "
                f"session whose ambient {'rises' if swing > 0 else 'falls'} as far without "
                "pause: a ramp or sawtooth over this range)")

    def _sustained_reason(self, rate: float, stay: float, excess: float,
                          count: str = "") -> str:
        """The refusal's text for a frame that held ``rate`` °C/min for ``stay`` s, ``excess`` s
        longer than its chamber session held any pace within a cell of it."""
        held = max(stay - excess, 0.0)
        return (f"the FPA held a pace for longer than its chamber session held it ({count}"
                f"{'first ' if count else ''}{rate:+.2f} °C/min for {stay / 60:.1f} min, the "
                f"session at most {held / 60:.1f} min near it): the {self.report.method} "
                "calibration, with no memory of how the FPA changed, cannot vouch for the "
                "state what lags the FPA reaches then (record a session that holds such paces "
                "as long, a ramp or sawtooth at this rate; lin-lag follows the pace's history)")

    def _still(self, fpa_c: Any, time_s: Any, still_s: Any = None, since_s: Any = None,
               rate_c_per_min: Any = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """How long frames had held their FPA still, s (NaN: not measured), its
        :meth:`still_excess`, whether that is not known where it is refused, and whether it
        is not known at all (all ``(N,)``): the stillness given
        (``still_s``, one or one per frame, taken from their recording; NaN: not known; with
        ``since_s``, each frame's time since its recording began, s: a stillness reaching back
        to it is a lower bound), or that of the frames of one recording at FPA temperatures
        ``fpa_c`` (°C, one per frame) and times ``time_s`` (s, in time order;
        :func:`~thermocal.calibration.dataset.recording_still_time`: none for an FPA given as
        one value, nor without times); zeros where the report lists neither stillness nor
        settling (the drift at its plateaus' ends, :meth:`settling_drift`).

        *Not known* (only where the report lists stillness — a session whose plateaus ended
        before the camera settled — and the excess is not already above 1): frames still since
        their recording began, or with no stillness measured, unless their FPA rate
        (``rate_c_per_min``, °C/min, one or one per frame, where known) says the FPA was moving
        (:meth:`_moving`): a camera that may have been held still for hours."""
        still = (self.report.paces or {}).get("still")
        band = stillness_band(self.report.paces)
        if still_s is not None:
            held = np.asarray(still_s, dtype=np.float64).reshape(-1)
            unknown = ~np.isfinite(held)
            if since_s is not None:  # one stillness for many frames, or the reverse
                since = np.asarray(since_s, dtype=np.float64).reshape(-1)
                shape = _common_shape(held, since, "still_s", "time_since_start_s")
                held = np.broadcast_to(held, shape)
                unknown = np.broadcast_to(unknown, shape) | (held >= since - SINCE_START_TOL_S)
        else:
            f = np.asarray(fpa_c, dtype=np.float64).reshape(-1)
            t = None if time_s is None else np.asarray(time_s, dtype=np.float64).reshape(-1)
            if t is not None and f.size == 1:
                f = np.broadcast_to(f, t.shape)  # one value for all: not measured
            found = (recording_still_time(f, t, band_c=band, max_gap_s=PACE_LAG_S)
                     if band is not None and t is not None and f.shape == t.shape else None)
            if found is None:
                held = np.full(f.shape, np.nan)
                unknown = np.ones(f.shape, dtype=bool)
            else:
                held, unknown = found, found >= (t - t[0]) - SINCE_START_TOL_S
        if rate_c_per_min is not None and band is not None:  # one stillness, many rates, or reverse
            rate = np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1)
            shape = _common_shape(held, rate, "still_s", "rate_c_per_min")
            held = np.broadcast_to(held, shape)
            unknown = np.broadcast_to(unknown, shape) & ~self._moving(rate, shape)
        excess = self.still_excess(np.nan_to_num(held, nan=0.0))
        return held, excess, unknown & bool(still) & (excess <= 1.0), unknown & (band is not None)

    def settling_drift(self, still_s: Any, unknown: Any = False) -> np.ndarray:
        """How far the error may yet drift, °C ``(N,)``, in frames held still longer than the
        session's plateaus did (``still_s``, s, NaN: not measured) or for a time ``unknown``
        (bool): what it changed by over the plateaus' last minutes (the report's ``settling``:
        ``|slope| × window``), whether or not that refuses them; 0 elsewhere and without it.

        The slope at the plateaus' ends says the session never saw the camera settle; below
        the refusal's threshold a camera held still longer is answered, and its σ takes that
        drift in quadrature (`polynomial` on `tau2`, fitted on 19-min steps: −0.025 °C/min,
        0.2 °C over 8 min; a camera held at 25 and 40 °C ambient for 1–2 h read −0.08…−0.13 °C
        off where σ said 0.03–0.05, 42–60 % within 2σ). Linear beyond the window it would say
        2.9 °C after 2 h, an exponential settling far less: one window's change is the least
        the frames do not show."""
        settle = (self.report.paces or {}).get("settling")
        held = np.asarray(still_s, dtype=np.float64).reshape(-1)
        if not settle:
            return np.zeros(held.shape)
        beyond = (np.nan_to_num(held, nan=0.0) > settle["held_s"]) | np.asarray(unknown,
                                                                                  dtype=bool)
        drift = abs(settle["slope_c_per_min"]) * settle["window_s"] / 60.0
        return np.where(beyond, drift, 0.0)

    def _moving(self, rate_c_per_min: Any, shape: tuple[int, ...]) -> np.ndarray:
        """Whether each FPA rate (°C/min, one or one per frame; NaN: not known) says the FPA
        was moving, not held still: faster than the stillness band over the rate's smoothing
        window (:data:`~thermocal.calibration.dataset.RATE_SMOOTH_S`), ``shape`` bool."""
        rate = np.broadcast_to(np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1), shape)
        band = stillness_band(self.report.paces)
        with np.errstate(invalid="ignore"):
            return np.abs(rate) > band / (RATE_SMOOTH_S / 60.0)

    def _unknown_still_reason(self, fpa: float | None, held: float, count: str = "") -> str:
        """The refusal's text for a frame at ``fpa`` °C (None: not known) whose recording was
        still throughout its ``held`` s (0: no FPA history at all)."""
        where = "" if fpa is None else f" at {fpa:.1f} °C"
        what = (f"its FPA was still throughout its recording ({count}{'first ' if count else ''}"
                f"{held / 60:.1f} min{where})" if np.isfinite(held) else
                f"no history of its FPA was given ({count}a constant FPA temperature, or a "
                f"recording too short to measure one{where})")
        return (f"{what}, so how long the camera had held it still is not known, and the "
                f"plateaus of the {self.report.method} calibration's chamber session ended "
                f"before the camera settled ({self.report.paces['still']['held_s'] / 60:.0f} "
                f"min): {settling_cause(self._memoryless)}, it cannot vouch for a camera held "
                "still longer (give the recording from before the camera last changed "
                "temperature"
                f"{settling_alternative(self._memoryless)})")

    def _worst_sigma(self) -> float:
        """The largest σ of the report's rate bins (or its overall σ), °C: the level of frames
        in a state no session measured, per unit of how far beyond it they lie."""
        return max([self._overall_sigma()] + [self._bin_sigma(b) for b in self.report.by_rate])

    def _still_reason(self, fpa: float | None, still: float, count: str = "") -> str:
        """The stillness refusal's text for a frame at ``fpa`` °C (None: not known) held still
        ``still`` s, longer than the session's plateaus held it."""
        excess = float(self.still_excess([still])[0])
        where = "" if fpa is None else f"at {fpa:.1f} °C "
        return (f"the camera held its FPA still ({count}{'first ' if count else ''}{where}"
                f"for {still / 60:.1f} min), {excess:.2f}× longer than the plateaus "
                f"of its chamber session, which ended before the camera settled: the "
                f"{self.report.method} calibration, {settling_cause(self._memoryless)}, "
                "cannot vouch for the state it settles into (record plateaus long enough for "
                "its error to stop changing"
                f"{settling_alternative(self._memoryless)})")

    @property
    def max_rate_c_per_min(self) -> float:
        """The fastest FPA rate (absolute) of the chamber session, °C/min."""
        return float(max(abs(v) for v in self.report.fpa_rate_c_per_min))

    def sigma(self, temps_c: np.ndarray, fpa_c: Any, *, rate_c_per_min: Any = None,
              time_since_start_s: Any = None, lagged_rate_c_per_min: Any = None,
              still_s: Any = None, sustained_s: Any = None, swing_c: Any = None,
              history_seen: bool = True) -> np.ndarray:
        """σ (°C, float32, the shape of ``temps_c``: ``(H, W)`` or ``(N, H, W)``) of
        temperatures at FPA temperature ``fpa_c`` (°C: one, or one per frame) changing at
        ``rate_c_per_min`` (°C/min, one or one per frame; None: not known), taken
        ``time_since_start_s`` after their recording began (s; None: not known): the level is
        at least the report's σ of that time, for a method that learns as frames stream by;
        and, for the frames of one recording (``(N, H, W)``, N > 1, in time order) at paces the
        session never held, :meth:`_pace_sigma`, or held still longer than the session did,
        the report's largest rate-bin σ times :meth:`still_excess` (one frame has no pace
        history: give its ``lagged_rate_c_per_min``, °C/min, and ``still_s``, s, one or one
        per frame, taken from its recording); for a memoryless method with a pace history, at
        least :meth:`change_sigma` of ``|rate − lagged rate|``, and where a pace was held
        longer than the session held it (:meth:`sustained_excess`, from the recording or each
        frame's ``sustained_s``, s, its stay at its pace), :meth:`_sustained_sigma`; for a
        method with memory whose FPA ran further one way than the session's did (from the
        recording or each frame's ``swing_c``, °C), :meth:`_swing_sigma`; and a frame held
        still longer than the session's plateaus, or for a time not known, takes in quadrature
        :meth:`settling_drift` (from the recording or each frame's ``still_s``).
        ``history_seen`` False: the calibration was applied to these frames without their
        recording's FPA history (a burst: a model remembering the FPA's rates started steady
        at the burst), whatever
        ``time_since_start_s`` says: :meth:`history_sigma` in full."""
        temps = np.asarray(temps_c, dtype=np.float64)
        frames = temps if temps.ndim == 3 else temps[None]
        fpa = np.broadcast_to(np.asarray(fpa_c, dtype=np.float64).reshape(-1), frames.shape[:1])
        n = frames.shape[0]
        recording = bool(time_since_start_s is not None and n > 1 and self.report.paces)
        history = rate_c_per_min is not None and (recording or lagged_rate_c_per_min is not None)
        level = np.full(n, self._overall_sigma())
        if rate_c_per_min is not None:
            rate = np.broadcast_to(np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1), (n,))
            if history:  # a recording: its own paces; else the lagged rates given
                times = (np.broadcast_to(np.asarray(time_since_start_s, dtype=np.float64)
                                         .reshape(-1), (n,)) if recording else None)
                rate, lagged, d = self._pace(
                    rate, times, None if recording else lagged_rate_c_per_min, fpa)
                change = self.change_sigma(np.abs(rate - lagged))
                _, sustained = self._sustained(rate, times, None if recording else sustained_s)
                sustained = self._sustained_sigma(rate, sustained)
                sustained = np.maximum(sustained, self._swing_sigma(*self._swings(
                    np.ascontiguousarray(fpa), rate, times if recording else None,
                    None if recording else swing_c)))
                if self.by_pace:  # the bins are of the pace: the larger of the two rates
                    rate = np.maximum(np.abs(rate), np.abs(lagged))
            level = self.rate_sigma(rate, at_least=self.by_pace and not history)
            if history:
                level = np.maximum(level, np.maximum(self._pace_sigma(d), change))
                level = np.maximum(level, sustained)
        elif self.report.paces.get("fpa_cells"):  # no rate: taken as steady, as applied
            level = np.maximum(level, self._pace_sigma(self._distance(np.zeros(n), np.zeros(n),
                                                                      fpa)))
        held, excess, unknown, not_known = self._still(
            fpa, time_since_start_s if recording else None, still_s,
            None if recording else time_since_start_s, rate_c_per_min)
        level = np.maximum(level, self._still_sigma(np.where(
            unknown, np.maximum(excess, UNKNOWN_STILL_EXCESS), excess)))
        if self._learns_online and not history_seen:
            time_since_start_s = np.zeros(n)  # its estimate begins at these frames
        if time_since_start_s is not None:
            level = np.maximum(level, np.broadcast_to(self.start_sigma(time_since_start_s),
                                                      frames.shape[:1]))

        moved = None  # whether the FPA had changed since the estimate began (None: not known)
        if recording and rate_c_per_min is not None:
            moved = np.maximum.accumulate(np.abs(np.nan_to_num(np.broadcast_to(np.asarray(
                rate_c_per_min, dtype=np.float64).reshape(-1), (n,)))) > SWING_BAND_C_PER_MIN)
        elif rate_c_per_min is not None and lagged_rate_c_per_min is not None:
            # a burst of a recording whose pace is known: an estimate begun at it, its FPA
            # changing now or over the pace's lag before
            pace = np.maximum(np.abs(np.asarray(rate_c_per_min, dtype=np.float64)),
                              np.abs(np.asarray(lagged_rate_c_per_min, dtype=np.float64)))
            moved = np.broadcast_to(np.nan_to_num(pace.reshape(-1), nan=np.inf)
                                    > SWING_BAND_C_PER_MIN, (n,))
        # frames taken alone were scored over all the session's scene levels and FPA
        # temperatures: their σ is not narrowed where the folds' is (wolf2016 on boson, begun
        # settled with a step in its first minute, erred +5.5 °C at a 40 °C set point whose
        # folds' σ narrowed it to 2.5)
        alone = self.history_sigma(time_since_start_s if history_seen else None, n,
                                   moved=moved)
        _, _, k_scene, k_fpa, (step_lo, step_hi) = self._curves
        lo, hi = self.report.scene_range_c
        d_scene = np.maximum(lo - frames, 0.0) + np.maximum(frames - hi, 0.0)
        flo, fhi = self.report.fpa_range_c
        d_fpa = np.maximum(flo - fpa, 0.0) + np.maximum(fpa - fhi, 0.0)
        shape = self._shape(frames, fpa)
        growth = k_scene * d_scene + (k_fpa * d_fpa)[:, None, None]
        # beyond one set-point step outside, no fold measured the error: it may be the whole
        # distance (a pixel clipped at the radiance tables' floor reads −123 °C whatever it saw)
        unmeasured = (np.maximum(lo - step_lo - frames, 0.0)
                      + np.maximum(frames - hi - step_hi, 0.0))
        # and beyond one FPA segment outside: UNMEASURED_FPA_GROWTH_PER_C (lin-level forced at
        # an FPA of 80 °C, 35 °C above its session's: 9.9 °C off where σ said 2.6)
        seg_lo, seg_hi = self._fpa_ends
        unmeasured = unmeasured + (UNMEASURED_FPA_GROWTH_PER_C * (
            np.maximum(flo - seg_lo - fpa, 0.0) + np.maximum(fpa - fhi - seg_hi, 0.0)))[
                :, None, None]
        base = np.maximum(level[:, None, None] * shape,
                          alone[:, None, None] * np.maximum(shape, 1.0))
        drift = self.settling_drift(held, not_known)  # (N,)
        base = np.hypot(base, np.broadcast_to(drift, frames.shape[:1])[:, None, None])
        out = (base + _GAUSS * growth + unmeasured).astype(np.float32)
        return out if temps.ndim == 3 else out[0]

    @property
    def _pace_cell(self) -> float:
        """The report's pace cell, °C/min (inf without paces)."""
        return self.report.paces.get("cell_c_per_min", math.inf)

    @property
    def _pace_margin(self) -> float:
        """How far from the held paces a frame's may lie, °C/min (its report's
        ``margin_c_per_min``: a cell for a memoryless method; inf without paces: nothing is
        unseen)."""
        paces = self.report.paces
        return paces.get("margin_c_per_min", paces.get("cell_c_per_min", math.inf))

    def _pace_reason(self, rate: float, lagged: float, count: str = "",
                     fpa: float | None = None, *, unknown: bool = False) -> str:
        """The pace refusal's text for a frame at ``rate`` after ``lagged`` °C/min (at FPA
        temperature ``fpa``, °C, where known; ``unknown``: its pace was not known, and taken as
        steady)."""
        what = (f"{count}{'first ' if count else ''}{rate:+.2f} °C/min after {lagged:+.2f} over "
                f"the last {self.report.paces['lag_s'] / 60:.0f} min")
        if unknown:
            what = (f"{count}its pace not known from so short a recording, taken as steady, as "
                    "the calibration applies it")
        if self._learns_online and self._beyond_rates(np.array([rate]))[0] > 0:
            cell = self.report.paces["cell_c_per_min"]
            held = np.asarray(self.report.paces["cells"], dtype=np.float64)[:, 0] * cell
            way = "fell" if rate < held.min() else "rose"
            return (f"the FPA {way} at a pace its chamber session never did ({what}; the "
                    f"session's paces {held.min():+.2f}…{held.max():+.2f} °C/min): the "
                    f"{self.report.method} calibration learned its FPA terms on those alone "
                    "(record a session whose ambient rises and falls, a sawtooth at this rate)")
        if fpa is not None and self._distance(np.array([rate]), np.array([lagged]))[0] \
                <= self._pace_margin:  # held, but at other FPA temperatures only
            paces = self.report.paces
            return (f"the FPA changed at a pace its chamber session held only more than "
                    f"{paces['fpa_reach_c']:g} °C from {fpa:.1f} °C ({what}), and the "
                    f"{self.report.method} calibration, with no memory of how the FPA changed, "
                    "fitted each FPA temperature to the paces it saw there (record a session "
                    "that holds the FPA still, in steps, across its range; lin-lag follows the "
                    "pace's history)")
        if self._pace_margin <= self._pace_cell:
            return (f"the FPA changed at paces its chamber session never held ({what}), which "
                    f"the {self.report.method} calibration, with no memory of how the FPA "
                    "changed, cannot vouch for (lin-lag follows the pace's history)")
        return (f"the FPA changed at paces more than {self._pace_margin:g} °C/min from any "
                f"pace its chamber session held ({what}): the {self.report.method} "
                "calibration's lag terms were fitted on those alone (record a session that "
                "changes the FPA at such paces, e.g. a sawtooth at this rate)")

    def _pace_sigma(self, distance: np.ndarray) -> np.ndarray:
        """``s`` of frames at paces the session never held (more than the margin from them),
        from their :meth:`pace_distance` (°C/min): the largest σ of the report's rate bins
        times the cells beyond the margin, one at the margin (for a memoryless method, whose
        margin is a cell, the distance in cells; 0 for the others); and at least what so much
        more FPA change over the report's lag is worth in the counts, uncorrected (its
        ``fpa_sensitivity_c_per_c`` × distance × lag: the FPA has run that far from where
        anything lagging it stood at any pace a fold saw). A helper's audit: `polynomial` fitted
        on a `boson` ramp and forced on steps erred 1.3–2.5 °C where σ said 0.35–1.0."""
        cells = (distance - self._pace_margin) / self._pace_cell + 1.0
        s = self._worst_sigma() * cells
        paces = self.report.paces
        sensitivity = paces.get("fpa_sensitivity_c_per_c") if paces else None
        if sensitivity is not None:
            s = np.maximum(s, sensitivity * distance * paces["lag_s"] / 60.0)
        return np.where(distance > self._pace_margin, s, 0.0)

    def _still_sigma(self, excess: np.ndarray) -> np.ndarray:
        """``s`` of frames held still longer than the session's plateaus held it, from their
        :meth:`still_excess`: the largest σ of the report's rate bins times the excess (0 for
        the others)."""
        return np.where(excess > 1.0, self._worst_sigma() * excess, 0.0)

    def burst_sigma(self, temps_c: np.ndarray, fpa_c: Any, pace: Any, *,
                    time_since_start_s: Any = None, history_seen: bool = False) -> np.ndarray:
        """:meth:`sigma` of one burst's temperatures ``(H, W)`` °C (its pivot's) at FPA
        temperature ``fpa_c`` (°C) changing at ``pace`` (an
        :class:`~thermocal.estimation.base.FpaPace` from its recording, or None: not known,
        taken as steady), ``time_since_start_s`` after its recording began (s, or None): the
        pace judged where it was held near the FPA, as :meth:`outside_burst` judges it, and
        calibrated without its recording's history unless ``history_seen`` (a lin-lag burst
        given its lagged rates, :attr:`~thermocal.estimation.base.FpaPace.lag_rates`)."""
        if np.ndim(temps_c) != 2:  # frames of one time would be taken for a recording
            raise InvalidInputError(f"burst_sigma: one frame (H, W), got {np.shape(temps_c)}")
        since = None if time_since_start_s is None else [time_since_start_s]
        if pace is None:
            return self.sigma(temps_c, fpa_c, time_since_start_s=since,
                              history_seen=history_seen)
        return self.sigma(
            temps_c, fpa_c, rate_c_per_min=[pace.rate_c_per_min], time_since_start_s=since,
            lagged_rate_c_per_min=(None if pace.lagged_c_per_min is None
                                   else [pace.lagged_c_per_min]),
            still_s=None if pace.still_s is None else [pace.still_s],
            sustained_s=None if pace.sustained_s is None else [pace.sustained_s],
            swing_c=None if pace.swing_c is None else [pace.swing_c],
            history_seen=history_seen)

    def outside_burst(self, temps_c: np.ndarray, fpa_c: float | None, pace: Any, *,
                      time_since_start_s: float | None = None) -> tuple[str, ...]:
        """:meth:`outside` for one burst of calibrated frames ``(N, H, W)`` at FPA temperature
        ``fpa_c`` (°C; None: not known) changing at ``pace`` (a
        :class:`~thermocal.estimation.base.FpaPace` or None: not known): its FPA rate against
        the session's fastest, and for a memoryless method its rate and lagged rate against the
        paces the session held, and its stillness (not known without a pace, or where it
        reaches back to the recording's start, ``time_since_start_s`` s before: refused where
        the session never settled)."""
        rate = None if pace is None else [pace.rate_c_per_min]
        lagged = (None if pace is None or pace.lagged_c_per_min is None
                  else [pace.lagged_c_per_min])
        still = [math.nan if pace is None or pace.still_s is None else pace.still_s]
        stays = None if pace is None or pace.sustained_s is None else [pace.sustained_s]
        swing = None if pace is None or pace.swing_c is None else [pace.swing_c]
        return self.outside(temps_c, () if fpa_c is None else fpa_c, rate_c_per_min=rate,
                            lagged_rate_c_per_min=lagged, still_s=still, sustained_s=stays,
                            swing_c=swing,
                            time_since_start_s=(None if time_since_start_s is None
                                                else [time_since_start_s]))

    def outside(self, temps_c: np.ndarray, fpa_c: Any, *, rate_c_per_min: Any = None,
                time_s: Any = None, lagged_rate_c_per_min: Any = None,
                still_s: Any = None, time_since_start_s: Any = None,
                sustained_s: Any = None, swing_c: Any = None) -> tuple[str, ...]:
        """Why frames lie outside what the calibration was fitted on: their FPA temperatures
        (more than :data:`FPA_MARGIN_C` beyond the session's), their FPA rates (°C/min, where
        known: faster than :data:`RATE_MARGIN` times the session's fastest), their paces (with
        ``time_s``, s, one recording's: a memoryless method's paces the session never held,
        :meth:`unseen_paces`; or, given each frame's ``lagged_rate_c_per_min``, °C/min, taken
        from its recording, by its rate and lagged rate), their stillness (where the session's
        plateaus ended before the camera settled: the FPA held still longer than they held it,
        :meth:`still_excess`, from ``time_s`` or each frame's ``still_s``, s; or not known:
        still since their recording began, ``time_since_start_s`` s before, or NaN), for a
        memoryless method a pace held longer than the session held it
        (:meth:`sustained_excess`, from ``time_s`` or each frame's ``sustained_s``, s), for a
        method with memory a longer run of the FPA in one direction than the session's
        (:meth:`swing_excess`, from ``time_s`` or each frame's ``swing_c``, °C, signed), or
        their scene (its 1st–99th percentile beyond the blackbody's range); ``()`` inside."""
        reasons = []
        fpa = np.asarray(fpa_c, dtype=np.float64).reshape(-1)
        if rate_c_per_min is not None and self.report.paces and (
                lagged_rate_c_per_min is not None
                or (time_s is not None and np.size(rate_c_per_min) > 1)):
            rate, lagged, d = self._pace(rate_c_per_min, time_s, lagged_rate_c_per_min,
                                         fpa if fpa.size else None)
            unseen = d > self._pace_margin
            if unseen.any():
                k = int(np.argmax(unseen))
                count = _count(unseen)
                at = float(fpa[min(k, fpa.size - 1)]) if fpa.size else None
                reasons.append(self._pace_reason(rate[k], lagged[k], count=count, fpa=at))
            stays, excess = self._sustained(rate, time_s if lagged_rate_c_per_min is None
                                            else None, sustained_s)
            held_long = self._held_too_long(excess)
            if held_long.any():
                k = int(np.argmax(held_long))
                count = _count(held_long)
                reasons.append(self._sustained_reason(float(rate[min(k, rate.size - 1)]),
                                                      float(stays[k]), float(excess[k]),
                                                      count=count))
            swings, beyond = self._swings(
                fpa, rate, time_s if lagged_rate_c_per_min is None else None, swing_c)
            too_far = self._ran_too_far(beyond)
            if too_far.any():
                k = int(np.argmax(np.where(too_far, beyond, -1.0)))  # the farthest run
                reasons.append(self._swing_reason(float(swings[k]), float(beyond[k]),
                                                  count=_count(too_far)))
        elif rate_c_per_min is None and fpa.size and self.report.paces.get("fpa_cells"):
            # no rate (a recording too short to show it): taken as steady, as it is applied
            unseen = self._distance(np.zeros(fpa.size), np.zeros(fpa.size), fpa) \
                > self._pace_margin
            if unseen.any():
                k = int(np.argmax(unseen))
                count = _count(unseen)
                reasons.append(self._pace_reason(0.0, 0.0, count=count, fpa=float(fpa[k]),
                                                 unknown=True))
        if rate_c_per_min is not None and np.size(rate_c_per_min):
            fastest = float(np.max(np.abs(rate_c_per_min)))
            if fastest > RATE_MARGIN * self.max_rate_c_per_min + 0.05:
                reasons.append(f"the FPA changes at up to {fastest:.2f} °C/min, faster than the "
                               f"{self.max_rate_c_per_min:.2f} °C/min of the "
                               f"{self.report.method} calibration's chamber session")
        if still_s is not None or (time_s is not None and fpa.size):
            held, excess, unknown, _ = self._still(fpa, time_s, still_s, time_since_start_s,
                                                   rate_c_per_min)
            for beyond, reason in ((excess > 1.0, self._still_reason),
                                   (unknown, self._unknown_still_reason)):
                if np.any(beyond):
                    k = int(np.argmax(beyond))
                    count = _count(beyond)
                    at = float(fpa[min(k, fpa.size - 1)]) if fpa.size else None
                    reasons.append(reason(at, held[k], count=count))
        flo, fhi = self.report.fpa_range_c
        if fpa.size and (fpa.min() < flo - FPA_MARGIN_C or fpa.max() > fhi + FPA_MARGIN_C):
            reasons.insert(0, f"the FPA temperature {fpa.min():.1f}…{fpa.max():.1f} °C is "
                              f"outside the {flo:.1f}…{fhi:.1f} °C the {self.report.method} "
                              "calibration was fitted on")  # the plainest cause first
        lo, hi = self.report.scene_range_c
        p1, p99 = (float(v) for v in np.percentile(temps_c, [1, 99]))
        if p1 < lo - SCENE_MARGIN_C or p99 > hi + SCENE_MARGIN_C:
            reasons.append(f"the scene spans {p1:.1f}…{p99:.1f} °C, beyond the blackbody's "
                           f"{lo:.1f}…{hi:.1f} °C of its chamber session"
                           + self._fitted_fpa_note(fpa))
        return tuple(reasons)

    def _fitted_fpa_note(self, fpa: np.ndarray) -> str:
        """Where frames lie more than :data:`FITTED_FPA_NOTE_C` from the FPA temperatures the
        fit used (a two-point at one reference), that their FPA may be what misreads the scene;
        else ``""``."""
        if self.fitted_fpa_c is None or not fpa.size:
            return ""
        a, b = self.fitted_fpa_c
        away = max(a - float(fpa.min()), float(fpa.max()) - b, 0.0)
        if away <= FITTED_FPA_NOTE_C:
            return ""
        at = f"{a:.1f} °C" if b - a < 0.1 else f"{a:.1f}…{b:.1f} °C"
        return (f" (read through a fit made at FPA {at}, {away:.1f} °C from these frames': "
                f"their FPA, which {self.report.method} does not follow, may be what misreads "
                "the scene)")
