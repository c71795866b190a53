"""Two-point (Riou et al.) and one-point (Schulz & Caldwell) calibration at one FPA temperature.

Each pixel is taken as linear in the band radiance of the scene, ``counts = g · L(T) + o``.
Two-point fits ``g`` and ``o`` per pixel from flat fields of a blackbody at two temperatures
recorded at one FPA temperature; one-point assumes one gain for the whole array and fits the
per-pixel offset from one flat field. Applied at another FPA temperature both drift: that drift is
what the temperature-dependent methods (polynomial, wolf2016, lin) fix.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import as_frames, as_temperature_c, check_same_shape
from thermocal.calibration.base import (
    band_for,
    calibration_info,
    check_frames,
    fill_bad_pixels,
    per_frame_series,
    robust_outliers,
    warn_outside_range,
)
from thermocal.calibration.dataset import (
    STABLE,
    UNSTABLE,
    ChamberData,
    FrameScan,
    group_means,
    prepare_chamber,
)
from thermocal.calibration.store import (
    FPA_LIMITS_C,
    FileLayout,
    StoredCalibration,
    StoredCalibrationMixin,
    check_band,
    check_offsets,
    check_response,
    check_scalar,
    damaged,
)
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FitError
from thermocal.radiometry import BandRadiance

METHOD = "two-point"
METHODS = ("two-point", "one-point")


@dataclass(frozen=True, eq=False)
class TwoPointCalibration(StoredCalibrationMixin):
    """Per-pixel gain (counts per W·m⁻²·sr⁻¹) and offset (counts), ``(H, W)`` float32.

    ``bad`` marks pixels whose fit is unusable (dead, hot, non-positive or outlying gain); their
    output is the median of their 3×3 neighbourhood. ``method`` is ``"two-point"`` or
    ``"one-point"`` (one gain for all pixels). ``fpa_range_c`` is the FPA range of the frames
    it was fitted on; applying it elsewhere warns.
    """

    gain: np.ndarray
    offset: np.ndarray
    bad: np.ndarray
    fpa_ref_c: float
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    info: dict[str, Any] = field(default_factory=dict)
    method: str = METHOD
    fpa_range_c: tuple[float, float] | None = None

    _layout = FileLayout(
        methods=METHODS, arrays={"gain": np.float32, "offset": np.float32, "bad": bool},
        metadata={"fpa_ref_c": float, "band_m": tuple}, fpa_range="fpa_range",
    )

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape ``(H, W)``."""
        return self.gain.shape  # type: ignore[return-value]

    @classmethod
    def _check_fields(cls, kw: dict[str, Any], stored: StoredCalibration,
                      path: str | Path) -> None:
        """See :func:`check_linear_gain`; one-point also has one gain for every pixel."""
        super()._check_fields(kw, stored, path)
        check_linear_gain(kw, stored.method, path)
        if stored.method == "one-point" and np.ptp(kw["gain"]) != 0:
            raise damaged(path, stored.method, "one-point has one gain for every pixel, the "
                                               "file's differ")

    @property
    def fpa_range(self) -> tuple[float, float]:
        """FPA range covered, °C (the reference ± 0.5 °C when unknown)."""
        if self.fpa_range_c is not None:
            return self.fpa_range_c
        return (self.fpa_ref_c - 0.5, self.fpa_ref_c + 0.5)

    def apply(self, frames: Any, *, fpa_c: Any = None, time_s: Any = None) -> np.ndarray:
        """Scene temperature, °C, ``(N, H, W)`` float32, from raw counts ``(N, H, W)``.

        ``fpa_c`` (°C, scalar or ``(N,)``) is only checked against the calibrated range (a
        warning when outside); ``time_s`` is ignored.
        """
        counts = check_frames(frames, self.shape)
        if fpa_c is not None:
            warn_outside_range(per_frame_series(fpa_c, len(counts), "fpa_c"), self.fpa_range,
                               self.method)
        band = band_for(tuple(self.band_m))
        lo, hi = band.radiance_range
        out = np.empty(counts.shape, dtype=np.float32)
        inv_gain = (1.0 / self.gain).astype(np.float32)
        for k, frame in enumerate(counts):
            radiance = (frame.astype(np.float32) - self.offset) * inv_gain
            np.clip(radiance, lo, hi, out=radiance)
            out[k] = band.temperature(radiance) - np.float32(ZERO_CELSIUS_K)
        return fill_bad_pixels(out, self.bad)


