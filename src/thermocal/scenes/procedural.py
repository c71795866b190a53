"""Procedural aerial thermal scenes: daytime temperature maps of farmland, towns and both.

A scene is drawn as objects with sharp edges (fields, roads, buildings, trees, water) -- OpenCV
polygons, lines and circles -- each with a plausible daytime surface temperature, plus multi-scale
texture from fractal (1/f^beta) noise, cast shadows, and a slight Gaussian blur for the optics.
Typical apparent temperatures, °C (clear summer day, nadir view):

==================  ==========  ====================================================
surface             °C          note
==================  ==========  ====================================================
water               15 - 22     nearly uniform
trees, dense crops  20 - 28     transpiring canopy
lawn, pasture       22 - 32
wet / irrigated     18 - 26     bare soil after irrigation
dry soil, stubble   30 - 45     ploughed furrows and young crop rows show soil
dirt road           36 - 46
asphalt             38 - 55
concrete            33 - 45
roofs               30 - 65     white / metal (low emissivity) cool, bitumen hot
shadow              cooler      ground in shadow relaxes toward air temperature
==================  ==========  ====================================================

Sizes are in map pixels at ``scale = 1`` (fields of ~100-400 px, crop rows 3-12 px apart,
buildings 10-80 px, tree crowns 3-8 px in radius); ``scale`` multiplies every size.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
from scipy.fft import next_fast_len

from thermocal._validate import check_rng
from thermocal.errors import InvalidInputError

__all__ = ["KINDS", "OPTICS_BLUR_SIGMA_PX", "fractal_noise", "procedural_scene"]

#: Scene kinds understood by :func:`procedural_scene`.
KINDS = ("farmland", "urban", "mixed")

#: Standard deviation of the Gaussian blur standing for the optics, map pixels.
OPTICS_BLUR_SIGMA_PX = 0.7

_SHIFT = 4  # sub-pixel bits for OpenCV drawing
_ONE = 1 << _SHIFT


# --------------------------------------------------------------------------------------------
# checks and noise
# --------------------------------------------------------------------------------------------


def _check_shape(shape: Any) -> tuple[int, int]:
    try:
        h, w = shape
    except (TypeError, ValueError):
        raise InvalidInputError(f"shape: expected (height, width), got {shape!r}") from None
    for v in (h, w):
        if isinstance(v, bool) or not float(v).is_integer() or not 1 <= int(v) <= 32768:
            raise InvalidInputError(
                f"shape: height and width must be integers in 1..32768, got {shape!r}"
            )
    return int(h), int(w)


def fractal_noise(shape: tuple[int, int], *, beta: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian fractal noise with power spectrum ``P(f) ∝ 1 / |f|^beta``.

    Made in the Fourier domain (numpy FFT): complex white noise shaped by ``|f|^(-beta/2)`` and
    transformed back, on a grid padded to a fast FFT length and cropped. ``beta = 0`` is white
    noise, ``beta = 2`` the 1/f amplitude spectrum of natural images, larger ``beta`` smoother.

    Parameters
    ----------
    shape : tuple of int
        ``(H, W)``, pixels.
    beta : float
        Spectral exponent, ``0 <= beta <= 8``.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        Zero mean, unit standard deviation (all zeros for a single pixel).
    """
    rng = check_rng(rng)
    h, w = _check_shape(shape)
    try:
        b = float(beta)
    except (TypeError, ValueError):
        raise InvalidInputError(f"beta: expected a number, got {beta!r}") from None
    if not (math.isfinite(b) and 0.0 <= b <= 8.0):
        raise InvalidInputError(f"beta: expected 0 <= beta <= 8, got {beta!r}")
    fh = next_fast_len(h, real=True)
    fw = next_fast_len(max(w, 2), real=True)
    ky = np.fft.fftfreq(fh).astype(np.float32)[:, None]
    kx = np.fft.rfftfreq(fw).astype(np.float32)[None, :]
    f2 = ky * ky + kx * kx
    f2[0, 0] = 1.0
    amp = f2 ** np.float32(-b / 4.0)
    amp[0, 0] = 0.0
    spec_shape = (fh, fw // 2 + 1)
    spec = np.empty(spec_shape, dtype=np.complex64)
    spec.real = rng.standard_normal(spec_shape, dtype=np.float32)
    spec.imag = rng.standard_normal(spec_shape, dtype=np.float32)
    spec *= amp
    field = np.fft.irfft2(spec, s=(fh, fw))[:h, :w].astype(np.float32, copy=False)
    field = field - field.mean(dtype=np.float64)
    std = float(field.std(dtype=np.float64))
    if std > 0:
        field /= std
    return np.ascontiguousarray(field, dtype=np.float32)


# --------------------------------------------------------------------------------------------
# geometry and drawing helpers
# --------------------------------------------------------------------------------------------


def _fix(pts: np.ndarray) -> np.ndarray:
    """Points (float, pixels) to OpenCV fixed point with ``_SHIFT`` fractional bits."""
    return np.round(np.asarray(pts, dtype=np.float64) * _ONE).astype(np.int32)


def _fill(img: np.ndarray, polys: list[np.ndarray], value: float) -> None:
    cv2.fillPoly(img, [_fix(p) for p in polys], float(value), cv2.LINE_8, _SHIFT)


def _line(img: np.ndarray, p0: Any, p1: Any, value: float, width: float) -> None:
    a, b = _fix(p0), _fix(p1)
    cv2.line(img, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), float(value),
             max(1, int(round(width))), cv2.LINE_8, _SHIFT)


