"""The estimation pipeline: a burst of raw frames → its pivot frame's temperature.

One path for every estimator (:mod:`thermocal.estimation.registry`) and every caller
(``thermocal estimate``, ``thermocal flight``, the demo, the benchmarks), in named stages:

1. **validate** the burst (:func:`thermocal.burst.check_burst`), the pivot and the FPA
   temperature, then the estimator's own checks;
2. **register** it onto the pivot (homographies given, taken as registered, or found:
   :func:`thermocal.burst.find_homographies`);
3. **fill** its stuck pixels (:func:`thermocal.burst.fill_stuck_pixels`);
4. **calibrate** each raw frame where it lies on the sensor (the estimator's per-pixel map);
5. **warp** the calibrated frames onto the pivot and check the overlap, then check that the
   burst lies inside the estimator's domain (refused otherwise, unless ``force``; the
   calibration's warnings are given only to a burst not refused: a refusal is one message);
6. **estimate** the pivot's temperature and its uncertainty (the estimator) → :class:`Estimate`.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np

from thermocal._validate import FPA_RANGE_C
from thermocal.burst import (
    check_burst,
    check_overlap,
    fill_stuck_pixels,
    find_homographies,
    fpa_value,
    pivot_index,
)
from thermocal.errors import InvalidInputError, OutsideDomainError
from thermocal.estimation.base import Estimate, Estimator, FpaPace, PreparedBurst, fpa_pace
from thermocal.registration.warp import warp_to_pivot
from thermocal.threads import caught_warnings

__all__ = ["calibrate_stage", "checked_stage", "domain_stage", "estimate", "refuse_unchecked",
           "register_stage"]


def register_stage(
    frames: np.ndarray, pivot: int, *, registered: bool, homographies: Any
) -> np.ndarray:
    """Stage 2: frame → pivot homographies ``(N, 3, 3)``: ``homographies`` as given, the
    identity for ``registered`` frames, or found by registration."""
    if registered and homographies is None:
        return np.repeat(np.eye(3)[None], frames.shape[0], axis=0)
    return find_homographies(frames, pivot, homographies)


def domain_stage(estimator: Estimator, calibrated: np.ndarray, fpa_c: float | None, *,
                 force: bool, pace: FpaPace | None = None,
                 burst: PreparedBurst | None = None) -> tuple[str, ...]:
    """Stage 5's check: why the burst, at FPA temperature ``fpa_c`` (°C) changing at ``pace``
    (where known), lies outside ``estimator``'s domain (``()`` inside). ``calibrated`` is its
    frames through the estimator's calibration where they lie on the sensor ``(N, H, W)``;
    ``burst`` the prepared burst: the same registered onto the pivot, or for a per-frame
    estimator (``per_frame``) as they lie, with its raw frames.

    Raises
    ------
    OutsideDomainError
        Outside, unless ``force``: one line with every reason and the estimator's remedy.
    """
    reasons = estimator.outside(calibrated, fpa_c, pace=pace, burst=burst)
    if reasons and not force:
        raise OutsideDomainError(f"{'; '.join(reasons)}; {estimator.remedy}")
    return reasons


def refuse_unchecked(estimator: Estimator, source: Any, *, force: bool) -> None:
    """Before any work: an estimator that can check no burst against its domain (one built
    from a calibration file without its cross-validation report: ``unchecked()``) is refused
    with one line naming ``source`` (the file) and its remedy, unless ``force``.

    Raises
    ------
    OutsideDomainError
    """
    unchecked = getattr(estimator, "unchecked", None)
    why = unchecked() if unchecked is not None else None
    if why and not force:
        raise OutsideDomainError(f"{source}: {why}; {estimator.remedy}")


def calibrate_stage(estimator: Estimator, frames: np.ndarray, fpa_c: Any, time_s: Any, *,
                    pace: FpaPace | None) -> tuple[np.ndarray, list[warnings.WarningMessage]]:
    """Stage 4: the frames through ``estimator``'s calibration (``fpa_c`` and ``time_s`` as
    it takes them) and the warnings it raised (e.g. an FPA outside its range), held back for
    :func:`checked_stage`: a refused burst is told once, by its refusal."""
    with caught_warnings() as raised:
        calibrated = estimator.calibrate(frames, fpa_c, time_s, pace=pace)
    return calibrated, raised


def checked_stage(estimator: Estimator, calibrated: np.ndarray, burst: PreparedBurst,
                  raised: list[warnings.WarningMessage], *, force: bool, pace: FpaPace | None
                  ) -> tuple[str, ...]:
    """:func:`domain_stage` of a prepared burst, then the calibration's held-back warnings."""
    outside = domain_stage(estimator, calibrated, burst.fpa_c, force=force, pace=pace,
                           burst=burst)
    for w in raised:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return outside


