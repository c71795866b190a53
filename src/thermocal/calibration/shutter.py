"""Shutter-based baseline: two-point gains, offsets re-referenced on a shutter (FLIR GEV style).

The workflow of Lin et al. Fig. 5b: the per-pixel gain comes from a two-point calibration at a
reference FPA temperature; every few minutes the camera closes its shutter, a uniform source
assumed to be at the FPA sensor's temperature, and each pixel's offset is re-referenced to it:
``o_p = Y_shutter,p − g_p · L(T_fpa)``. Between shutter events the last offset holds. The
assumption that the shutter sits at the FPA temperature fails when the FPA changes fast (the
shutter lags), which is what Lin et al. improve on.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.calibration.base import (
    ThermocalWarning,
    band_for,
    check_frames,
    fill_bad_pixels,
    per_frame_series,
    warn_outside_range,
)
from thermocal.calibration.store import (
    FileLayout,
    StoredCalibration,
    StoredCalibrationMixin,
    check_offsets,
    check_scalar,
    damaged,
)
from thermocal.calibration.two_point import TwoPointCalibration, check_linear_gain, two_point
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError

METHOD = "shutter"


@dataclass(frozen=True, eq=False)
class ShutterCalibration(StoredCalibrationMixin):
    """Per-pixel gain and reference offset ``(H, W)``, and the shutter offsets recorded so far.

    ``event_time_s`` ``(E,)`` and ``event_offset`` ``(E, H, W)``: the offsets from each shutter
    closure (see :meth:`with_shutter`); with none, the reference offset is used.
    """

    gain: np.ndarray
    offset: np.ndarray
    bad: np.ndarray
    fpa_ref_c: float
    fpa_range_c: tuple[float, float]
    interval_s: float = 180.0
    event_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    event_offset: np.ndarray | None = None
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    info: dict[str, Any] = field(default_factory=dict)

    method = METHOD
    _layout = FileLayout(
        methods=(METHOD,), arrays={"gain": np.float32, "offset": np.float32, "bad": bool},
        metadata={"fpa_ref_c": float, "interval_s": float, "band_m": tuple},
        optional_arrays=("event_time_s", "event_offset"),
    )

    @property
    def shape(self) -> tuple[int, int]:
        return self.bad.shape  # type: ignore[return-value]

    @classmethod
    def _check_fields(cls, kw: dict[str, Any], stored: StoredCalibration,
                      path: str | Path) -> None:
        """Two-point's checks (:func:`~thermocal.calibration.two_point.check_linear_gain`);
        ``interval_s`` in (0, 1 day] s; the shutter events: times ``(E,)`` finite and in order
        (``apply`` looks them up by bisection), offsets ``(E, H, W)`` finite, within
        :data:`~thermocal.calibration.store.OFFSET_LIMIT_COUNTS`, one per time."""
        super()._check_fields(kw, stored, path)
        method = stored.method
        check_linear_gain(kw, method, path)
        check_scalar(kw["interval_s"], "interval_s", 0.0, 86400.0, path, method, unit="s",
                     low_open=True)
        times = np.asarray(kw.get("event_time_s", np.zeros(0)))
        offsets = kw.get("event_offset")
        if (times.ndim != 1 or times.dtype.kind not in "iuf" or not np.all(np.isfinite(times))
                or np.any(np.diff(times) < 0)):
            raise damaged(path, method, "event_time_s is not a finite series in time order")
        if offsets is None:
            if times.size:
                raise damaged(path, method, "shutter event times without their offsets")
            return
        offsets = np.asarray(offsets)
        if offsets.shape != (times.size, *stored.shape) or offsets.dtype.kind not in "iuf":
            raise damaged(path, method, f"event_offset has shape {offsets.shape}, expected "
                                        f"{(times.size, *stored.shape)}")
        check_offsets(offsets, "event_offset", path, method)

    @classmethod
    def from_two_point(cls, cal: TwoPointCalibration, *, interval_s: float = 180.0
                       ) -> ShutterCalibration:
        return cls(gain=cal.gain, offset=cal.offset, bad=cal.bad, fpa_ref_c=cal.fpa_ref_c,
                   fpa_range_c=cal.fpa_range, interval_s=interval_s, band_m=cal.band_m,
                   info=dict(cal.info))

    def with_shutter(self, frames: Any, *, fpa_c: Any, time_s: Any) -> ShutterCalibration:
        """Add shutter closures: frames ``(E, H, W)`` of the closed shutter, the FPA sensor (°C)
        and the time (s) of each. Returns a new calibration; this one is unchanged."""
        counts = check_frames(frames, self.shape).astype(np.float32)
        n = len(counts)
        fpa = per_frame_series(fpa_c, n, "fpa_c")
        t = per_frame_series(time_s, n, "time_s", temperature=False)
        band = band_for(tuple(self.band_m))
        shutter_l = band.radiance((fpa + ZERO_CELSIUS_K).astype(np.float32))
        offsets = counts - self.gain[None] * shutter_l[:, None, None]
        times = np.concatenate([self.event_time_s, t])
        stack = offsets if self.event_offset is None else np.concatenate(
            [self.event_offset, offsets])
        order = np.argsort(times, kind="stable")
        return replace(self, event_time_s=times[order], event_offset=stack[order])

    def apply(self, frames: Any, *, fpa_c: Any = None, time_s: Any = None) -> np.ndarray:
        """Scene temperature, °C, float32 ``(N, H, W)``; each frame uses the last shutter offset
        at or before its ``time_s`` (s, the closures' clock; the reference offset before the
        first closure). Frames more than :data:`STALE_INTERVALS` intervals after the closure
        they use are warned of (closures of another recording, or a shutter that stopped)."""
        counts = check_frames(frames, self.shape)
        n = len(counts)
        if fpa_c is not None and self.event_offset is None:
            warn_outside_range(per_frame_series(fpa_c, n, "fpa_c"), self.fpa_range_c, METHOD)
        if self.event_offset is not None and time_s is None:
            raise InvalidInputError("shutter: applying shutter offsets needs the frame times")
        which = np.full(n, -1)
        if self.event_offset is not None:
            t = per_frame_series(time_s, n, "time_s", temperature=False)
            which = np.searchsorted(self.event_time_s, t, side="right") - 1
            _warn_stale(t, which, self.event_time_s, self.interval_s)
        band = band_for(tuple(self.band_m))
        lo, hi = band.radiance_range
        inv_gain = (1.0 / self.gain).astype(np.float32)
        out = np.empty(counts.shape, dtype=np.float32)
        for k in range(n):
            off = self.offset if which[k] < 0 else self.event_offset[which[k]]  # type: ignore[index]
            rad = (counts[k].astype(np.float32) - off) * inv_gain
            out[k] = band.temperature(np.clip(rad, lo, hi)) - np.float32(ZERO_CELSIUS_K)
        return fill_bad_pixels(out, self.bad)

    def closure_shift(self, frames: Any, temps: np.ndarray, *, time_s: Any) -> np.ndarray | None:
        """How far the shutter closures moved ``temps`` (°C ``(N, H, W)``: this calibration's
        temperatures of ``frames`` at ``time_s``, its closures applied) from what the chamber's
        reference offset gives, °C, float32 ``(N, H, W)`` (0 before the first closure); None
        without closures or frame times.

        Nothing checks a closure: it takes the shutter at the FPA sensor's temperature, which
        a shutter warming or cooling with the housing is not, and the chamber session that made
        the report (and σ) saw none. So the shift, a correction nothing verified, is taken at
        its full size as a component of σ, in quadrature
        (:func:`~thermocal.calibration.base.calibration_sigma_extra`). A helper's audit: a
        `boson` unit's closures at the start of a held-out run erred 0.96 °C where the
        reference offset erred 0.19 and σ said 0.27 (43 of 105 frames silent)."""
        if self.event_offset is None or time_s is None:
            return None
        plain = replace(self, event_time_s=np.zeros(0), event_offset=None).apply(frames)
        return np.abs(np.asarray(temps, dtype=np.float32) - plain)


#: A frame more than this many shutter intervals after the closure it uses is warned of.
STALE_INTERVALS = 2.0


def _warn_stale(time_s: np.ndarray, which: np.ndarray, event_time_s: np.ndarray,
                interval_s: float) -> None:
    """Warn of frames more than :data:`STALE_INTERVALS` intervals after the closure they use, or
    of a recording that ends that long before the first closure (closures on another clock)."""
    if time_s.size and np.all(which < 0) and (
            float(event_time_s[0] - time_s.max()) > STALE_INTERVALS * interval_s):
        warnings.warn(
            f"shutter: the {time_s.size} frame(s) end at t = {float(time_s.max()):g} s, long "
            f"before the first closure (t = {float(event_time_s[0]):g} s): they keep the "
            "chamber's reference offset; are the closures this recording's, on its clock?",
            ThermocalWarning, stacklevel=3)
        return
    used = which >= 0
    age = np.where(used, time_s - event_time_s[np.maximum(which, 0)], 0.0)
    stale = int(np.count_nonzero(age > STALE_INTERVALS * interval_s))
    if stale:
        warnings.warn(
            f"shutter: {stale} frame(s) lie up to {float(age.max()):.0f} s after the closure "
            f"they use (closures every {interval_s:g} s, the last at t = "
            f"{float(event_time_s[-1]):g} s): are the closures this recording's, on its "
            "clock?", ThermocalWarning, stacklevel=3)


def shutter(session: Any, *, interval_s: float = 180.0, **two_point_options: Any
            ) -> ShutterCalibration:
    """The shutter-based baseline: two-point gains from the chamber (see
    :func:`~thermocal.calibration.two_point.two_point` for the options), offsets re-referenced
    on shutter closures every ``interval_s`` seconds at apply time (:meth:`with_shutter`)."""
    if interval_s <= 0:
        raise InvalidInputError(f"shutter interval must be > 0 s, got {interval_s}")
    return ShutterCalibration.from_two_point(two_point(session, **two_point_options),
                                             interval_s=interval_s)
