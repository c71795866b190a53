"""Shared pieces of every calibration: what one is (:class:`Calibration`,
:class:`StreamingCorrector`), warnings, input checks, bad-pixel filling, range checks.

Every fitted calibration is a frozen dataclass with ``apply(frames, *, fpa_c=None, time_s=None)``
returning the scene's blackbody-equivalent (radiance) temperature in °C as float32 ``(N, H, W)``,
and ``save(path)`` / ``load(path)`` through :mod:`thermocal.calibration.store`.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Protocol, Self, runtime_checkable

import numpy as np

from thermocal._validate import (
    as_frames,
    as_temperature_c,
    check_not_saturated,
    check_same_shape,
)
from thermocal.errors import InvalidInputError
from thermocal.radiometry import BandRadiance, band_table
from thermocal.threads import caught_warnings


@runtime_checkable
class Calibration(Protocol):
    """A fitted per-pixel calibration: raw counts → the scene's temperature, °C.

    ``apply`` means the same for every calibration: a stateless map of a stack of frames,
    never changing the calibration.
    A method that learns as frames stream by (``wolf2016``) keeps that state in a
    :class:`StreamingCorrector` it makes afresh for each ``apply``.

    Attributes
    ----------
    method : str
        Its name in :data:`thermocal.calibration.CALIBRATION_METHODS` (and in its file).
    shape : (H, W)
        The frame size it applies to, pixels.
    bad : (H, W) bool
        Pixels whose fit is unusable; their output is filled from their neighbours.
    """

    method: str
    bad: np.ndarray

    @property
    def shape(self) -> tuple[int, int]: ...

    def apply(self, frames: Any, *, fpa_c: Any = None, time_s: Any = None) -> np.ndarray:
        """Scene temperature, °C, float32 ``(N, H, W)``, of raw counts ``(N, H, W)`` (or one
        ``(H, W)`` frame); ``fpa_c`` (°C) and ``time_s`` (s): one value or one per frame, for
        the methods that need them."""
        ...

    def save(self, path: str | Path) -> Path:
        """Write the calibration file (HDF5, atomic); returns its path."""
        ...

    @classmethod
    def load(cls, path: str | Path) -> Self:
        """Read a calibration file of this class's method(s)."""
        ...


def apply_with_rate(calibration: Calibration, frames: Any, *, fpa_c: Any, time_s: Any,
                    fpa_rate_c_per_min: Any = None, fpa_lag_rates_c_per_min: Any = None
                    ) -> np.ndarray:
    """``calibration.apply`` of ``frames`` at ``fpa_c`` and ``time_s``, given also the FPA rate
    their recording measured (°C/min, one or one per frame; None: not known) where the
    calibration takes it (``takes_fpa_rate``: a rate term, which a burst's own second of
    readings cannot feed), and that rate through each of its lags (°C/min, ``(K,)`` for its
    ``rate_lags_s``; None: not known) where it has lags (``lin-lag``: a burst has no history)."""
    if fpa_rate_c_per_min is not None and getattr(calibration, "takes_fpa_rate", False):
        lags = ({} if fpa_lag_rates_c_per_min is None or not rate_lags_of(calibration)
                else {"fpa_lag_rates_c_per_min": fpa_lag_rates_c_per_min})
        return calibration.apply(frames, fpa_c=fpa_c, time_s=time_s,
                                 fpa_rate_c_per_min=fpa_rate_c_per_min, **lags)
    return calibration.apply(frames, fpa_c=fpa_c, time_s=time_s)