def _circle(img: np.ndarray, centre: Any, radius: float, value: float) -> None:
    c = _fix(centre)
    cv2.circle(img, (int(c[0]), int(c[1])), max(1, int(round(radius * _ONE))), float(value), -1,
               cv2.LINE_8, _SHIFT)


def _split_convex(
    poly: np.ndarray, point: np.ndarray, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split a convex polygon by the line through ``point`` with ``normal``.

    Returns the two halves and the cut segment ``(2, 2)`` (empty halves when the line misses).
    """
    d = (poly - point) @ normal
    pos: list[np.ndarray] = []
    neg: list[np.ndarray] = []
    seg: list[np.ndarray] = []
    k = len(poly)
    for i in range(k):
        a, b = poly[i], poly[(i + 1) % k]
        da, db = d[i], d[(i + 1) % k]
        if da >= 0:
            pos.append(a)
        if da <= 0:
            neg.append(a)
        if da * db < 0:
            p = a + (da / (da - db)) * (b - a)
            pos.append(p)
            neg.append(p)
            seg.append(p)
    if len(seg) != 2:
        return np.empty((0, 2)), np.empty((0, 2)), np.empty((0, 2))
    return np.array(pos), np.array(neg), np.array(seg)


def _rot(angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along ``angle`` and perpendicular to it."""
    e = np.array([math.cos(angle), math.sin(angle)])
    return e, np.array([-e[1], e[0]])


def _rect(centre: np.ndarray, eu: np.ndarray, ev: np.ndarray, half_u: float, half_v: float):
    return np.array(
        [
            centre - half_u * eu - half_v * ev,
            centre + half_u * eu - half_v * ev,
            centre + half_u * eu + half_v * ev,
            centre - half_u * eu + half_v * ev,
        ]
    )


def _shadow(mask: np.ndarray, length: float, direction: np.ndarray) -> np.ndarray:
    """Pixels reached by sweeping ``mask`` up to ``length`` px along ``direction`` (bool)."""
    n = int(math.ceil(length))
    if n < 1 or not mask.any():
        return np.zeros(mask.shape, dtype=bool)
    size = 2 * n + 1
    kernel = np.zeros((size, size), dtype=np.uint8)
    end = (int(round(n - length * direction[0])), int(round(n - length * direction[1])))
    cv2.line(kernel, (n, n), end, 1, 1)
    return cv2.dilate(mask, kernel, anchor=(n, n)).astype(bool)


def _blob(centre: np.ndarray, radius: float, rng: np.random.Generator, n: int = 96) -> np.ndarray:
    """A star-shaped blob (pond, lake): radius modulated by a few random harmonics."""
    t = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    r = np.ones(n)
    for k in range(1, 7):
        r += rng.normal(0.0, 0.22 / k) * np.cos(k * t + rng.uniform(0, 2 * math.pi))
    r = radius * np.clip(r, 0.35, None)
    return np.stack([centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)], axis=1)


class _Layer:
    """An object layer: a mask, its temperature and texture amplitude (drawn, then pasted)."""

    def __init__(self, h: int, w: int) -> None:
        self.mask = np.zeros((h, w), dtype=np.uint8)
        self.temp = np.zeros((h, w), dtype=np.float32)
        self.tex = np.zeros((h, w), dtype=np.float32)

    def poly(self, polys: list[np.ndarray], temp: float, tex: float) -> None:
        _fill(self.mask, polys, 1)
        _fill(self.temp, polys, temp)
        _fill(self.tex, polys, tex)

    def circle(self, centre: np.ndarray, radius: float, temp: float, tex: float) -> None:
        _circle(self.mask, centre, radius, 1)
        _circle(self.temp, centre, radius, temp)
        _circle(self.tex, centre, radius, tex)

    def line(self, p0: Any, p1: Any, temp: float, tex: float, width: float) -> None:
        _line(self.mask, p0, p1, 1, width)
        _line(self.temp, p0, p1, temp, width)
        _line(self.tex, p0, p1, tex, width)

    def paste(self, out: np.ndarray, noise: np.ndarray) -> None:
        m = self.mask.astype(bool)
        out[m] = self.temp[m] + self.tex[m] * noise[m]


class _Sun:
    """Sun direction and the shadow it casts: ``length = height * factor`` along ``direction``."""

    def __init__(self, rng: np.random.Generator) -> None:
        az = rng.uniform(0.0, 2.0 * math.pi)
        elevation = math.radians(rng.uniform(35.0, 65.0))
        self.direction = np.array([math.cos(az), math.sin(az)])
        self.factor = 1.0 / math.tan(elevation)
        self.shade_c = rng.uniform(19.0, 25.0)  # ground in shade relaxes toward this
        self.strength = rng.uniform(0.45, 0.75)

    def darken(self, temp: np.ndarray, shadow: np.ndarray) -> None:
        temp[shadow] -= self.strength * (temp[shadow] - self.shade_c)


def _tree(layer: _Layer, centre: np.ndarray, radius: float, temp: float, sun: _Sun) -> None:
    """A tree crown: a disc, its sunlit side slightly warmer."""
    layer.circle(centre, radius, temp, 0.7)
    if radius >= 2.5:
        layer.circle(centre - 0.35 * radius * sun.direction, 0.6 * radius, temp + 1.2, 0.7)


