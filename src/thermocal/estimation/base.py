"""What every estimator is: the :class:`Estimator` protocol, the burst it is given and the
:class:`Estimate` it makes (numpy only)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

__all__ = ["Estimate", "Estimator", "FpaPace", "PreparedBurst", "fpa_pace", "view_spread"]


class FpaPace(NamedTuple):
    """How the FPA temperature was changing at a burst, from its whole recording (a burst's
    fraction of a second cannot show it).

    Attributes
    ----------
    rate_c_per_min : float
        The FPA rate, °C/min.
    lagged_c_per_min : float or None
        The same seen through a first-order lag (:func:`~thermocal.calibration.dataset.lagged_rate`)
        of the time constant the calibration's paces were binned at (its report's ``lag_s``,
        :data:`~thermocal.calibration.report.PACE_LAG_S` so far), °C/min: how it has been
        changing over the last minutes; None without the recording's history or without a
        calibration that judges paces.
    still_s : float or None
        How long the FPA had stayed within the band of its temperature at the burst that the
        calibration's report judges stillness by
        (:func:`~thermocal.calibration.dataset.still_time`), s; None without the recording's
        history or without a calibration that judges it.
    lag_rates : tuple of float or None
        The FPA rate through each lag of a calibration that remembers the rate (``lin-lag``'s
        ``rate_lags_s``), °C/min, from the recording: the history its lag terms need; None
        without it (then they start steady at the burst).
    sustained_s : float or None
        How long the FPA rate had stayed within a cell of its value at the burst
        (:func:`~thermocal.calibration.report.pace_stays`), s, where the calibration's report
        judges how long paces were held (a memoryless method's); None without the recording's
        history or without such a calibration.
    swing_c : float or None
        How far the FPA had run in one direction without pause at the burst, °C, signed
        (:func:`~thermocal.calibration.report.fpa_swings`), where the calibration's report
        judges it (a method with memory's); None without the recording's history or without
        such a calibration.
    """

    rate_c_per_min: float
    lagged_c_per_min: float | None = None
    still_s: float | None = None
    lag_rates: tuple[float, ...] | None = None
    sustained_s: float | None = None
    swing_c: float | None = None


def fpa_pace(rate_c_per_min: float | None, lagged_c_per_min: float | None = None,
             still_s: float | None = None, lag_rates: tuple[float, ...] | None = None, *,
             sustained_s: float | None = None, swing_c: float | None = None
             ) -> FpaPace | None:
    """A burst's :class:`FpaPace`, None without its rate."""
    return (None if rate_c_per_min is None
            else FpaPace(rate_c_per_min, lagged_c_per_min, still_s, lag_rates, sustained_s,
                         swing_c))


@dataclass(frozen=True)
class Estimate:
    """A burst's pivot-frame temperature.

    Attributes
    ----------
    temperature_c : (H, W) float32
        Estimated scene temperature of the pivot frame, °C.
    coverage : (H, W) int
        How many frames see each pivot pixel.
    homographies : (N, 3, 3) float64
        Frame → pivot homographies used.
    pivot : int
        The pivot frame's index in the burst.
    outside : tuple of str
        Why the burst lies outside the estimator's domain (:meth:`Estimator.outside`), when it
        was estimated all the same (``force``); ``()`` inside.
    sigma_c : (H, W) float32 or None
        Standard uncertainty (1σ) of ``temperature_c``, °C (:meth:`Estimator.uncertainty`);
        inflated outside the domain. None: the estimator has no uncertainty model.
    """

    temperature_c: np.ndarray
    coverage: np.ndarray
    homographies: np.ndarray
    pivot: int
    outside: tuple[str, ...] = ()
    sigma_c: np.ndarray | None = None


@dataclass(frozen=True)
class PreparedBurst:
    """A burst after the pipeline's stages, as an estimator's :meth:`Estimator.estimate` gets it.

    Attributes
    ----------
    frames : (N, H, W)
        The raw frames (counts) with their stuck pixels replaced.
    warped : (N, H, W) float32
        The estimator's per-frame input (:meth:`Estimator.calibrate`) warped onto the pivot;
        0 where not ``valid``.
    valid : (N, H, W) bool
        Where each frame sees each pivot pixel.
    homographies : (N, 3, 3) float64
        Frame → pivot.
    pivot : int
    fpa_c : float or None
        The burst's FPA temperature, °C (the mean of the frames'), where it has one.
    fpa_rate_c_per_min : float or None
        How fast the FPA temperature changed at the burst, °C/min, where known (from the whole
        recording: a burst's own fraction of a second cannot show it); for the uncertainty.
    time_since_start_s : float or None
        How long after its recording began the burst was taken, s, where known (an online
        calibration errs most at first); for the uncertainty.
    fpa_lagged_rate_c_per_min : float or None
        The FPA rate through the pace's lag (:class:`FpaPace`), where the recording's history
        is known; for the uncertainty of a calibration with no memory of the FPA's pace.
    fpa_still_s : float or None
        How long the FPA had held still at the burst (:class:`FpaPace`), s, where the
        recording's history is known; for the same.
    fpa_sustained_s : float or None
        How long the FPA had held its pace at the burst (:attr:`FpaPace.sustained_s`), s,
        where the recording's history is known; for the same.
    fpa_swing_c : float or None
        How far the FPA had run one way without pause at the burst (:attr:`FpaPace.swing_c`),
        °C, where the recording's history is known; for a calibration with memory of it.
    fpa_lag_rates_c_per_min : tuple of float or None
        The FPA rate through each lag of a calibration that remembers it
        (:attr:`FpaPace.lag_rates`), given to its calibration; None: it started steady at the
        burst, without the recording's history (σ says so).
    pivot_time_s : float or None
        The pivot frame's time, s, where the frames have times (a shutter calibration's
        offsets are those of the closure before it).
    """

    frames: np.ndarray
    warped: np.ndarray
    valid: np.ndarray
    homographies: np.ndarray
    pivot: int
    fpa_c: float | None
    fpa_rate_c_per_min: float | None = None
    time_since_start_s: float | None = None
    fpa_lagged_rate_c_per_min: float | None = None
    fpa_still_s: float | None = None
    fpa_lag_rates_c_per_min: tuple[float, ...] | None = None
    pivot_time_s: float | None = None
    fpa_sustained_s: float | None = None
    fpa_swing_c: float | None = None

    @property
    def pace(self) -> FpaPace | None:
        """How the FPA was changing at the burst (:func:`fpa_pace`), None where not known."""
        return fpa_pace(self.fpa_rate_c_per_min, self.fpa_lagged_rate_c_per_min,
                        self.fpa_still_s, sustained_s=self.fpa_sustained_s,
                        swing_c=self.fpa_swing_c)


@runtime_checkable
class Estimator(Protocol):
    """Turns a burst of raw frames into its pivot frame's temperature.

    The pipeline (:func:`thermocal.estimation.pipeline.estimate`) validates the burst, calls
    :meth:`check`, registers it, replaces its stuck pixels, calls :meth:`calibrate` on the raw
    frames where they lie on the sensor, warps the result onto the pivot and calls
    :meth:`estimate`. A ``per_frame`` estimator skips registration and warping: it gets the
    pivot frame's calibration alone.

    Attributes
    ----------
    name : str
        The registry name (:data:`thermocal.estimation.registry.ESTIMATORS`).
    n_frames : int or None
        Frames per burst it needs (None: any).
    needs_fpa : bool
        Whether it needs the FPA temperature (:class:`~thermocal.errors.InvalidInputError`
        without one).
    per_frame : bool
        Whether it estimates from the pivot frame alone.
    accepts_registered : bool
        Whether it may be given frames already registered onto the pivot.
    remedy : str
        What to do about a burst outside its domain (:meth:`outside`).
    fpa_paces : dict
        The FPA paces its calibration was judged on (its report's
        :attr:`~thermocal.calibration.report.CalibrationReport.paces`: ``lag_s``, the cells
        held, and ``still`` where the session had not settled), for a calibration with no
        memory of how the FPA changed; ``{}`` for the others. A caller with the whole
        recording (``thermocal flight``) gives each burst its :class:`FpaPace` from it.
    """

    name: str
    n_frames: int | None
    needs_fpa: bool
    per_frame: bool
    accepts_registered: bool
    remedy: str
    fpa_paces: dict[str, Any]

    def check(self, frames: np.ndarray, *, registered: bool, homographies: Any) -> None:
        """Refuse a burst ``(N, H, W)`` it cannot take (size, length), before any work."""
        ...

    def calibrate(self, frames: np.ndarray, fpa_c: Any, time_s: Any, *,
                  pace: FpaPace | None = None) -> np.ndarray:
        """Per-pixel map of raw frames ``(N, H, W)`` where they lie on the sensor, ``(N, H, W)``
        (°C, or the counts themselves); never changes ``frames``. ``fpa_c`` is the burst's FPA
        temperature as given (one value or one per frame, or None), ``time_s`` the frames'
        times (or None), ``pace`` how the FPA was changing as their recording measured it
        (None: not known; a calibration with a rate term takes its rate)."""
        ...

    def outside(self, calibrated: np.ndarray, fpa_c: float | None, *,
                pace: FpaPace | None = None, burst: PreparedBurst | None = None
                ) -> tuple[str, ...]:
        """Why a burst lies outside what the estimator was fitted or trained on, from its
        :meth:`calibrate` output ``(N, H, W)``, FPA temperature (°C) and, where known, how the
        FPA was changing (``pace``) and the prepared burst (``burst``: its raw frames, and
        the same frames registered onto the pivot, or as they lie for a ``per_frame``
        estimator): one clause per failed check, ``()`` inside."""
        ...

    def estimate(self, burst: PreparedBurst) -> np.ndarray:
        """The pivot frame's temperature, °C ``(H, W)`` float32."""
        ...

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> np.ndarray | None:
        """The standard uncertainty (1σ, °C, ``(H, W)`` float32) of :meth:`estimate`'s
        ``temperature_c``, inflated when the burst lies ``outside`` the domain; None without an
        uncertainty model."""
        ...


def view_spread(warped: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How much the views of each pivot pixel disagree: the standard deviation over the frames
    that see it of ``warped`` ``(N, H, W)`` (°C) where ``valid``, and how many frames see it (at
    least 1); ``(H, W)`` float64 each. Misregistration and what a calibration leaves of the
    fixed pattern show there (the uncertainties of :mod:`thermocal.nn.uncertainty` and of
    eq. 9's mean)."""
    w = np.asarray(warped, dtype=np.float64)
    v = np.asarray(valid, dtype=bool)
    n = np.maximum(v.sum(axis=0), 1)
    mean = (w * v).sum(axis=0) / n
    return np.sqrt(((w - mean) ** 2 * v).sum(axis=0) / n), n