def check_linear_gain(kw: dict[str, Any], method: str, path: str | Path) -> None:
    """The load checks of a linear per-pixel model ``counts = gain · L + offset`` (two-point,
    one-point, shutter), beyond finiteness: the band within
    :data:`~thermocal.calibration.store.BAND_LIMITS_M`; ``fpa_ref_c`` within
    :data:`~thermocal.calibration.store.FPA_LIMITS_C`; every gain positive (a fit marks a pixel
    with a non-positive gain bad and gives it the median gain), with a 0 → 100 °C response of
    :data:`~thermocal.calibration.store.RESPONSE_LIMITS_COUNTS`; offsets within
    :data:`~thermocal.calibration.store.OFFSET_LIMIT_COUNTS`."""
    check_band(kw["band_m"], path, method)
    check_scalar(kw["fpa_ref_c"], "fpa_ref_c", *FPA_LIMITS_C, path, method, unit="°C")
    band = band_for(tuple(kw["band_m"]))
    span = float(band.radiance(np.float64(100.0 + ZERO_CELSIUS_K))
                 - band.radiance(np.float64(ZERO_CELSIUS_K)))
    gain = np.asarray(kw["gain"], dtype=np.float64)
    if not np.all(gain > 0):
        raise damaged(path, method, "a gain is not positive")
    check_response(gain * span, path, method, "(gain)")
    check_offsets(kw["offset"], "offset", path, method)


def fit_two_point(
    frames_low: Any,
    frames_high: Any,
    t_low_c: float,
    t_high_c: float,
    *,
    fpa_ref_c: float,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    outlier_mads: float = 8.0,
) -> TwoPointCalibration:
    """Fit gain and offset from flat fields at two blackbody temperatures (°C).

    ``frames_low`` and ``frames_high`` are ``(N, H, W)`` raw counts (averaged over N), taken at the
    FPA temperature ``fpa_ref_c``. The blackbody temperatures are radiance temperatures (emissivity
    already accounted for). Pixels with a gain more than ``outlier_mads`` median absolute
    deviations from the median, or not positive, are marked bad.
    """
    low = as_frames(frames_low, "frames_low")
    high = as_frames(frames_high, "frames_high")
    check_same_shape(low, high, "frames_low", "frames_high")
    t_low, t_high = as_temperature_c([t_low_c, t_high_c], "blackbody temperatures")
    return _two_point_from_means(
        low.mean(axis=0, dtype=np.float64), high.mean(axis=0, dtype=np.float64),
        float(t_low), float(t_high), fpa_ref_c=float(fpa_ref_c), band_m=tuple(band_m),
        outlier_mads=outlier_mads,
    )


def _two_point_from_means(
    mean_low: np.ndarray, mean_high: np.ndarray, t_low: float, t_high: float, *,
    fpa_ref_c: float, band_m: tuple[float, float], outlier_mads: float,
    extra_bad: np.ndarray | None = None, fpa_range_c: tuple[float, float] | None = None,
    info: dict[str, Any] | None = None,
) -> TwoPointCalibration:
    if abs(t_high - t_low) < 1.0:
        raise FitError(
            f"two-point calibration needs blackbody temperatures at least 1 °C apart, "
            f"got {t_low:.2f} and {t_high:.2f} °C"
        )
    band = band_for(tuple(band_m))
    l_low, l_high = (float(band.radiance(np.float64(t + ZERO_CELSIUS_K))) for t in (t_low, t_high))
    gain = (mean_high - mean_low) / (l_high - l_low)
    offset = mean_low - gain * l_low
    bad = robust_outliers(gain, mads=outlier_mads) | (gain <= 0)
    if extra_bad is not None:
        bad |= extra_bad
    if bad.mean() > 0.5:
        raise FitError("two-point calibration: more than half of the pixels did not respond")
    median = float(np.median(gain[~bad]))
    gain = np.where(bad, median, gain)
    return TwoPointCalibration(
        gain=gain.astype(np.float32),
        offset=offset.astype(np.float32),
        bad=bad,
        fpa_ref_c=float(fpa_ref_c),
        band_m=tuple(band_m),
        fpa_range_c=fpa_range_c,
        info=dict(info or {}),
    )