def _tree_row(
    layer: _Layer,
    p0: np.ndarray,
    p1: np.ndarray,
    rng: np.random.Generator,
    sun: _Sun,
    *,
    radius: tuple[float, float],
    temp: float,
    gap: float = 0.1,
) -> float:
    """Trees along a segment; returns the mean crown radius."""
    length = float(np.hypot(*(p1 - p0)))
    if length < 1:
        return 0.0
    e = (p1 - p0) / length
    n = np.array([-e[1], e[0]])
    s = 0.0
    radii = []
    while s < length:
        r = rng.uniform(*radius)
        if rng.random() > gap:
            c = p0 + s * e + rng.normal(0.0, 0.3 * r) * n
            _tree(layer, c, r, temp + rng.normal(0.0, 0.8), sun)
            radii.append(r)
        s += r * rng.uniform(1.1, 1.9)
    return float(np.mean(radii)) if radii else 0.0


def _water(
    out: np.ndarray,
    water_mask: np.ndarray,
    noise_large: np.ndarray,
    noise_fine: np.ndarray,
    rng: np.random.Generator,
    scale: float,
) -> None:
    """Paint water (15-22 °C, almost uniform) with a vegetated shore."""
    m = water_mask.astype(bool)
    if not m.any():
        return
    k = max(3, int(round(rng.uniform(3, 8) * scale)) | 1)
    ring = cv2.dilate(water_mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))).astype(
        bool
    ) & ~m
    t_shore = rng.uniform(22.0, 28.0)
    out[ring] = t_shore + 1.0 * noise_fine[ring]
    t_w = rng.uniform(15.0, 22.0)
    out[m] = t_w + 0.3 * noise_large[m] + 0.05 * noise_fine[m]


# --------------------------------------------------------------------------------------------
# farmland
# --------------------------------------------------------------------------------------------

# Field classes: (probability, sampler of (t_soil, t_veg, cover, row_depth, spacing, grid, tex,
# large, cover_var)). Temperatures in °C, spacing in pixels at scale 1.
_FIELD_CLASSES: dict[str, tuple[float, Callable[[np.random.Generator], tuple]]] = {
    # dense canopy (maize, wheat, alfalfa): cool, faint rows
    "dense_crop": (0.22, lambda r: (r.uniform(30, 40), r.uniform(20, 26), r.uniform(0.85, 0.97),
                                    r.uniform(0.05, 0.35), r.uniform(3, 8), 0, r.uniform(0.3, 0.8),
                                    r.uniform(0.4, 1.2), r.uniform(0.03, 0.1))),
    # young row crop: canopy rows on hot soil
    "row_crop": (0.18, lambda r: (r.uniform(32, 44), r.uniform(22, 28), r.uniform(0.3, 0.65),
                                  r.uniform(0.75, 1.0), r.uniform(4, 12), 0, r.uniform(0.3, 0.8),
                                  r.uniform(0.5, 1.5), r.uniform(0.05, 0.15))),
    # orchard / vineyard: tree crowns on a grid
    "orchard": (0.07, lambda r: (r.uniform(30, 42), r.uniform(21, 26), r.uniform(0.25, 0.45),
                                 1.0, r.uniform(7, 15), 1, r.uniform(0.3, 0.8),
                                 r.uniform(0.4, 1.0), 0.03)),
    # harvested stubble: dry, warm, faint rows
    "stubble": (0.13, lambda r: (r.uniform(34, 45), r.uniform(29, 37), r.uniform(0.4, 0.6),
                                 r.uniform(0.2, 0.5), r.uniform(3, 6), 0, r.uniform(0.5, 1.2),
                                 r.uniform(0.6, 1.5), 0.05)),
    # ploughed bare soil: hot ridges, cooler shaded furrows
    "ploughed": (0.13, lambda r: (r.uniform(34, 45), r.uniform(29, 38), r.uniform(0.4, 0.6),
                                  r.uniform(0.5, 0.9), r.uniform(3, 8), 0, r.uniform(0.6, 1.5),
                                  r.uniform(0.8, 2.0), 0.05)),
    # irrigated / wet bare soil: cool, patchy
    "wet_soil": (0.07, lambda r: (r.uniform(20, 27), r.uniform(18, 24), r.uniform(0.2, 0.5),
                                  r.uniform(0.0, 0.3), r.uniform(4, 10), 0, r.uniform(0.4, 1.0),
                                  r.uniform(1.0, 2.5), 0.1)),
    # pasture: grass, no rows, more texture
    "pasture": (0.12, lambda r: (r.uniform(28, 36), r.uniform(22, 28), r.uniform(0.6, 0.9), 0.0,
                                 5.0, 0, r.uniform(0.8, 1.6), r.uniform(0.8, 2.0),
                                 r.uniform(0.1, 0.2))),
    # dry grass / fallow
    "dry_grass": (0.08, lambda r: (r.uniform(33, 44), r.uniform(28, 34), r.uniform(0.4, 0.7),
                                   0.0, 5.0, 0, r.uniform(0.8, 1.6), r.uniform(0.8, 2.0),
                                   r.uniform(0.1, 0.2))),
}