def calibration_sigma_extra(calibration: Any, frames: Any, temps: np.ndarray, *,
                            time_s: Any, fpa_c: Any = None, unverified: Any = None
                            ) -> np.ndarray | None:
    """What a calibration adds to its report's σ for ``frames`` and the temperatures it gave
    them, ``temps`` ``(N, H, W)`` °C: °C, float32 ``(N, H, W)``, or None where nothing is added.
    Each part is an uncertainty component (the parts add in quadrature, and the callers add
    the sum so to the report's σ). A correction nothing verified is taken at its full size,
    sign and size unknown (conservative: GUM's rectangular ±size would give size/√3):

    - a ``shutter`` calibration's :meth:`~thermocal.calibration.shutter.ShutterCalibration.
      closure_shift` (its closures, which no chamber fold saw);
    - on the frames ``unverified`` (bool ``(N,)``: at FPA paces its session never held, forced),
      :func:`rate_correction` (at the frames' FPA temperatures ``fpa_c``): its rate terms were
      fitted on other paces (a helper's audit: `lin-level` from a session whose FPA only rose,
      forced on a falling FPA, erred 8–14 °C where σ said 1.6–7.7);
    - at the pixels it marks bad, which :func:`fill_bad_pixels` filled with their good
      neighbours' median, half their range (:func:`filled_pixel_spread`): the scene there may
      lie anywhere among them, at most about that far from their median (a `lin-lag` bad pixel
      erred 4.5 °C where σ said 1.4: a helper's audit). A mean over views takes it too, at the
      pivot's bad pixels: on a hovering camera every view sees that place through them.
    """
    closure_shift = getattr(calibration, "closure_shift", None)
    parts = [] if closure_shift is None else [closure_shift(frames, temps, time_s=time_s)]
    if unverified is not None and np.any(unverified) and fpa_c is not None:
        which = np.flatnonzero(unverified)
        fpa = np.broadcast_to(np.asarray(fpa_c, dtype=np.float64).reshape(-1), (len(temps),))
        t = None if time_s is None else np.broadcast_to(  # one time, or one per frame
            np.asarray(time_s, dtype=np.float64).reshape(-1), (len(temps),))[which]
        moved = rate_correction(calibration, np.asarray(frames)[which], temps[which],
                                fpa_c=fpa[which], time_s=t)
        if moved is not None:
            whole = np.zeros(np.shape(temps), dtype=np.float32)
            whole[which] = moved
            parts.append(whole)
    bad = getattr(calibration, "bad", None)
    if bad is not None and np.shape(bad) == np.shape(temps)[1:] and np.any(bad):
        parts.append(0.5 * filled_pixel_spread(temps, np.asarray(bad, dtype=bool)))
    parts = [p for p in parts if p is not None]
    if not parts:
        return None
    return np.sqrt(sum(np.square(p, dtype=np.float32) for p in parts)).astype(np.float32)


def rate_correction(calibration: Any, frames: Any, temps: np.ndarray, *, fpa_c: Any,
                    time_s: Any) -> np.ndarray | None:
    """How far a calibration's FPA-rate terms moved ``temps``, its output for ``frames`` at
    FPA temperatures ``fpa_c`` (°C) and times ``time_s`` (s): ``|temps − its output at rate
    0|`` (the lagged rates at 0 too), °C float32 ``(N, H, W)``; None for a calibration without
    rate terms (``takes_fpa_rate``)."""
    if not getattr(calibration, "takes_fpa_rate", False):
        return None
    lags = rate_lags_of(calibration)
    with caught_warnings():  # dropped: the frames were warned of (thread-safe, unlike
        # warnings.catch_warnings, whose filters every thread of a flight's pool shares)
        steady = apply_with_rate(calibration, frames, fpa_c=fpa_c, time_s=time_s,
                                 fpa_rate_c_per_min=np.zeros(len(temps)),
                                 fpa_lag_rates_c_per_min=np.zeros(len(lags)) if lags else None)
    return np.abs(np.asarray(temps, dtype=np.float32) - steady)


def _neighbourhoods(bad: np.ndarray) -> tuple[np.ndarray, ...]:
    """The ``bad`` pixels ``(B,)`` rows and columns, their 3×3 neighbourhoods' rows and columns
    ``(B, 9)`` (clipped at the edges) and which of those are good ``(B, 9)``."""
    h, w = bad.shape
    rows, cols = np.nonzero(bad)
    dr, dc = np.meshgrid(np.arange(-1, 2), np.arange(-1, 2), indexing="ij")
    nr = np.clip(rows[:, None] + dr.ravel()[None], 0, h - 1)
    nc = np.clip(cols[:, None] + dc.ravel()[None], 0, w - 1)
    return rows, cols, nr, nc, ~bad[nr, nc]