def estimate(
    frames: Any,
    estimator: Estimator,
    *,
    fpa_c: Any = None,
    time_s: Any = None,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
    fill_defects: bool = True,
    force: bool = False,
    fpa_rate_c_per_min: float | None = None,
    time_since_start_s: float | None = None,
    fpa_lagged_rate_c_per_min: float | None = None,
    fpa_still_s: float | None = None,
    fpa_lag_rates_c_per_min: Any = None,
    fpa_sustained_s: float | None = None,
    fpa_swing_c: float | None = None,
    bit_depth: int = 14,
    fpa_sigma_c: float = 0.0,
) -> Estimate:
    """The pivot frame's temperature of a raw burst through ``estimator``.

    Parameters
    ----------
    frames : (N, H, W) array_like
        Raw counts (14-bit).
    estimator : Estimator
        From :func:`thermocal.estimation.registry.make_estimator` (or any object of the
        :class:`~thermocal.estimation.base.Estimator` protocol).
    fpa_c : float or (N,) array_like, optional
        FPA temperature, °C (one value or one per frame).
    time_s : (N,) array_like, optional
        Frame times, s (for calibrations with a rate term).
    pivot : int, optional
        Pivot frame (default the middle one).
    registered : bool
        The frames are already registered onto the pivot: no registration, no stuck-pixel
        filling (they no longer stay in place); pixels at 0 counts are not covered.
    homographies : (N, 3, 3) array_like, optional
        Known frame → pivot homographies (skips registration).
    fill_defects : bool
        Replace the burst's stuck pixels by their neighbours' median before calibrating
        (otherwise each leaves a short trail along the motion).
    force : bool
        Estimate a burst outside the estimator's domain all the same; the reasons are kept in
        :attr:`Estimate.outside`.
    fpa_rate_c_per_min : float, optional
        How fast the FPA temperature changed at the burst, °C/min (from the whole recording),
        for the estimators whose uncertainty depends on it (the calibrations).
    time_since_start_s : float, optional
        How long after its recording began the burst was taken, s (for an online
        calibration's uncertainty).
    fpa_lagged_rate_c_per_min : float, optional
        The FPA rate through the pace's lag, °C/min (:class:`~thermocal.estimation.base.FpaPace`,
        from the whole recording): with ``fpa_rate_c_per_min``, a calibration with no memory of
        the FPA's pace refuses a pace its chamber session never held (unless ``force``: σ grown).
    fpa_still_s : float, optional
        How long the FPA had held still at the burst, s
        (:class:`~thermocal.estimation.base.FpaPace`, from the whole recording): such a
        calibration whose session had not settled refuses a camera held still longer than its
        session's plateaus held it (unless ``force``: σ grown).
    fpa_lag_rates_c_per_min : (K,) array_like, optional
        The FPA rate through each lag of a calibration that remembers it (``lin-lag``'s
        ``rate_lags_s``), °C/min, from the whole recording (with ``fpa_rate_c_per_min``):
        without it, its lag terms start steady at the burst and σ is that of frames without
        their history.
    fpa_sustained_s : float, optional
        How long the FPA had held its pace at the burst, s
        (:attr:`~thermocal.estimation.base.FpaPace.sustained_s`, from the whole recording): a
        calibration with no memory of the FPA's pace refuses a pace held longer than its
        chamber session held it (unless ``force``: σ grown).
    fpa_swing_c : float, optional
        How far the FPA had run one way without pause at the burst, °C, signed
        (:attr:`~thermocal.estimation.base.FpaPace.swing_c`, from the whole recording): a
        calibration with memory of the FPA's history refuses a longer run than its chamber
        session's (unless ``force``: σ grown).
    bit_depth : int
        The counts' bit depth (14 for a Tau2 core; 16 for FLIR files): saturation is at
        ``2**bit_depth − 1``.
    fpa_sigma_c : float
        The standard uncertainty of ``fpa_c``, °C (0: exact, a camera's own reading): σ takes
        in quadrature how far the estimate moves per °C of it (:func:`fpa_sensitivity`) times
        this, for an FPA temperature typed rather than measured (``--fpa-sigma-c``).

    Raises
    ------
    InvalidInputError
        A bad burst (saturated, constant, wrong length or size), pivot or FPA temperature.
    OutsideDomainError
        The burst lies outside what the estimator was fitted or trained on (not with
        ``force``).
    RegistrationError
        Registration failed or the frames do not overlap.
    """
    kwargs = {"time_s": time_s, "pivot": pivot, "registered": registered,
              "homographies": homographies, "fill_defects": fill_defects, "force": force,
              "fpa_rate_c_per_min": fpa_rate_c_per_min, "time_since_start_s": time_since_start_s,
              "fpa_lagged_rate_c_per_min": fpa_lagged_rate_c_per_min,
              "fpa_still_s": fpa_still_s, "fpa_lag_rates_c_per_min": fpa_lag_rates_c_per_min,
              "fpa_sustained_s": fpa_sustained_s, "fpa_swing_c": fpa_swing_c,
              "bit_depth": bit_depth}
    result = _estimate(frames, estimator, fpa_c=fpa_c, **kwargs)
    sigma_fpa = float(fpa_sigma_c)
    if sigma_fpa:
        check_fpa_sigma(fpa_c, sigma_fpa)
    if sigma_fpa == 0.0 or result.sigma_c is None:
        return result
    moved = fpa_sensitivity(frames, estimator, result, fpa_c=fpa_c, **kwargs)
    sigma = np.hypot(result.sigma_c, moved * sigma_fpa).astype(np.float32)
    return dataclasses.replace(result, sigma_c=sigma)