def _bsp(
    poly: np.ndarray, rng: np.random.Generator, angle: float, size: tuple[float, float]
) -> tuple[list[np.ndarray], list[tuple[np.ndarray, int]]]:
    """Split a convex polygon into fields by nearly grid-aligned cuts (binary space partition).

    Returns the fields and the cut segments with their depth (0 = first cut).
    """
    eu, ev = _rot(angle)
    fields: list[np.ndarray] = []
    cuts: list[tuple[np.ndarray, int]] = []
    stack = [(poly, 0)]
    while stack:
        p, depth = stack.pop()
        pu, pv = p @ eu, p @ ev
        lu, lv = float(np.ptp(pu)), float(np.ptp(pv))
        target = rng.uniform(*size)
        if max(lu, lv) <= target or depth > 14 or len(fields) > 20000:
            fields.append(p)
            continue
        ratio = max(lu, lv) / max(min(lu, lv), 1e-9)
        along_u = (lu >= lv) if ratio > 1.4 else bool(rng.random() < 0.5)
        axis, other = (eu, ev) if along_u else (ev, eu)
        proj = pu if along_u else pv
        frac = rng.uniform(0.3, 0.7)
        point = axis * (proj.min() + frac * np.ptp(proj)) + other * float((p @ other).mean())
        jit = rng.normal(0.0, math.radians(5.0))
        normal = np.array(
            [axis[0] * math.cos(jit) - axis[1] * math.sin(jit),
             axis[0] * math.sin(jit) + axis[1] * math.cos(jit)]
        )
        a, b, seg = _split_convex(p, point, normal)
        if len(a) < 3 or len(b) < 3:
            fields.append(p)
            continue
        cuts.append((seg, depth))
        stack.append((a, depth + 1))
        stack.append((b, depth + 1))
    return fields, cuts


def _farmland(h: int, w: int, rng: np.random.Generator, scale: float) -> np.ndarray:
    noise_fine = fractal_noise((h, w), beta=1.6, rng=rng)
    noise_med = fractal_noise((h, w), beta=2.6, rng=rng)
    noise_large = fractal_noise((h, w), beta=3.6, rng=rng)
    sun = _Sun(rng)

    m = 24.0
    outer = np.array([[-m, -m], [w - 1 + m, -m], [w - 1 + m, h - 1 + m], [-m, h - 1 + m]])
    angle0 = rng.uniform(0.0, math.pi)
    fields, cuts = _bsp(outer, rng, angle0, (110.0 * scale, 400.0 * scale))

    # field parameters; label 0 is the margin between fields (grass, weeds)
    nf = len(fields)
    names = list(_FIELD_CLASSES)
    probs = np.array([_FIELD_CLASSES[k][0] for k in names])
    kinds = rng.choice(len(names), size=nf, p=probs / probs.sum())
    params = np.zeros((nf + 1, 9))
    params[0] = (rng.uniform(28, 36), rng.uniform(22, 28), 0.6, 0.0, 5.0, 0, 1.2, 1.0, 0.15)
    angles = np.zeros(nf + 1)
    for i, (poly, kind) in enumerate(zip(fields, kinds, strict=True), start=1):
        params[i] = _FIELD_CLASSES[names[kind]][1](rng)
        edges = np.roll(poly, -1, axis=0) - poly
        longest = edges[int(np.argmax(np.hypot(edges[:, 0], edges[:, 1])))]
        along = math.atan2(longest[1], longest[0])
        if rng.random() < 0.25:
            along += math.pi / 2
        if rng.random() < 0.1:
            along = rng.uniform(0.0, math.pi)
        angles[i] = along + math.pi / 2  # rows run along the edge: the pattern varies across it
    params[:, 4] *= scale

    label = np.zeros((h, w), dtype=np.int32)
    for i, poly in enumerate(fields, start=1):
        _fill(label, [poly], i)
    for poly in fields:
        t = max(1, int(round(rng.uniform(1.0, 4.0) * scale)))
        cv2.polylines(label, [_fix(poly)], True, 0, t, cv2.LINE_8, _SHIFT)

    t_soil, t_veg, cover0, depth, spacing, grid, tex, large, cvar = (
        params[:, j].astype(np.float32) for j in range(9)
    )
    lab = label
    cos_n = np.cos(angles).astype(np.float32)[lab]
    sin_n = np.sin(angles).astype(np.float32)[lab]
    xs = np.arange(w, dtype=np.float32)[None, :]
    ys = np.arange(h, dtype=np.float32)[:, None]
    k = (2.0 * np.pi / spacing).astype(np.float32)
    phase = rng.uniform(0, 2 * np.pi, nf + 1).astype(np.float32)
    wobble = rng.uniform(0.3, 1.5, nf + 1).astype(np.float32)
    u = xs * cos_n + ys * sin_n
    u += wobble[lab] * noise_med
    p = 0.5 + 0.5 * np.cos(u * k[lab] + phase[lab])
    gpix = np.flatnonzero(grid[lab].ravel() > 0)
    if gpix.size:
        v = (-xs * sin_n + ys * cos_n).ravel()[gpix]
        lg = lab.ravel()[gpix]
        p2 = 0.5 + 0.5 * np.cos(v * k[lg] + phase[(lg + 1) % (nf + 1)])
        p.ravel()[gpix] *= p2
    c0 = cover0[lab]
    d = depth[lab]
    c = (1.0 - d) * c0 + d * np.clip((p - (1.0 - c0)) * 4.0 + 0.5, 0.0, 1.0)
    c += cvar[lab] * noise_large
    np.clip(c, 0.0, 1.0, out=c)
    ts = t_soil[lab]
    temp = ts + (t_veg[lab] - ts) * c
    temp += tex[lab] * noise_fine
    temp += large[lab] * noise_large

    # dirt roads along early cuts, hedges / tree lines along some others
    trees = _Layer(h, w)
    roads = _Layer(h, w)
    tree_r: list[float] = []
    for seg, dep in cuts:
        if rng.random() < (0.75 if dep <= 1 else 0.08):
            width = rng.uniform(4.0, 9.0) * scale
            t_road = rng.uniform(36.0, 46.0)
            roads.line(seg[0], seg[1], t_road, 0.6, width)
            e = seg[1] - seg[0]
            nrm = np.array([-e[1], e[0]]) / max(float(np.hypot(*e)), 1e-9)
            dt = rng.uniform(-2.5, 2.5)
            for off in (-0.25 * width, 0.25 * width):
                roads.line(seg[0] + off * nrm, seg[1] + off * nrm, t_road + dt, 0.6,
                           max(1.0, width / 6))
        elif rng.random() < 0.35:
            r = _tree_row(trees, seg[0], seg[1], rng, sun, radius=(3.0 * scale, 7.0 * scale),
                          temp=rng.uniform(20.0, 26.0), gap=rng.uniform(0.0, 0.4))
            tree_r.append(r)
    # isolated trees
    for _ in range(rng.poisson(h * w / 40000.0)):
        c_xy = np.array([rng.uniform(0, w), rng.uniform(0, h)])
        r = rng.uniform(3.0, 8.0) * scale
        _tree(trees, c_xy, r, rng.uniform(20.0, 26.0), sun)
        tree_r.append(r)
    roads.paste(temp, noise_fine)

    # a farmstead
    buildings = _Layer(h, w)
    heights: list[float] = []
    if rng.random() < 0.6:
        eu, ev = _rot(angle0)
        centre = np.array([rng.uniform(0.15, 0.85) * w, rng.uniform(0.15, 0.85) * h])
        yard = _rect(centre, eu, ev, rng.uniform(35, 70) * scale, rng.uniform(30, 60) * scale)
        yard_layer = _Layer(h, w)
        yard_layer.poly([yard], rng.uniform(34.0, 46.0), 0.8)
        yard_layer.paste(temp, noise_fine)
        for _ in range(int(rng.integers(2, 7))):
            bc = centre + rng.uniform(-40, 40) * scale * eu + rng.uniform(-35, 35) * scale * ev
            half = rng.uniform(6, 20, 2) * scale
            buildings.poly([_rect(bc, eu, ev, half[0], half[1])], rng.uniform(30.0, 65.0), 0.4)
            heights.append(rng.uniform(4.0, 10.0) * scale)

    # shadows on the ground, then the objects themselves
    shade = np.zeros((h, w), dtype=bool)
    if heights:
        shade |= _shadow(buildings.mask, float(np.mean(heights)) * sun.factor, sun.direction)
    if tree_r:
        shade |= _shadow(trees.mask, 2.0 * float(np.mean(tree_r)) * sun.factor, sun.direction)
    shade &= ~(buildings.mask.astype(bool) | trees.mask.astype(bool))
    sun.darken(temp, shade)
    buildings.paste(temp, noise_fine)
    trees.paste(temp, noise_fine)

    # a pond now and then
    if rng.random() < 0.35:
        water = np.zeros((h, w), dtype=np.uint8)
        centre = np.array([rng.uniform(0, w), rng.uniform(0, h)])
        _fill(water, [_blob(centre, rng.uniform(20, 70) * scale, rng)], 1)
        _water(temp, water, noise_large, noise_fine, rng, scale)
    return temp


