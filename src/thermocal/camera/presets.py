"""Camera presets and seeded camera *units*.

A preset describes a model family (a Tau2-class core); a *unit* is one physical camera of that
family: the same physics with its own per-pixel coefficients, column FPN, radial strength, optical
centre and defective pixels, drawn from a generator seeded by ``(preset, unit)``. A method fitted on
one unit can then be tested on another.

Two families, which differ in the *form* of six parts of the model, not only in coefficients:

=====================  ==========================================  =================================
part                   ``tau2`` (Tau2-class core, Oz et al.)       ``boson`` (a second VOx family)
=====================  ==========================================  =================================
response vs FPA temp.  cubic polynomials (Oz eq. 13, Nugent 2013)  exponentials (thermistor-like)
spectral band          flat 7.5–13.5 µm                            8–14 µm, sloped response
FPN structure          columns (Oz eq. 19) + radial offset         rows + smooth random offset field
optics / housing       radial emission, first-order lag            one-sided gradient, second-order
drift and noise        white noise only                            + row noise, 1/f, warm-up drift
transient              ``C·dT/dt``                                 ``C·`` lagged ``dT/dt``
=====================  ==========================================  =================================

The spatial structure follows Oz et al. eq. 16–17: a radial map ``R = sqrt(h² + w²)`` with ``h, w``
running from −0.5 to 0.5 across the frame, and coefficient maps that are polynomials in ``R``
(here in ``R²``, which is smooth at the centre), times a small per-pixel variation. Column FPN
follows Oz et al. eq. 19: a multiplicative factor ``U[0.9, 1.01]`` per column on the responsivity,
plus an additive column offset (``boson``: the same per row).

The ``boson`` numbers are a plausible second family, not a fitted camera: the 8–14 µm band, VOx
sensor, < 50 mK NETD and small housing of the FLIR Boson data sheet; an exponential response as
a bolometer's resistance ``R ∝ exp(E/kT)`` gives; row-wise readout FPN; the 1/f noise and warm-up
drift of uncooled cores (Wolf et al. 2016 §II); a transient that lags the FPA rate (Lin et al.
2019 observe the rate term's delay).
"""

from __future__ import annotations

import zlib
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.ndimage import map_coordinates

from thermocal.camera.model import CameraModel
from thermocal.camera.thermal import ThermalParams
from thermocal.errors import InvalidInputError
from thermocal.radiometry import TAU2, BandRadiance, band_table

#: Forms of the parts that differ between families (the first of each is ``tau2``'s).
FPN_FORMS = ("column", "row-field")
HOUSING_FORMS = ("radial", "gradient")


