"""``selfcal``: flight-level self-calibration, an estimator fitted on a whole pass.

A 7-frame burst of a drone pass moves the scene some 25 px across the sensor, too little to
tell a column's offset from its neighbours' far away; the whole pass moves it across every
column. :class:`SelfCalibration` starts from a start model — the camera family's average unit
(calibration-free, :func:`thermocal.nn.inputs.preset_nominal` of the family's training units)
or the unit's own chamber calibration — fits what that model gets wrong for this unit over the
pass (:func:`~thermocal.estimation.pass_pattern.fit_residual_pattern`: per-pixel gain and
offset, the column, row and radial pattern, their FPA dependence), corrects every raw frame
with it, and then estimates each pivot as Oz et al.'s eq. 9 does: the registered mean of the
group's corrected frames.

The flight (:func:`thermocal.pipeline.flight.process_flight`) fits one pattern per batch of
frames (:data:`~thermocal.pipeline.flight.BATCH_FRAMES`: long flights in segments) with
:meth:`SelfCalibration.fitted`; ground references (:mod:`thermocal.pipeline.references`) fix the
level that no motion reveals (:meth:`SelfCalibration.with_level`).

Uncertainty (1σ, °C): ``√(level² + unseen² + pattern² + spread²/n)`` — the level the start
model leaves (calibration-free: the family's unit-to-unit spread at the pass's FPA and scene
temperatures, :func:`family_level_sigma`; from a chamber calibration, its own
cross-validated σ; from references, theirs), the line pattern the pass's motion could not show
(calibration-free: how much the family's units differ from their average along those lines,
:func:`unseen_line_sigma`; from a calibration, inside its σ), the offset's standard error over
the views that fitted it, and the spread of the group's views over √n.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from thermocal.calibration.base import Calibration, apply_with_rate, fill_bad_pixels
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError, ResolutionMismatchError
from thermocal.estimation.base import PreparedBurst, view_spread
from thermocal.estimation.pass_pattern import (
    ResidualPattern,
    fine_part,
    fit_residual_pattern,
    radial_line_profile,
)
from thermocal.radiometry import TAU2, BandRadiance

__all__ = ["LEVEL_UNITS", "MIN_FREE_SHAPE", "OTHER_FAMILY_SIGMA_C", "SMALL_FRAME_SIGMA_C",
           "SelfCalibration", "family_level_sigma",
           "start_band", "unseen_line_sigma"]

#: The camera units whose spread about their family's average unit is the level's σ
#: (:func:`family_level_sigma`): neither the family's training units (the average's own) nor
#: any unit a benchmark scores ``selfcal`` on.
LEVEL_UNITS: tuple[int, ...] = tuple(range(1000, 1100))

#: The frame size, ``(H, W)``, at which :func:`family_level_sigma` takes a unit's frame mean.
LEVEL_SHAPE = (128, 160)

REMEDY = ("selfcal fits a whole pass: run `thermocal flight --method selfcal` on a recording of "
          "at least 30 frames that moves across the scene")

#: The smallest frames, ``(H, W)``, whose calibration-free σ was measured (the pass benchmark,
#: ``benchmarks/passes.py``, at 336×256; 320×256 likewise). On smaller ones the pattern fit errs
#: more than its σ says: at 160×120 a helper's audit found 0.58–0.61 °C of error beyond the
#: unit's level (0.34 at 320×256 and 336×256, 0.39 at 640×512, same scene and units), 82–84 %
#: of the pixels within 2σ. Such a pass is outside, unless the start is the unit's own
#: calibration.
MIN_FREE_SHAPE = (256, 320)

#: σ added in quadrature to a pass of smaller frames forced through, °C: the error it showed
#: beyond what the measured sizes showed, √(0.6² − 0.34²).
SMALL_FRAME_SIGMA_C = 0.5

#: σ added in quadrature to a pass forced through another family's average unit, °C: a
#: calibration of one family errs 12–17 °C on the other (``benchmarks/physics.py``, the
#: calibrations' cross-family MAE); the audit's ``boson`` pass through ``tau2``'s: 9.5 °C.
OTHER_FAMILY_SIGMA_C = 15.0
#: Frames of a pass the family check looks at (evenly spaced over the frames fitted on).
FAMILY_CHECK_FRAMES = 7


def start_band(calibration: Calibration | None, family: str) -> BandRadiance:
    """The spectral band the pattern is fitted in: the calibration's, else the family's."""
    if calibration is not None:
        band = getattr(calibration, "band", None)
        return band if isinstance(band, BandRadiance) else TAU2
    from thermocal.calibration.base import band_for
    from thermocal.camera.presets import PRESETS

    return band_for(tuple(PRESETS[family].band_m))


def _through_average_unit(family: str, shape: tuple[int, int], fpa_c: float,
                          levels_c: np.ndarray, units: tuple[int, ...]):
    """Uniform scenes at ``levels_c`` (°C, ``(L,)``) seen by each unit of ``family`` in
    ``units`` at FPA ``fpa_c`` (°C; the housing settled below it) and read back through the
    family's average unit: yields ``(unit camera, temperatures °C (L, H, W))``, frames of
    ``shape`` ``(H, W)``."""
    from thermocal.camera.model import expected_counts
    from thermocal.camera.presets import make_camera
    from thermocal.nn.inputs import calibrate_frames

    nominal = _nominal(family, shape)
    housing = fpa_c - nominal.thermal.fpa_self_heating_c
    n = len(levels_c)
    scenes = np.broadcast_to(np.asarray(levels_c, np.float32)[:, None, None],
                             (n, *shape)).astype(np.float32)
    for u in units:
        unit = make_camera(family, unit=u, size=(shape[1], shape[0]))
        counts = expected_counts(unit, scenes, [fpa_c] * n, housing_c=[housing] * n)
        yield unit, calibrate_frames(nominal, counts, np.full(n, fpa_c))


def _cell_c(value_c: float) -> float:
    """``value_c`` (°C) rounded to its 5 °C cell (halves up)."""
    return 5.0 * float(np.floor(float(value_c) / 5.0 + 0.5))


def family_level_sigma(family: str, fpa_c: float, scene_c: float) -> float:
    """The level no motion reveals when starting from the family's average unit, °C: the RMS
    over :data:`LEVEL_UNITS` of how far a unit's frame mean, read through the average unit,
    lies from a uniform scene at ``scene_c`` (°C) with the FPA at ``fpa_c`` (°C); no view of a
    pass shows it. It grows with the FPA temperature and the scene's contrast with it (``tau2``:
    0.50–0.52 °C at an FPA of 30 °C and scenes of 10–40 °C, 0.64 at −20 °C; 0.67–0.72 at
    45 °C, 0.89 at −20 °C). Both rounded to their 5 °C cell, computed once per cell
    (:data:`LEVEL_SHAPE` frames: a frame mean, not a pattern)."""
    return _family_level_sigma(family, _cell_c(fpa_c), _cell_c(scene_c))


@functools.lru_cache(maxsize=256)
def _family_level_sigma(family: str, fpa_c: float, scene_c: float) -> float:
    means = [float(np.mean(temps[0][~unit.defects])) - scene_c
             for unit, temps in _through_average_unit(family, LEVEL_SHAPE, fpa_c,
                                                      np.array([scene_c]), LEVEL_UNITS)]
    return float(np.sqrt(np.mean(np.square(means))))


@functools.lru_cache(maxsize=16)
def unseen_line_sigma(family: str, shape: tuple[int, int], fpa_c: float, scene_c: float,
                      lines: str, *, radial: bool = True) -> float:
    """How much a unit of ``family`` differs from the family's average unit along ``lines``
    (``"rows"`` or ``"columns"``) beyond what the pass's priors give back (its fine stripes, and
    a family's radial quadratic: :func:`~thermocal.estimation.pass_pattern.unseen_line_profile`),
    °C: the RMS over the family's training units of what is left of the line means (less their
    mean) of the average unit's error on a uniform scene at ``scene_c`` (°C), FPA ``fpa_c``
    (°C), frames of ``shape`` ``(H, W)``. The radial quadratic is taken, as the fit takes it,
    from the offset part of the error (its gain part, fitted apart, is left out): the error in
    radiance is split into ``gain · L + offset`` from two scene levels; ``radial=False``: the
    quadratic was not given back (a pass that moved across the lines, but too little to show
    their slow part). The σ of the line pattern a pass that never moves across those lines
    leaves; FPA and scene rounded to 5 °C (cached)."""
    from thermocal.camera.presets import PRESETS
    from thermocal.nn.data import TRAIN_UNITS

    band = start_band(None, family)
    levels = np.array([scene_c, scene_c + 10.0])
    true = band.radiance(levels + ZERO_CELSIUS_K)
    per_c = float(band.radiance(scene_c + 0.5 + ZERO_CELSIUS_K)
                  - band.radiance(scene_c - 0.5 + ZERO_CELSIUS_K))
    axis = 1 if lines == "rows" else 0
    profiles = []
    for unit, temps in _through_average_unit(family, shape, fpa_c, levels, TRAIN_UNITS):
        seen = band.radiance(temps + np.float32(ZERO_CELSIUS_K))
        gain = (seen[1] - seen[0]) / (true[1] - true[0])
        offset = seen[0] - gain * true[0]
        err = (seen[0] - true[0]) / per_c  # °C at scene_c
        ok = ~unit.defects
        line = np.nansum(np.where(ok, err, 0), axis=axis) / np.maximum(ok.sum(axis=axis), 1)
        left = line - fine_part(line)  # what the pass's priors give back is not left
        if radial and PRESETS[family].radial_offset:
            left = left - radial_line_profile(offset, ok, axis) / per_c
        profiles.append(left - left.mean())
    return float(np.sqrt(np.mean(np.square(profiles))))


@functools.lru_cache(maxsize=2)
def _nominal(family: str, shape: tuple[int, int]) -> Any:
    from thermocal.nn.data import TRAIN_UNITS
    from thermocal.nn.inputs import preset_nominal

    return preset_nominal(family, (shape[1], shape[0]), TRAIN_UNITS)


@dataclass(frozen=True, eq=False)
class SelfCalibration:
    """The ``selfcal`` estimator (see the module).

    Parameters
    ----------
    calibration : Calibration, optional
        The unit's own calibration to start from; None: the family's average unit.
    family : str
        The camera family (a preset of :data:`thermocal.camera.presets.PRESETS`) when starting
        from its average unit.
    pattern : ResidualPattern, optional
        The pass's fitted pattern (:meth:`fitted`); an unfitted estimator refuses bursts.
    level_offset : float
        Radiance (W·m⁻²·sr⁻¹) subtracted from every corrected frame: the level fixed by ground
        references (:meth:`with_level`).
    level_sigma_c : float, optional
        σ of the level, °C: the references' when given, else the start model's.
    fpa_rates : (times s, rates °C/min), optional
        The FPA temperature's rate of change over the pass (from the whole recording), for
        the family start model's transient term (1.7 °C per °C/min on ``tau2``): looked up
        by each frame's time.
    not_of_family : str, optional
        Set by :meth:`fitted` when starting from the family's average unit: why the pass's
        frames are not of that family (their fixed pattern runs the other way:
        :func:`~thermocal.nn.validity.family_pattern_reason`, as the network checks); every
        burst is then outside, and forced, its σ grows by :data:`OTHER_FAMILY_SIGMA_C`. Frames
        under :data:`~thermocal.nn.validity.LINE_CHECK_MIN_PX` a side are not checked.
    report_needed : bool
        The start ``calibration`` came from a file, which must carry its cross-validation
        report (:meth:`unchecked`); a fit in hand is the caller's to vouch for.
    """

    calibration: Calibration | None = None
    family: str = "tau2"
    pattern: ResidualPattern | None = None
    level_offset: float = 0.0
    level_sigma_c: float | None = None
    fpa_rates: tuple[np.ndarray, np.ndarray] | None = None
    not_of_family: str | None = None
    report_needed: bool = False

    name = "selfcal"
    n_frames = None
    needs_fpa = True
    per_frame = False
    accepts_registered = False

    @property
    def remedy(self) -> str:
        """What to do about a burst outside: of another family, say which to start from."""
        from thermocal.camera.presets import PRESETS

        if self.not_of_family:
            return (f"give --family of the camera's family ({', '.join(PRESETS)}), or start "
                    "from its own calibration (--calibration); --force estimates anyway with "
                    f"σ grown by {OTHER_FAMILY_SIGMA_C:g} °C")
        if self.calibration is None:  # outside by its frames' size alone
            return ("start from the camera's own calibration (--calibration); --force "
                    f"estimates anyway with σ grown by {SMALL_FRAME_SIGMA_C:g} °C")
        if self.unchecked():
            from thermocal.calibration.uncertainty import NO_REPORT_REMEDY

            return NO_REPORT_REMEDY
        return REMEDY

    def unchecked(self) -> str | None:
        """Why nothing can be checked against the start calibration (a file without its
        report, when ``report_needed``: its σ would be the family's, not its own), or None."""
        if self.report_needed and self.calibration is not None and self.sigma_model is None:
            from thermocal.calibration.uncertainty import no_sigma_reason

            return no_sigma_reason(self.calibration)
        return None

    def __post_init__(self) -> None:
        from thermocal.camera.presets import PRESETS

        if self.calibration is None and self.family not in PRESETS:
            raise InvalidInputError(
                f"unknown camera family {self.family!r}; choose from {', '.join(PRESETS)}")

    @property
    def band(self) -> BandRadiance:
        return start_band(self.calibration, self.family)

    @property
    def radial(self) -> bool:
        """Whether the residual pattern may be taken as radially symmetric along unseen lines:
        from the family's average unit of a family whose offset is (its unit-to-unit
        differences are then radial too); from a calibration, no."""
        from thermocal.camera.presets import PRESETS

        return self.calibration is None and PRESETS[self.family].radial_offset

    @property
    def sigma_model(self) -> Any:
        from thermocal.calibration.uncertainty import CalibrationSigma

        return None if self.calibration is None else CalibrationSigma.of(self.calibration)

    @property
    def fpa_paces(self) -> dict[str, Any]:
        """The paces of the start calibration's report (``{}`` from the family's average
        unit or without a report)."""
        model = self.sigma_model
        return {} if model is None else model.report.paces

    # -- the start model -------------------------------------------------------------------

    def start_temperature(self, frames: np.ndarray, fpa_c: Any, time_s: Any = None
                          ) -> np.ndarray:
        """Raw frames ``(N, H, W)`` taken at ``time_s`` (s, or None) → °C through the start
        model, float32: the calibration, or the family's average unit inverted exactly at the
        reported FPA temperature and (where the frames' times are known) its rate."""
        if self.calibration is not None:  # with the times, and the recording's rate
            rate = (None if self.fpa_rates is None or time_s is None
                    else np.interp(np.asarray(time_s, np.float64), *self.fpa_rates))
            return np.asarray(apply_with_rate(self.calibration, frames, fpa_c=fpa_c,
                                              time_s=time_s, fpa_rate_c_per_min=rate),
                              np.float32)
        from thermocal.camera.model import invert

        nominal = _nominal(self.family, frames.shape[1:])
        fpa = np.broadcast_to(np.asarray(fpa_c, np.float64), (len(frames),))
        rate = 0.0
        if self.fpa_rates is not None and time_s is not None:
            rate = np.interp(np.asarray(time_s, np.float64), *self.fpa_rates)
        return invert(nominal, frames, fpa, housing_c=fpa - nominal.thermal.fpa_self_heating_c,
                      fpa_rate_c_per_min=rate)

    def start_radiance(self, frames: np.ndarray, fpa_c: Any, time_s: Any = None
                       ) -> np.ndarray:
        """Raw frames → band radiance through the start model, ``(N, H, W)`` float32."""
        t = self.start_temperature(frames, fpa_c, time_s)
        return np.asarray(self.band.radiance(t + np.float32(ZERO_CELSIUS_K)), np.float32)

    # -- fitting -----------------------------------------------------------------------------

    def fitted(self, frames: np.ndarray, homographies: np.ndarray, fpa_c: Any, *,
               use: np.ndarray | None = None, good: np.ndarray | None = None,
               time_s: Any = None, fpa_rate_c_per_min: Any = None) -> SelfCalibration:
        """A copy with the residual pattern of a pass fitted: raw ``frames`` ``(N, H, W)``,
        ``homographies`` ``(N, 3, 3)`` frame → a common reference, FPA ``fpa_c`` ``(N,)``
        °C, frames to ``use`` and ``good`` pixels (stuck pixels left out); the frames' times
        ``time_s`` (s) and the FPA's rate ``fpa_rate_c_per_min`` (°C/min, from the whole
        recording), each ``(N,)`` or None. Raises :class:`~thermocal.errors.InvalidInputError`
        for a pass too short or too still."""
        fpa = np.broadcast_to(np.asarray(fpa_c, np.float64), (len(frames),))
        est = self
        if time_s is not None and fpa_rate_c_per_min is not None:
            t = np.asarray(time_s, np.float64)
            est = replace(self, fpa_rates=(t, np.asarray(fpa_rate_c_per_min, np.float64)))
        radiance = est.start_radiance(np.asarray(frames), fpa, time_s)
        pattern = fit_residual_pattern(radiance, homographies, fpa_c=fpa, use=use, good=good,
                                       radial=self.radial)
        return replace(est, pattern=pattern,
                       not_of_family=est._family_check(np.asarray(frames), fpa, time_s, use))

    def _family_check(self, frames: np.ndarray, fpa: np.ndarray, time_s: Any,
                      use: np.ndarray | None) -> str | None:
        """Why a pass's raw ``frames`` are not of the start family (None: they are, or the
        start is the unit's own calibration, or the frames are too small to tell):
        :func:`~thermocal.nn.validity.family_pattern_reason` of
        :data:`FAMILY_CHECK_FRAMES` of them through the family's average unit."""
        from thermocal.camera.presets import PRESETS
        from thermocal.nn.validity import LINE_CHECK_MIN_PX, family_pattern_reason

        if self.calibration is not None or min(frames.shape[1:]) < LINE_CHECK_MIN_PX:
            return None
        pool = np.flatnonzero(use) if use is not None else np.arange(len(frames))
        if pool.size == 0:
            return None
        pick = pool[np.unique(np.linspace(0, pool.size - 1, FAMILY_CHECK_FRAMES).astype(int))]
        times = None if time_s is None else np.asarray(time_s, np.float64)[pick]
        temps = self.start_temperature(frames[pick], fpa[pick], times)
        return family_pattern_reason(temps, self.family,
                                     PRESETS[self.family].fpn.split("-")[0],
                                     of="that selfcal starts from (--family)")

    def with_level(self, offset: float, sigma_c: float) -> SelfCalibration:
        """A copy whose level is fixed by references: ``offset`` radiance removed, σ ``sigma_c``."""
        return replace(self, level_offset=float(offset), level_sigma_c=float(sigma_c))

    # -- the Estimator protocol ------------------------------------------------------------------

    def check(self, frames: np.ndarray, *, registered: bool, homographies: Any) -> None:
        if self.pattern is None:
            raise InvalidInputError(f"selfcal has no pattern fitted: {REMEDY}")
        if tuple(self.pattern.shape) != frames.shape[1:]:
            raise ResolutionMismatchError(
                f"frames are {frames.shape[2]}x{frames.shape[1]} but the pattern was fitted on "
                f"{self.pattern.shape[1]}x{self.pattern.shape[0]}")

    def calibrate(self, frames: np.ndarray, fpa_c: Any, time_s: Any, *,
                  pace: Any = None) -> np.ndarray:
        """Raw frames → °C: the start model, the pattern removed, the references' level."""
        assert self.pattern is not None  # check() refused otherwise
        fpa = np.broadcast_to(np.asarray(fpa_c, np.float64), (len(frames),))
        radiance = self.pattern.correct(self.start_radiance(frames, fpa, time_s), fpa)
        radiance -= np.float32(self.level_offset)
        lo, hi = self.band.radiance_range
        temps = self.band.temperature(np.clip(radiance, lo, hi)) - np.float32(ZERO_CELSIUS_K)
        temps = np.asarray(temps, np.float32)
        return fill_bad_pixels(temps, self.pattern.bad)  # a new array, filled in place

    def outside(self, calibrated: np.ndarray, fpa_c: float | None, *,
                pace: Any = None, burst: PreparedBurst | None = None) -> tuple[str, ...]:
        """The start calibration's ranges (FPA, scene; its FPA rates and paces where ``pace``
        is known); the family's average unit has none."""
        small = self._small_frames(calibrated.shape[-2:])
        family = ((self.not_of_family,) if self.not_of_family else ()) + ((small,) if small
                                                                          else ())
        model = self.sigma_model
        if model is None:
            return family
        since = None if burst is None else burst.time_since_start_s
        return family + tuple(model.outside_burst(calibrated, fpa_c, pace,
                                                  time_since_start_s=since))

    def _small_frames(self, shape: tuple[int, ...]) -> str | None:
        """Why frames of ``shape`` ``(H, W)`` are outside a calibration-free start's measured
        σ (:data:`MIN_FREE_SHAPE`), or None."""
        h, w = (int(v) for v in shape)
        if (self.calibration is not None or self.sigma_model is not None
                or (h >= MIN_FREE_SHAPE[0] and w >= MIN_FREE_SHAPE[1])):
            return None
        return (f"frames of {w}x{h}, smaller than the {MIN_FREE_SHAPE[1]}x{MIN_FREE_SHAPE[0]} "
                "on which a calibration-free selfcal's σ was measured (at 160x120 it erred "
                "0.6 °C beyond the unit's level, 82-84 % of pixels within 2σ)")

    def estimate(self, burst: PreparedBurst) -> np.ndarray:
        """Oz et al. eq. 9 on the corrected frames: the registered mean."""
        count = burst.valid.sum(axis=0)
        return ((burst.warped * burst.valid).sum(axis=0) / np.maximum(count, 1)).astype(
            np.float32)

    def level_sigma(self, temperature_c: np.ndarray, fpa_c: float | None, *,
                    pace: Any = None, time_since_start_s: float | None = None) -> np.ndarray:
        """σ of the level no motion reveals, °C ``(H, W)``: a start calibration's at least the
        level of a ``pace`` (:class:`~thermocal.estimation.base.FpaPace`) its session never
        held, or of a stillness not known (still since its recording began,
        ``time_since_start_s`` s before)."""
        if self.level_sigma_c is not None:
            return np.full(temperature_c.shape, self.level_sigma_c, np.float32)
        model = self.sigma_model
        if model is not None and fpa_c is not None:
            return np.asarray(model.burst_sigma(temperature_c, fpa_c, pace,
                                                time_since_start_s=time_since_start_s),
                              np.float32)
        # the family's spread at this FPA and scene; at an FPA not known, the largest over
        # the FPA temperatures it is trained at
        scene = float(np.median(temperature_c))
        level = max(family_level_sigma(self.family, f, scene)
                    for f in ((fpa_c,) if fpa_c is not None else (10.0, 30.0, 50.0)))
        return np.full(temperature_c.shape, level, np.float32)

    def unseen_sigma(self, temperature_c: np.ndarray, fpa_c: float | None) -> float:
        """σ of the line pattern the pass did not show (°C; 0 from a calibration, whose σ holds
        it, or when the pass moved across both lines by half a frame or more):
        :func:`unseen_line_sigma` of each direction of
        :meth:`~thermocal.estimation.pass_pattern.ResidualPattern.lines_not_identified`."""
        assert self.pattern is not None
        missing = self.pattern.lines_not_identified()
        if self.calibration is not None or not missing or fpa_c is None:
            return 0.0
        fpa, scene = (_cell_c(v) for v in (fpa_c, float(np.median(temperature_c))))
        return float(np.hypot.reduce([
            unseen_line_sigma(self.family, temperature_c.shape, fpa, scene, lines,
                              radial=kind == "all") for lines, kind in missing.items()]))

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> np.ndarray | None:
        """``√(level² + unseen² + pattern² + spread²/n)`` (see the module), °C ``(H, W)``
        float32; the pattern's standard error converted from radiance at each pixel's
        temperature."""
        assert self.pattern is not None
        level = self.level_sigma(temperature_c, burst.fpa_c, pace=burst.pace,
                                 time_since_start_s=burst.time_since_start_s).astype(
            np.float64)
        unseen = self.unseen_sigma(temperature_c, burst.fpa_c)
        t_k = temperature_c.astype(np.float64) + ZERO_CELSIUS_K
        dl_dt = (self.band.radiance(t_k + 0.5) - self.band.radiance(t_k - 0.5))
        pattern = self.pattern.offset_se / np.maximum(dl_dt, 1e-9)
        spread, n = view_spread(burst.warped, burst.valid)
        other = OTHER_FAMILY_SIGMA_C if outside and self.not_of_family else 0.0
        small = (SMALL_FRAME_SIGMA_C if outside and self._small_frames(temperature_c.shape)
                 else 0.0)
        return np.sqrt(level**2 + unseen**2 + pattern**2 + spread**2 / n + other**2
                       + small**2).astype(np.float32)