def filled_pixel_spread(temps: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """The range (max − min, °C) of each ``bad`` pixel's good 3×3 neighbours in every frame of
    ``temps`` ``(N, H, W)``, 0 at the good pixels; a bad pixel with no good neighbour takes
    its frame's range. float32 ``(N, H, W)``; ``temps`` unchanged."""
    out = np.zeros(temps.shape, dtype=np.float32)
    rows, cols, nr, nc, usable = _neighbourhoods(bad)
    alone = ~usable.any(axis=1)  # no good neighbour: the frame's range
    for k0 in range(0, temps.shape[0], _FILL_BLOCK):  # (n, B, 9) at a time, bounded
        block = np.asarray(temps[k0:k0 + _FILL_BLOCK], dtype=np.float32)
        values = block[:, nr, nc]
        spread = (np.where(usable[None], values, -np.inf).max(axis=2)
                  - np.where(usable[None], values, np.inf).min(axis=2))
        if alone.any():
            good = block[:, ~bad]
            whole = (good.max(axis=1) - good.min(axis=1)) if good.size else np.zeros(len(block))
            spread = np.where(alone[None], whole[:, None], spread)
        out[k0:k0 + _FILL_BLOCK, rows, cols] = spread
    return out


def rate_lags_of(calibration: Any) -> tuple[float, ...]:
    """The lags, s, through which a calibration remembers the FPA's rate (``lin-lag``'s
    ``rate_lags_s`` when it has lag terms); ``()`` for every other."""
    if getattr(calibration, "lag", None) is None:
        return ()
    return tuple(getattr(calibration, "rate_lags_s", ()))


@runtime_checkable
class StreamingCorrector(Protocol):
    """Corrects a recording frame by frame, learning from each frame as it goes (stateful).

    The keyword arguments are a method's per-frame data (``wolf2016``: ``fpa_c`` °C and
    ``time_s`` s; ``zuo2011``: the homography to the previous frame). Outputs are float32.
    """

    def correct_frame(self, frame: Any, **per_frame: Any) -> np.ndarray:
        """One frame ``(H, W)`` corrected with the current state, ``(H, W)``; learns nothing."""
        ...

    def process(self, frame: Any, **per_frame: Any) -> np.ndarray:
        """One step of the stream: correct one frame ``(H, W)`` and learn from it (in the
        method's order), ``(H, W)``."""
        ...

    def correct(self, frames: Any, **per_frame: Any) -> np.ndarray:
        """:meth:`process` every frame of ``(N, H, W)`` in order (causal), ``(N, H, W)``; the
        per-frame data as one value or one per frame."""
        ...


class ThermocalWarning(UserWarning):
    """A result that is computed but may be wrong (e.g. applied outside its calibrated range)."""


class OutsideCalibrationRangeWarning(ThermocalWarning):
    """A calibration applied at FPA temperatures it was not fitted on."""


class ProtocolWarning(ThermocalWarning):
    """A chamber session that supports a calibration method only in part: the fit is made, but
    degraded (:func:`thermocal.calibration.protocol.check_protocol`)."""


class UnverifiedFileWarning(ThermocalWarning):
    """A model file written before thermocal stored checksums in it (a version-1 calibration, a
    version-1 or 2 weights file): read, but it cannot be checked for damage beyond its ranges."""


def check_frames(frames: Any, shape: tuple[int, int], *, bit_depth: int = 14) -> np.ndarray:
    """Validate raw counts for a calibration of frame ``shape`` ``(H, W)``; ``(N, H, W)`` out.

    Raises :class:`InvalidInputError` for non-numeric or NaN input, counts outside
    ``bit_depth`` bits, or saturated frames (:func:`thermocal._validate.check_not_saturated`),
    and :class:`ResolutionMismatchError` for frames of another size than the calibration.
    """
    counts = as_frames(frames, bit_depth=bit_depth)
    check_same_shape(counts, np.empty(shape, dtype=np.uint8), "each frame", "the calibration")
    check_not_saturated(counts, bit_depth=bit_depth)
    return counts


def per_frame_series(values: Any, n: int, name: str, *, temperature: bool = True) -> np.ndarray:
    """A scalar or ``(n,)`` series as float64 ``(n,)``; raises InvalidInputError otherwise."""
    check = as_temperature_c if temperature else _as_float
    arr = check(values, name, ndim=(0, 1))
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise InvalidInputError(f"{name}: expected {n} values (one per frame), got {arr.shape}")
    return arr.astype(np.float64)


def _as_float(values: Any, name: str, *, ndim: Any) -> np.ndarray:
    from thermocal._validate import as_float_array

    return as_float_array(values, name, ndim=ndim)


def require_fpa(fpa_c: Any, n: int, method: str) -> np.ndarray:
    """The FPA temperature of each frame, °C ``(n,)``; a method that needs it raises without it."""
    if fpa_c is None:
        raise InvalidInputError(
            f"{method}: needs the FPA temperature of every frame (the recording's sidecar "
            "'fpa_c', or --fpa-c)"
        )
    return per_frame_series(fpa_c, n, "fpa_c")


def warn_outside_range(fpa_c: np.ndarray, fpa_range_c: tuple[float, float], method: str,
                       *, margin_c: float = 0.5) -> None:
    """Warn (:class:`OutsideCalibrationRangeWarning`) if any FPA value leaves the fitted range."""
    lo, hi = fpa_range_c
    if fpa_c.size == 0:
        return
    mn, mx = float(fpa_c.min()), float(fpa_c.max())
    if mn < lo - margin_c or mx > hi + margin_c:
        warnings.warn(
            f"{method}: FPA temperatures {mn:.2f}…{mx:.2f} °C leave the calibrated range "
            f"{lo:.2f}…{hi:.2f} °C; the temperatures may be off by several °C",
            OutsideCalibrationRangeWarning,
            stacklevel=3,
        )


#: Frames whose bad pixels :func:`fill_bad_pixels` fills at once (bounds its memory).
_FILL_BLOCK = 256


def fill_bad_pixels(temps: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """Replace ``bad`` pixels of each frame by the median of their good 3×3 neighbours (in place).

    ``temps`` is ``(N, H, W)`` float32, ``bad`` ``(H, W)`` bool. Only the bad pixels'
    neighbourhoods are gathered (a few pixels: far cheaper than a full median filter), every
    frame's at once; a bad pixel with no good neighbour gets the frame's median. Returns
    ``temps``.
    """
    if not bad.any():
        return temps
    rows, cols, nr, nc, usable = _neighbourhoods(bad)
    # the median of each neighbourhood's good values, as np.nanmedian gives it (NaN values left
    # out; the mean of the middle two of an even count), from one sort of a block of frames'
    # (NaN last): nanmedian takes a masked array's path per frame for so few values, 4× slower
    for k0 in range(0, temps.shape[0], _FILL_BLOCK):
        block = temps[k0:k0 + _FILL_BLOCK]
        values = np.where(usable[None], block[:, nr, nc], np.float32(np.nan))  # (n, B, 9)
        good = np.count_nonzero(~np.isnan(values), axis=2)[..., None]  # (n, B, 1)
        values.sort(axis=2)
        low = np.take_along_axis(values, np.maximum((good - 1) // 2, 0), axis=2)
        high = np.take_along_axis(values, np.minimum(good // 2, values.shape[2] - 1), axis=2)
        filled = ((low + high) / values.dtype.type(2))[..., 0]
        for k in range(block.shape[0]):
            f = filled[k]
            if not np.all(np.isfinite(f)):
                f = np.where(np.isfinite(f), f, np.median(block[k][~bad]))
            block[k][rows, cols] = f
    return temps


def band_for(band_m: tuple[float, float]) -> BandRadiance:
    """A shared :class:`BandRadiance` per band (its lookup tables are built once, ~15 ms)."""
    return band_table(tuple(float(b) for b in band_m))


def robust_outliers(values: np.ndarray, *, mads: float, valid: np.ndarray | None = None
                    ) -> np.ndarray:
    """Boolean map of values more than ``mads`` scaled MADs from the median of ``values``."""
    ref = values if valid is None else values[valid]
    median = float(np.median(ref))
    mad = float(np.median(np.abs(ref - median))) * 1.4826 + 1e-12 * max(1.0, abs(median))
    return np.abs(values - median) > mads * mad


def calibration_info(session: Any) -> dict[str, Any]:
    """Camera unit and source metadata of a chamber session, for the calibration file."""
    attrs = getattr(session, "attrs", {}) or {}
    info: dict[str, Any] = {}
    for key in ("preset", "unit", "seed", "source", "source_file"):
        if key in attrs:
            value = attrs[key]
            info["camera_unit" if key == "unit" else key] = (
                value.item() if isinstance(value, np.generic) else value
            )
    return info