# --------------------------------------------------------------------------------------------
# urban
# --------------------------------------------------------------------------------------------

# Roof classes: (probability, (low, high) °C)
_ROOFS = (
    (0.30, (50.0, 65.0)),  # dark bitumen / membrane
    (0.30, (40.0, 55.0)),  # tiles
    (0.20, (30.0, 38.0)),  # white / cool roof
    (0.20, (30.0, 42.0)),  # bare metal (low emissivity: cool apparent temperature)
)


def _street_lines(lo: float, hi: float, rng: np.random.Generator, scale: float) -> list:
    """Positions and widths of parallel streets covering ``[lo, hi]``."""
    out = []
    pos = lo - rng.uniform(0.0, 1.0) * 200.0 * scale
    while pos < hi + 250.0 * scale:
        wide = rng.random() < 0.25
        width = (rng.uniform(18, 28) if wide else rng.uniform(9, 15)) * scale
        out.append((pos, width, wide))
        pos += rng.uniform(110.0, 240.0) * scale
    return out


def _urban(h: int, w: int, rng: np.random.Generator, scale: float) -> np.ndarray:
    noise_fine = fractal_noise((h, w), beta=1.6, rng=rng)
    noise_large = fractal_noise((h, w), beta=3.4, rng=rng)
    sun = _Sun(rng)

    base = np.full((h, w), rng.uniform(30.0, 40.0), dtype=np.float32)  # dry grass / bare lots
    tex = np.full((h, w), 1.2, dtype=np.float32)

    def fill_ground(polys: list[np.ndarray], temp: float, amp: float) -> None:
        _fill(base, polys, temp)
        _fill(tex, polys, amp)

    def line_ground(p0: Any, p1: Any, temp: float, amp: float, width: float) -> None:
        _line(base, p0, p1, temp, width)
        _line(tex, p0, p1, amp, width)

    angle = rng.uniform(0.0, math.pi / 2)
    eu, ev = _rot(angle)
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], dtype=np.float64)
    us = _street_lines(float((corners @ eu).min()), float((corners @ eu).max()), rng, scale)
    vs = _street_lines(float((corners @ ev).min()), float((corners @ ev).max()), rng, scale)
    sidewalk = rng.uniform(2.0, 5.0) * scale

    def _uv(u: float, v: float) -> np.ndarray:
        return u * eu + v * ev

    def _quad(u0: float, u1: float, v0: float, v1: float) -> np.ndarray:
        return np.array([_uv(u0, v0), _uv(u1, v0), _uv(u1, v1), _uv(u0, v1)])


    roofs = _Layer(h, w)
    trees = _Layer(h, w)
    cars = _Layer(h, w)
    n_bins = 3
    height_bins = [np.zeros((h, w), dtype=np.uint8) for _ in range(n_bins)]
    bin_edges = np.array([3.0, 8.0, 15.0, 28.0]) * scale
    tree_r: list[float] = []
    roof_p = np.array([p for p, _ in _ROOFS])

    def add_building(poly: np.ndarray, size: float) -> None:
        lo, hi = _ROOFS[int(rng.choice(len(_ROOFS), p=roof_p / roof_p.sum()))][1]
        t_roof = rng.uniform(lo, hi)
        roofs.poly([poly], t_roof, rng.uniform(0.2, 0.7))
        if size >= 14 * scale:
            cv2.polylines(roofs.temp, [_fix(poly)], True, float(t_roof - rng.uniform(2, 8)), 1,
                          cv2.LINE_8, _SHIFT)
        if size >= 30 * scale:  # air-conditioning units, skylights
            c = poly.mean(axis=0)
            for _ in range(int(rng.integers(1, 5))):
                off = rng.uniform(-0.3, 0.3, 2) * size
                half = rng.uniform(1.5, 3.5) * scale
                unit = _rect(c + off[0] * eu + off[1] * ev, eu, ev, half, half)
                _fill(roofs.temp, [unit], min(65.0, max(30.0, t_roof + rng.uniform(-10, 10))))
        height = rng.uniform(bin_edges[0], bin_edges[-1]) if size > 30 * scale else rng.uniform(
            bin_edges[0], bin_edges[2]
        )
        b = min(n_bins - 1, int(np.searchsorted(bin_edges, height) - 1))
        _fill(height_bins[b], [poly], 1)

    def block_buildings(u0: float, u1: float, v0: float, v1: float) -> None:
        fill_ground([_quad(u0, u1, v0, v1)], rng.uniform(24.0, 32.0) if rng.random() < 0.5
                    else rng.uniform(34.0, 44.0), 1.0)
        if rng.random() < 0.15:  # one large building
            s = rng.uniform(3, 8) * scale
            if u1 - u0 > 2 * s + 8 and v1 - v0 > 2 * s + 8:
                add_building(_quad(u0 + s, u1 - s, v0 + s, v1 - s), min(u1 - u0, v1 - v0))
            return
        stack = [(u0, u1, v0, v1)]
        while stack:
            a0, a1, b0, b1 = stack.pop()
            target = rng.uniform(28.0, 80.0) * scale
            if max(a1 - a0, b1 - b0) > target:
                if a1 - a0 >= b1 - b0:
                    cut = a0 + rng.uniform(0.35, 0.65) * (a1 - a0)
                    stack += [(a0, cut, b0, b1), (cut, a1, b0, b1)]
                else:
                    cut = b0 + rng.uniform(0.35, 0.65) * (b1 - b0)
                    stack += [(a0, a1, b0, cut), (a0, a1, cut, b1)]
                continue
            if rng.random() < 0.85:
                s = rng.uniform(1.0, 5.0) * scale
                if a1 - a0 > 2 * s + 5 and b1 - b0 > 2 * s + 5:
                    add_building(_quad(a0 + s, a1 - s, b0 + s, b1 - s), min(a1 - a0, b1 - b0))
            elif rng.random() < 0.6:
                c = _uv(0.5 * (a0 + a1), 0.5 * (b0 + b1))
                r = rng.uniform(3.0, 7.0) * scale
                _tree(trees, c, r, rng.uniform(20.0, 27.0), sun)
                tree_r.append(r)

    def block_park(u0: float, u1: float, v0: float, v1: float) -> None:
        fill_ground([_quad(u0, u1, v0, v1)], rng.uniform(22.0, 30.0), 0.9)
        area = (u1 - u0) * (v1 - v0)
        for _ in range(rng.poisson(area / (900.0 * scale * scale))):
            c = _uv(rng.uniform(u0, u1), rng.uniform(v0, v1))
            r = rng.uniform(3.0, 8.0) * scale
            _tree(trees, c, r, rng.uniform(20.0, 27.0), sun)
            tree_r.append(r)

    def block_parking(u0: float, u1: float, v0: float, v1: float) -> None:
        t_asph = rng.uniform(40.0, 55.0)
        fill_ground([_quad(u0, u1, v0, v1)], t_asph, 0.5)
        car_w, car_l = 2.6 * scale, 5.5 * scale
        v = v0 + car_l + 2
        while v < v1 - car_l - 2:
            u = u0 + car_w + 2
            while u < u1 - car_w - 2:
                if rng.random() < 0.7:
                    cars.poly([_rect(_uv(u, v), eu, ev, car_w, car_l)], rng.uniform(25.0, 52.0),
                              0.3)
                u += 2 * car_w + 2 * scale
            v += 4 * car_l

    def block_lot(u0: float, u1: float, v0: float, v1: float) -> None:
        fill_ground([_quad(u0, u1, v0, v1)], rng.uniform(32.0, 45.0), 1.3)

    kinds = (block_buildings, block_park, block_parking, block_lot)
    kind_p = np.array([0.6, 0.14, 0.12, 0.14])
    for (ua, wa, _), (ub, wb, _) in zip(us[:-1], us[1:], strict=True):
        for (va, wva, _), (vb, wvb, _) in zip(vs[:-1], vs[1:], strict=True):
            u0, u1 = ua + wa / 2 + sidewalk, ub - wb / 2 - sidewalk
            v0, v1 = va + wva / 2 + sidewalk, vb - wvb / 2 - sidewalk
            if u1 - u0 < 4 or v1 - v0 < 4:
                continue
            q = _quad(u0, u1, v0, v1)
            if q[:, 0].max() < 0 or q[:, 0].min() > w or q[:, 1].max() < 0 or q[:, 1].min() > h:
                continue
            kinds[int(rng.choice(4, p=kind_p))](u0, u1, v0, v1)

    # streets: sidewalks, asphalt, painted centre lines, street trees
    reach = 2.0 * (w + h)
    segs = [(_uv(p, -reach), _uv(p, reach), wd, wide) for p, wd, wide in us]
    segs += [(_uv(-reach, p), _uv(reach, p), wd, wide) for p, wd, wide in vs]
    t_concrete = rng.uniform(33.0, 44.0)
    for p0, p1, wd, _ in segs:
        line_ground(p0, p1, t_concrete, 0.5, wd + 2 * sidewalk)
    t_asphalt = rng.uniform(40.0, 55.0)
    for p0, p1, wd, _ in segs:
        line_ground(p0, p1, t_asphalt + rng.normal(0.0, 1.5), 0.4, wd)
    paint = t_asphalt - rng.uniform(3.0, 6.0)
    for p0, p1, _, wide in segs:
        if not wide:
            continue
        e = (p1 - p0) / float(np.hypot(*(p1 - p0)))
        dash = 6.0 * scale
        for s in np.arange(0.0, float(np.hypot(*(p1 - p0))), 2 * dash):
            a = p0 + s * e
            if -dash <= a[0] <= w + dash and -dash <= a[1] <= h + dash:
                line_ground(a, a + dash * e, paint, 0.2, max(1.0, scale))
    for p0, p1, wd, _ in segs:
        if rng.random() < 0.5:
            continue
        e = (p1 - p0) / float(np.hypot(*(p1 - p0)))
        nrm = np.array([-e[1], e[0]])
        r_lo, r_hi = 2.5 * scale, 5.5 * scale
        off = wd / 2 + sidewalk
        # only the part of the street inside the map
        s_in = _segment_inside(p0, e, float(np.hypot(*(p1 - p0))), w, h)
        if s_in is None:
            continue
        a, b = p0 + s_in[0] * e, p0 + s_in[1] * e
        t_tree = rng.uniform(20.0, 27.0)
        for side in (-1.0, 1.0):
            r = _tree_row(trees, a + side * off * nrm, b + side * off * nrm, rng, sun,
                          radius=(r_lo, r_hi), temp=t_tree, gap=0.25)
            if r:
                tree_r.append(r)

    temp = base + tex * noise_fine
    temp += rng.uniform(0.5, 1.5) * noise_large
    cars.paste(temp, noise_fine)

    # shadows of buildings (by height class) and trees on the ground and cars
    shade = np.zeros((h, w), dtype=bool)
    for b, mask in enumerate(height_bins):
        height = 0.5 * (bin_edges[b] + bin_edges[b + 1])
        shade |= _shadow(mask, height * sun.factor, sun.direction)
    if tree_r:
        shade |= _shadow(trees.mask, 2.0 * float(np.mean(tree_r)) * sun.factor, sun.direction)
    shade &= ~(roofs.mask.astype(bool) | trees.mask.astype(bool))
    sun.darken(temp, shade)
    roofs.paste(temp, noise_fine)
    trees.paste(temp, noise_fine)

    # a water body: a lake or a river
    water = np.zeros((h, w), dtype=np.uint8)
    if rng.random() < 0.6:
        centre = np.array([rng.uniform(0.1, 0.9) * w, rng.uniform(0.1, 0.9) * h])
        radius = min(rng.uniform(40.0, 140.0) * scale, 0.3 * min(h, w))
        _fill(water, [_blob(centre, max(radius, 4.0), rng)], 1)
    else:
        phi = rng.uniform(0.0, math.pi)
        e, nrm = _rot(phi)
        centre = np.array([rng.uniform(0.2, 0.8) * w, rng.uniform(0.2, 0.8) * h])
        s = np.linspace(-reach / 2, reach / 2, 400)
        wander = np.zeros_like(s)
        for _ in range(5):  # meanders of random wavelength, amplitude ~ 10 % of it
            lam = rng.uniform(120.0, 900.0) * scale
            wander += rng.uniform(0.03, 0.12) * lam * np.sin(
                2 * math.pi * s / lam + rng.uniform(0, 2 * math.pi)
            )
        pts = centre + s[:, None] * e + wander[:, None] * nrm
        width = max(4, int(round(rng.uniform(20.0, 45.0) * scale)))
        cv2.polylines(water, [_fix(pts)], False, 1, width, cv2.LINE_8, _SHIFT)
    _water(temp, water, noise_large, noise_fine, rng, scale)
    return temp