#: The largest standard uncertainty of a typed FPA temperature, °C: beyond it the temperature
#: is not known at all.
MAX_FPA_SIGMA_C = 20.0

#: ``--fpa-sigma-c``'s help: what it is and what it does.
FPA_SIGMA_HELP = ("Standard uncertainty of --fpa-c, °C (a value typed, not the camera's "
                  "reading): σ grows by how far the temperatures move per °C of it, which costs "
                  "a second pass of the method.")

#: The step of :func:`fpa_sensitivity`, °C.
FPA_STEP_C = 1.0


def check_fpa_sigma(fpa_c: float | None, fpa_sigma_c: float | None,
                    sigma_out: Any = True) -> None:
    """Refuse ``--fpa-sigma-c`` without the ``--fpa-c`` it qualifies, without a σ to write
    (``sigma_out`` None: it would cost a second pass for nothing), or out of range."""
    if fpa_sigma_c is None:
        return
    if fpa_c is None:
        raise InvalidInputError("--fpa-sigma-c is the uncertainty of --fpa-c: give --fpa-c too "
                                "(an FPA temperature the recording holds is the camera's own "
                                "reading, whose uncertainty σ holds already)")
    if sigma_out is None:
        raise InvalidInputError("--fpa-sigma-c grows σ: give --sigma-out too, or leave it out")
    if not 0.0 <= fpa_sigma_c <= MAX_FPA_SIGMA_C:  # NaN too
        raise InvalidInputError(f"--fpa-sigma-c must be 0-{MAX_FPA_SIGMA_C:g} °C, got "
                                f"{fpa_sigma_c:g}")


def fpa_sensitivity(frames: Any, estimator: Estimator, result: Estimate, *, fpa_c: Any,
                    **kwargs: Any) -> np.ndarray:
    """How far each pixel of ``result`` (:func:`estimate` of ``frames`` at ``fpa_c``) moves per
    °C of the FPA temperature, °C/°C ``(H, W)``: the burst estimated again (its registration
    kept, forced: only the temperatures count) at ``fpa_c`` + :data:`FPA_STEP_C`, the
    difference. The shipped network's moved 0.48–0.58 °C per °C (median; three ``tau2`` units,
    160×120: a typed FPA 15 °C off read 7.7 °C off where σ had said 0.84)."""
    if not kwargs.get("registered"):
        kwargs = kwargs | {"homographies": result.homographies}
    fpa = np.asarray(fpa_c, dtype=np.float64)
    step = fpa_step(fpa)
    with caught_warnings():  # its warnings are the first run's, or of its forcing: not told
        moved = _estimate(frames, estimator, fpa_c=fpa + step, **(kwargs | {"force": True}))
    return np.abs(moved.temperature_c.astype(np.float64)
                  - result.temperature_c.astype(np.float64)) / FPA_STEP_C


def fpa_step(fpa_c: Any) -> float:
    """The FPA step of :func:`fpa_sensitivity`, °C: :data:`FPA_STEP_C` up, or down where up
    would leave the plausible FPA range (:data:`~thermocal._validate.FPA_RANGE_C`)."""
    top = float(np.max(np.asarray(fpa_c, dtype=np.float64)))
    return -FPA_STEP_C if top + FPA_STEP_C > FPA_RANGE_C[1] else FPA_STEP_C