def _reference_frames(
    data: ChamberData, fpa_ref_c: float | None, fpa_tolerance_c: float
) -> tuple[float, np.ndarray]:
    """The reference FPA temperature (default: the first frame's) and the frames near it."""
    ref = float(data.fpa_c[np.flatnonzero(data.usable)[0]]) if fpa_ref_c is None else fpa_ref_c
    near = (
        data.usable
        & (np.abs(data.fpa_c - ref) <= fpa_tolerance_c)
        & (data.stability != UNSTABLE)
    )
    # Prefer stable frames (no transient); fall back to relatively stable ones if they cover
    # fewer than two set points.
    stable = near & (data.stability == STABLE)
    if np.unique(np.round(data.session.blackbody_c[stable], 6)).size >= 2:
        near = stable
    if not near.any():
        raise FitError(
            f"no settled frame with the FPA within ±{fpa_tolerance_c:g} °C of {ref:.2f} °C; "
            f"the chamber data cover {data.fpa_c.min():.2f}…{data.fpa_c.max():.2f} °C"
        )
    return ref, near


def _mean_scene_c(data: ChamberData, sel: np.ndarray, band: BandRadiance) -> float:
    """Radiance-mean scene temperature of the selected frames, °C."""
    radiance = band.radiance(data.scene_c[sel] + ZERO_CELSIUS_K).mean()
    return float(band.temperature(radiance)) - ZERO_CELSIUS_K


def two_point(
    session: Any,
    *,
    fpa_ref_c: float | None = None,
    low_c: float | None = None,
    high_c: float | None = None,
    fpa_tolerance_c: float = 0.5,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    outlier_mads: float = 8.0,
    chunk: int = 64,
) -> TwoPointCalibration:
    """Two-point calibration from a chamber session at one FPA temperature.

    Parameters
    ----------
    session : ChamberSession, ChamberData or path
        The chamber data.
    fpa_ref_c : float, optional
        Reference FPA temperature, °C; default the FPA reading of the first frame.
    low_c, high_c : float, optional
        The two blackbody set points, °C; default the lowest and highest recorded near the
        reference FPA temperature.
    fpa_tolerance_c : float
        Frames within ``± fpa_tolerance_c`` of the reference are used: the stable ones when
        they cover two set points, else the stable and relatively stable ones.
    """
    data = prepare_chamber(session)
    ref, near = _reference_frames(data, fpa_ref_c, fpa_tolerance_c)
    bb = np.round(data.session.blackbody_c, 6)
    points = np.unique(bb[near])
    if points.size < 2:
        raise FitError(
            f"two-point calibration needs 2 blackbody set points near FPA {ref:.2f} °C, found "
            f"{points.size}; record set points at this FPA temperature, or choose as reference "
            "(--fpa-ref-c) an FPA temperature the session held for 2 set points"
        )
    lo = float(points[0] if low_c is None else low_c)
    hi = float(points[-1] if high_c is None else high_c)
    groups = np.full(data.n_frames, -1)
    for g, value in enumerate((lo, hi)):
        sel = near & (np.abs(bb - value) < 1e-6)
        if not sel.any():
            raise FitError(f"no frame at blackbody {value:g} °C near FPA {ref:.2f} °C")
        groups[sel] = g
    scan = FrameScan(data.frame_shape, data.session.bit_depth)
    means, _ = group_means(data, groups, 2, chunk=chunk, scan=scan)
    band = band_for(tuple(band_m))
    t = [_mean_scene_c(data, groups == g, band) for g in (0, 1)]
    used = data.fpa_c[groups >= 0]
    info = calibration_info(data.session) | scan.report() | {
        "setpoints_c": [lo, hi], "frames_used": scan.n_seen,
        "stable_frames_used": int(((groups >= 0) & (data.stability == STABLE)).sum()),
    }
    return _two_point_from_means(
        means[0], means[1], t[0], t[1], fpa_ref_c=ref, band_m=tuple(band_m),
        outlier_mads=outlier_mads, extra_bad=scan.saturated_pixels(),
        fpa_range_c=(float(used.min()), float(used.max())), info=info,
    )