def _segment_inside(
    p0: np.ndarray, e: np.ndarray, length: float, w: int, h: int
) -> tuple[float, float] | None:
    """Parameter range ``[s0, s1]`` of the segment ``p0 + s e, 0 <= s <= length`` inside the map."""
    s0, s1 = 0.0, length
    for k, size in ((0, w - 1.0), (1, h - 1.0)):
        if abs(e[k]) < 1e-12:
            if not 0 <= p0[k] <= size:
                return None
            continue
        a, b = (0 - p0[k]) / e[k], (size - p0[k]) / e[k]
        s0, s1 = max(s0, min(a, b)), min(s1, max(a, b))
    return (s0, s1) if s1 > s0 else None


# --------------------------------------------------------------------------------------------
# mixed and the public entry point
# --------------------------------------------------------------------------------------------


def _mixed(h: int, w: int, rng: np.random.Generator, scale: float) -> np.ndarray:
    """Farmland with a town on one side of a (road) boundary."""
    temp = _farmland(h, w, rng, scale)
    frac = rng.uniform(0.3, 0.55)
    alpha = rng.integers(0, 4) * (math.pi / 2) + math.radians(rng.uniform(-20.0, 20.0))
    nrm = np.array([math.cos(alpha), math.sin(alpha)])
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], dtype=np.float64)
    # offset that leaves about ``frac`` of the map on the town side (coarse grid quantile)
    gy, gx = np.mgrid[0 : h : max(1, h // 64), 0 : w : max(1, w // 64)]
    proj = gx.ravel() * nrm[0] + gy.ravel() * nrm[1]
    c = float(np.quantile(proj, 1.0 - frac))
    point = c * nrm
    town, _, _ = _split_convex(corners, point, nrm)
    if len(town) < 3:
        return temp
    x0 = max(0, int(math.floor(town[:, 0].min())))
    x1 = min(w, int(math.ceil(town[:, 0].max())) + 1)
    y0 = max(0, int(math.floor(town[:, 1].min())))
    y1 = min(h, int(math.ceil(town[:, 1].max())) + 1)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return temp
    sub = _urban(y1 - y0, x1 - x0, rng, scale)
    mask = np.zeros((h, w), dtype=np.uint8)
    _fill(mask, [town], 1)
    m = mask[y0:y1, x0:x1].astype(bool)
    temp[y0:y1, x0:x1][m] = sub[m]
    # the boundary road
    e = np.array([-nrm[1], nrm[0]])
    reach = 2.0 * (w + h)
    width = rng.uniform(10.0, 18.0) * scale
    road = _Layer(h, w)
    road.line(point - reach * e, point + reach * e, rng.uniform(33.0, 44.0), 0.5,
              width + 2 * rng.uniform(2, 4) * scale)
    road.line(point - reach * e, point + reach * e, rng.uniform(40.0, 55.0), 0.4, width)
    road.paste(temp, fractal_noise((h, w), beta=1.6, rng=rng))
    return temp


def procedural_scene(
    shape: tuple[int, int],
    *,
    rng: np.random.Generator,
    kind: str = "farmland",
    scale: float = 1.0,
) -> np.ndarray:
    """A procedural daytime aerial temperature map.

    Parameters
    ----------
    shape : tuple of int
        ``(H, W)`` of the map, pixels.
    rng : numpy.random.Generator
        Source of randomness (the same seed gives the same scene).
    kind : {"farmland", "urban", "mixed"}
        ``"farmland"``: fields of different crops with crop rows at various orientations, orchards,
        stubble, ploughed, dry and wet bare soil, pasture; dirt roads, hedges and tree lines,
        isolated trees, sometimes a farmstead and a pond. ``"urban"``: a street grid (asphalt,
        sidewalks, painted lines), blocks of buildings with hot or cool roofs, parks, parking
        lots with cars, vacant lots, street trees, cast shadows, a lake or a river.
        ``"mixed"``: farmland with a town on one side of a road.
    scale : float
        Multiplies every object size (fields, rows, buildings, trees), ``0.25 <= scale <= 8``.

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        Surface temperature, °C (the ranges in the module docstring), blurred by a Gaussian of
        :data:`OPTICS_BLUR_SIGMA_PX` pixels.

    Raises
    ------
    InvalidInputError
        A bad shape, kind, scale or rng.
    """
    rng = check_rng(rng)
    h, w = _check_shape(shape)
    if kind not in KINDS:
        raise InvalidInputError(f"kind {kind!r}: choose from {', '.join(KINDS)}")
    try:
        s = float(scale)
    except (TypeError, ValueError):
        raise InvalidInputError(f"scale: expected a number, got {scale!r}") from None
    if not (0.25 <= s <= 8.0):
        raise InvalidInputError(f"scale: expected 0.25 <= scale <= 8, got {scale!r}")
    builder = {"farmland": _farmland, "urban": _urban, "mixed": _mixed}[kind]
    temp = builder(h, w, rng, s)
    temp = cv2.GaussianBlur(temp, (0, 0), OPTICS_BLUR_SIGMA_PX, borderType=cv2.BORDER_REFLECT)
    np.clip(temp, -40.0, 90.0, out=temp)
    return np.ascontiguousarray(temp, dtype=np.float32)
