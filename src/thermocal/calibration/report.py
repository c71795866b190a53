"""How well a calibration will do: cross-validated on the chamber session it was fitted to.

:func:`cross_validate` refits a method with parts of the session left out and measures, on the
frames left out, the mean absolute error of the scene temperature it gives against the
blackbody's (radiance-equivalent) temperature, °C:

- *leave one set point out*: each blackbody set point in turn (the lowest and highest are
  extrapolations in the scene level, reported apart);
- *leave one FPA segment out*: the FPA range of the session cut into ``fpa_segments`` contiguous
  segments of equal width, each in turn (the two at the ends are extrapolations in the FPA
  temperature, reported apart).

``expected_mae_c``, the error to expect from the calibration within the ranges it covers, is the
mean error of every frame of the interior folds (the interpolations). A frame is scored in the
fold that left it out, through the method's own ``apply`` run over the whole session in time
order (``wolf2016``'s stream and ``lin``'s FPA rate need the recording whole): what the method
learns as frames stream by is not the truth, so it is no leak.

The refits run on a sample of the session: a mosaic of ``16`` pixel tiles spread over the frame
(every method's fit is per pixel, or uses the pixels' mean; tiles keep the neighbours that
``wolf2016``'s LMS and the bad-pixel filling look at) and at most ``max_frames`` frames, so that
a report costs a few seconds on a 160x120 session whatever the method.

The report (:class:`CalibrationReport`) also states the ranges the session covers (scene, FPA
temperature and FPA rate: the errors are measured at the FPA rates the session holds, so a
session whose FPA only rises says nothing of a falling one, and its report says so), the frames
the fit used and why it left the others out, and the protocol's warnings; it is stored in the
calibration file (``info["report"]``, JSON) and read back by :func:`report_of`.

A method with no memory of how the FPA changed also gets a warning when the session's ambient
plateaus ended before the camera settled (:func:`settling_warning`): its error, on the fit's own
frames, was still changing at their ends, so a camera held still for longer than they lasted
(its optics settling on) may be off by more than the report measured. Its report then states how
long the session's plateaus held the FPA still (:func:`stillness_of`), and frames held still for
longer are outside what it vouches for
(:class:`~thermocal.calibration.uncertainty.CalibrationSigma`).

:func:`fit_with_report` checks the protocol
(:func:`~thermocal.calibration.registry.check_session`), fits and cross-validates one method
(``thermocal calibrate``); :func:`auto_calibration`
cross-validates every method the session supports and keeps the one of lowest expected error
(``--method auto``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from functools import cache
from typing import Any

import numpy as np

from thermocal._validate import SATURATED_FRACTION, saturated_fraction
from thermocal.calibration.base import Calibration, ThermocalWarning, apply_with_rate
from thermocal.calibration.dataset import (
    ChamberData,
    fpa_change,
    fpa_pace,
    iter_frames,
    lagged_rate,
    prepare_chamber,
    recording_still_time,
    still_time,
)
from thermocal.errors import InvalidInputError, ThermocalError
from thermocal.io.chamber import ChamberSession

__all__ = [
    "CalibrationReport",
    "auto_calibration",
    "cross_validate",
    "fit_with_report",
    "frame_counts",
    "report_of",
    "sample_chamber",
]

#: Pixels the refits see by default: 16 tiles of 8x8 spread over the frame.
DEFAULT_PIXELS = 1024
#: Tiles of the pixel sample, per side.
TILES_PER_SIDE = 4
#: Frames the refits see at most (every k-th frame beyond: the FPA rates and stability classes
#: stay those of the whole session).
MAX_FRAMES = 2000
#: FPA segments left out in turn.
FPA_SEGMENTS = 4
#: Version of the report's layout in a calibration file.
REPORT_VERSION = 1


@dataclass(frozen=True)
class CalibrationReport:
    """A calibration's cross-validation and what its chamber session covered.

    Attributes
    ----------
    method : str
        The calibration method.
    expected_mae_c : float or None
        Mean absolute error to expect within the covered ranges, °C: the mean over every frame
        of the interior folds (None when no interior fold could be refitted; ``notes`` say why).
    folds : list of dict
        One per fold: ``kind`` (``"setpoint"`` or ``"fpa"``), ``held_out`` (the set point, °C,
        or the FPA segment ``[low, high]``, °C), ``extrapolation`` (an end fold), ``frames``
        (frames scored) and ``mae_c``, or ``error`` (why it could not be refitted); an end fold
        also has ``own_mae_c``, the MAE on its frames of the fit on the whole sample (its own
        error at that end: what σ takes there); one of a method fitted on the reference FPA's
        frames alone whose refit is the fit itself on its frames (within 1e-4 °C: the left-out
        frames were not the fit's) has ``fit_unchanged``. Each scored fold also has
        ``relative_mae`` (and an end fold ``own_relative_mae``): the mean over its frames of
        their error over the level σ gives them (their rate bin's σ, ``by_rate``, the overall
        σ outside every bin; for a memoryless method at least their ``by_change`` bin's above
        steady), what σ's curves are drawn from: where a fold errs more than its frames' paces
        explain.
    fpa_range_c, scene_range_c : (float, float)
        FPA temperatures and scene (radiance-equivalent) temperatures the session covers, °C.
    fpa_rate_c_per_min : (float, float)
        Lowest and highest FPA rate in the session, °C/min.
    frames : dict
        ``total``, ``used`` (by the fit), ``left_out`` (reason → count).
    sample : dict
        The refits' sample: ``pixels``, ``frames``.
    warnings : list of str
        What the protocol lacks for this method (the fit is degraded, not refused).
    notes : list of str
        Anything else worth knowing (folds that could not be refitted, ...).
    options : dict
        The options the method was fitted with (JSON values).
    ranking : list of dict
        ``--method auto``: every candidate, best first: ``method`` and ``expected_mae_c``, or
        ``refused`` (why it could not be fitted); empty otherwise.
    by_rate : list of dict
        The interior folds' MAE and σ by bin of the absolute FPA rate: ``rate_c_per_min`` (``[low,
        high]``, high None for the last), ``frames``, ``mae_c``, ``sigma_c``; for a memoryless
        method, by bin of the FPA's pace instead (``pace_c_per_min``:
        :func:`~thermocal.calibration.dataset.fpa_pace` through :data:`PACE_LAG_S`, so that its
        settled bin holds settled frames only); empty in a report made before it.
    sigma_c : float or None
        The σ that covers the interior folds' pixel errors as a Gaussian's would
        (:func:`coverage_sigma`), °C; None in a report made before it.
    paces : dict
        The FPA paces the session held: ``lag_s`` (:data:`PACE_LAG_S`), ``cell_c_per_min``
        (:data:`PACE_CELL_C_PER_MIN`) and ``cells``, the held cells ``[i, j]`` of the plane
        (FPA rate, the same through a lag of ``lag_s``) / ``cell_c_per_min`` (:func:`paces_of`:
        for a memoryless method those stayed in for a minute at a time, for the others every
        one visited),
        and ``margin_c_per_min``, how far from them a frame is still inside: a cell for a
        method whose model has no memory of how the FPA changed
        (:attr:`~thermocal.calibration.registry.CalibrationInfo.memoryless`),
        :data:`MEMORY_PACE_MARGIN_C_PER_MIN` for the others (empty for those in a report made
        before it);
        and, where the session's plateaus ended before the camera settled
        (:func:`settling_warning`), ``still``: how long its plateaus held the FPA still
        (:func:`stillness_of`); wherever its plateaus could be judged, ``settling``: the same
        and how fast the error still changed at their ends (:func:`settling_slope`,
        ``slope_c_per_min``, over ``window_s``), what σ of a camera held still longer takes
        (absent in a report made before it); ``fpa_sensitivity_c_per_c``, the scene °C one
        FPA °C is worth in the counts (:func:`fpa_sensitivity`; absent in a report made before
        it); for a memoryless method ``sustained``, how long it held each pace
        (:func:`sustained_of`), for one with memory ``swing``, how far its FPA ran one way
        without pause (:func:`swing_of`). Empty for the others and in a report made before it.
    by_time : list of dict
        For a method that learns as frames stream by (``wolf2016``'s LMS: it errs most at
        first; :attr:`~thermocal.calibration.registry.CalibrationInfo.learns_online`), the same
        by time since the session began (``time_s``: ``[low, high]`` s, :data:`TIME_EDGES`);
        empty for the others and in a report made before it.
    by_change : list of dict
        For a memoryless method, the same by how far the FPA's pace was from steady
        (``change_c_per_min``: :func:`~thermocal.calibration.dataset.fpa_change` through
        :data:`PACE_LAG_S`, ``[low, high]``, :data:`CHANGE_EDGES`): a pace bin pools frames
        just after a step with frames of a steady ramp at the same pace, and the first err
        more; empty for the others and in a report made before it.
    without_history : dict
        For a method whose model remembers how the FPA changed (``lin-lag``'s lagged rates) or
        learns it online (``wolf2016``), the interior folds' error on each frame taken alone,
        its lagged rates started steady at its own rate (or its estimate started afresh) as a
        recording too short to show its history starts them (:func:`frame_errors_alone`):
        ``sigma_c`` (:func:`coverage_sigma`), ``mae_c``, ``frames``, and ``lag_s``, the model's
        longest lag (one that learns online: :data:`ONLINE_START_S`), over which a recording's
        own history takes that start's place; for one that learns online also ``by_time``, its
        estimate begun afresh at each of the session's steps (:func:`cold_start_errors`) by time
        since then (``time_s`` ``[low, high]`` s, closed at :data:`COLD_START_SPAN_S`, with
        ``frames``, ``mae_c``, ``sigma_c``). Empty for the others and in a report made before
        it.
    """

    method: str
    expected_mae_c: float | None
    folds: list[dict[str, Any]]
    fpa_range_c: tuple[float, float]
    scene_range_c: tuple[float, float]
    fpa_rate_c_per_min: tuple[float, float]
    frames: dict[str, Any] = field(default_factory=dict)
    sample: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)
    ranking: list[dict[str, Any]] = field(default_factory=list)
    by_rate: list[dict[str, Any]] = field(default_factory=list)
    sigma_c: float | None = None
    by_time: list[dict[str, Any]] = field(default_factory=list)
    paces: dict[str, Any] = field(default_factory=dict)
    by_change: list[dict[str, Any]] = field(default_factory=list)
    without_history: dict[str, Any] = field(default_factory=dict)

    @property
    def extrapolated_mae_c(self) -> float | None:
        """Mean absolute error of the end folds' frames (the extrapolations), °C, or None."""
        done = [f for f in self.folds if f["extrapolation"] and f.get("mae_c") is not None]
        frames = sum(f["frames"] for f in done)
        return sum(f["mae_c"] * f["frames"] for f in done) / frames if frames else None

    def by_scene(self) -> list[dict[str, Any]]:
        """The set-point folds: MAE by scene level (``held_out``: the set point, °C)."""
        return [f for f in self.folds if f["kind"] == "setpoint"]

    def by_fpa(self) -> list[dict[str, Any]]:
        """The FPA folds: MAE by FPA temperature (``held_out``: the segment, °C)."""
        return [f for f in self.folds if f["kind"] == "fpa"]

    def to_dict(self) -> dict[str, Any]:
        """The report as JSON values (a calibration file's ``info["report"]``, ``--report``)."""
        return {
            "version": REPORT_VERSION,
            "method": self.method,
            "expected_mae_c": self.expected_mae_c,
            "fpa_range_c": list(self.fpa_range_c),
            "scene_range_c": list(self.scene_range_c),
            "fpa_rate_c_per_min": list(self.fpa_rate_c_per_min),
            "frames": self.frames,
            "mae_by_scene_c": [_row(f) for f in self.by_scene()],
            "mae_by_fpa_c": [_row(f) for f in self.by_fpa()],
            "mae_by_fpa_rate_c": self.by_rate,
            "expected_sigma_c": self.sigma_c,
            "mae_by_time_since_start_c": self.by_time,
            "mae_by_fpa_change_c": self.by_change,
            "without_history": self.without_history,
            "fpa_paces": self.paces,
            "sample": self.sample,
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "options": self.options,
            **({"auto_ranking": self.ranking} if self.ranking else {}),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CalibrationReport:
        """The report of :meth:`to_dict`; :class:`InvalidInputError` if it is not one."""
        try:
            folds = _folds_from([{"kind": "setpoint", **f} for f in d.get("mae_by_scene_c", [])]
                                + [{"kind": "fpa", **f} for f in d.get("mae_by_fpa_c", [])])
            mae = d["expected_mae_c"]
            return cls(
                method=str(d["method"]),
                expected_mae_c=None if mae is None else float(mae),
                folds=folds,
                fpa_range_c=_pair(d["fpa_range_c"]),
                scene_range_c=_pair(d["scene_range_c"]),
                fpa_rate_c_per_min=_pair(d["fpa_rate_c_per_min"]),
                frames=dict(d.get("frames", {})),
                sample=dict(d.get("sample", {})),
                warnings=[str(w) for w in d.get("warnings", [])],
                notes=[str(n) for n in d.get("notes", [])],
                options=dict(d.get("options", {})),
                ranking=[dict(r) for r in d.get("auto_ranking", [])],
                by_rate=_rate_bins_from(d.get("mae_by_fpa_rate_c") or []),
                sigma_c=None if d.get("expected_sigma_c") is None else float(
                    d["expected_sigma_c"]),
                by_time=[dict(r) for r in d.get("mae_by_time_since_start_c", [])],
                paces=_paces_from(d.get("fpa_paces") or {}),
                by_change=_change_bins_from(d.get("mae_by_fpa_change_c") or []),
                without_history=_without_history_from(d.get("without_history") or {}),
            )
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise InvalidInputError(f"not a calibration report ({type(exc).__name__}: "
                                    f"{str(exc)[:80]})") from None

    def summary_lines(self) -> list[str]:
        """The report in 3–4 lines for the terminal (its warnings apart)."""
        failed = [f for f in self.folds if f.get("mae_c") is None and not f["extrapolation"]]
        if self.expected_mae_c is None:
            extra = self.extrapolated_mae_c
            lines = [f"  expected error: not measured ({'; '.join(self.notes[:1]) or 'no fold'})"
                     + ("" if extra is None else f"; {extra:.2f} °C MAE on the extrapolations")]
        else:
            n_sp = sum(1 for f in self.by_scene() if not f["extrapolation"])
            n_fpa = sum(1 for f in self.by_fpa() if not f["extrapolation"])
            cannot = f", {len(failed)} of them not refittable" if failed else ""
            lines = [f"  expected error {self.expected_mae_c:.2f} °C MAE (cross-validated: {n_sp} "
                     f"set point(s) and {n_fpa} FPA segment(s) left out in turn{cannot})"]
        scene = _table(self.by_scene(), lambda f: f"{f['held_out']:g}")
        fpa = _table(self.by_fpa(), lambda f: f"{f['held_out'][0]:.1f}…{f['held_out'][1]:.1f}")
        lines.append(f"  MAE by set point °C: {scene}; by FPA °C: {fpa} (* extrapolated)")
        lo, hi = self.scene_range_c
        flo, fhi = self.fpa_range_c
        rlo, rhi = self.fpa_rate_c_per_min
        rates = [n for n in self.notes if n.startswith("the FPA never")]
        lines.append(f"  covers scene {lo:.1f}…{hi:.1f} °C, FPA {flo:.1f}…{fhi:.1f} °C at "
                     f"{rlo:+.2f}…{rhi:+.2f} °C/min" + (f" ({rates[0].split(' (')[0]}: errors "
                                                        "measured at these rates only)"
                                                        if rates else ""))
        cell = self.paces.get("cell_c_per_min")
        if self.paces and self.paces.get("margin_c_per_min", cell) <= cell:
            longest = _longest_stay(self.paces)
            lines.append(f"  held steadily at {_steady_paces(self.paces)} °C/min: {self.method} "
                         "has no memory of how the FPA changed, so frames at paces the session "
                         "never held" + (", or held longer than it held them (a changing FPA's "
                                         f"pace for {longest / 60:.1f} min at most)"
                                         if longest is not None else "")
                         + ", are refused (lin-lag follows the pace's history)")
        elif self.paces:
            from thermocal.calibration.registry import CALIBRATION_METHODS  # here: no cycle

            info = CALIBRATION_METHODS.get(self.method)
            online = info is not None and info.learns_online
            lines.append(f"  held steadily at {_steady_paces(self.paces)} °C/min: frames more "
                         f"than {self.paces['margin_c_per_min']:g} °C/min from the paces the "
                         "session held" + (", or changing the other way than it ever did,"
                                           if online else "")
                         + f" are refused ({self.method}'s lag terms were fitted on those "
                         "alone)")
        if self.paces.get("swing"):
            swing = self.paces["swing"]
            lines.append(f"  its FPA ran at most {swing['rise_c']:.1f} °C up and "
                         f"{swing['fall_c']:.1f} °C down without pause: frames whose FPA runs "
                         f"more than {swing['slack_c']:g} °C further are refused")
        if self.paces.get("still"):
            still = self.paces["still"]
            lines.append(f"  its {still['plateaus']} plateau(s) held the FPA still for "
                         f"{still['held_s'] / 60:.0f} min (median), before the camera "
                         "settled: frames held still for "
                         "longer are refused")
        if self.without_history:
            alone = self.without_history
            lines.append(f"  frames whose FPA history it cannot see (a recording's first "
                         f"{alone['lag_s'] / 60:.0f} min, a burst): {alone['mae_c']:.2f} °C MAE "
                         f"(σ {alone['sigma_c']:.2f}, fading over those minutes)")
            if alone.get("by_time"):
                cold = [b["sigma_c"] for b in alone["by_time"]]
                last = alone["by_time"][-1]["time_s"][1]
                lines.append(f"  its estimate begun afresh at a step: σ {min(cold):.2f}…"
                             f"{max(cold):.2f} °C over the first "
                             + (f"{last / 60:.0f} min" if last is not None else "minutes")
                             + " of a recording whose FPA changes")
        return lines


def _row(fold: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in fold.items() if k != "kind"}


def _pair(value: Any) -> tuple[float, float]:
    lo, hi = (float(v) for v in value)
    return lo, hi


def _table(folds: list[dict[str, Any]], label: Any) -> str:
    """``"10: 0.12*, 20: 0.08, ..."`` (``-``: the fold could not be refitted)."""
    if not folds:
        return "none"
    cells = []
    for f in folds:
        value = "-" if f.get("mae_c") is None else f"{f['mae_c']:.2f}"
        cells.append(f"{label(f)}: {value}{'*' if f['extrapolation'] else ''}")
    return ", ".join(cells)


def report_of(calibration: Calibration) -> CalibrationReport | None:
    """The report stored with a calibration (``info["report"]``), or None (an older file)."""
    stored = (getattr(calibration, "info", None) or {}).get("report")
    return None if stored is None else CalibrationReport.from_dict(stored)


# --------------------------------------------------------------------------------- sampling


def _tile_index(n: int, tiles: int, size: int) -> np.ndarray:
    """Indices of ``tiles`` runs of ``size`` spread evenly over ``0 … n−1`` (all of them when
    they would overlap)."""
    if tiles * size >= n:
        return np.arange(n)
    starts = np.round(np.linspace(0, n - size, tiles)).astype(np.int64)
    return (starts[:, None] + np.arange(size)[None]).ravel()


def sample_chamber(data: ChamberData, *, pixels: int = DEFAULT_PIXELS,
                   max_frames: int = MAX_FRAMES, chunk: int = 64
                   ) -> tuple[ChamberData, np.ndarray, np.ndarray]:
    """A small copy of a prepared session for refits, its saturated frames, and which frames of
    the session it holds.

    Returns the session reduced to a mosaic of ``TILES_PER_SIDE²`` tiles (about ``pixels``
    pixels in all, spread over the frame) and at most ``max_frames`` frames (every k-th), in
    memory, with the series of ``data`` (FPA rates and stability classes of the whole session);
    and a bool ``(M',)`` of its frames that are saturated (more than
    :data:`~thermocal._validate.SATURATED_FRACTION` of their pixels clipped: judged on the
    full-width rows through the tiles, about a tenth of the frame, and on the tiles), which no
    method applies to; and the indices ``(M',)`` of its frames in ``data``. Only those rows are
    read.
    """
    if pixels < 16:
        raise InvalidInputError(f"the report's pixel sample must be >= 16 pixels, got {pixels}")
    if max_frames < 2:
        raise InvalidInputError(f"the report's frame sample must be >= 2 frames, got {max_frames}")
    h, w = data.frame_shape
    side = max(1, int(math.sqrt(pixels)) // TILES_PER_SIDE)
    rows = _tile_index(h, TILES_PER_SIDE, side)
    cols = _tile_index(w, TILES_PER_SIDE, side)
    step = -(-data.n_frames // max_frames)
    index = np.arange(0, data.n_frames, step)
    s = data.session
    bit_depth = s.bit_depth
    crop = np.empty((index.size, rows.size, cols.size), dtype=np.uint16)
    saturated = np.zeros(index.size, dtype=bool)
    pos = 0
    for _, band in iter_frames(s, index, chunk=chunk, rows=rows):  # the tiles' rows alone
        k = len(band)
        tiles = band[:, :, cols]
        crop[pos:pos + k] = tiles
        saturated[pos:pos + k] = np.maximum(saturated_fraction(band, bit_depth),
                                            saturated_fraction(tiles, bit_depth)) \
            > SATURATED_FRACTION  # the frame's (its rows through the tiles), or the sample's
        pos += k

    def sub(series: np.ndarray | None) -> np.ndarray | None:
        return None if series is None else np.asarray(series)[index]

    session = ChamberSession(crop, blackbody_c=s.blackbody_c[index], fpa_c=s.fpa_c[index],
                             time_s=s.time_s[index], housing_c=sub(s.housing_c),
                             ambient_c=sub(s.ambient_c), attrs=dict(s.attrs))
    small = replace(data, session=session, scene_c=data.scene_c[index], fpa_c=data.fpa_c[index],
                    time_s=data.time_s[index],
                    fpa_rate_c_per_min=data.fpa_rate_c_per_min[index],
                    stability=data.stability[index], block=data.block[index],
                    usable=data.usable[index], info=dict(data.info))
    return small, saturated, index


# --------------------------------------------------------------------------------- folds


def setpoint_folds(data: ChamberData) -> list[tuple[dict[str, Any], np.ndarray]]:
    """Leave-one-set-point-out folds: ``(description, frames held out (M,) bool)`` for each set
    point of the usable frames; the lowest and highest are extrapolations."""
    bb = np.round(data.session.blackbody_c, 6)
    points = data.setpoints_c
    return [({"kind": "setpoint", "held_out": float(p),
              "extrapolation": bool(i in (0, points.size - 1))}, data.usable & (bb == p))
            for i, p in enumerate(points)]


def fpa_folds(data: ChamberData, segments: int = FPA_SEGMENTS
              ) -> list[tuple[dict[str, Any], np.ndarray]]:
    """Leave-one-FPA-segment-out folds: the usable frames' FPA range cut into ``segments``
    contiguous segments of equal width; the two at the ends are extrapolations. Empty when the
    FPA spans less than 0.5 °C per segment."""
    fpa = data.fpa_c[data.usable]
    if fpa.size == 0:
        return []
    lo, hi = float(fpa.min()), float(fpa.max())
    if hi - lo < 0.5 * segments:
        return []
    edges = np.linspace(lo, hi, segments + 1)
    which = np.clip(np.searchsorted(edges, data.fpa_c, side="right") - 1, 0, segments - 1)
    return [({"kind": "fpa", "held_out": [float(edges[i]), float(edges[i + 1])],
              "extrapolation": bool(i in (0, segments - 1))}, data.usable & (which == i))
            for i in range(segments)]


# --------------------------------------------------------------------------------- scoring


def frame_errors(calibration: Calibration, data: ChamberData, scored: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The absolute error of each pixel of the ``scored`` frames of ``data`` (°C, ``(M, P)``,
    NaN in the frames not scored) and each frame's mean of it (``(M,)``): ``calibration``
    applied to those frames, in time order, as one recording, against ``data.scene_c``."""
    pixels = int(np.prod(data.frame_shape))
    out = np.full((data.n_frames, pixels), np.nan, dtype=np.float32)
    idx = np.flatnonzero(scored)
    if idx.size == 0:
        return out, np.full(data.n_frames, np.nan)
    out[idx] = _pixel_errors(_applied(calibration, data, idx), data, idx)
    return out, out.mean(axis=1, dtype=np.float64)


def _pixel_errors(est: np.ndarray, data: ChamberData, idx: np.ndarray) -> np.ndarray:
    """The absolute error of each pixel of ``est`` (°C ``(M, H, W)``, the frames ``idx`` of
    ``data`` through a calibration) against ``data.scene_c``, °C ``(M, P)``."""
    return np.abs(est - data.scene_c[idx, None, None].astype(np.float32)).reshape(idx.size, -1)


#: The end of an ambient plateau whose error trend says whether the camera had settled, s; a
#: plateau needs 1.5 times it to be judged.
SETTLE_WINDOW_S = 480.0
#: An ambient plateau: the chamber's temperature within this of where the plateau ended, °C.
PLATEAU_BAND_C = 0.25
#: An error still changing by more than this at the plateaus' ends (median over them), °C/min:
#: the camera had not settled. Set between the two camera families on the physics suite's
#: 20-minute steps: `polynomial`, `lin`, `lin-level` −0.03…0.00 on `tau2`, +0.08…+0.12 on
#: `boson` (whose optics lag by a second-order response).
SETTLE_SLOPE_C_PER_MIN = 0.05
#: The same for a method with memory of the FPA's history (``lin-lag``, ``wolf2016``), °C/min:
#: its terms follow the settling the session showed, so an error still changing at all is a
#: state beyond them. Its σ is small (``lin-lag`` 0.06 °C on ``tau2``): the memoryless
#: threshold would pass drifts that leave a settled camera several σ off. A helper's map of
#: silent frames (``benchmarks/silent_map.py``, ambient steps of 19-min plateaus): ``lin-lag``
#: on ``tau2`` drifted −0.007 °C/min at their ends and read a camera held at 25 °C ambient for
#: 2 h −0.12 °C off where σ said 0.07 (60 % within 2σ); ``wolf2016`` on ``boson`` −0.032,
#: and −1.4…−2.2 °C off where σ said 0.9 (41 frames silent). The physics suite's 20-min
#: plateaus (three units each): ``lin-lag`` on ``tau2`` −0.002…0.000 (settled, and covered),
#: on ``boson`` +0.020…+0.025; ``wolf2016`` +0.06…+0.07 and −0.008…−0.022.
SETTLE_SLOPE_MEMORY_C_PER_MIN = 0.005


def plateau_ends(data: ChamberData, scored: np.ndarray) -> list[np.ndarray]:
    """The ``scored`` frames (indices) of the last :data:`SETTLE_WINDOW_S` of each ambient
    plateau of ``data``: a run over which the chamber's ``ambient_c`` stays within
    :data:`PLATEAU_BAND_C` of where it ended (a set point, or a logged temperature with its
    noise), at least 1.5 times that long, within one recording; none without an ambient
    series."""
    ambient = data.session.ambient_c
    if ambient is None:
        return []
    amb, t = np.asarray(ambient, dtype=np.float64), data.time_s
    ends, last = [], amb.size - 1
    while last >= 0:  # by hand: each run is judged from where it ended, backwards
        first = last
        while (first > 0 and abs(amb[first - 1] - amb[last]) <= PLATEAU_BAND_C
               and t[first] - t[first - 1] <= SETTLE_WINDOW_S):
            first -= 1
        run = np.arange(first, last + 1)
        if t[last] - t[first] >= 1.5 * SETTLE_WINDOW_S:
            end = run[(t[run] >= t[last] - SETTLE_WINDOW_S) & scored[run]]
            if end.size >= 5:
                ends.append(end)
        last = first - 1
    return ends[::-1]


def settling_slope(calibration: Calibration, data: ChamberData, ends: list[np.ndarray], *,
                   memoryless: bool = True) -> float | None:
    """How fast ``calibration``'s error was still changing at the session's plateaus' ends,
    °C/min (None without one): the slope of its signed mean error in time over each of
    ``ends`` (:func:`plateau_ends` of ``data``), fitted beside a quadratic in the blackbody's
    temperature (the error depends on the scene level, and the set points cycle), median over
    the plateaus; ``memoryless``: each plateau's end applied alone, else (a method with memory
    of the FPA's history) the session's frames applied in time order, each end with the
    history that led to it."""
    if not ends:
        return None
    if not memoryless:
        scored = np.unique(np.concatenate(ends))
        signed = np.full(data.n_frames, np.nan)
        signed[scored] = _signed_in_order(calibration, data, scored)
    slopes = []
    for end in ends:
        err = _signed_errors(calibration, data, end) if memoryless else signed[end]
        minutes = (data.time_s[end] - data.time_s[end[0]]) / 60.0
        level = (data.scene_c[end] - data.scene_c[end].mean()) / 50.0
        design = np.stack([minutes, np.ones(end.size), level, level**2], axis=1)
        slopes.append(float(np.linalg.lstsq(design, err, rcond=None)[0][0]))
    return float(np.median(slopes))


def settling_warning(slope: float | None, plateaus: int, method: str, *,
                     memoryless: bool = True) -> str | None:
    """The warning that the session's ``plateaus`` ended before the camera settled, or None:
    their :func:`settling_slope` (°C/min) beyond :data:`SETTLE_SLOPE_C_PER_MIN` or, for a
    method with memory of the FPA's history, :data:`SETTLE_SLOPE_MEMORY_C_PER_MIN`."""
    limit = SETTLE_SLOPE_C_PER_MIN if memoryless else SETTLE_SLOPE_MEMORY_C_PER_MIN
    if slope is None or abs(slope) <= limit:
        return None
    return (f"the session's plateaus ended before the camera settled: {method}'s error was "
            f"still changing by {slope:+.{2 if memoryless else 3}f} °C/min over their last "
            f"{SETTLE_WINDOW_S / 60:.0f} min (median of {plateaus} plateaus); "
            f"{settling_cause(memoryless)}, it may be off by more than its σ once a camera has "
            "held still longer than they lasted: record plateaus long enough for this error to "
            f"stop changing{settling_alternative(memoryless)}")


def settling_cause(memoryless: bool) -> str:
    """Why a calibration cannot vouch for a camera held still longer than its session's
    unsettled plateaus, in words (a refusal's middle)."""
    return ("with no memory of how the FPA changed" if memoryless else
            "since its terms for the FPA's history never saw the camera settle")


def settling_alternative(memoryless: bool) -> str:
    """The other remedy for an unsettled session: lin-lag, which follows the settling, for a
    memoryless method; none for one with memory (it already follows what the session showed)."""
    return ", or use lin-lag, which follows the settling" if memoryless else ""


def _signed_in_order(calibration: Calibration, data: ChamberData, scored: np.ndarray
                     ) -> np.ndarray:
    """The signed mean error (°C ``(len(scored),)``) of the frames ``scored`` (indices, in time
    order) of ``data`` through ``calibration`` applied to its usable frames up to the last of
    them, in time order: what a method with memory of the FPA's history gives them after that
    history."""
    run = np.flatnonzero(data.usable)
    run = np.union1d(run[run <= scored[-1]], scored)
    err = _signed_errors(calibration, data, run)
    return err[np.searchsorted(run, scored)]


def _signed_errors(calibration: Calibration, data: ChamberData, idx: np.ndarray) -> np.ndarray:
    """Frames ``idx`` of ``data`` through ``calibration``: each one's mean less the blackbody's
    temperature, °C ``(len(idx),)``."""
    est = _applied(calibration, data, idx)
    return est.reshape(idx.size, -1).mean(axis=1, dtype=np.float64) - data.scene_c[idx]


def _applied(calibration: Calibration, data: ChamberData, idx: np.ndarray) -> np.ndarray:
    """Frames ``idx`` of ``data`` through ``calibration``, as one recording in time order, °C
    ``(len(idx), H, W)``; its range warnings silenced (refits applied outside their range, a
    plateau at the range's end)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ThermocalWarning)
        return calibration.apply(np.asarray(data.session.frames[idx]), fpa_c=data.fpa_c[idx],
                                 time_s=data.time_s[idx])


#: Frame times, s, that make each frame a recording of its own: a lag's state keeps
#: exp(−1e9 / τ) = 0 of the frame before, so the lagged rates start steady at the frame's rate.
_APART_S = 1e9


def frame_errors_alone(calibration: Calibration, data: ChamberData, scored: np.ndarray, *,
                       learns_online: bool = False) -> np.ndarray:
    """The absolute error of each pixel of the ``scored`` frames of ``data`` (°C, ``(M, P)``
    for the M scored frames) with each frame taken alone, at its own FPA rate: what a model
    that remembers the FPA's rates (lin-lag's lags) gives a recording too short to show its
    history, which starts its lagged rates steady at the present one. ``learns_online``: each
    frame in a call of its own (an online estimate carries its state from frame to frame of
    one call, whatever their times: wolf2016's LMS), its estimate begun afresh at it."""
    idx = np.flatnonzero(scored)
    frames = np.asarray(data.session.frames[idx])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ThermocalWarning)
        if learns_online:
            est = np.concatenate([
                apply_with_rate(calibration, frames[k : k + 1], fpa_c=data.fpa_c[idx[k : k + 1]],
                                time_s=np.zeros(1),
                                fpa_rate_c_per_min=data.fpa_rate_c_per_min[idx[k : k + 1]])
                for k in range(idx.size)]) if idx.size else frames.astype(np.float32)
        else:
            est = apply_with_rate(calibration, frames, fpa_c=data.fpa_c[idx],
                                  time_s=np.arange(idx.size) * _APART_S,
                                  fpa_rate_c_per_min=data.fpa_rate_c_per_min[idx])
    return _pixel_errors(est, data, idx)


def coverage_sigma(abs_errors: np.ndarray) -> float:
    """The σ that best covers ``abs_errors`` (°C, any shape) as a Gaussian's would: the one
    whose shares of errors within 1σ and 2σ come closest (least squares) to 68.3 % and 95.4 %.

    Errors are seldom Gaussian (a calibration errs most in a few frames: the FPA changing, a set
    point far from the others); √(π/2)·MAE then states a σ that covers too much at 1σ and too
    little at 2σ. This one balances the two."""
    e = np.sort(np.asarray(abs_errors, dtype=np.float64).ravel())
    e = e[np.isfinite(e)]
    if e.size == 0:
        return math.nan
    candidates = np.geomspace(max(float(np.quantile(e, 0.05)), 1e-4),
                              max(float(e[-1]), 1e-3), 400)
    within = lambda k: np.searchsorted(e, k * candidates, side="right") / e.size  # noqa: E731
    loss = (within(1.0) - 0.6827) ** 2 + (within(2.0) - 0.9545) ** 2
    return float(candidates[int(np.argmin(loss))])


def _fit(data: ChamberData, method: str, options: dict[str, Any]) -> Calibration:
    from thermocal.calibration.registry import CALIBRATION_METHODS

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ThermocalWarning)
        return CALIBRATION_METHODS[method].fit(data, **options)


def fixed_reference(calibration: Calibration, method: str) -> dict[str, float]:
    """The reference FPA temperature of a fit as the option that fixes it in a refit
    (``fpa_ref_c``), for the methods that take one; ``{}`` for the others."""
    from thermocal.calibration.registry import CALIBRATION_METHODS

    if not CALIBRATION_METHODS[method].takes_fpa_ref:
        return {}
    ref = getattr(calibration, "fpa_ref_c", None)
    if ref is None:
        ref = getattr(calibration, "t_ref_c", None)
    return {} if ref is None else {"fpa_ref_c": float(ref)}


def cross_validate(
    session: Any,
    method: str,
    *,
    calibration: Calibration | None = None,
    fpa_segments: int = FPA_SEGMENTS,
    pixels: int = DEFAULT_PIXELS,
    max_frames: int = MAX_FRAMES,
    counts: dict[str, Any] | None = None,
    protocol_warnings: list[str] | None = None,
    **options: Any,
) -> CalibrationReport:
    """Cross-validate calibration ``method`` on a chamber session.

    Parameters
    ----------
    session : ChamberData, ChamberSession or path
        The chamber session the calibration is fitted to.
    method : str
        A key of :data:`~thermocal.calibration.registry.CALIBRATION_METHODS`.
    calibration : Calibration, optional
        The fit on the whole session; its reference FPA temperature is kept in every refit
        (default: that of a fit on the sample).
    fpa_segments : int
        FPA segments left out in turn (>= 3: two ends and an interior).
    pixels, max_frames : int
        Size of the refits' sample (:func:`sample_chamber`).
    counts : dict, optional
        The fit's frame counts (:func:`frame_counts`) for the report.
    protocol_warnings : list of str, optional
        The protocol's warnings for this method, for the report.
    **options
        The method's fitting options.

    Returns
    -------
    CalibrationReport
    """
    if fpa_segments < 3:
        raise InvalidInputError(f"fpa_segments must be >= 3, got {fpa_segments}")
    data = prepare_chamber(session)
    if not data.usable.any():
        raise InvalidInputError("the chamber session has no usable frame to cross-validate")
    small, saturated, index = sample_chamber(data, pixels=pixels, max_frames=max_frames)
    scorable = small.usable & ~saturated
    notes: list[str] = []
    options = dict(options)
    if options.get("frame_mask") is not None:  # polynomial: a mask of the session's frames
        mask = np.asarray(options["frame_mask"], dtype=bool)
        if mask.shape != (data.n_frames,):
            raise InvalidInputError(f"frame_mask: expected {(data.n_frames,)}, got {mask.shape}")
        options["frame_mask"] = mask[index]
    if calibration is None:
        calibration = _fit(small, method, options)
    refit_options = options | fixed_reference(calibration, method)
    errors: list[np.ndarray] = []  # per-frame errors of the interior folds
    rates: list[np.ndarray] = []  # and their frames' FPA rates (or paces), °C/min
    changes: list[np.ndarray] = []  # and how far from steady their paces were, °C/min
    since: list[np.ndarray] = []  # and their time since the session began, s
    from thermocal.calibration.registry import CALIBRATION_METHODS

    folds = []
    # (fold, its frames' errors, its frames, the fit's own errors there): each fold scored
    scored_folds: list[tuple[int, np.ndarray, np.ndarray, np.ndarray | None]] = []
    # an end fold also scores the fit on all the sample's frames there (its own error at that
    # end, where a refit without them extrapolates); a method fitted on the reference FPA's
    # frames alone keeps its fit when an end FPA segment without them is left out: that fold
    # then measures the fit's own error there (see below)
    at_reference = CALIBRATION_METHODS[method].needs.frames == "reference"
    # a memoryless method's error follows how fast the FPA has been changing, not its present
    # rate alone (what lags the FPA catches up after the rate is 0): its bins are by pace
    memoryless = CALIBRATION_METHODS[method].memoryless
    online = CALIBRATION_METHODS[method].learns_online
    # a model that remembers the FPA's rates (lin-lag's lags), or learns its FPA terms online
    # (wolf2016's LMS): its error on frames whose history it cannot see, measured too (a short
    # recording's; for one that learns online, a recording begun while its FPA changed, a
    # start its session, begun settled, never showed)
    lags = tuple(getattr(calibration, "rate_lags_s", ()) or ())
    remembers = not memoryless and (bool(lags) or online)
    alone: list[np.ndarray] = []  # the interior folds' pixel errors, each frame alone
    rate_key = "pace_c_per_min" if memoryless else "rate_c_per_min"
    binned_rate = (fpa_pace(small.fpa_rate_c_per_min, small.time_s, PACE_LAG_S) if memoryless
                   else small.fpa_rate_c_per_min)
    change = (fpa_change(small.fpa_rate_c_per_min, small.time_s, PACE_LAG_S) if memoryless
              else None)
    # the fit on the sample, all its frames, and its pixel errors: made once, when first needed
    # (by the end folds' check and the settling check)
    sample_fit = cache(lambda: _fit(small, method, refit_options))
    own_errors = cache(lambda: frame_errors(sample_fit(), small, scorable)[0])
    for desc, held in setpoint_folds(small) + fpa_folds(small, fpa_segments):
        held = held & scorable
        if not held.any():
            continue
        try:
            cal = _fit(replace(small, usable=small.usable & ~held), method, refit_options)
            pix, err = frame_errors(cal, small, scorable)
            pix, err = pix[held], err[held]
            if not np.all(np.isfinite(err)):
                raise InvalidInputError("the refit gives non-finite temperatures")
        except ThermocalError as exc:
            folds.append(desc | {"frames": int(held.sum()), "mae_c": None,
                                 "error": " ".join(str(exc).split())[:200]})
            continue
        if desc["extrapolation"]:  # the fit's own error there (on the sample, all frames)
            try:
                own = own_errors()[held]
            except ThermocalError:
                own = None  # no fit on the sample: the folds' notes say why
            if own is not None:
                desc = desc | {"own_mae_c": float(np.mean(own))}
                if at_reference and np.allclose(pix, own, rtol=0.0, atol=1e-4,
                                                equal_nan=True):
                    desc = desc | {"fit_unchanged": True}
        folds.append(desc | {"frames": int(held.sum()), "mae_c": float(np.mean(err))})
        scored_folds.append((len(folds) - 1, err, np.flatnonzero(held),
                             own_errors()[held].mean(axis=1) if "own_mae_c" in desc else None))
        if not desc["extrapolation"]:
            errors.append(pix)
            if remembers:
                alone.append(frame_errors_alone(cal, small, held, learns_online=online))
            rates.append(binned_rate[held])
            if change is not None:
                changes.append(change[held])
            since.append(small.time_s[held] - small.time_s[0])
    failed = [f for f in folds if f.get("mae_c") is None and not f["extrapolation"]]
    if failed:
        notes.append(f"{len(failed)} interior fold(s) could not be refitted without their "
                     f"frames ({failed[0]['error']})")
    expected = float(np.mean(np.concatenate(errors))) if errors else None
    sigma = coverage_sigma(np.concatenate(errors)) if errors else None
    by_rate = (_by_rate(np.concatenate(errors), np.concatenate(rates), rate_key) if errors
               else [])
    by_time = (_binned(np.concatenate(errors), np.concatenate(since), TIME_EDGES, "time_s",
                       min_frames=MIN_BIN_FRAMES)
               if errors and CALIBRATION_METHODS[method].learns_online else [])
    by_change = (_binned(np.concatenate(errors), np.concatenate(changes), CHANGE_EDGES,
                         "change_c_per_min", min_frames=MIN_BIN_FRAMES)
                 if errors and memoryless else [])
    if by_rate:  # each fold's error relative to its frames' level: where, not how fast
        # the level σ gives them (CalibrationSigma.rate_sigma, change_sigma): their rate bin's
        # σ, the overall σ outside every bin, at least the σ of a change bin above steady
        level = bins_sigma(np.abs(binned_rate), by_rate, rate_key, outside=sigma)
        if by_change:
            level = np.fmax(level, bins_sigma(
                change, [b for b in by_change if b["change_c_per_min"][0] > 0],
                "change_c_per_min", outside=math.nan))
        for k, err, frames, own in scored_folds:
            ratio = _relative(err, level[frames])
            if ratio is not None:
                folds[k] = folds[k] | {"relative_mae": ratio}
                if own is not None and (own_ratio := _relative(own, level[frames])) is not None:
                    folds[k] = folds[k] | {"own_relative_mae": own_ratio}
    without_history = ({"sigma_c": coverage_sigma(np.concatenate(alone)),
                        "mae_c": float(np.mean(np.concatenate(alone))),
                        "lag_s": max(lags) if lags else ONLINE_START_S,
                        "frames": int(sum(len(a) for a in alone))} if alone else {})
    ends = plateau_ends(small, scorable)
    if without_history and online:
        # its estimate begun afresh at each step: how its error fades after a cold start
        try:
            cold, cold_since = cold_start_errors(sample_fit(), small, scorable, ends)
        except ThermocalError:
            cold = None  # no fit on the sample: the folds' notes say why
        if cold is not None and cold.size:
            # closed at the span measured: beyond it, the fade of frames alone
            without_history["by_time"] = _binned(
                cold, cold_since, (*[e for e in TIME_EDGES if e < COLD_START_SPAN_S],
                                   COLD_START_SPAN_S), "time_s", min_frames=MIN_BIN_FRAMES)
    if expected is None:
        notes.append("no interior set point or FPA segment could be left out and refitted")
    paces = paces_of(data, memoryless=memoryless)
    sensitivity = fpa_sensitivity(small, scorable)
    if paces and sensitivity is not None:
        paces = paces | {"fpa_sensitivity_c_per_c": sensitivity}
    found = list(protocol_warnings or [])
    if ends:
        try:
            slope = settling_slope(sample_fit(), small, ends, memoryless=memoryless)
        except ThermocalError:
            slope = None  # no fit on the sample: the folds' notes say why
        settling = settling_warning(slope, len(ends), method, memoryless=memoryless)
        # how long the plateaus held the FPA still, from the whole session's FPA series (the
        # sample keeps every k-th frame: a stillness at another frame rate than a recording's)
        still = stillness_of(data, [index[end] for end in ends]) if slope is not None else {}
        if still:  # how far the error was still changing, whether or not it is refused
            paces = paces | {"settling": still | {"slope_c_per_min": slope,
                                                  "window_s": SETTLE_WINDOW_S}}
        if still and settling:
            settling += (f" (frames held still longer than {still['held_s'] / 60:.1f} min, the "
                         "median of the plateaus, are refused; --force gives them with σ grown)")
            paces = paces | {"still": still}
        found += [settling] if settling else []
    usable = data.usable
    scene = data.scene_c[usable]
    rate = data.fpa_rate_c_per_min[usable]
    fpa = data.fpa_c[usable]
    notes.extend(_rate_notes(data, rate))
    return CalibrationReport(
        method=method,
        expected_mae_c=expected,
        folds=folds,
        fpa_range_c=(float(fpa.min()), float(fpa.max())),
        scene_range_c=(float(scene.min()), float(scene.max())),
        fpa_rate_c_per_min=(float(rate.min()), float(rate.max())),
        frames=dict(counts or {}),
        sample={"pixels": int(small.frame_shape[0] * small.frame_shape[1]),
                "frames": int(small.n_frames)},
        warnings=found,
        notes=notes,
        options=_json_options(options),
        by_rate=by_rate,
        sigma_c=sigma,
        by_time=by_time,
        paces=paces,
        by_change=by_change,
        without_history=without_history,
    )


#: The lag through which a frame's FPA rate tells the pace it has been changing at, s (the
#: longest lag of ``lin-lag``'s rate terms: what lags the FPA by minutes).
PACE_LAG_S = 480.0
#: How long an estimate learned online and begun afresh (a frame alone, a recording whose FPA
#: changes soon after it began) keeps the error of one, s (:attr:`CalibrationReport.
#: without_history`'s ``lag_s`` for ``wolf2016``): the pace lag, as for lin-lag's lags. A
#: helper's map, ``benchmarks/silent_map.py``: `wolf2016` on `boson` read clips begun settled
#: +4…+5.6 °C off where σ said 1.1–2.5 when an ambient step came in their first minute (for
#: 3 min), and the first frame of clips begun in a 0.25 °C/min rise −3 °C where σ said 1.3;
#: its frames alone err 2.7 °C MAE (σ 3.3).
ONLINE_START_S = PACE_LAG_S
#: Cells of the (FPA rate, lagged FPA rate) plane that :attr:`CalibrationReport.paces` marks as
#: held, °C/min a side.
PACE_CELL_C_PER_MIN = 0.1
#: How long a session must stay in a cell of :data:`PACE_CELL_C_PER_MIN` for its pace to be
#: held by a memoryless method, s (the FPA rate's smoothing window,
#: :data:`~thermocal.calibration.dataset.RATE_SMOOTH_S`): a step's steep rise passes through
#: paces in seconds, which no fold measured a camera staying at. `lin-level` on `boson`,
#: fitted on ambient steps and forced on a sawtooth: its first rise from a settled start stayed
#: 2–5 min at paces the steps had passed through in 10–50 s (1–5 frames) and erred
#: 1.0–2.1 °C where σ said 0.22–0.33 (42 frames silent; 10 with the dwell, a Gaussian σ's
#: share 24: ``benchmarks/forced_paces.py``).
PACE_DWELL_S = 60.0
#: How far a memoryless method's FPA rate may stray from its present pace and still hold it
#: (:func:`pace_stays`), °C/min: a cell of :data:`PACE_CELL_C_PER_MIN`.
SUSTAIN_BAND_C_PER_MIN = PACE_CELL_C_PER_MIN
#: How much longer than its chamber session held any pace within a cell of it a recording may
#: hold a pace before a memoryless method's frames are outside, s (``sustained``: a pace held
#: for minutes brings what lags the FPA to a state the session's steps, whose rises pass
#: through each pace in a minute or two, never showed). A helper's map of silent frames:
#: `polynomial` on `tau2` fitted on ambient steps erred 1.0–1.2 °C where σ said 0.46–0.53,
#: 14–23 min into a steady 0.5 °C/min rise (a pace the steps held 1.5–3 min); `lin-level` on
#: `boson` 1.0–1.6 °C where σ said 0.18–0.38 over a 0.25 °C/min rise. Two minutes: what the
#: rate's own smoothing (:data:`~thermocal.calibration.dataset.RATE_SMOOTH_S`) and noise can
#: lengthen a stay by, twice.
SUSTAIN_SLACK_S = 120.0
#: How far (°C/min, Chebyshev, beyond the nearest held cell's half-width) a method *with*
#: memory of the FPA's pace (``lin-lag``, ``wolf2016``) may be taken from the paces its session
#: held. Its lag terms follow a pace's history, but their form was fitted on the session's
#: paces alone: on the ``boson`` preset, whose optics lag in another form than the model's,
#: ``lin-lag``'s error on a held-out 1 °C/min sawtooth grows with the distance of its turns
#: from the session's cells (steps and a 1.5 °C/min sawtooth: MAE 0.09 °C at the cells, 0.23 °C
#: 0.2–0.4 °C/min away), on ``tau2`` not at all (0.07 °C throughout). No fold of the session
#: can tell the two apart (refitted without its sawtooth, lin-lag errs 2–4 °C on it, on both).
#: Chosen on the coverage benchmark's held-out runs (five units of each family): 0.3 °C/min
#: refuses 13–15 % of ``boson``'s frames and 0–4 % of ``tau2``'s; 0.4 refuses none and leaves
#: ``boson`` at 90–94 % within 2σ.
MEMORY_PACE_MARGIN_C_PER_MIN = 0.3


def paces_of(data: ChamberData, *, memoryless: bool = True) -> dict[str, Any]:
    """The paces a session's usable frames held (:attr:`CalibrationReport.paces`): each frame's
    FPA rate ``r`` and the same through a first-order lag of :data:`PACE_LAG_S`, ``y``
    (:func:`~thermocal.calibration.dataset.lagged_rate`), binned in cells of
    :data:`PACE_CELL_C_PER_MIN`: for a ``memoryless`` method those the session stayed in, or
    within a cell of, for :data:`PACE_DWELL_S` at a time (:func:`_longest_stays`; all it
    visited where it stayed that long nowhere), for one
    with memory all it visited (its lag terms follow a history through the paces it passes:
    kept to the cells of long stays, `lin-lag` and `wolf2016` refused 22 % of the coverage
    benchmark's held-out `tau2` frames and 33–37 % of `boson`'s, against 0.1 % and 14–19 %,
    where none of theirs was silent). A steady pace has ``y = r``; a pace just changed,
    ``y ≠ r``. ``margin_c_per_min``: how far from them a frame's pace may lie, one cell for a
    ``memoryless`` method, :data:`MEMORY_PACE_MARGIN_C_PER_MIN` for one with memory. For a
    memoryless method also how long the session held each pace (``sustained``,
    :func:`sustained_of`); for one with memory, how far the FPA ran in one direction without
    pause (``swing``, :func:`swing_of`)."""
    use = data.usable
    y = lagged_rate(data.fpa_rate_c_per_min, data.time_s, PACE_LAG_S)
    points = np.stack([data.fpa_rate_c_per_min, y], axis=1)[use] / PACE_CELL_C_PER_MIN
    plane = np.round(points).astype(np.int64)
    cells, which = np.unique(plane, axis=0, return_inverse=True)
    which = which.reshape(-1)
    held = (_longest_stays(points, data.time_s[use], cells) >= PACE_DWELL_S if memoryless
            else np.ones(len(cells), dtype=bool))
    if not held.any():  # a session too short to stay anywhere that long: what it visited
        held[:] = True
    out = {"lag_s": PACE_LAG_S, "cell_c_per_min": PACE_CELL_C_PER_MIN,
           "cells": cells[held].tolist(),
           "margin_c_per_min": (PACE_CELL_C_PER_MIN if memoryless
                                else MEMORY_PACE_MARGIN_C_PER_MIN)}
    if memoryless:  # where (at which FPA temperatures) each pace was held, and how long
        fpa = np.floor(data.fpa_c[use] / PACE_FPA_CELL_C).astype(np.int64)[:, None]
        kept = held[which]
        out |= {"fpa_cell_c": PACE_FPA_CELL_C, "fpa_reach_c": PACE_FPA_REACH_C,
                "fpa_cells": np.unique(np.hstack([plane, fpa])[kept], axis=0).tolist()}
        stays = sustained_of(data)
        if stays["held_s"]:  # none without usable frames: nothing to hold a recording to
            out["sustained"] = stays
    elif data.usable.any():
        out["swing"] = swing_of(data)
    return out


#: A method with memory's run of FPA change in one direction: frames whose rate stays beyond
#: this, °C/min (a pace cell: a plateau's creep and the rate's noise stay within it).
SWING_BAND_C_PER_MIN = PACE_CELL_C_PER_MIN
#: How much further than its session's longest run in one direction a recording's FPA may
#: run before a method with memory's frames are outside, °C: 1 °C, about where `lin-lag` on
#: `tau2`, fitted on 5 °C ambient steps, went beyond 2σ on a steady 0.5 °C/min rise.
SWING_SLACK_C = 1.0


#: How long a run of FPA change survives its rate back within the band, s (the rate's
#: smoothing window, :data:`~thermocal.calibration.dataset.RATE_SMOOTH_S`): a slow ramp whose
#: rate flickers across the band for a frame is one run, not many short ones.
SWING_PAUSE_S = 60.0


def fpa_swings(fpa_c: Any, rate_c_per_min: Any, time_s: Any, *,
               band_c_per_min: float = SWING_BAND_C_PER_MIN) -> np.ndarray:
    """How far each frame's FPA had run since its run of change in one direction began, °C
    ``(M,)`` (signed: + rising; 0 outside a run): a run starts at a frame whose rate lies
    beyond ``band_c_per_min`` on one side and goes on through frames beyond it on that side,
    frames whose rate is not known (NaN), and pauses within the band of up to
    :data:`SWING_PAUSE_S`; it ends at a longer pause, a frame beyond it on the other side
    (which starts a run that way) or a gap of more than :data:`PACE_LAG_S` between frames.
    ``fpa_c`` (°C), ``rate_c_per_min`` (°C/min) and ``time_s`` (s) ``(M,)``: one recording, in
    time order.

    For a model that remembers the FPA's rates through lags of minutes (lin-lag's 8), what
    lags the FPA more slowly falls behind by about as much as the FPA ran: a session's steps
    show runs of a few °C; a ramp runs on. By hand, frame by frame: a run with pauses has no
    numpy primitive (a session or recording has thousands of frames)."""
    fpa = np.asarray(fpa_c, dtype=np.float64).reshape(-1)
    rate = np.asarray(rate_c_per_min, dtype=np.float64).reshape(-1)
    t = np.asarray(time_s, dtype=np.float64).reshape(-1)
    if not fpa.shape == rate.shape == t.shape:
        raise InvalidInputError(f"fpa_swings: fpa_c {fpa.shape}, rate_c_per_min {rate.shape} "
                                f"and time_s {t.shape} must be equal")
    out = np.zeros(fpa.size)
    side, start, paused = 0, 0, None  # the run's direction, first frame, pause's start (s)
    for i in range(fpa.size):
        if i and t[i] - t[i - 1] > PACE_LAG_S:
            side, paused = 0, None  # another recording: what the FPA did between is not known
        r = rate[i]
        way = 0 if not np.isfinite(r) else (1 if r > band_c_per_min else
                                              -1 if r < -band_c_per_min else 0)
        if way and way != side:  # a run starts (or turns)
            side, start, paused = way, i, None
        elif way:
            paused = None
        elif side and np.isfinite(r):  # within the band: a pause, or the run's end
            paused = t[i] if paused is None else paused
            if t[i] - paused > SWING_PAUSE_S:
                side, paused = 0, None
        out[i] = fpa[i] - fpa[start] if side else 0.0
    return out


def swing_of(data: ChamberData) -> dict[str, Any]:
    """How far a session's FPA ran in one direction without pause (:attr:`CalibrationReport.
    paces`' ``swing``, a method with memory's): ``band_c_per_min``
    (:data:`SWING_BAND_C_PER_MIN`), ``slack_c`` (:data:`SWING_SLACK_C`), ``rise_c`` and
    ``fall_c``: the farthest its usable frames had run up and down (:func:`fpa_swings`), °C."""
    swings = fpa_swings(data.fpa_c, data.fpa_rate_c_per_min, data.time_s)[data.usable]
    return {"band_c_per_min": SWING_BAND_C_PER_MIN, "slack_c": SWING_SLACK_C,
            "rise_c": float(max(swings.max(), 0.0)), "fall_c": float(max(-swings.min(), 0.0))}


def pace_stays(rate_c_per_min: Any, time_s: Any, *,
               band_c_per_min: float = SUSTAIN_BAND_C_PER_MIN) -> np.ndarray:
    """How long each frame's FPA rate had stayed within ``band_c_per_min`` (a report's
    ``sustained`` band; :data:`SUSTAIN_BAND_C_PER_MIN` where it is made) of its present value,
    s ``(M,)`` (:func:`~thermocal.calibration.dataset.still_time` of the rate; a
    gap of :data:`PACE_LAG_S` between frames starts anew; a rate not known, NaN, stays
    nowhere: 0): how long the FPA had been changing at its present pace. ``rate_c_per_min``
    (°C/min) and ``time_s`` (s) ``(M,)`` of one recording, in time order."""
    rate = np.asarray(rate_c_per_min, dtype=np.float64)
    known = np.isfinite(rate)
    stays = still_time(np.where(known, rate, 0.0), time_s, band_c=band_c_per_min,
                       max_gap_s=PACE_LAG_S)
    return np.where(known, stays, 0.0)


def sustained_of(data: ChamberData) -> dict[str, Any]:
    """How long a session held each pace (:attr:`CalibrationReport.paces`' ``sustained``, a
    memoryless method's): ``band_c_per_min`` (:data:`SUSTAIN_BAND_C_PER_MIN`), ``slack_s``
    (:data:`SUSTAIN_SLACK_S`) and ``held_s``, ``[cell, s]`` for each cell of the FPA rate
    (``round(rate / PACE_CELL_C_PER_MIN)``) its usable frames visited: the longest they had
    stayed at a pace by then (:func:`pace_stays`)."""
    stays = pace_stays(data.fpa_rate_c_per_min, data.time_s)[data.usable]
    rate = np.nan_to_num(np.asarray(data.fpa_rate_c_per_min, dtype=np.float64)[data.usable])
    cells = np.round(rate / PACE_CELL_C_PER_MIN).astype(np.int64)
    held = {}
    for c, s in zip(cells.tolist(), stays.tolist(), strict=True):
        held[c] = max(held.get(c, 0.0), s)
    return {"band_c_per_min": SUSTAIN_BAND_C_PER_MIN, "slack_s": SUSTAIN_SLACK_S,
            "held_s": [[c, held[c]] for c in sorted(held)]}


#: How far from a cell's centre a frame's pace may lie and still stay in it (:func:`paces_of`'s
#: stays), cells (Chebyshev): the cell and a quarter-cell border, so that a steady pace on a
#: cell's edge, which flickers across it, stays in both; a step's rise still passes through.
STAY_REACH_CELLS = 0.75


def _longest_stays(points: np.ndarray, time_s: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The longest each of ``cells`` ``(C, 2)`` was stayed in, s ``(C,)``: over runs of
    consecutive frames (``points`` ``(M, 2)``, their paces in cells, at ``time_s`` ``(M,)``) all
    within :data:`STAY_REACH_CELLS` of its centre, from the run's first frame's time to its
    last's (one frame: 0), a gap of more than :data:`PACE_DWELL_S` between frames ending a run
    (what the FPA did then was not seen). Passes through a cell on separate steps do not add
    up: each is its own run."""
    t = np.asarray(time_s, dtype=np.float64)
    cut = np.r_[True, np.diff(t) > PACE_DWELL_S]  # a frame that starts a run whatever its cell
    out = np.zeros(len(cells))
    for k, c in enumerate(cells):
        near = np.abs(points - c).max(axis=1) <= STAY_REACH_CELLS
        idx = np.flatnonzero(near)
        if idx.size < 2:
            continue
        starts = np.r_[0, np.flatnonzero((np.diff(idx) != 1) | cut[idx[1:]]) + 1]
        ends = np.r_[starts[1:], idx.size] - 1
        out[k] = float(np.max(t[idx[ends]] - t[idx[starts]]))
    return out


def fpa_sensitivity(data: ChamberData, frames: np.ndarray) -> float | None:
    """How many °C of scene one °C of FPA temperature is worth in the raw counts: ``|c / b|``
    of the least-squares ``mean counts = a + b·T_scene + c·T_fpa`` over the ``frames`` (bool
    ``(M,)``) of a session read into memory (a report's sample), scene °C per FPA °C; None
    where the frames span under 1 °C of FPA or of scene, or give no response. What an FPA
    change no fold saw can do to a frame, uncorrected (:meth:`~thermocal.calibration.
    uncertainty.CalibrationSigma._pace_sigma`): 0.5 on the `tau2` preset, 1.0 on `boson`."""
    idx = np.flatnonzero(frames)
    if idx.size < 3 or np.ptp(data.fpa_c[idx]) < 1.0 or np.ptp(data.scene_c[idx]) < 1.0:
        return None
    counts = np.asarray(data.session.frames[idx], dtype=np.float64)
    mean = counts.reshape(idx.size, -1).mean(axis=1)
    design = np.stack([np.ones(idx.size), data.scene_c[idx], data.fpa_c[idx]], axis=1)
    (_, b, c), *_ = np.linalg.lstsq(design, mean, rcond=None)
    if not (np.isfinite(b) and np.isfinite(c)) or abs(b) < 1e-9:
        return None
    return float(abs(c / b))


#: The FPA temperature cells in which :func:`paces_of` records where a pace was held, °C.
PACE_FPA_CELL_C = 1.0
#: How far from the FPA temperatures at which the session held a pace a memoryless method's
#: frame at that pace is inside, °C. A memoryless fit at an FPA temperature absorbs the lag
#: bias of the paces it saw there: a polynomial fitted to a session that only ramped at
#: 2 °C/min through 30 °C (held still only at its 15.5 °C start) erred 5.5 °C on a camera held
#: still at 30 °C, σ 0.6. A steps session's plateaus lie 5 °C apart (every FPA within 2.5 °C
#: of one).
PACE_FPA_REACH_C = 3.0


#: The FPA held still: within this of its present temperature, °C (a plateau's creep and the
#: sensor's noise).
STILL_BAND_C = 0.15


def stillness_of(data: ChamberData, ends: list[np.ndarray]) -> dict[str, Any]:
    """How long a session's plateaus held the FPA still (:attr:`CalibrationReport.paces`'
    ``still``): ``band_c`` (:data:`STILL_BAND_C`); ``held_s``, over the plateaus whose ends are
    ``ends`` (:func:`plateau_ends` of ``data``), the median of how long each had held the FPA
    within the band by its end (:func:`~thermocal.calibration.dataset.recording_still_time`, a
    gap of :data:`PACE_LAG_S` between frames ending a stretch), s; ``plateaus``: how many. ``{}``
    without plateaus, without a measured FPA series, or when the plateaus never held the FPA
    within the band (nothing to judge by).

    The median: a session's first hold (before its first step) is often much longer than the
    plateaus between its steps, which are what a camera held still is judged against, whatever
    its FPA temperature (a session need not hold a plateau at every temperature it spans)."""
    still = recording_still_time(data.fpa_c, data.time_s, band_c=STILL_BAND_C,
                                 max_gap_s=PACE_LAG_S)
    held = (float(np.median([still[end].max() for end in ends]))
            if ends and still is not None else 0.0)
    return ({"band_c": STILL_BAND_C, "held_s": held, "plateaus": len(ends)} if held > 0
            else {})


def stillness_band(paces: dict[str, Any] | None) -> float | None:
    """The band, °C, by which a recording's stillness is judged against a report's
    :attr:`CalibrationReport.paces` (its ``still``, else its ``settling``: both hold the band
    the session's plateaus were measured with); None where the report lists neither (a method
    with memory whose session settled, an older report)."""
    judged = (paces or {}).get("still") or (paces or {}).get("settling")
    return judged["band_c"] if judged else None


def _steady_paces(paces: dict[str, Any]) -> str:
    """The steady paces of :attr:`CalibrationReport.paces` (cells whose lagged rate is within a
    cell of the rate) as runs, ``"-0.10…+0.30, +1.40…+1.60"`` °C/min."""
    cell = paces["cell_c_per_min"]
    steady = sorted({i for i, j in paces["cells"] if abs(i - j) <= 1})
    runs: list[list[int]] = []
    for i in steady:
        if runs and i == runs[-1][1] + 1:
            runs[-1][1] = i
        else:
            runs.append([i, i])
    return ", ".join(f"{a * cell:+.2f}" if a == b else f"{a * cell:+.2f}…{b * cell:+.2f}"
                     for a, b in runs) or "no pace"


def _longest_stay(paces: dict[str, Any]) -> float | None:
    """The longest a session held a changing FPA's pace (its ``sustained`` stays off the rest
    cell), s; None where the report lists no stays or only rest."""
    stays = [s for c, s in (paces.get("sustained") or {}).get("held_s", []) if c != 0]
    return max(stays) if stays else None


#: A fold's errors, each None (not refitted) or a finite value >= 0 (°C, or a ratio).
_FOLD_ERRORS = ("mae_c", "own_mae_c", "relative_mae", "own_relative_mae")


def _folds_from(folds: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """A report's folds read back, their errors checked (a NaN ratio would make σ NaN
    everywhere)."""
    for f in folds:
        for key in _FOLD_ERRORS:
            if f.get(key) is not None and not 0 <= float(f[key]) < math.inf:
                raise ValueError(f"a fold's {key} must be >= 0 and finite, got {f[key]!r}")
    return folds


def _paces_from(d: dict[str, Any]) -> dict[str, Any]:
    """A report's ``fpa_paces`` read back, checked (``{}`` when absent)."""
    if not d:
        return {}
    cells = np.asarray(d["cells"], dtype=np.int64).reshape(-1, 2)
    lag, cell = float(d["lag_s"]), float(d["cell_c_per_min"])
    margin = float(d.get("margin_c_per_min", cell))  # a report made before margins: one cell
    if not (lag > 0 and cell > 0 and margin >= cell and math.isfinite(lag)
            and math.isfinite(margin)):
        raise ValueError(f"fpa_paces: lag {lag} s, cell {cell} °C/min and margin {margin} "
                         "°C/min must be > 0, finite, the margin at least a cell")
    out = {"lag_s": lag, "cell_c_per_min": cell, "cells": cells.tolist()}
    if "margin_c_per_min" in d:
        out["margin_c_per_min"] = margin
    if d.get("fpa_cells") is not None:
        fpa_cells = np.asarray(d["fpa_cells"], dtype=np.int64).reshape(-1, 3)
        fpa_cell, reach = float(d["fpa_cell_c"]), float(d["fpa_reach_c"])
        if not (0 < fpa_cell < math.inf and 0 <= reach < math.inf and fpa_cells.size):
            raise ValueError(f"fpa_paces: FPA cells of {fpa_cell} °C within {reach} °C must be "
                             "> 0, finite, and some")
        out |= {"fpa_cell_c": fpa_cell, "fpa_reach_c": reach, "fpa_cells": fpa_cells.tolist()}
    if d.get("fpa_sensitivity_c_per_c") is not None:
        sensitivity = float(d["fpa_sensitivity_c_per_c"])
        if not 0 <= sensitivity < math.inf:
            raise ValueError(f"fpa_paces: an FPA sensitivity of {sensitivity} scene °C per °C "
                             "must be >= 0 and finite")
        out["fpa_sensitivity_c_per_c"] = sensitivity
    if d.get("still") is not None:
        still = d["still"]
        band, held, plateaus = float(still["band_c"]), float(still["held_s"]), still["plateaus"]
        if not (0 < band < math.inf and 0 < held < math.inf and isinstance(plateaus, int)
                and not isinstance(plateaus, bool) and plateaus >= 1):
            raise ValueError("fpa_paces: still needs a band and a held time > 0, finite, and "
                             "at least one plateau")
        out["still"] = {"band_c": band, "held_s": held, "plateaus": plateaus}
    if d.get("settling") is not None:
        settle = d["settling"]
        band, held, plateaus = float(settle["band_c"]), float(settle["held_s"]), \
            settle["plateaus"]
        slope, window = float(settle["slope_c_per_min"]), float(settle["window_s"])
        if not (0 < band < math.inf and 0 < held < math.inf and isinstance(plateaus, int)
                and not isinstance(plateaus, bool) and plateaus >= 1
                and math.isfinite(slope) and 0 < window < math.inf):
            raise ValueError("fpa_paces: settling needs a band, a held time and a window > 0, "
                             "a finite slope, all finite, and at least one plateau")
        out["settling"] = {"band_c": band, "held_s": held, "plateaus": plateaus,
                           "slope_c_per_min": slope, "window_s": window}
    if d.get("swing") is not None:
        swing = {k: float(d["swing"][k]) for k in ("band_c_per_min", "slack_c", "rise_c",
                                                    "fall_c")}
        if not (0 < swing["band_c_per_min"] < math.inf
                and all(0 <= v < math.inf for v in swing.values())):
            raise ValueError("fpa_paces: swing needs a band > 0, and a slack and runs >= 0, "
                             "all finite")
        out["swing"] = swing
    if d.get("sustained") is not None:
        sus = d["sustained"]
        band, slack = float(sus["band_c_per_min"]), float(sus["slack_s"])
        held = np.asarray(sus["held_s"], dtype=np.float64).reshape(-1, 2)
        if not (0 < band < math.inf and 0 <= slack < math.inf and held.size
                and np.all(np.isfinite(held)) and np.all(held[:, 1] >= 0)
                and np.array_equal(held[:, 0], np.round(held[:, 0]))):
            raise ValueError("fpa_paces: sustained needs a band > 0, a slack >= 0, both "
                             "finite, and a held time >= 0 for some whole cells")
        out["sustained"] = {"band_c_per_min": band, "slack_s": slack,
                            "held_s": [[int(c), float(s)] for c, s in held]}
    return out


def rate_bin_range(b: dict[str, Any]) -> list:
    """A bin of :attr:`CalibrationReport.by_rate`'s ``[low, high]``, °C/min: of the rate, or of
    the pace (a memoryless method's bins)."""
    return b.get("rate_c_per_min") or b["pace_c_per_min"]


def _rate_bins_from(rows: list[Any]) -> list[dict[str, Any]]:
    """A report's ``mae_by_fpa_rate_c`` read back, checked: every bin of one kind (the rate's
    or the pace's range, ``[low, high]`` °C/min, high None for the last) with a finite MAE."""
    out = [dict(r) for r in rows]
    kinds = {("pace_c_per_min" if "pace_c_per_min" in b else "rate_c_per_min") for b in out}
    if len(kinds) > 1 or any(("pace_c_per_min" in b) == ("rate_c_per_min" in b) for b in out):
        raise ValueError("mae_by_fpa_rate_c: every bin needs one range, all of rate or of pace")
    for b in out:
        lo, hi = rate_bin_range(b)
        mae = float(b["mae_c"])
        if not (0 <= float(lo) < math.inf and (hi is None or float(hi) > float(lo))
                and 0 <= mae < math.inf):
            raise ValueError(f"mae_by_fpa_rate_c: a bin [{lo}, {hi}] °C/min of MAE {mae} °C")
    return out


def _change_bins_from(rows: list[Any]) -> list[dict[str, Any]]:
    """A report's ``mae_by_fpa_change_c`` read back, checked: ``change_c_per_min`` ``[low,
    high]`` (°C/min, high None for the last), ``frames``, and a finite σ."""
    out = []
    for row in rows:
        b = dict(row)
        lo, hi = b["change_c_per_min"]
        lo, hi = float(lo), None if hi is None else float(hi)
        sigma, frames = float(b["sigma_c"]), float(b["frames"])
        if not (0 <= lo < math.inf and (hi is None or hi > lo) and 0 <= sigma < math.inf
                and 0 <= frames < math.inf and frames == int(frames)):
            raise ValueError(f"mae_by_fpa_change_c: a bin [{lo}, {hi}] °C/min of σ {sigma} °C "
                             f"over {frames} frames")
        out.append(b | {"change_c_per_min": [lo, hi], "sigma_c": sigma, "frames": int(frames)})
    return out


def _without_history_from(d: Any) -> dict[str, Any]:
    """A report's ``without_history`` read back, checked: finite ``sigma_c``, ``mae_c`` (°C)
    and ``lag_s`` (s, > 0), whole ``frames`` (empty: none)."""
    d = dict(d)
    if not d:
        return {}
    sigma, mae, lag, frames = (float(d[k]) for k in ("sigma_c", "mae_c", "lag_s", "frames"))
    if not (0 <= sigma < math.inf and 0 <= mae < math.inf and 0 < lag < math.inf
            and 0 < frames < math.inf and frames == int(frames)):
        raise ValueError(f"without_history: σ {sigma} °C, MAE {mae} °C, lag {lag} s over "
                         f"{frames} frames")
    out = {"sigma_c": sigma, "mae_c": mae, "lag_s": lag, "frames": int(frames)}
    if d.get("by_time") is not None:  # an online estimate's cold starts
        bins, end = [], 0.0
        for b in d["by_time"]:
            lo, hi = (float(v) for v in b["time_s"])
            sigma, mae, count = float(b["sigma_c"]), float(b["mae_c"]), float(b["frames"])
            if not (end <= lo < hi < math.inf and 0 <= sigma < math.inf
                    and 0 <= mae < math.inf and 1 <= count == int(count)):
                raise ValueError(f"without_history: a cold-start bin {b} (bins in order, "
                                 "closed, σ and MAE >= 0, frames >= 1)")
            bins.append({"time_s": [lo, hi], "frames": int(count), "mae_c": mae,
                         "sigma_c": sigma})
            end = hi
        out["by_time"] = bins
    return out


#: How long after each step :func:`cold_start_errors` follows an online estimate begun
#: afresh, s (the last of :data:`TIME_EDGES` before its open bin).
COLD_START_SPAN_S = 1800.0


def cold_start_errors(calibration: Calibration, data: ChamberData, scored: np.ndarray,
                      ends: list[np.ndarray], *, span_s: float = COLD_START_SPAN_S
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The pixel errors (°C ``(M, P)``) of a method that learns online begun afresh at each
    ambient step of ``data`` (the first ``scored`` frame after each of the plateau ``ends``,
    :func:`plateau_ends`) and applied to the ``scored`` frames of the next ``span_s`` s, and
    their time since that start (s ``(M,)``): what a recording begun just before the FPA
    changes gives it, which its session, begun settled, does not show. The calibration is
    the one fitted on all the session's frames (its cross-validated error is the folds'; what
    a cold start adds is the estimate's state, which no refit changes)."""
    errors, since = [], []
    idx = np.flatnonzero(scored)
    for end in ends:
        after = idx[idx > end[-1]]
        if not after.size:
            continue
        t0 = data.time_s[after[0]]
        run = after[data.time_s[after] < t0 + span_s]
        if run.size < 2:
            continue
        errors.append(_pixel_errors(_applied(calibration, data, run), data, run))
        since.append(data.time_s[run] - t0)
    if not errors:
        return np.zeros((0, 0), dtype=np.float32), np.zeros(0)
    return np.concatenate(errors), np.concatenate(since)


#: Edges of the bins of :attr:`CalibrationReport.by_change`, °C/min: settled, settling,
#: steady-going, just changed, stepped. The first two part at 0.05 (a plateau's unsettled start
#: from its settled end: `polynomial` on `boson` read a hold's first minutes after a slow ramp
#: 1.1–1.3 °C off where σ of one 0–0.2 bin said 0.55–0.62; benchmarks/RESULTS.md, "The change
#: bins part at 0.05 °C/min").
CHANGE_EDGES = (0.0, 0.05, 0.2, 0.5, 1.0, math.inf)

#: Edges of the FPA-rate bins of :attr:`CalibrationReport.by_rate`, absolute rates in °C/min.
RATE_EDGES = (0.0, 0.05, 0.2, 0.5, 1.0, 2.0, math.inf)


def _by_rate(errors: np.ndarray, rates: np.ndarray, key: str = "rate_c_per_min"
             ) -> list[dict[str, Any]]:
    """The interior folds' MAE and :func:`coverage_sigma` by bin of the absolute FPA rate or
    pace (:data:`RATE_EDGES`; ``key`` names which), bins with frames only; ``errors`` ``(M, P)``
    per pixel, ``rates`` ``(M,)``."""
    return _binned(errors, np.abs(rates), RATE_EDGES, key)


#: Edges of the bins of time since a recording began, s (:attr:`CalibrationReport.by_time`).
TIME_EDGES = (0.0, 60.0, 300.0, 900.0, 1800.0, math.inf)
#: Frames a bin of :attr:`CalibrationReport.by_time` holds at least: a bin with fewer is pooled
#: with the bins after it (the last with the one before). The report's sample holds few frames
#: of a recording's first minutes (1 and 9 of the physics suite's, in the first two bins),
#: and those are where an online method errs most.
MIN_BIN_FRAMES = 10


def _binned(errors: np.ndarray, values: np.ndarray, edges: tuple[float, ...], key: str, *,
            min_frames: int = 1) -> list[dict[str, Any]]:
    """MAE and :func:`coverage_sigma` of ``errors`` ``(M, P)`` by bin of ``values`` ``(M,)``
    (``edges``), bins with frames only; with ``min_frames`` > 1, a bin of fewer frames pooled
    with the bins after it (the last with the one before), the spans covering the edges
    without a gap: ``key`` (``[low, high]``, high None for the last), ``frames``, ``mae_c``,
    ``sigma_c``."""
    spans: list[tuple[float, float, np.ndarray]] = []  # (low, high, frames)
    low, pooled = edges[0], np.zeros(values.shape, dtype=bool)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        pooled = pooled | ((values >= lo) & (values < hi))
        if not pooled.any() and min_frames <= 1:
            low = hi  # an empty bin left out: the next starts at its own edge (pooled, the
            # spans cover the edges without a gap: the start-up bins are where σ matters)
        elif pooled.sum() >= min_frames:
            spans.append((low, hi, pooled))
            low, pooled = hi, np.zeros(values.shape, dtype=bool)
    if pooled.any():  # too few at the end
        if spans:
            first, _, sel = spans.pop()
            spans.append((first, edges[-1], sel | pooled))
        else:
            spans.append((low, edges[-1], pooled))
    return [{key: [lo, hi if math.isfinite(hi) else None], "frames": int(sel.sum()),
             "mae_c": float(np.mean(errors[sel])), "sigma_c": coverage_sigma(errors[sel])}
            for lo, hi, sel in spans]


def bins_sigma(values: np.ndarray, bins: list[dict[str, Any]], key: str,
               outside: float = 0.0) -> np.ndarray:
    """Each of ``values`` ``(N,)``'s σ in ``bins`` (a report's bins, :func:`_binned`'s:
    ``key`` ``[low, high]``, high None for the last, and ``sigma_c``), °C; ``outside``
    outside every bin."""
    out = np.full(values.shape, outside, dtype=np.float64)
    for b in bins:
        lo, hi = b[key]
        out[(values >= lo) & (values < (math.inf if hi is None else hi))] = b["sigma_c"]
    return out


def _relative(errors: np.ndarray, level: np.ndarray) -> float | None:
    """The mean of ``errors`` ``(M,)`` over their frames' ``level`` ``(M,)`` (°C both), over
    the frames with both; None without one."""
    ok = np.isfinite(errors) & np.isfinite(level) & (level > 0)
    return float(np.mean(errors[ok] / level[ok])) if ok.any() else None


def _json_options(options: dict[str, Any]) -> dict[str, Any]:
    """The options as JSON values for the report (tuples as lists, other objects by their
    ``repr``; a frame mask left out)."""
    out: dict[str, Any] = {}
    for key, value in options.items():
        if isinstance(value, np.ndarray):
            continue  # a frame mask: not worth storing
        if isinstance(value, np.generic):
            value = value.item()
        if isinstance(value, tuple):
            value = list(value)
        out[key] = value if isinstance(value, str | int | float | bool | list | None) else repr(
            value)
    return out


def _rate_notes(data: ChamberData, rate: np.ndarray) -> list[str]:
    """A note when the FPA never falls, or never rises, in the session: the errors are measured
    at the FPA rates it covers only."""
    stable = float(data.info.get("stable_c_per_min", 0.05))
    rises, falls = bool(np.any(rate > stable)), bool(np.any(rate < -stable))
    if rises and falls:
        return []
    how = "never changes" if not (rises or falls) else ("never falls" if rises else
                                                         "never rises")
    return [f"the FPA {how} in this session ({rate.min():+.2f}…{rate.max():+.2f} °C/min): the "
            "errors are measured at these FPA rates only"]


# --------------------------------------------------------------------------- frames used

#: Why a method leaves chamber frames out of its fit by default (saturated frames apart).
LEFT_OUT_WHY = {
    "two-point": "not at the two end set points with the FPA settled at the reference",
    "one-point": "not at its set points with the FPA settled at the reference",
    "shutter": "not at the two end set points with the FPA settled at the reference",
    "polynomial": "with a changing FPA (it fits the stable frames)",
    "wolf2016": "with the FPA changing or away from the reference",
    "lin": "taken while the blackbody settled",
    "lin-level": "taken while the blackbody settled",
    "lin-lag": "taken while the blackbody settled",
}
#: ``LEFT_OUT_WHY`` of the polynomial model by its ``frames`` option.
_POLYNOMIAL_WHY = {
    "settled": "with a fast-changing FPA (it fits the settled frames)",
    "all": "taken while the blackbody settled",
}


def frame_counts(method: str, info: dict[str, Any], n_frames: int,
                 options: dict[str, Any] | None = None) -> dict[str, Any]:
    """The true frame counts of a fit, from its ``info``: ``total`` (the session's
    ``n_frames``), ``used`` (None when the method does not record it), ``left_out`` (reason →
    count: the saturated frames apart from the others) and, for wolf2016, ``used_hw`` (the frames
    of its Hammerstein-Wiener estimator)."""
    why = LEFT_OUT_WHY.get(method, "outside its default selection")
    if method == "polynomial":
        why = _POLYNOMIAL_WHY.get(str((options or {}).get("frames", "stable")), why)
    if "frames_used" in info:
        used = int(info["frames_used"])
    elif "frames_used_s" in info:  # wolf2016: the S maps; its HW estimator uses more
        used = int(info["frames_used_s"])
    elif "stable_frames" in info and "unstable_frames" in info:  # lin
        used = int(info["stable_frames"]) + int(info["unstable_frames"])
    else:
        return {"total": n_frames, "used": None, "left_out": {}}
    saturated = int(info.get("excluded_frames", 0) or 0)
    other = max(0, n_frames - used - saturated)
    left = ({why: other} if other else {}) | ({"saturated": saturated} if saturated else {})
    out: dict[str, Any] = {"total": n_frames, "used": used, "left_out": left}
    if "frames_used_hw" in info:
        out["used_hw"] = int(info["frames_used_hw"])
    return out


# --------------------------------------------------------------------------- fit and report


def fit_with_report(session: Any, method: str, **options: Any
                    ) -> tuple[Calibration, CalibrationReport]:
    """Check the protocol, fit ``method`` to the whole session and cross-validate it: the
    calibration, with the report stored in it (``info["report"]``: its uncertainty,
    :mod:`thermocal.calibration.uncertainty`), and the report.

    Raises :class:`~thermocal.errors.FitError` with the protocol's refusal (what the session
    lacks, what to record); the protocol's warnings go into the report (not warned).
    """
    from thermocal.calibration.registry import check_session, fit_calibration
    from thermocal.errors import FitError

    data = prepare_chamber(session)
    verdict = check_session(data, method, **options)
    if not verdict.ok:
        raise FitError(verdict.refusal)
    cal = fit_calibration(data, method, check=False, **verdict.options)
    report = cross_validate(
        data, method, calibration=cal, protocol_warnings=verdict.warnings,
        counts=frame_counts(method, getattr(cal, "info", {}), data.n_frames, verdict.options),
        **verdict.options,
    )
    return replace(cal, info=cal.info | {"report": report.to_dict()}), report


def auto_calibration(session: Any, *, options: dict[str, dict[str, Any]] | None = None,
                     methods: tuple[str, ...] | None = None
                     ) -> tuple[Calibration, CalibrationReport]:
    """``--method auto``: cross-validate every candidate the protocol supports, fit the one of
    lowest expected error to the whole session.

    Parameters
    ----------
    session : ChamberData, ChamberSession or path
    options : dict, optional
        Fitting options by method name.
    methods : tuple of str, optional
        The candidates (default: the registry's methods with ``auto``).

    Returns
    -------
    (Calibration, CalibrationReport)
        The chosen fit and its report, whose ``ranking`` lists every candidate, best first,
        and the refused ones with why.

    Raises
    ------
    FitError
        When no candidate can be fitted and cross-validated (the refusals, in one line).
    """
    from thermocal.calibration.registry import CALIBRATION_METHODS, check_session, fit_calibration
    from thermocal.errors import FitError

    data = prepare_chamber(session)
    names = methods or tuple(n for n, c in CALIBRATION_METHODS.items() if c.auto)
    measured: dict[str, tuple[CalibrationReport, dict[str, Any]]] = {}
    refused: list[dict[str, Any]] = []
    for name in names:
        verdict = check_session(data, name, **(options or {}).get(name, {}))
        if not verdict.ok:
            refused.append({"method": name, "refused": verdict.refusal})
            continue
        try:
            report = cross_validate(data, name, protocol_warnings=verdict.warnings,
                                    **verdict.options)
        except ThermocalError as exc:
            refused.append({"method": name, "refused": " ".join(str(exc).split())})
            continue
        if report.expected_mae_c is None and report.extrapolated_mae_c is None:
            refused.append({"method": name, "refused": "not cross-validated: "
                            + "; ".join(report.notes)})
            continue
        measured[name] = (report, verdict.options)
    if not measured:
        why = "; ".join(f"{r['method']}: {r['refused']}" for r in refused)
        raise FitError(f"no calibration method can be fitted to this session ({why})")
    order = sorted(measured, key=lambda n: _rank_key(measured[n][0]))
    best = order[0]
    report, fit_options = measured[best]
    cal = fit_calibration(data, best, check=False, **fit_options)
    ranking = [{"method": n, "expected_mae_c": measured[n][0].expected_mae_c}
               | ({} if measured[n][0].expected_mae_c is not None else
                  {"extrapolated_mae_c": measured[n][0].extrapolated_mae_c}) for n in order]
    report = replace(
        report, ranking=ranking + refused,
        frames=frame_counts(best, getattr(cal, "info", {}), data.n_frames, fit_options),
    )
    return cal, report


def _rank_key(report: CalibrationReport) -> tuple[bool, float]:
    """Auto's order: by expected error; the methods measured on extrapolations only after."""
    if report.expected_mae_c is not None:
        return False, report.expected_mae_c
    return True, report.extrapolated_mae_c if report.extrapolated_mae_c is not None else math.inf


def ranking_line(report: CalibrationReport) -> str:
    """``--method auto``'s ranking in a line: each candidate's expected MAE, best first (``x``:
    measured on extrapolations only), and the refused ones."""
    kept = [f"{r['method']} {r['expected_mae_c']:.2f}" if r["expected_mae_c"] is not None
            else f"{r['method']} {r['extrapolated_mae_c']:.2f}x" for r in report.ranking
            if "refused" not in r]
    out = f"auto: expected MAE °C {', '.join(kept)}; chose {report.method}"
    refused = [r["method"] for r in report.ranking if "refused" in r]
    return out + (f"; not supported by this session: {', '.join(refused)}" if refused else "")
