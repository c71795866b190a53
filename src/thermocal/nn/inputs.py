"""What the network is given at inference and in training (numpy only, no torch).

The normalisation of eq. 20-21 (:class:`Normalisation`, kept with the weights), the input planes
(:func:`input_frames`), the sensor position ``R²`` of Oz et al. eq. 16 (:func:`sensor_r2`,
:func:`frame_r2`) and, for a calibrated network, its *nominal camera*: the camera model the raw
frames go through before the network sees them (:func:`nominal_camera`,
:func:`calibrate_frames`).
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from thermocal.calibration.base import fill_bad_pixels
from thermocal.camera.model import CameraModel, invert
from thermocal.camera.presets import CameraPreset, make_camera, radial_map
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError
from thermocal.radiometry import band_table
from thermocal.registration.warp import warp_to_pivot

__all__ = [
    "Normalisation",
    "calibrate_frames",
    "frame_r2",
    "input_frames",
    "nominal_camera",
    "preset_nominal",
    "sensor_r2",
]


@dataclass(frozen=True)
class Normalisation:
    """Eq. 20-21: ``x̄ = (x − min) / (max − min)`` for temperatures, counts and the FPA.

    Attributes
    ----------
    temp_min_c, temp_max_c : float
        Scene temperature range of the training maps, °C (eq. 20).
    counts_min, counts_max : float
        Raw-count range of the training frames, counts (eq. 21).
    fpa_min_c, fpa_max_c : float
        FPA temperature range, °C (the operating range of the training data).
    """

    temp_min_c: float = -40.0
    temp_max_c: float = 100.0
    counts_min: float = 2000.0
    counts_max: float = 14000.0
    fpa_min_c: float = 10.0
    fpa_max_c: float = 50.0

    def temp(self, t_c: np.ndarray) -> np.ndarray:
        """Normalised temperature (eq. 20)."""
        return (t_c - self.temp_min_c) / (self.temp_max_c - self.temp_min_c)

    def temp_inverse(self, x: np.ndarray) -> np.ndarray:
        """°C from a normalised temperature."""
        return x * (self.temp_max_c - self.temp_min_c) + self.temp_min_c

    def counts(self, counts: np.ndarray) -> np.ndarray:
        """Normalised gray levels (eq. 21)."""
        return (counts - self.counts_min) / (self.counts_max - self.counts_min)

    def fpa(self, fpa_c: np.ndarray | float) -> np.ndarray | float:
        """Normalised FPA temperature (eq. 20 applied to the camera's temperature)."""
        return (fpa_c - self.fpa_min_c) / (self.fpa_max_c - self.fpa_min_c)

    def radiance(self, t_c: np.ndarray, band_m: tuple[float, float]) -> np.ndarray:
        """Band radiance of ``t_c`` (°C, any shape), normalised over the temperature range:
        ``(L(T) − L(t_min)) / (L(t_max) − L(t_min))``, what
        :class:`~thermocal.nn.model.RadianceToTemperature` inverts (the band's lookup tables,
        :func:`~thermocal.radiometry.band_table`: relative error < 1e-5)."""
        band = band_table(tuple(band_m))
        lo, hi = band.radiance(np.array([self.temp_min_c, self.temp_max_c]) + ZERO_CELSIUS_K)
        t_k = np.clip(np.asarray(t_c, dtype=np.float32) + np.float32(ZERO_CELSIUS_K),
                      np.float32(band.t_min_k), np.float32(band.t_max_k))
        return ((band.radiance(t_k) - np.float32(lo)) / np.float32(hi - lo)).astype(np.float32)

    def to_dict(self) -> dict[str, float]:
        """Plain floats, for the weights file."""
        return {k: float(v) for k, v in asdict(self).items()}


@functools.lru_cache(maxsize=8)
def _sensor_r2(shape: tuple[int, int]) -> np.ndarray:
    r2 = radial_map(shape) ** 2
    r2.flags.writeable = False
    return r2


def sensor_r2(shape: tuple[int, int], top: int = 0, left: int = 0,
              size: tuple[int, int] | None = None) -> np.ndarray:
    """``R²`` (Oz et al. eq. 16: axes −0.5 … 0.5 over the sensor, nominal centre) of the window
    ``size = (H, W)`` at ``(top, left)`` of a sensor of ``shape = (H, W)``; float32, read-only."""
    h, w = size or shape
    if not (0 <= top and 0 <= left and top + h <= shape[0] and left + w <= shape[1]):
        raise InvalidInputError(f"window {h}x{w} at ({top}, {left}) leaves the sensor {shape}")
    return _sensor_r2(tuple(int(v) for v in shape))[top : top + h, left : left + w]


def frame_r2(r2: np.ndarray, homographies: np.ndarray, valid: np.ndarray,
             pivot: int | None = None) -> np.ndarray:
    """Where on the sensor each frame saw each pivot pixel, ``(N, H, W)`` float32.

    ``r2`` is ``R²`` (Oz et al. eq. 16) of the frames' sensor windows: ``(H, W)`` when every
    frame comes from the same window (whole frames, or the paper's crops), ``(N, H, W)`` each
    its own. It is warped onto the pivot like the frames (``homographies`` frame → pivot,
    ``(N, 3, 3)``); where a frame does not see a pivot pixel (``valid (N, H, W)`` False), the
    pivot's own ``R²`` (frame ``pivot``'s window, default the middle one) stands in.
    """
    n = valid.shape[0]
    planes = np.broadcast_to(np.asarray(r2, dtype=np.float32), valid.shape)
    warped, _ = warp_to_pivot(np.ascontiguousarray(planes), homographies)
    own = planes[n // 2 if pivot is None else pivot]
    return np.where(valid, warped, own[None]).astype(np.float32)


def input_frames(frames: np.ndarray, valid: np.ndarray, norm: Normalisation, *,
                 calibrated: bool = False, band_m: tuple[float, float] | None = None) -> np.ndarray:
    """The network's input planes from registered frames ``(N, H, W)``, float32, 0 where not
    ``valid``: raw counts by eq. 21, or for a ``calibrated`` model frames in °C in the units of
    its linear output: eq. 20's normalised temperature, or with ``band_m`` (a ``radiance``
    model) the normalised band radiance (:meth:`Normalisation.radiance`)."""
    if not calibrated:
        x = norm.counts(frames)
    elif band_m is None:
        x = norm.temp(frames)
    else:
        x = norm.radiance(frames, band_m)
    return np.where(valid, x, 0.0).astype(np.float32)


def nominal_camera(cameras: list[CameraModel]) -> CameraModel:
    """The average of camera units of one family: gain, offset and housing maps averaged (their
    unit-to-unit and pixel spread averages out), the first unit's transient and physics, no
    defects. What a user knows of a camera family before calibrating the unit at hand. Pixels
    without a positive gain (a chamber fit's dead pixels) take their neighbours' median
    coefficients, so that the model inverts everywhere."""
    base = cameras[0]
    # new arrays (np.mean, astype): filled in place below, the cameras' own maps untouched
    gain = np.mean([c.gain for c in cameras], axis=0).astype(np.float32)
    offset = np.mean([c.offset for c in cameras], axis=0).astype(np.float32)
    housing = np.mean([c.housing for c in cameras], axis=0).astype(np.float32)
    transient = base.transient.astype(np.float32)
    bad = ~(gain[0] > 0)
    same = all("preset" in c.info and c.info.get("preset_parameters")
               == base.info.get("preset_parameters") for c in cameras)
    preset = base.info.get("preset") if same else None
    for coefficients in (gain, offset, housing[None], transient[None]):
        fill_bad_pixels(coefficients, bad)
    return replace(
        base,
        gain=gain,
        offset=offset,
        housing=housing,
        transient=transient,
        defects=np.zeros(base.shape, bool),
        defect_counts=np.zeros(base.shape, np.uint16),
        # a preset's units are remade from their numbers; others (a chamber fit) are not
        info={"preset": preset, "units": [c.info.get("unit") for c in cameras],
              "preset_parameters": base.info.get("preset_parameters") if preset else None},
    )


@functools.lru_cache(maxsize=4)
def preset_nominal(preset: str | CameraPreset, sensor_size: tuple[int, int],
                   units: tuple[int, ...]) -> CameraModel:
    """:func:`nominal_camera` of a preset's ``units`` on a sensor of ``sensor_size = (W, H)``
    (made once per process: about 50 ms per unit at 336×256); ``preset`` is a name of
    :data:`~thermocal.camera.presets.PRESETS` or the parameters themselves."""
    return nominal_camera([make_camera(preset, unit=u, size=sensor_size) for u in units])


def calibrate_frames(nominal: CameraModel, counts: np.ndarray, fpa_c: Any) -> np.ndarray:
    """Raw frames ``(N, H, W)`` seen by the sensor window of ``nominal`` → scene temperature
    ``(N, H, W)`` °C, float32, through that model's exact inverse at the reported FPA
    temperature ``fpa_c`` (°C, one or one per frame; the camera settled: housing = FPA − its
    self-heating)."""
    return invert(nominal, counts, fpa_c, housing_c=fpa_c - nominal.thermal.fpa_self_heating_c)