def one_point(
    session: Any,
    *,
    fpa_ref_c: float | None = None,
    setpoint_c: float | None = None,
    gain: float | None = None,
    fpa_tolerance_c: float = 0.5,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    outlier_mads: float = 8.0,
    chunk: int = 64,
) -> TwoPointCalibration:
    """One-point calibration: one gain for the whole array, per-pixel offsets from one flat field.

    ``gain`` (counts per W·m⁻²·sr⁻¹) is the array's responsivity; when not given it is the
    slope of the frame-mean counts between the lowest and highest set points near the reference
    FPA temperature. The per-pixel offset comes from the flat field at ``setpoint_c`` (default
    the set point nearest the middle of those recorded).
    """
    data = prepare_chamber(session)
    ref, near = _reference_frames(data, fpa_ref_c, fpa_tolerance_c)
    bb = np.round(data.session.blackbody_c, 6)
    points = np.unique(bb[near])
    band = band_for(tuple(band_m))
    if setpoint_c is None:
        setpoint_c = float(points[np.argmin(np.abs(points - np.median(points)))])
    chosen = [float(setpoint_c)]
    if gain is None:
        if points.size < 2:
            raise FitError(
                "one-point calibration without a given gain needs 2 set points near the "
                f"reference FPA {ref:.2f} °C to estimate it, found {points.size}"
            )
        chosen += [float(points[0]), float(points[-1])]
    # one group per distinct set point (the flat field may be an end point too)
    distinct = sorted(set(chosen))
    groups = np.full(data.n_frames, -1)
    for g, value in enumerate(distinct):
        sel = near & (np.abs(bb - value) < 1e-6)
        if not sel.any():
            raise FitError(f"no frame at blackbody {value:g} °C near FPA {ref:.2f} °C")
        groups[sel] = g
    scan = FrameScan(data.frame_shape, data.session.bit_depth)
    group_mean, _ = group_means(data, groups, len(distinct), chunk=chunk, scan=scan)
    order = [distinct.index(v) for v in chosen]
    means = group_mean[order]
    temps = [_mean_scene_c(data, groups == g, band) for g in order]
    rad = [float(band.radiance(t + ZERO_CELSIUS_K)) for t in temps]
    bad = scan.saturated_pixels()
    if gain is None:
        valid = ~bad
        gain = float(
            (np.median(means[2][valid]) - np.median(means[1][valid])) / (rad[2] - rad[1])
        )
    if not gain > 0:
        raise FitError(f"one-point calibration: the array gain {gain:.3g} is not positive")
    offset = means[0] - gain * rad[0]
    bad = bad | robust_outliers(offset, mads=4 * outlier_mads)
    used = data.fpa_c[groups >= 0]
    info = calibration_info(data.session) | scan.report() | {
        "setpoints_c": distinct, "frames_used": scan.n_seen}
    return TwoPointCalibration(
        gain=np.full(offset.shape, gain, dtype=np.float32),
        offset=offset.astype(np.float32),
        bad=bad,
        fpa_ref_c=ref,
        band_m=tuple(band_m),
        info=info,
        method="one-point",
        fpa_range_c=(float(used.min()), float(used.max())),
    )
