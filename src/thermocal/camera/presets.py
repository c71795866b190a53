"""Camera presets and seeded camera *units*.

A preset describes a model family (a Tau2-class core); a *unit* is one physical camera of that
family: the same physics with its own per-pixel coefficients, column FPN, radial strength, optical
centre and defective pixels, drawn from a generator seeded by ``(preset, unit)``. A method fitted on
one unit can then be tested on another.

The spatial structure follows Oz et al. eq. 16–17: a radial map ``R = sqrt(h² + w²)`` with ``h, w``
running from −0.5 to 0.5 across the frame, and coefficient maps that are polynomials in ``R``
(here in ``R²``, which is smooth at the centre), times a small per-pixel variation. Column FPN
follows Oz et al. eq. 19: a multiplicative factor ``U[0.9, 1.01]`` per column on the responsivity,
plus an additive column offset.
"""

from __future__ import annotations

import zlib
from dataclasses import asdict, dataclass

import numpy as np

from thermocal.camera.model import CameraModel
from thermocal.errors import InvalidInputError
from thermocal.radiometry import band_table


@dataclass(frozen=True)
class CameraPreset:
    """Parameters of a camera family (all temperatures °C, counts are 14-bit raw counts).

    Responsivity: ``G(t) = gain · v(R) · (1 + ε) · column · (1 + a1·Δt + a2·Δt² + a3·Δt³)`` in
    counts per W·m⁻²·sr⁻¹, with ``Δt = t_fpa − t_ref_c``, vignetting ``v(R) = 1 − vignetting·R²``.
    Offset: ``O(t) = offset + offset_radial·R² + ε + column + (b1 + b1_radial·R²)·Δt + b2·Δt² +
    b3·Δt³`` in counts. Self-radiation ``H = housing·(housing_floor + R²)``; transient
    ``C = transient·(1 + transient_radial·R²)`` counts per °C/min.
    """

    name: str = "tau2"
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    t_ref_c: float = 25.0
    gain: float = 70.0
    gain_unit_sigma: float = 0.005
    gain_tempco: tuple[float, float, float] = (-4.0e-3, 1.5e-5, -1.0e-7)
    vignetting: float = 0.06
    gain_pixel_sigma: float = 0.015
    column_gain_range: tuple[float, float] = (0.9, 1.01)
    offset: float = 4500.0
    offset_unit_sigma: float = 15.0
    offset_radial: float = -100.0
    offset_pixel_sigma: float = 30.0
    column_offset_sigma: float = 6.0
    offset_tempco: tuple[float, float, float] = (-14.0, 0.15, -0.004)
    offset_tempco_radial: float = -6.0
    housing: float = 100.0
    housing_floor: float = 0.5
    transient: float = 75.0
    transient_radial: float = 0.3
    radial_strength_range: tuple[float, float] = (0.8, 1.2)
    tempco_unit_sigma: float = 0.05
    centre_jitter: float = 0.03
    defect_fraction: float = 2e-4
    hot_fraction: float = 0.4
    noise_variance: float = 5.0
    bit_depth: int = 14


PRESETS: dict[str, CameraPreset] = {"tau2": CameraPreset()}