def _estimate(frames: Any, estimator: Estimator, *, fpa_c: Any, time_s: Any = None,
              pivot: int | None = None, registered: bool = False, homographies: Any = None,
              fill_defects: bool = True, force: bool = False,
              fpa_rate_c_per_min: float | None = None, time_since_start_s: float | None = None,
              fpa_lagged_rate_c_per_min: float | None = None, fpa_still_s: float | None = None,
              fpa_lag_rates_c_per_min: Any = None, fpa_sustained_s: float | None = None,
              fpa_swing_c: float | None = None, bit_depth: int = 14) -> Estimate:
    """:func:`estimate` at the FPA temperature ``fpa_c`` taken as exact."""
    # 1. validate
    arr = check_burst(frames, registered=registered, bit_depth=bit_depth)
    p = pivot_index(pivot, arr.shape[0])
    estimator.check(arr, registered=registered, homographies=homographies)
    # the burst's FPA temperature: required by some estimators, used by all that get one (their
    # domain and uncertainty)
    fpa = fpa_value(fpa_c, arr.shape[0]) if estimator.needs_fpa or fpa_c is not None else None
    lag_rates = (None if fpa_lag_rates_c_per_min is None
                 else tuple(float(v) for v in np.asarray(fpa_lag_rates_c_per_min).reshape(-1)))
    pace = fpa_pace(fpa_rate_c_per_min, fpa_lagged_rate_c_per_min, fpa_still_s, lag_rates,
                    sustained_s=fpa_sustained_s, swing_c=fpa_swing_c)
    lag_rates = None if pace is None else lag_rates  # given to the calibration with its rate
    # the pivot's time, for a calibration whose correction depends on it (a shutter's
    # closures): one time for every frame, as the calibrations take it, or the pivot's own
    times = None if time_s is None else np.asarray(time_s, dtype=np.float64).reshape(-1)
    pivot_time = (float(times[0]) if times is not None and times.size == 1
                  else float(times[p]) if times is not None and times.size == arr.shape[0]
                  else None)  # another length: the calibration refuses it
    if estimator.per_frame:  # the pivot frame alone: its calibration, not registered
        if fpa is not None and np.size(fpa_c) == arr.shape[0] > 1:  # its own FPA, not the mean
            fpa = float(np.asarray(fpa_c, dtype=np.float64).reshape(-1)[p])
        if fill_defects and not registered:  # its clipped defects, as a burst's (a frame
            # alone shows no stuck pixel): a saturated pixel read 80 °C with σ 1 over 17 °C;
            # a saturated object (a larger group) is left for the domain check
            pivot_frame, isolated = fill_stuck_pixels(arr[p : p + 1], top=2**bit_depth - 1)
            if isolated.any():
                arr = arr.copy()
                arr[p] = pivot_frame[0]
        valid = np.zeros(arr.shape, dtype=bool)
        valid[p] = True
        hs = np.repeat(np.eye(3)[None], arr.shape[0], axis=0)
        calibrated, raised = calibrate_stage(estimator, arr, fpa_c, time_s, pace=pace)
        burst = PreparedBurst(arr, calibrated, valid, hs, p, fpa, fpa_rate_c_per_min,
                              time_since_start_s, fpa_lagged_rate_c_per_min, fpa_still_s,
                              lag_rates, pivot_time, fpa_sustained_s, fpa_swing_c)
        # the pivot alone is estimated: the pivot alone is checked (a recording's other frames
        # may lie anywhere: a chamber session's cycle through its set points)
        outside = checked_stage(estimator, calibrated[p : p + 1], burst, raised, force=force,
                                pace=pace)
        return _estimate_of(estimator, burst, outside)
    if registered and not estimator.accepts_registered:
        raise InvalidInputError(
            "each frame is calibrated where it lies on the sensor, before registration: give "
            "the burst as recorded (not --registered)"
        )
    # 2. register
    hs = register_stage(arr, p, registered=registered, homographies=homographies)
    # 3. fill stuck pixels
    filled = (fill_stuck_pixels(arr, hs, top=2**bit_depth - 1)[0]
              if fill_defects and not registered else arr)
    # 4. calibrate
    calibrated, raised = calibrate_stage(estimator, filled,
                                         fpa if estimator.needs_fpa else fpa_c, time_s, pace=pace)
    # 5. warp, and check the domain
    if registered and homographies is None:
        warped = np.asarray(calibrated, dtype=np.float32)
        valid = arr > 0
        valid[p] = True
    else:
        warped, valid = warp_to_pivot(calibrated, hs)
    check_overlap(valid, p)
    burst = PreparedBurst(filled, warped, valid, hs, p, fpa, fpa_rate_c_per_min,
                          time_since_start_s, fpa_lagged_rate_c_per_min, fpa_still_s, lag_rates,
                          pivot_time, fpa_sustained_s, fpa_swing_c)
    outside = checked_stage(estimator, calibrated, burst, raised, force=force, pace=pace)
    # 6. estimate
    return _estimate_of(estimator, burst, outside)


def _estimate_of(estimator: Estimator, burst: PreparedBurst, outside: tuple[str, ...]
                 ) -> Estimate:
    """Stage 6: the estimate and its uncertainty."""
    temperature = estimator.estimate(burst)
    sigma = estimator.uncertainty(burst, temperature, outside=bool(outside))
    return Estimate(temperature, burst.valid.sum(axis=0), burst.homographies, burst.pivot,
                    outside, sigma)