@dataclass(frozen=True)
class CameraPreset:
    """Parameters of a camera family (all temperatures °C, counts are 14-bit raw counts).

    Responsivity: ``G(t) = gain · v(R) · (1 + ε) · column · (1 + a1·Δt + a2·Δt² + a3·Δt³)`` in
    counts per W·m⁻²·sr⁻¹, with ``Δt = t_fpa − t_ref_c``, vignetting ``v(R) = 1 − vignetting·R²``.
    Offset: ``O(t) = offset + offset_radial·R² + ε + column + (b1 + b1_radial·R²)·Δt + b2·Δt² +
    b3·Δt³`` in counts. Self-radiation ``H = housing·(housing_floor + R²)``; transient
    ``C = transient·(1 + transient_radial·R²)`` counts per °C/min.

    The other forms: ``fpa_scales_c = (θa, θb)`` replaces ``Δt², Δt³`` by ``θ·expm1(Δt/θ)``
    in both expansions (:func:`thermocal.camera.model.fpa_basis`); ``fpn = "row-field"`` puts
    the line FPN on rows and replaces ``offset_radial·R²`` by a smooth random field of RMS
    ``offset_field_sigma`` counts; ``housing_form = "gradient"`` makes ``H = housing·
    (housing_floor + 0.5 + g)`` with ``g`` a linear ramp −0.5 … 0.5 across the frame in a unit's
    own direction; ``spectral_response`` weights the band; ``thermal`` holds the lags (optics,
    transient); ``row_noise_counts``, ``flicker_counts``, ``warmup_counts``/``warmup_tau_s``
    the temporal noise and drift (:class:`thermocal.camera.model.CameraModel`).
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
    fpa_scales_c: tuple[float, ...] = ()
    fpn: str = "column"
    offset_field_sigma: float = 0.0
    housing_form: str = "radial"
    spectral_response: tuple[tuple[float, float], ...] = ()
    row_noise_counts: float = 0.0
    flicker_counts: float = 0.0
    warmup_counts: float = 0.0
    warmup_tau_s: float = 900.0
    thermal: ThermalParams = ThermalParams()

    def __post_init__(self) -> None:
        if self.fpn not in FPN_FORMS or self.housing_form not in HOUSING_FORMS:
            raise InvalidInputError(
                f"camera preset {self.name!r}: fpn must be one of {FPN_FORMS} and housing_form "
                f"one of {HOUSING_FORMS}"
            )

    @property
    def radial_offset(self) -> bool:
        """Whether the smooth part of the offset pattern is radially symmetric (Oz et al. eq.
        16–17: ``offset_radial·R²`` and a radial housing, no random field)."""
        return self.housing_form == "radial" and self.offset_field_sigma == 0.0

    def as_dict(self) -> dict:
        """The parameters as plain values (:func:`dataclasses.asdict`), leaving out the fields of
        the second family's forms where they keep ``tau2``'s default: files that store a
        ``tau2`` preset are the same as before those fields existed."""
        d = asdict(self)
        default = asdict(CameraPreset())
        for name in _FORM_FIELDS:
            if d[name] == default[name]:
                del d[name]
        return d

    @classmethod
    def from_dict(cls, params: dict) -> CameraPreset:
        """The preset of :func:`dataclasses.asdict` output read back from JSON (lists become
        tuples, ``thermal`` a :class:`ThermalParams`); :class:`TypeError` for unknown fields."""
        def tuples(v):  # noqa: ANN001, ANN202 - JSON values
            return tuple(tuples(x) for x in v) if isinstance(v, list) else v

        d = {k: tuples(v) for k, v in params.items()}
        if isinstance(d.get("thermal"), dict):
            d["thermal"] = ThermalParams(**d["thermal"])
        return cls(**d)


#: The fields added for the second family's forms (their defaults are ``tau2``'s).
_FORM_FIELDS = ("fpa_scales_c", "fpn", "offset_field_sigma", "housing_form", "spectral_response",
                "row_noise_counts", "flicker_counts", "warmup_counts", "warmup_tau_s", "thermal")

#: The ``boson`` family (see the module docstring for what differs in form from ``tau2``).
BOSON = CameraPreset(
    name="boson",
    band_m=(8.0e-6, 14.0e-6),
    gain=62.0,
    gain_tempco=(0.0, 1.0 / -120.0, 0.0),  # G ∝ exp(−Δt / 120 °C)
    vignetting=0.10,
    column_gain_range=(0.95, 1.02),
    offset=5200.0,
    offset_radial=0.0,
    offset_field_sigma=45.0,
    column_offset_sigma=4.0,
    offset_tempco=(-9.0, 0.0, -4.0),  # linear + a steepening exponential above t_ref
    offset_tempco_radial=-3.0,
    housing=140.0,
    housing_floor=0.3,
    transient=55.0,
    transient_radial=-0.2,
    noise_variance=6.0,
    fpa_scales_c=(-120.0, 18.0),
    fpn="row-field",
    housing_form="gradient",
    spectral_response=((8.0e-6, 0.0), (8.6e-6, 0.9), (10.0e-6, 1.0), (13.0e-6, 0.7),
                       (14.0e-6, 0.0)),
    row_noise_counts=1.2,
    flicker_counts=2.0,
    warmup_counts=35.0,
    warmup_tau_s=600.0,
    thermal=ThermalParams(tau_housing_s=180.0, tau_fpa_s=40.0, housing_self_heating_c=3.0,
                          fpa_self_heating_c=1.0, tau_optics_s=240.0, transient_lag_s=45.0),
)

PRESETS: dict[str, CameraPreset] = {"tau2": CameraPreset(), "boson": BOSON}


def preset_band(name: Any) -> BandRadiance:
    """The spectral band of the family ``name`` (a key of :data:`PRESETS`) as its shared
    radiance table; the ``tau2`` band (flat 7.5–13.5 µm) for any other name or none: what a
    chamber session of an unnamed camera is prepared with."""
    p = PRESETS.get(name) if isinstance(name, str) else None
    return band_table(tuple(p.band_m), tuple(p.spectral_response)) if p else TAU2


def _smooth_field(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """A unit-RMS smooth random field ``(H, W)`` float32, the same at every size: a 6×8 grid of
    unit-level draws, cubic-spline interpolated onto the frame (scipy)."""
    coarse = rng.standard_normal((6, 8))
    h, w = shape
    rows = np.linspace(0.0, 5.0, h)[:, None] * np.ones((1, w))
    cols = np.ones((h, 1)) * np.linspace(0.0, 7.0, w)[None, :]
    field = map_coordinates(coarse, [rows, cols], order=3, mode="nearest")
    field -= field.mean()
    return (field / max(float(field.std()), 1e-9)).astype(np.float32)


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
    # the second family's unit-level draws come after tau2's, which stay as they were
    field = _smooth_field(rng, shape) if p.fpn == "row-field" else None
    gradient_angle = rng.uniform(0.0, 2.0 * np.pi) if p.housing_form == "gradient" else 0.0

    pix = np.random.default_rng([zlib.crc32(p.name.encode()), int(unit), width, height])
    r2 = radial_map(shape, centre) ** 2
    n_lines = width if p.fpn == "column" else height
    column_gain = pix.uniform(*p.column_gain_range, size=n_lines).astype(np.float32)
    column_offset = (p.column_offset_sigma * pix.standard_normal(n_lines)).astype(np.float32)
    # the line FPN as a map: per column (tau2, Oz et al. eq. 19) or per row
    line_gain = column_gain[None, :] if p.fpn == "column" else column_gain[:, None]
    line_offset = column_offset[None, :] if p.fpn == "column" else column_offset[:, None]

    pixel_gain = 1.0 + p.gain_pixel_sigma * pix.standard_normal(shape, dtype=np.float32)
    responsivity = (
        unit_gain * (1.0 - strength[0] * p.vignetting * r2) * pixel_gain * line_gain
    )
    gain = np.stack(
        [responsivity] + [responsivity * np.float32(a * s) for a, s in zip(
            p.gain_tempco, tempco_scale, strict=True)]
    ).astype(np.float32)

    offset = np.empty((4, *shape), dtype=np.float32)
    pixel_offset = p.offset_pixel_sigma * pix.standard_normal(shape, dtype=np.float32)
    offset[0] = unit_offset + strength[1] * p.offset_radial * r2 + pixel_offset + line_offset
    if field is not None:
        offset[0] += np.float32(strength[1] * p.offset_field_sigma) * field
    offset[1] = tempco_scale[0] * p.offset_tempco[0] + p.offset_tempco_radial * strength[1] * r2
    offset[2] = tempco_scale[1] * p.offset_tempco[1]
    offset[3] = tempco_scale[2] * p.offset_tempco[2]

    if p.housing_form == "radial":
        housing = (strength[2] * p.housing * (p.housing_floor + r2)).astype(np.float32)
    else:  # a warm side: a linear ramp across the frame, in the unit's own direction
        rows = np.linspace(-0.5, 0.5, height, dtype=np.float32)[:, None]
        cols = np.linspace(-0.5, 0.5, width, dtype=np.float32)[None, :]
        ramp = np.cos(gradient_angle) * cols + np.sin(gradient_angle) * rows
        housing = (strength[2] * p.housing * (p.housing_floor + 0.5 + ramp)).astype(np.float32)
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
        # the line FPN under the name of its lines (a row FPN is not a column FPN to redraw)
        f"{p.fpn.split('-')[0]}_gain": column_gain,
        f"{p.fpn.split('-')[0]}_offset": column_offset,
        "pixel_gain": pixel_gain,
        "pixel_offset": pixel_offset,
        "preset_parameters": p.as_dict(),
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
        band=band_table(tuple(p.band_m), tuple(p.spectral_response)),
        bit_depth=p.bit_depth,
        info=info,
        **family_physics(p),
        flicker_seed=zlib.crc32(f"{p.name}/{unit}".encode()),
    )


def family_physics(p: CameraPreset) -> dict:
    """The :class:`~thermocal.camera.model.CameraModel` fields a family sets beyond its maps
    (its expansion basis, temporal noise and drift, thermal lags)."""
    return {"fpa_scales_c": tuple(p.fpa_scales_c), "row_noise_counts": p.row_noise_counts,
            "flicker_counts": p.flicker_counts, "warmup_counts": p.warmup_counts,
            "warmup_tau_s": p.warmup_tau_s, "thermal": p.thermal}