def radial_map(shape: tuple[int, int], centre: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """``R`` of Oz et al. eq. 16: distance from ``centre`` with axes running −0.5 … 0.5, (H, W)."""
    h, w = shape
    rows = np.linspace(-0.5, 0.5, h, dtype=np.float32)[:, None] - np.float32(centre[0])
    cols = np.linspace(-0.5, 0.5, w, dtype=np.float32)[None, :] - np.float32(centre[1])
    return np.sqrt(rows**2 + cols**2)


def unit_rng(preset: str, unit: int) -> np.random.Generator:
    """The generator that draws unit ``unit`` of ``preset`` (stable across runs and platforms)."""
    return np.random.default_rng([zlib.crc32(preset.encode()), int(unit)])


def make_camera(
    preset: str | CameraPreset = "tau2", *, unit: int = 0, size: tuple[int, int] = (336, 256)
) -> CameraModel:
    """Draw camera unit ``unit`` of ``preset`` at ``size = (W, H)`` pixels.

    The same ``(preset, unit, size)`` always gives the same camera. Sizes are free (the radial
    structure is resolution independent); the Tau2 cores are 336×256 and 640×512.
    """
    p = PRESETS.get(preset) if isinstance(preset, str) else preset
    if p is None:
        raise InvalidInputError(f"unknown camera preset {preset!r}; known: {', '.join(PRESETS)}")
    if unit < 0:
        raise InvalidInputError(f"camera unit must be >= 0, got {unit}")
    width, height = size
    if not (8 <= width <= 8192 and 8 <= height <= 8192):
        raise InvalidInputError(f"camera size {width}x{height}: both sides must be 8 … 8192")
    rng = unit_rng(p.name, unit)
    shape = (height, width)

    # Unit-level draws first, so that every size of the same unit shares them.
    centre = tuple(rng.uniform(-p.centre_jitter, p.centre_jitter, 2))
    strength = rng.uniform(*p.radial_strength_range, size=4)  # vignetting, offset, housing, trans.
    unit_gain = p.gain * (1.0 + p.gain_unit_sigma * rng.standard_normal())
    unit_offset = p.offset + p.offset_unit_sigma * rng.standard_normal()
    tempco_scale = 1.0 + p.tempco_unit_sigma * rng.standard_normal(3)
    transient_scale = float(np.clip(1.0 + 0.15 * rng.standard_normal(), 0.75, 1.25))

    pix = np.random.default_rng([zlib.crc32(p.name.encode()), int(unit), width, height])
    r2 = radial_map(shape, centre) ** 2
    column_gain = pix.uniform(*p.column_gain_range, size=width).astype(np.float32)
    column_offset = (p.column_offset_sigma * pix.standard_normal(width)).astype(np.float32)

    pixel_gain = 1.0 + p.gain_pixel_sigma * pix.standard_normal(shape, dtype=np.float32)
    responsivity = (
        unit_gain * (1.0 - strength[0] * p.vignetting * r2) * pixel_gain * column_gain[None, :]
    )
    gain = np.stack(
        [responsivity] + [responsivity * np.float32(a * s) for a, s in zip(
            p.gain_tempco, tempco_scale, strict=True)]
    ).astype(np.float32)

    offset = np.empty((4, *shape), dtype=np.float32)
    pixel_offset = p.offset_pixel_sigma * pix.standard_normal(shape, dtype=np.float32)
    offset[0] = (
        unit_offset + strength[1] * p.offset_radial * r2 + pixel_offset + column_offset[None, :]
    )
    offset[1] = tempco_scale[0] * p.offset_tempco[0] + p.offset_tempco_radial * strength[1] * r2
    offset[2] = tempco_scale[1] * p.offset_tempco[1]
    offset[3] = tempco_scale[2] * p.offset_tempco[2]

    housing = (strength[2] * p.housing * (p.housing_floor + r2)).astype(np.float32)
    transient = (
        transient_scale
        * p.transient
        * (1.0 + strength[3] * p.transient_radial * r2)
        * (1.0 + 0.03 * pix.standard_normal(shape, dtype=np.float32))
    ).astype(np.float32)

    n_defects = int(round(p.defect_fraction * width * height))
    defects = np.zeros(shape, dtype=bool)
    defect_counts = np.zeros(shape, dtype=np.uint16)
    if n_defects:
        flat = pix.choice(width * height, size=n_defects, replace=False)
        hot = pix.random(n_defects) < p.hot_fraction
        defects.flat[flat] = True
        max_counts = 2**p.bit_depth - 1
        dead_values = pix.integers(0, 2000, n_defects)
        defect_counts.flat[flat] = np.where(hot, max_counts, dead_values).astype(np.uint16)

    info = {
        "preset": p.name,
        "unit": int(unit),
        "size": [width, height],
        "optical_centre": [float(c) for c in centre],
        "radial_strength": [float(s) for s in strength],
        "column_gain": column_gain,
        "column_offset": column_offset,
        "pixel_gain": pixel_gain,
        "pixel_offset": pixel_offset,
        "preset_parameters": asdict(p),
    }
    return CameraModel(
        gain=gain,
        offset=offset,
        housing=housing,
        transient=transient,
        defects=defects,
        defect_counts=defect_counts,
        noise_sigma=float(np.sqrt(p.noise_variance)),
        t_ref_c=p.t_ref_c,
        band=band_table(tuple(p.band_m)),
        bit_depth=p.bit_depth,
        info=info,
    )
