"""Estimators from a per-pixel calibration (numpy only): the registered mean of eq. 9 of
Oz et al. (``mean``) and the pivot frame alone (``calibration``)."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from thermocal.calibration.base import (
    Calibration,
    ThermocalWarning,
    apply_with_rate,
    calibration_sigma_extra,
    rate_lags_of,
)
from thermocal.calibration.imprint import OTHER_CAMERA_SIGMA_C, imprint_reason
from thermocal.calibration.uncertainty import (
    NO_REPORT_REMEDY,
    REMEDY,
    CalibrationSigma,
    no_sigma_reason,
    older_report_warning,
)
from thermocal.errors import ResolutionMismatchError
from thermocal.estimation.base import Estimate, FpaPace, PreparedBurst, view_spread
from thermocal.estimation.pipeline import estimate

__all__ = ["OzMean", "PivotCalibration", "naive_mean"]


class _ThroughCalibration:
    """Shared by both: a fitted :class:`~thermocal.calibration.base.Calibration`
    (``apply(frames, *, fpa_c, time_s)`` → °C) of one frame size."""

    n_frames = None
    needs_fpa = False

    def __init__(self, calibration: Calibration, *, report_needed: bool = False) -> None:
        """``report_needed``: without a cross-validation report the calibration cannot be
        checked, so every burst is outside its domain (as a file given to a command must be);
        otherwise (a fit in hand, e.g. a benchmark's camera model) it is not checked."""
        self.calibration = calibration
        self.report_needed = report_needed
        self.sigma_model = CalibrationSigma.of(calibration)
        older = None if self.sigma_model is None else self.sigma_model.older_report()
        if older:
            warnings.warn(older_report_warning(older), ThermocalWarning, stacklevel=2)

    def calibrate(self, frames: np.ndarray, fpa_c: Any, time_s: Any, *,
                  pace: FpaPace | None = None) -> np.ndarray:
        """The frames through the calibration, with their FPA temperatures and times (the
        methods with a rate term need both), and for those that take it the FPA rate their
        recording measured (``pace``): a burst of a second cannot tell its own (a lin
        calibration without its rate term errs 1.7–3.6 °C on a 1 °C/min sawtooth)."""
        return apply_with_rate(self.calibration, frames, fpa_c=fpa_c, time_s=time_s,
                               fpa_rate_c_per_min=None if pace is None else pace.rate_c_per_min,
                               fpa_lag_rates_c_per_min=None if pace is None else pace.lag_rates)

    @property
    def rate_lags_s(self) -> tuple[float, ...]:
        """The lags, s, through which the calibration remembers the FPA's rate (``lin-lag``;
        ``()`` otherwise): a recording gives it the rates through them
        (:func:`~thermocal.estimation.paces.recording_paces`)."""
        return rate_lags_of(self.calibration)

    def unchecked(self) -> str | None:
        """Why no burst can be checked against the calibration (a file without its report,
        when ``report_needed``), or None."""
        return (no_sigma_reason(self.calibration)
                if self.report_needed and self.sigma_model is None else None)

    @property
    def remedy(self) -> str:
        """What to do about a burst outside its domain: calibrate over its conditions, or
        (a calibration without a report) calibrate again."""
        return NO_REPORT_REMEDY if self.sigma_model is None else REMEDY

    @property
    def fpa_paces(self) -> dict[str, Any]:
        """The paces of the calibration's report (``{}`` without a report)."""
        return {} if self.sigma_model is None else self.sigma_model.report.paces

    def outside(self, calibrated: np.ndarray, fpa_c: float | None, *,
                pace: FpaPace | None = None, burst: PreparedBurst | None = None
                ) -> tuple[str, ...]:
        """The FPA and scene ranges of the calibration's chamber session, and where ``pace`` is
        known its FPA rates and (a memoryless method) its paces
        (:meth:`~thermocal.calibration.uncertainty.CalibrationSigma.outside_burst`; the FPA
        only when the burst has one); and, given the prepared ``burst``, that its pivot is of
        the camera the calibration was made for (:func:`~thermocal.calibration.imprint.
        imprint_reason`). Without a report (an older file, a session too small to
        cross-validate): that it cannot be checked when ``report_needed``, else ``()``."""
        if self.sigma_model is None:
            why = self.unchecked()
            return (why,) if why else ()
        foreign = () if burst is None else (self._foreign(burst),)
        since = None if burst is None else burst.time_since_start_s
        return self.sigma_model.outside_burst(calibrated, fpa_c, pace,
                                              time_since_start_s=since) + tuple(
            r for r in foreign if r)

    def _foreign(self, burst: PreparedBurst) -> str | None:
        """Why the burst's pivot is not of the calibration's camera, or None
        (:func:`~thermocal.calibration.imprint.imprint_reason` of its raw and calibrated
        pivot, at the burst's FPA temperature and the pivot's time)."""
        return imprint_reason(self.calibration, burst.frames[burst.pivot],
                              burst.warped[burst.pivot], fpa_c=burst.fpa_c,
                              time_s=burst.pivot_time_s)

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> np.ndarray | None:
        """σ from the calibration's cross-validation report, growing outside its ranges
        (:class:`~thermocal.calibration.uncertainty.CalibrationSigma`), at the burst's FPA rate
        and time since its recording began where known; None without a report or without the
        burst's FPA temperature. A burst calibrated without its recording's FPA history (a
        model remembering the FPA's rates started steady at it: no
        ``fpa_lag_rates_c_per_min``) takes σ of frames so taken in full, however long the
        recording had run (a ``lin-lag`` burst 8 min into a flight of a ``boson`` camera:
        σ 0.16 °C for a 1.7 °C error before). What the calibration adds
        (:func:`~thermocal.calibration.base.calibration_sigma_extra`: a ``shutter``'s closures,
        its rate terms' correction at a pace its session never held, its bad pixels filled
        from their neighbours) is added in quadrature. A burst forced through the calibration
        of
        another camera: σ grown by :data:`~thermocal.calibration.imprint.OTHER_CAMERA_SIGMA_C`
        (in quadrature)."""
        if self.sigma_model is None or burst.fpa_c is None:
            return None
        pace = burst.pace  # its stillness and stays judged with its pace, as checked
        sigma = self.sigma_model.burst_sigma(
            temperature_c, burst.fpa_c, pace, time_since_start_s=burst.time_since_start_s,
            history_seen=burst.fpa_lag_rates_c_per_min is not None)
        # forced at a pace the session never held: the rate terms' correction is unverified
        unverified = outside and pace is not None and self.sigma_model.pace_unseen(
            pace.rate_c_per_min, pace.lagged_c_per_min, burst.fpa_c)
        added = calibration_sigma_extra(  # at the pivot, through the calibration (a mean's
            # too: hovering, every view sees the pivot's bad pixels through the same pixels)
            self.calibration, burst.frames[burst.pivot][None], burst.warped[burst.pivot][None],
            time_s=None if burst.pivot_time_s is None else [burst.pivot_time_s],
            fpa_c=[burst.fpa_c], unverified=[unverified])
        if added is not None:
            sigma = np.hypot(sigma, added[0]).astype(np.float32)
        if outside and self._foreign(burst):  # forced through another camera's calibration
            sigma = np.hypot(sigma, np.float32(OTHER_CAMERA_SIGMA_C)).astype(np.float32)
        return sigma

    def check(self, frames: np.ndarray, *, registered: bool, homographies: Any) -> None:
        shape = tuple(self.calibration.shape)
        if shape != frames.shape[1:]:
            raise ResolutionMismatchError(
                f"frames are {frames.shape[2]}x{frames.shape[1]} but the calibration is "
                f"{shape[1]}x{shape[0]}"
            )


class OzMean(_ThroughCalibration):
    """Oz et al. eq. 9: the registered average of the per-frame temperatures a calibration
    gives. Each frame goes through ``calibration.apply(frames, fpa_c=…, time_s=…)`` (°C) where
    it lies on the sensor, is warped onto the pivot, and each pivot pixel's valid values are
    averaged."""

    name = "mean"
    per_frame = False
    accepts_registered = True

    def estimate(self, burst: PreparedBurst) -> np.ndarray:
        count = burst.valid.sum(axis=0)
        mean = (burst.warped * burst.valid).sum(axis=0) / np.maximum(count, 1)
        return mean.astype(np.float32)

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> np.ndarray | None:
        """The calibration's σ of one frame, combined with the views' spread ``s``
        (misregistration and what the calibration leaves show there): ``√(σ_cal² + s²)``.
        Neither is divided by the views: the calibration's own error is the same unit's in
        every view, and what misregistration and the warp's interpolation blur at an edge they
        blur alike in every view. Divided by √n, as a standard error of the mean (before
        2026-11-29), σ covered 51 % / 74 % of a 21-frame 64×48 walk's pixels within 1σ / 2σ
        (a helper's audit); whole, 67 / 96 %, and 75–89 % / 99–100 % on four other bursts of
        64×48 and 160×120 where it had covered 54–85 % / 74–97 % (a scratch check, five bursts
        of one unit, its own `lin-lag` and polynomial calibrations)."""
        sigma = super().uncertainty(burst, temperature_c, outside=outside)
        if sigma is None:
            return None
        spread, _ = view_spread(burst.warped, burst.valid)
        return np.sqrt(sigma.astype(np.float64) ** 2 + spread**2).astype(np.float32)


class PivotCalibration(_ThroughCalibration):
    """The pivot frame through a per-frame calibration (``apply`` with the frames' FPA
    temperatures and times, for methods with a rate term): no registration."""

    name = "calibration"
    per_frame = True
    accepts_registered = True

    def estimate(self, burst: PreparedBurst) -> np.ndarray:
        return np.asarray(burst.warped[burst.pivot], dtype=np.float32)


def naive_mean(frames: Any, calibration: Calibration, *, fpa_c: Any = None, **options: Any
               ) -> Estimate:
    """Oz et al. eq. 9 on a burst: the pipeline (:func:`thermocal.estimation.pipeline.estimate`,
    whose keyword ``options`` it takes) with :class:`OzMean` of a fitted ``calibration``."""
    return estimate(frames, OzMean(calibration), fpa_c=fpa_c, **options)
