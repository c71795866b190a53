"""Two-point calibration at one reference FPA temperature (Riou et al.; the classical baseline).

Each pixel is taken as linear in the band radiance of the scene, ``counts = g · L(T) + o``, fitted
from flat fields of a blackbody at two temperatures recorded at one FPA temperature. Applied at
another FPA temperature it drifts: that drift is what the temperature-dependent methods fix.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.ndimage import median_filter

from thermocal._validate import as_frames, as_temperature_c, check_same_shape
from thermocal.calibration.store import load_calibration, save_calibration
from thermocal.errors import FitError, InvalidInputError
from thermocal.radiometry import BandRadiance

METHOD = "two-point"
ZERO_C_K = 273.15


@dataclass(frozen=True, eq=False)
class TwoPointCalibration:
    """Per-pixel gain (counts per W·m⁻²·sr⁻¹) and offset (counts), ``(H, W)`` float32.

    ``bad`` marks pixels whose fit is unusable (dead, hot, non-positive or outlying gain); their
    output is the median of their 3×3 neighbourhood.
    """

    gain: np.ndarray
    offset: np.ndarray
    bad: np.ndarray
    fpa_ref_c: float
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape ``(H, W)``."""
        return self.gain.shape  # type: ignore[return-value]

    def apply(self, frames: Any) -> np.ndarray:
        """Scene temperature, °C, ``(N, H, W)`` float32, from raw counts ``(N, H, W)``."""
        counts = as_frames(frames)
        check_same_shape(counts, self.gain, "frames", "the calibration")
        band = BandRadiance(band_m=self.band_m)
        lo, hi = band.radiance_range
        out = np.empty(counts.shape, dtype=np.float32)
        for k, frame in enumerate(counts):
            radiance = (frame.astype(np.float32) - self.offset) / self.gain
            temp = band.temperature(np.clip(radiance, lo, hi)) - np.float32(ZERO_C_K)
            if self.bad.any():
                temp[self.bad] = median_filter(temp, size=3)[self.bad]
            out[k] = temp
        return out

    def save(self, path: str | Path) -> None:
        """Write the calibration file (HDF5, atomic)."""
        h, w = self.shape
        attrs = {"resolution": [w, h], "fpa_ref_c": self.fpa_ref_c, "band_m": list(self.band_m)}
        attrs |= self.info
        save_calibration(
            path, METHOD, {"gain": self.gain, "offset": self.offset, "bad": self.bad}, attrs
        )

    @classmethod
    def load(cls, path: str | Path) -> TwoPointCalibration:
        """Read a calibration file written by :meth:`save`."""
        method, arrays, meta = load_calibration(path)
        if method != METHOD:
            raise InvalidInputError(f"{path}: a {method} calibration, not {METHOD}")
        info = {k: v for k, v in meta.items() if k not in ("resolution", "fpa_ref_c", "band_m")}
        return cls(
            gain=arrays["gain"],
            offset=arrays["offset"],
            bad=arrays["bad"].astype(bool),
            fpa_ref_c=float(meta["fpa_ref_c"]),
            band_m=tuple(meta["band_m"]),
            info=info,
        )


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
    if abs(t_high - t_low) < 1.0:
        raise FitError(
            f"two-point calibration needs blackbody temperatures at least 1 °C apart, "
            f"got {t_low:.2f} and {t_high:.2f} °C"
        )
    band = BandRadiance(band_m=band_m)
    l_low, l_high = (float(band.radiance(np.float32(t + ZERO_C_K))) for t in (t_low, t_high))
    mean_low = low.mean(axis=0, dtype=np.float64)
    mean_high = high.mean(axis=0, dtype=np.float64)
    gain = (mean_high - mean_low) / (l_high - l_low)
    offset = mean_low - gain * l_low
    median = np.median(gain)
    mad = np.median(np.abs(gain - median)) * 1.4826 + 1e-12
    bad = (gain <= 0) | (np.abs(gain - median) > outlier_mads * mad)
    if bad.mean() > 0.5:
        raise FitError("two-point calibration: more than half of the pixels did not respond")
    gain = np.where(bad, median, gain)
    return TwoPointCalibration(
        gain=gain.astype(np.float32),
        offset=offset.astype(np.float32),
        bad=bad,
        fpa_ref_c=float(fpa_ref_c),
        band_m=tuple(band_m),
    )
