"""The physical model of one microbolometer camera unit, and rendering raw frames from it.

Per pixel p and frame k (DESIGN.md, the papers' models made into one)::

    I_p[k] = G_p(t_fpa) · L(T_scene,p)                 scene flux through the pixel's responsivity
           + O_p(t_fpa)                                offset drifting with the FPA temperature
           + H_p · (L(t_housing) − L(t_fpa))           housing/lens self-radiation, radial pattern
           + C_p · d t_fpa / dt                        transient term (Lin, Westfeld, Maas)
           + D(t)                                      drift: warm-up and 1/f, uniform
           + temporal noise (white, + row noise) → round → clip to 0 … 2**bit_depth − 1

``G_p`` and ``O_p`` are expansions in ``x = t_fpa − t_ref`` on a basis of the camera family
(:func:`fpa_basis`): cubic polynomials (``tau2``; Oz et al. eq. 13, Nugent et al.) or exponentials
(a bolometer whose response follows its thermistor-like resistance). The fixed-pattern noise is
folded into them when a unit is made (:mod:`thermocal.camera.presets`). ``L`` is band radiance,
W·m⁻²·sr⁻¹, through the family's spectral response. ``D(t)`` (0 for ``tau2``) depends on the time
since the camera was switched on, so it is only rendered when frame times are given.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from thermocal._validate import as_float_array, as_temperature_c
from thermocal.camera.thermal import ThermalParams
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError, ResolutionMismatchError
from thermocal.radiometry import TAU2, BandRadiance

POLY_ORDER = 3


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Per-pixel coefficients of one camera unit (all maps ``(H, W)``, float32).

    Parameters
    ----------
    gain : (4, H, W) array
        Coefficients of ``G_p(t) = Σ_i gain[i] · φ_i(t − t_ref_c)`` (:func:`fpa_basis`; for
        the default polynomial basis ``φ_i(x) = x^i``), counts per W·m⁻²·sr⁻¹.
    offset : (4, H, W) array
        Coefficients of ``O_p(t)`` on the same basis, counts.
    housing : (H, W) array
        Self-radiation responsivity ``H_p``, counts per W·m⁻²·sr⁻¹ of ``L(t_housing) − L(t_fpa)``.
    transient : (H, W) array
        ``C_p``, counts per °C/min of FPA temperature change.
    defects : (H, W) bool
        Dead or hot pixels; they output ``defect_counts`` whatever the scene.
    defect_counts : (H, W) uint16
        The stuck output of each defective pixel (0 elsewhere).
    noise_sigma : float
        Standard deviation of the temporal noise, counts (σ² ≈ 5 counts² for the Tau2).
    t_ref_c : float
        FPA temperature (°C) around which the polynomials are expanded.
    band : BandRadiance
        The spectral band of the camera.
    bit_depth : int
        Output bits; counts are clipped to ``0 … 2**bit_depth − 1``.
    info : dict
        Where the unit came from (preset, unit number, drawn parameters).
    fpa_scales_c : tuple of float
        ``()`` for the polynomial basis; ``(θa, θb)`` in °C for the exponential basis.
    row_noise_counts : float
        Standard deviation of a per-frame offset of each row (temporal row noise), counts.
    flicker_counts : float
        RMS of a uniform 1/f offset noise (0.3 mHz … 0.5 Hz), counts; deterministic in time.
    flicker_seed : int
        Seed of the 1/f noise's phases (a unit's own).
    warmup_counts, warmup_tau_s : float
        Uniform offset ``warmup_counts · exp(−t / warmup_tau_s)`` after switch-on (``t`` s).
    thermal : ThermalParams
        The family's thermal lags and FPA sensor (what the simulators use by default).
    """

    gain: np.ndarray
    offset: np.ndarray
    housing: np.ndarray
    transient: np.ndarray
    defects: np.ndarray
    defect_counts: np.ndarray
    noise_sigma: float = float(np.sqrt(5.0))
    t_ref_c: float = 25.0
    band: BandRadiance = TAU2
    bit_depth: int = 14
    info: dict[str, Any] = field(default_factory=dict)
    fpa_scales_c: tuple[float, ...] = ()
    row_noise_counts: float = 0.0
    flicker_counts: float = 0.0
    flicker_seed: int = 0
    warmup_counts: float = 0.0
    warmup_tau_s: float = 900.0
    thermal: ThermalParams = ThermalParams()

    def __post_init__(self) -> None:
        shape = self.housing.shape
        for name in ("gain", "offset"):
            arr = getattr(self, name)
            if arr.shape != (POLY_ORDER + 1, *shape):
                raise InvalidInputError(
                    f"CameraModel.{name}: expected shape {(POLY_ORDER + 1, *shape)}, "
                    f"got {arr.shape}"
                )
        for name in ("transient", "defects", "defect_counts"):
            if getattr(self, name).shape != shape:
                raise InvalidInputError(f"CameraModel.{name}: expected shape {shape}")
        if self.noise_sigma < 0:
            raise InvalidInputError("CameraModel.noise_sigma must be >= 0")
        if len(self.fpa_scales_c) not in (0, POLY_ORDER - 1) or not all(
                np.isfinite(t) and t != 0 for t in self.fpa_scales_c):
            raise InvalidInputError("CameraModel.fpa_scales_c: () or two finite, non-zero °C")
        if not (self.row_noise_counts >= 0 and self.flicker_counts >= 0
                and self.warmup_tau_s > 0 and np.isfinite(self.warmup_counts)):
            raise InvalidInputError("CameraModel: noise and drift terms must be >= 0")

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape ``(H, W)``."""
        return self.housing.shape  # type: ignore[return-value]

    @property
    def max_counts(self) -> int:
        """Largest output count, ``2**bit_depth − 1``."""
        return 2**self.bit_depth - 1

    def gain_at(self, fpa_c: float) -> np.ndarray:
        """``G_p(t_fpa)``, counts per W·m⁻²·sr⁻¹, ``(H, W)`` float32."""
        return _expand(self.gain, fpa_c - self.t_ref_c, self.fpa_scales_c)

    def offset_at(self, fpa_c: float) -> np.ndarray:
        """``O_p(t_fpa)``, counts, ``(H, W)`` float32."""
        return _expand(self.offset, fpa_c - self.t_ref_c, self.fpa_scales_c)

    @property
    def drifts(self) -> bool:
        """Whether the unit has time-dependent terms (warm-up, 1/f noise)."""
        return self.flicker_counts > 0 or self.warmup_counts != 0

    def drift_at(self, time_s: Any) -> np.ndarray:
        """``D(t)``: the uniform warm-up and 1/f offset at times ``time_s`` (s since switch-on),
        counts, ``(N,)`` float64."""
        t = as_float_array(time_s, "time_s", ndim=(0, 1)).reshape(-1).astype(np.float64)
        out = self.warmup_counts * np.exp(-np.maximum(t, 0.0) / self.warmup_tau_s)
        if self.flicker_counts > 0:
            out = out + self.flicker_counts * _flicker(t, self.flicker_seed)
        return out

    def without_transient(self) -> CameraModel:
        """The same unit with ``C_p = 0``: what a method that ignores the transient term assumes."""
        return replace(self, transient=np.zeros_like(self.transient))

    def crop(self, top: int, left: int, height: int, width: int) -> CameraModel:
        """The model of a sub-window of the sensor (same physics, smaller frames)."""
        h, w = self.shape
        if not (0 <= top and 0 <= left and top + height <= h and left + width <= w):
            raise InvalidInputError(f"crop {height}x{width} at ({top}, {left}) leaves {h}x{w}")
        rows, cols = slice(top, top + height), slice(left, left + width)
        return replace(
            self,
            gain=self.gain[:, rows, cols].copy(),
            offset=self.offset[:, rows, cols].copy(),
            housing=self.housing[rows, cols].copy(),
            transient=self.transient[rows, cols].copy(),
            defects=self.defects[rows, cols].copy(),
            defect_counts=self.defect_counts[rows, cols].copy(),
        )


def fpa_basis(x: float, scales_c: tuple[float, ...] = ()) -> np.ndarray:
    """The basis ``φ_i(x)``, ``i = 0 … 3``, of the FPA-temperature expansions, ``x`` in °C
    from the reference: ``x^i`` for ``scales_c = ()``; ``(1, x, θa·expm1(x/θa),
    θb·expm1(x/θb))`` for ``scales_c = (θa, θb)``. Returns ``(4,)`` float64."""
    if not scales_c:
        return np.array([1.0, x, x * x, x * x * x])
    return np.array([1.0, x] + [t * np.expm1(x / t) for t in scales_c])


def _expand(coeffs: np.ndarray, x: float, scales_c: tuple[float, ...]) -> np.ndarray:
    """``Σ_i coeffs[i] · φ_i(x)``, ``(H, W)`` float32 (Horner's rule for the polynomials)."""
    if not scales_c:
        return horner(coeffs, x)
    phi = fpa_basis(float(x), scales_c).astype(np.float32)
    out = coeffs[0] + coeffs[1] * phi[1]
    for c, p in zip(coeffs[2:], phi[2:], strict=True):
        out += c * p
    return out


def _flicker(t: np.ndarray, seed: int) -> np.ndarray:
    """Unit-RMS 1/f noise at times ``t`` (s), deterministic in ``(t, seed)``: a sum of sines at
    log-spaced frequencies (0.3 mHz … 0.5 Hz) with amplitudes ``∝ f^-1/2`` and random phases.

    Written out because the noise must be the same whichever frames are rendered, and in
    whatever chunks (a generator-drawn series is not)."""
    rng = np.random.default_rng([0x1F, int(seed)])
    freq = np.geomspace(3e-4, 0.5, 48)
    amp = freq**-0.5
    amp /= np.sqrt(np.sum(amp**2) / 2.0)  # RMS of the sum: sqrt(Σ a² / 2)
    phase = rng.uniform(0.0, 2.0 * np.pi, freq.size)
    return np.sin(2.0 * np.pi * t[:, None] * freq + phase) @ amp


def horner(coeffs: np.ndarray, x: float) -> np.ndarray:
    """Evaluate ``Σ_i coeffs[i] · x^i`` at a scalar ``x``; ``coeffs`` is ``(order+1, H, W)``."""
    x = np.float32(x)
    out = coeffs[-1] * x
    for c in coeffs[-2:0:-1]:
        out += c
        out *= x
    out += coeffs[0]
    return out


def _per_frame(values: Any, n: int, name: str) -> np.ndarray:
    """Broadcast a scalar or an ``(N,)`` series to ``(N,)`` float64."""
    arr = as_float_array(values, name, ndim=(0, 1))
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise InvalidInputError(f"{name}: expected {n} values (one per frame), got {arr.shape}")
    return arr.astype(np.float64)


def _scene_radiance(
    model: CameraModel, scene_c: Any, emissivity: float, reflected_c: float | None
) -> np.ndarray:
    """Band radiance reaching the camera from the scene, W·m⁻²·sr⁻¹, float32, ``(N, H, W)``-able."""
    if not 0.0 < emissivity <= 1.0:
        raise InvalidInputError(f"emissivity must be in (0, 1], got {emissivity}")
    scene = as_temperature_c(scene_c, "scene_c")
    if scene.ndim == 0:
        scene = scene.reshape(1, 1, 1)
    elif scene.ndim == 2:
        scene = scene[None]
    elif scene.ndim == 1:
        scene = scene[:, None, None]
    elif scene.ndim != 3:
        raise InvalidInputError(
            f"scene_c: expected a scalar, (N,), (H, W) or (N, H, W), got {scene.shape}"
        )
    if scene.shape[1:] != (1, 1) and scene.shape[1:] != model.shape:
        raise ResolutionMismatchError(
            f"scene is {scene.shape[2]}x{scene.shape[1]} but the camera is "
            f"{model.shape[1]}x{model.shape[0]}"
        )
    radiance = model.band.radiance((scene + ZERO_CELSIUS_K).astype(np.float32))
    if emissivity < 1.0:
        if reflected_c is None:
            raise InvalidInputError("reflected_c is required when emissivity < 1")
        reflected = float(model.band.radiance(np.float32(reflected_c + ZERO_CELSIUS_K)))
        radiance = emissivity * radiance + np.float32((1.0 - emissivity) * reflected)
    return radiance.astype(np.float32, copy=False)


def expected_counts(
    model: CameraModel,
    scene_c: Any,
    fpa_c: Any,
    *,
    housing_c: Any = None,
    fpa_rate_c_per_min: Any = 0.0,
    emissivity: float = 1.0,
    reflected_c: float | None = None,
    time_s: Any = None,
) -> np.ndarray:
    """Noise-free, unquantised output of the camera, counts, ``(N, H, W)`` float32.

    Parameters
    ----------
    model : CameraModel
    scene_c : array
        Scene temperature in °C: ``(H, W)``, ``(N, H, W)``, or ``(N,)`` for uniform scenes
        (a blackbody filling the view).
    fpa_c : float or (N,) array
        True FPA temperature of each frame, °C.
    housing_c : float or (N,) array, optional
        Housing temperature, °C; defaults to the FPA temperature (no self-radiation term).
    fpa_rate_c_per_min : float or (N,) array
        ``d t_fpa / dt`` in °C/min (the transient term).
    emissivity, reflected_c
        Emissivity of the scene and the temperature (°C) of what it reflects.
    time_s : float or (N,) array, optional
        Time of each frame since the camera was switched on, s: adds the drift ``D(t)`` of a
        unit that has one (:meth:`CameraModel.drift_at`); None: no drift.
    """
    radiance = _scene_radiance(model, scene_c, emissivity, reflected_c)
    fpa = as_temperature_c(fpa_c, "fpa_c", ndim=(0, 1))
    n = max(radiance.shape[0], fpa.size)
    if radiance.shape[0] not in (1, n):
        raise InvalidInputError(f"{radiance.shape[0]} scene frames but {fpa.size} FPA temperatures")
    radiance = np.broadcast_to(radiance, (n, *radiance.shape[1:]))
    fpa = _per_frame(fpa, n, "fpa_c")
    housing = fpa if housing_c is None else _per_frame(housing_c, n, "housing_c")
    as_temperature_c(housing, "housing_c")
    rate = _per_frame(fpa_rate_c_per_min, n, "fpa_rate_c_per_min")
    drift = (model.drift_at(_per_frame(time_s, n, "time_s"))
             if time_s is not None and model.drifts else np.zeros(n))
    self_radiance = (model.band.radiance(housing + ZERO_CELSIUS_K)
                     - model.band.radiance(fpa + ZERO_CELSIUS_K))

    out = np.empty((n, *model.shape), dtype=np.float32)
    for k in range(n):
        frame = out[k]
        np.multiply(model.gain_at(fpa[k]), radiance[k], out=frame)
        frame += model.offset_at(fpa[k])
        if self_radiance[k] != 0.0:
            frame += np.float32(self_radiance[k]) * model.housing
        if rate[k] != 0.0:
            frame += np.float32(rate[k]) * model.transient
        if drift[k] != 0.0:
            frame += np.float32(drift[k])
    return out


def render(
    model: CameraModel,
    scene_c: Any,
    fpa_c: Any,
    *,
    housing_c: Any = None,
    fpa_rate_c_per_min: Any = 0.0,
    emissivity: float = 1.0,
    reflected_c: float | None = None,
    rng: np.random.Generator | None = None,
    noise: bool = True,
    time_s: Any = None,
) -> np.ndarray:
    """Raw frames the camera would give: :func:`expected_counts` + noise, rounded, clipped.

    Returns ``(N, H, W)`` uint16 counts in ``0 … 2**bit_depth − 1``; defective pixels output their
    stuck value. ``rng`` is required when ``noise`` is True (seeded results only). ``time_s``:
    as for :func:`expected_counts` (the drift of a unit that has one).
    """
    counts = expected_counts(
        model,
        scene_c,
        fpa_c,
        housing_c=housing_c,
        fpa_rate_c_per_min=fpa_rate_c_per_min,
        emissivity=emissivity,
        reflected_c=reflected_c,
        time_s=time_s,
    )
    if noise and (model.noise_sigma > 0 or model.row_noise_counts > 0):
        if rng is None:
            raise InvalidInputError("render: pass rng=np.random.default_rng(seed) for noise")
        for frame in counts:  # frame by frame: bounded temporary memory
            if model.noise_sigma > 0:
                frame += rng.standard_normal(frame.shape, dtype=np.float32) * np.float32(
                    model.noise_sigma
                )
            if model.row_noise_counts > 0:
                frame += (rng.standard_normal(frame.shape[0], dtype=np.float32)
                          * np.float32(model.row_noise_counts))[:, None]
    np.rint(counts, out=counts)
    np.clip(counts, 0, model.max_counts, out=counts)
    frames = counts.astype(np.uint16)
    if model.defects.any():
        frames[:, model.defects] = model.defect_counts[model.defects]
    return frames


def invert(
    model: CameraModel,
    counts: Any,
    fpa_c: Any,
    *,
    housing_c: Any = None,
    fpa_rate_c_per_min: Any = 0.0,
    time_s: Any = None,
) -> np.ndarray:
    """Scene temperature (°C) from counts by inverting the model exactly (an oracle calibration).

    The counterpart of :func:`expected_counts` with ``emissivity = 1``: used to measure what is
    lost when a term of the model is ignored (e.g. ``model.without_transient()``). Returns
    ``(N, H, W)`` float32. Defective pixels give whatever their stuck counts imply.
    """
    frames = np.asarray(counts, dtype=np.float32)
    if frames.ndim == 2:
        frames = frames[None]
    if frames.shape[1:] != model.shape:
        raise ResolutionMismatchError(
            f"frames are {frames.shape[2]}x{frames.shape[1]} but the camera is "
            f"{model.shape[1]}x{model.shape[0]}"
        )
    n = frames.shape[0]
    zero_scene = expected_counts(
        model,
        np.zeros(1),
        _per_frame(fpa_c, n, "fpa_c"),
        housing_c=housing_c,
        fpa_rate_c_per_min=fpa_rate_c_per_min,
        time_s=time_s,
    )
    zero_radiance = float(model.band.radiance(np.float32(ZERO_CELSIUS_K)))
    fpa = _per_frame(fpa_c, n, "fpa_c")
    out = np.empty_like(frames)
    for k in range(n):
        gain = model.gain_at(fpa[k])
        radiance = (frames[k] - zero_scene[k]) / gain + np.float32(zero_radiance)
        lo, hi = model.band.radiance_range
        out[k] = model.band.temperature(np.clip(radiance, lo, hi)) - np.float32(ZERO_CELSIUS_K)
    return out
