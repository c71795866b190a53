"""Synthetic training bursts for the KPN, made on the fly by the camera simulator (numpy only).

The pipeline of Oz et al. §IV-C/D, with the physical camera model of :mod:`thermocal.camera` in
place of their fitted degradation model:

1. a temperature map is drawn from a pool of source scenes (procedural maps and real radiometric
   scenes of the *training* list), a random region is cut, resized and flipped / rotated by 90°,
   and its temperature level and contrast are re-drawn (so that the network sees the whole
   operating range, not only the few scenes it has);
2. ``N`` views of it are made by a random walk or a hover whose extreme views overlap the pivot
   (middle) frame by 60-80 %;
3. a sub-window of the sensor of a camera unit drawn from the *training units* renders every view
   at an FPA temperature drawn over the operating range (the camera settled at that ambient), with
   the column FPN of eq. 19 re-drawn for the burst (and, for a model fitted on a chamber file,
   pixel FPN of the spread measured there) and temporal noise σ² = 5 counts² per frame;
4. the true frame → pivot homographies get the registration error of §IV-D (±2 px, N(0, 5e-5) on
   h31, h32), the burst's stuck pixels are replaced by their neighbours (as at inference) and the
   frames are warped onto the pivot: the network's input, with validity masks (a pivot pixel that
   a frame does not see is 0 and flagged False);
5. the target is the scene in the pivot's view.

Normalisation (eq. 20-21) maps temperatures and counts linearly onto ``[0, 1]`` with constants
kept in :class:`~thermocal.nn.inputs.Normalisation`, which travels with the weights.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import cv2
import numpy as np

from thermocal.burst import fill_stuck_pixels
from thermocal.camera.model import CameraModel, render
from thermocal.camera.presets import PRESETS, make_camera
from thermocal.camera.thermal import WARMED_UP_S, fpa_sensor
from thermocal.errors import InvalidInputError
from thermocal.nn.inputs import (
    calibrate_frames,
    frame_r2,
    nominal_camera,
    sensor_r2,
)
from thermocal.registration.warp import render_views, warp_to_pivot
from thermocal.scenes import trajectory
from thermocal.scenes.maps import random_augment
from thermocal.scenes.procedural import KINDS, procedural_scene

__all__ = [
    "EVAL_SCENES",
    "EVAL_UNITS",
    "TRAIN_EXCLUDED_SCENES",
    "TRAIN_UNITS",
    "VAL_UNITS",
    "Burst",
    "BurstConfig",
    "ScenePool",
    "UnitCache",
    "coverage_mask",
    "make_burst",
    "make_bursts",
    "min_views",
    "window_offsets",
]

#: Camera units of the ``tau2`` preset used for training, validation (early stopping and the
#: learning-rate schedule) and evaluation (benchmarks, tests). The three sets never overlap.
TRAIN_UNITS: tuple[int, ...] = tuple(range(0, 24))
VAL_UNITS: tuple[int, ...] = (50, 51, 52, 53)
EVAL_UNITS: tuple[int, ...] = (100, 101, 102, 103, 104)

#: Real scenes held out for evaluation (never trained on): the built-in aerial scene (and its copy
#: in ``shared/data/flirpy``), the built-in floor heating (and its copy in ``shared/data/scenes``)
#: and a fixed subset of the shared JPEGs (the two car scenes are held out together, being alike).
EVAL_SCENES: tuple[str, ...] = (
    "builtin:aerial",
    "02_irwatercooler",
    "11_ir_moving_car",
    "12_ir_moving_mercedes",
    "14_kujawy_wiatrak",
)
TRAIN_EXCLUDED_SCENES: frozenset[str] = frozenset(
    {"example_radiometric", "10_ir_fussbodenheizung", *EVAL_SCENES}
)

#: Frame rate of a synthetic burst, Hz (the Tau2's 9 Hz export rate).
BURST_FPS = 9.0


@dataclass(frozen=True)
class BurstConfig:
    """How synthetic bursts are made (defaults: Oz et al. §IV-D at a CPU-friendly crop size).

    Attributes
    ----------
    n_frames : int
        Frames per burst ``N``; the pivot is frame ``N // 2``.
    crop : int
        Side of the square frames, pixels (the paper: 128).
    motions : tuple of str
        Trajectories drawn from: ``"walk"`` and/or ``"hover"``.
    overlap : (float, float)
        Overlap range of the extreme views with the pivot.
    walk_frames : int or None
        Draw each trajectory for this many frames (≥ ``n_frames``, of its parity) and keep the
        ``n_frames`` around its pivot: less motion than an ``n_frames`` walk, whose extremes
        overlap the pivot by ``overlap``. ``None``: ``n_frames``.
    translation_px, perspective_sigma : float
        Registration error: uniform ±``translation_px`` and N(0, σ²) on h31, h32.
    fpa_range_c : (float, float)
        FPA temperature drawn uniformly over this range, °C.
    temp_mean_range_c : (float, float)
        Mean temperature of a training map, drawn uniformly, °C.
    contrast_range : (float, float)
        Factor on the map's deviations from its mean, drawn log-uniformly.
    temp_clip_c : (float, float)
        Map temperatures are clipped to this range, °C.
    map_scale_range : (float, float)
        Map pixels per source-scene pixel, drawn log-uniformly.
    redraw_column_fpn : bool
        Re-draw the unit's column FPN (eq. 19: gain ``U[0.9, 1.01]`` per column, and the additive
        column term) for every burst, and draw pixel FPN for a camera fitted on a chamber file
        (:func:`draw_pixel_fpn`).
    redraw_pixel_fpn : bool
        Replace a preset unit's pixel FPN by a new draw for every burst
        (:func:`redraw_pixel_fpn`); the validation units keep theirs.
    augment : bool
        Flips and 90° rotations, re-drawn levels and contrast (off for validation).
    preset : str
        Camera preset.
    units : tuple of int
        Camera units drawn from.
    sensor_size : (int, int)
        ``(W, H)`` of the full sensor; each burst uses a random ``crop × crop`` window of it.
    sensor_motion : bool
        Displace the frames on the sensor as whole-sensor frames of the same overlap are: each
        frame is rendered by the sensor window that sees the pivot window's scene where a
        ``sensor_size`` frame would (the trajectory's displacements scaled by sensor side /
        crop per axis, less where the windows would leave the sensor; :func:`window_offsets`).
        Off (the paper's crops): every frame is rendered by the pivot's window, so a scene
        point moves across the sensor by crop-sized amounts only, and the radial offset and
        vignetting it meets in the other frames are those of nearby pixels. With it, stuck
        pixels are left out of the rendering (inference replaces them before the network).
    calibrated : bool
        Also give every burst its frames through the exact inverse of the *nominal* camera
        (:func:`~thermocal.nn.inputs.nominal_camera` of ``nominal_units``), calibrated on the
        sensor before warping (:attr:`Burst.frames_c`): the input of a
        :attr:`~thermocal.nn.model.ModelConfig.calibrated` network.
    nominal_units : tuple of int or None
        The units whose average is the nominal camera (default ``units``): the validation bursts
        of a run keep its training units' (what the network is given at inference).
    """

    n_frames: int = 7
    crop: int = 64
    motions: tuple[str, ...] = ("walk", "hover")
    overlap: tuple[float, float] = (0.6, 0.8)
    walk_frames: int | None = None
    translation_px: float = 2.0
    perspective_sigma: float = trajectory.PERSPECTIVE_SIGMA
    fpa_range_c: tuple[float, float] = (10.0, 50.0)
    temp_mean_range_c: tuple[float, float] = (-15.0, 60.0)
    contrast_range: tuple[float, float] = (0.3, 2.0)
    temp_clip_c: tuple[float, float] = (-40.0, 100.0)
    map_scale_range: tuple[float, float] = (0.5, 2.0)
    redraw_column_fpn: bool = True
    redraw_pixel_fpn: bool = False
    augment: bool = True
    preset: str = "tau2"
    units: tuple[int, ...] = TRAIN_UNITS
    sensor_size: tuple[int, int] = (336, 256)
    sensor_motion: bool = False
    calibrated: bool = False
    nominal_units: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.n_frames < 1:
            raise InvalidInputError(f"n_frames must be >= 1, got {self.n_frames}")
        if not 16 <= self.crop <= min(self.sensor_size):
            raise InvalidInputError(
                f"crop must be 16 … {min(self.sensor_size)} px, got {self.crop}"
            )
        bad = set(self.motions) - {"walk", "hover"}
        if bad or not self.motions:
            raise InvalidInputError(f"motions must be walk and/or hover, got {self.motions}")
        if not self.units:
            raise InvalidInputError("units: give at least one camera unit")
        if self.walk_frames is not None and (
            self.walk_frames < self.n_frames or self.walk_frames % 2 != self.n_frames % 2
        ):
            raise InvalidInputError(
                f"walk_frames must be >= n_frames ({self.n_frames}) and of its parity (the "
                f"pivots line up), got {self.walk_frames}"
            )
        lo, hi = self.temp_mean_range_c
        if not self.temp_clip_c[0] <= lo < hi <= self.temp_clip_c[1]:
            raise InvalidInputError(
                f"temp_mean_range_c {lo:g}…{hi:g} °C must lie inside the clip range "
                f"{self.temp_clip_c[0]:g}…{self.temp_clip_c[1]:g} °C"
            )

    @property
    def nominal_of(self) -> tuple[int, ...]:
        """The units whose average is the nominal camera: ``nominal_units``, else ``units``."""
        return self.nominal_units or self.units

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


@dataclass(frozen=True)
class Burst:
    """One synthetic burst registered onto its pivot.

    Attributes
    ----------
    frames : (N, S, S) float32
        Warped raw counts (0 where ``valid`` is False).
    valid : (N, S, S) bool
        Where each warped frame sees the pivot pixel.
    truth_c : (S, S) float32
        The scene in the pivot's view, °C.
    raw : (N, S, S) uint16
        The frames as the camera gave them (before registration).
    homographies : (N, 3, 3) float64
        The frame → pivot homographies used for warping (with the registration error).
    fpa_c : float
        The FPA temperature the camera reports, °C.
    unit : int
        Camera unit.
    camera : CameraModel
        The sensor window that rendered the burst (with the re-drawn FPN).
    r2 : (S, S) float32
        Where the pivot's pixels lie on the sensor: ``R²`` of Oz et al. eq. 16 for the window.
    r2_frames : (N, S, S) float32
        Where on the sensor each frame saw each pivot pixel: ``R²`` of the frame's pixels warped
        onto the pivot like the frames (:func:`frame_r2`); the pivot's ``r2`` where a frame does
        not see the pixel.
    frames_c : (N, S, S) float32 or None
        With :attr:`BurstConfig.calibrated`: the frames through the nominal camera
        (:func:`calibrate_frames`), warped like ``frames``, °C; else None.
    """

    frames: np.ndarray
    valid: np.ndarray
    truth_c: np.ndarray
    raw: np.ndarray
    homographies: np.ndarray
    fpa_c: float
    unit: int
    camera: CameraModel = field(repr=False)
    r2: np.ndarray = field(repr=False)
    r2_frames: np.ndarray = field(repr=False)
    frames_c: np.ndarray | None = field(default=None, repr=False)


def coverage_mask(valid: np.ndarray) -> np.ndarray:
    """Pixels of the pivot seen by at least half the frames, ``(H, W)`` bool.

    The mask ``M`` of eq. 12 (loss) and of the evaluation: where the burst really holds
    redundant views of the scene. ``valid`` is ``(N, H, W)``.
    """
    return valid.sum(axis=0) >= min_views(valid.shape[0])


def min_views(n_frames: int) -> int:
    """How many of a burst's ``n_frames`` must see a pivot pixel for it to count (half)."""
    return max(1, math.ceil(n_frames / 2))


class ScenePool:
    """Source temperature maps to cut training crops from.

    Parameters
    ----------
    maps : list of (H, W) float32 arrays
        Temperature maps, °C.
    names : list of str
        Their names (for the record).
    weights : list of float, optional
        Relative probability of drawing each map (default uniform).
    """

    def __init__(
        self, maps: list[np.ndarray], names: list[str], weights: list[float] | None = None
    ) -> None:
        if not maps or len(maps) != len(names):
            raise InvalidInputError("ScenePool needs at least one map and one name per map")
        self.maps = [np.ascontiguousarray(m, dtype=np.float32) for m in maps]
        self.names = list(names)
        w = np.ones(len(maps)) if weights is None else np.asarray(weights, dtype=np.float64)
        self.p = w / w.sum()

    @classmethod
    def training(
        cls,
        *,
        n_procedural: int = 24,
        size: int = 384,
        seed: int = 42,
        real: bool = True,
        real_weight: float = 0.35,
    ) -> ScenePool:
        """Procedural maps (farmland, urban, mixed) and the real scenes of the training list.

        Real scenes in :data:`TRAIN_EXCLUDED_SCENES` (the evaluation set) are never loaded.
        ``real_weight`` is the total probability of drawing a real scene.
        """
        maps, names, weights = [], [], []
        for i in range(n_procedural):
            kind = KINDS[i % len(KINDS)]
            rng = np.random.default_rng([seed, 7919, i])
            scale = float(np.exp(rng.uniform(np.log(0.5), np.log(2.0))))
            maps.append(procedural_scene((size, size), rng=rng, kind=kind, scale=scale))
            names.append(f"procedural:{kind}:{i}")
        real_maps = training_real_scenes() if real else {}
        n_real = len(real_maps)
        for name, m in real_maps.items():
            maps.append(m)
            names.append(name)
        if n_real:
            weights = [(1.0 - real_weight) / n_procedural] * n_procedural
            weights += [real_weight / n_real] * n_real
        return cls(maps, names, weights if n_real else None)

    def draw(self, rng: np.random.Generator) -> tuple[np.ndarray, str]:
        """A map drawn at random (not copied; callers must not modify it)."""
        i = int(rng.choice(len(self.maps), p=self.p))
        return self.maps[i], self.names[i]


def training_real_scenes() -> dict[str, np.ndarray]:
    """The real scenes of ``shared/data`` that are not held out for evaluation, °C maps."""
    from thermocal.scenes.real import list_shared_scenes, load_scene

    out = {}
    for name, path in list_shared_scenes().items():
        if name in TRAIN_EXCLUDED_SCENES:
            continue
        out[name] = load_scene(path)
    return out


def evaluation_scenes() -> dict[str, np.ndarray]:
    """The held-out real scenes (:data:`EVAL_SCENES`) that can be found, °C maps."""
    from thermocal.scenes.builtin import load_builtin_scene
    from thermocal.scenes.real import list_shared_scenes, load_scene

    shared = list_shared_scenes()
    out = {}
    for name in EVAL_SCENES:
        if name.startswith("builtin:"):
            out[name] = load_builtin_scene(name.split(":", 1)[1])
        elif name in shared:
            out[name] = load_scene(shared[name])
    return out


class UnitCache:
    """Full-sensor camera units, made once (``make_camera`` is the slow part); ``cameras``
    (unit number → model, e.g. fitted on a chamber file) stand in for the preset's units."""

    def __init__(self, preset: str, sensor_size: tuple[int, int],
                 cameras: dict[int, CameraModel] | None = None) -> None:
        self.preset = preset
        self.sensor_size = tuple(sensor_size)
        self._units: dict[int, CameraModel] = dict(cameras or {})
        self._nominal: dict[tuple[int, ...], CameraModel] = {}

    def get(self, unit: int) -> CameraModel:
        """Unit ``unit`` of the preset at the full sensor size."""
        if unit not in self._units:
            self._units[unit] = make_camera(self.preset, unit=unit, size=self.sensor_size)
        return self._units[unit]

    def nominal(self, units: tuple[int, ...]) -> CameraModel:
        """:func:`~thermocal.nn.inputs.nominal_camera` of ``units``, made once."""
        key = tuple(int(u) for u in units)
        if key not in self._nominal:
            self._nominal[key] = nominal_camera([self.get(u) for u in key])
        return self._nominal[key]


def _source_map(
    scene: np.ndarray, shape: tuple[int, int], cfg: BurstConfig, rng: np.random.Generator
) -> np.ndarray:
    """A ``shape`` map cut from ``scene`` at a random scale and place, °C, float32."""
    hm, wm = shape
    sh, sw = scene.shape
    lo, hi = cfg.map_scale_range if cfg.augment else (1.0, 1.0)
    scale = float(np.exp(rng.uniform(np.log(lo), np.log(hi)))) if hi > lo else lo
    scale = max(scale, hm / sh, wm / sw)  # a scene too small is enlarged to cover the map
    ch, cw = min(sh, math.ceil(hm / scale)), min(sw, math.ceil(wm / scale))
    if cfg.augment:
        top, left = int(rng.integers(0, sh - ch + 1)), int(rng.integers(0, sw - cw + 1))
    else:
        top, left = (sh - ch) // 2, (sw - cw) // 2
    region = scene[top : top + ch, left : left + cw]
    interp = cv2.INTER_AREA if scale < 1.0 else cv2.INTER_CUBIC
    out = cv2.resize(region, (wm, hm), interpolation=interp)
    return np.clip(out, region.min(), region.max()).astype(np.float32)


def _relevel(m: np.ndarray, cfg: BurstConfig, rng: np.random.Generator) -> np.ndarray:
    """Re-draw the mean temperature and the contrast of a map (augmentation), °C."""
    mean = float(m.mean())
    lo, hi = cfg.contrast_range
    k = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
    target = rng.uniform(*cfg.temp_mean_range_c)
    out = (m - mean) * np.float32(k) + np.float32(target)
    return np.clip(out, *cfg.temp_clip_c).astype(np.float32)


def redraw_column_fpn(camera: CameraModel, left: int, rng: np.random.Generator) -> CameraModel:
    """The sensor window ``camera`` (starting at column ``left`` of its unit) with new column FPN.

    Eq. 19: the multiplicative column factor ``U[u_min, u_max]`` and the additive column offset
    of the preset are drawn again, replacing the unit's own. A camera without column FPN of its
    own (a radial model fitted on a chamber file, Oz et al. §IV-C) gets it on top, with the
    ``tau2`` preset's ranges, divided by the mean of the factor's range: the radial fit already
    holds the unit's average column factor, which must not be counted twice.
    """
    info = camera.info
    p = info.get("preset_parameters") or asdict(PRESETS["tau2"])
    w = camera.shape[1]
    if "column_gain" in info:
        old_gain = np.asarray(info["column_gain"], dtype=np.float32)[left : left + w]
        old_off = np.asarray(info["column_offset"], dtype=np.float32)[left : left + w]
    else:
        old_gain = np.full(w, np.mean(p["column_gain_range"]), np.float32)
        old_off = np.zeros(w, np.float32)
    new_gain = rng.uniform(*p["column_gain_range"], size=w).astype(np.float32)
    new_off = (p["column_offset_sigma"] * rng.standard_normal(w)).astype(np.float32)
    gain = camera.gain * (new_gain / old_gain)[None, None, :]
    offset = camera.offset.copy()
    offset[0] += (new_off - old_off)[None, :]
    return replace(camera, gain=gain.astype(np.float32), offset=offset)


def draw_pixel_fpn(camera: CameraModel, rng: np.random.Generator) -> CameraModel:
    """``camera`` with random pixel FPN on top, if it is a smooth model fitted on a chamber file.

    A radial model (:func:`~thermocal.calibration.polynomial.camera_model_from_chamber`) has no
    pixel FPN; the spread it dropped is in ``camera.info["pixel_fpn"]``. Each call draws a new
    pattern of that spread: responsivity × (1 + σ_g·z) and offset + σ_o·z′, z, z′ ~ N(0, 1) per
    pixel. Any other camera is returned as it is (a preset unit has FPN of its own).
    """
    fpn = camera.info.get("pixel_fpn")
    if not fpn:
        return camera
    return _new_pixel_fpn(camera, fpn["gain_sigma"], fpn["offset_sigma_counts"], rng)


def redraw_pixel_fpn(
    camera: CameraModel, top: int, left: int, rng: np.random.Generator
) -> CameraModel:
    """The sensor window ``camera`` (at ``top, left`` of a preset unit) with new pixel FPN.

    The unit's own pixel patterns (``info["pixel_gain"]``, ``info["pixel_offset"]``) are replaced
    by a new draw of the preset's spreads: every burst then shows the network a pattern it has
    not seen, as Oz et al. add random FPN to their model. A camera without its own patterns is
    returned as it is.
    """
    info = camera.info
    if "pixel_gain" not in info:
        return camera
    p = info["preset_parameters"]
    h, w = camera.shape
    window = (slice(top, top + h), slice(left, left + w))
    return _new_pixel_fpn(camera, p["gain_pixel_sigma"], p["offset_pixel_sigma"], rng,
                          old_gain=info["pixel_gain"][window],
                          old_offset=info["pixel_offset"][window])


def _new_pixel_fpn(
    camera: CameraModel,
    gain_sigma: float,
    offset_sigma: float,
    rng: np.random.Generator,
    *,
    old_gain: np.ndarray | float = 1.0,
    old_offset: np.ndarray | float = 0.0,
) -> CameraModel:
    """``camera`` with its pixel FPN ``old_gain`` (factor on the responsivity) and
    ``old_offset`` (counts) replaced by a new draw: ``1 + gain_sigma·z``, ``offset_sigma·z′``."""
    shape = camera.shape
    new_gain = 1.0 + np.float32(gain_sigma) * rng.standard_normal(shape, np.float32)
    new_off = np.float32(offset_sigma) * rng.standard_normal(shape, np.float32)
    offset = camera.offset.copy()
    offset[0] += new_off - old_offset
    gain = camera.gain * (new_gain / old_gain)[None]
    return replace(camera, gain=gain.astype(np.float32), offset=offset)


def window_offsets(
    homographies: np.ndarray, crop: int, sensor_size: tuple[int, int], pivot: int
) -> np.ndarray:
    """Each frame's sensor window relative to the pivot's, ``(N, 2)`` int (rows, columns), for
    :attr:`BurstConfig.sensor_motion`.

    Frame ``i`` sees the pivot window's centre ``c`` at ``q_i = H_i⁻¹ c`` within its window
    (``homographies`` frame → pivot, ``(N, 3, 3)``), a displacement ``δ_i = q_i − c`` scaled to
    the crop. A whole ``sensor_size`` frame of the same overlap would see it displaced by
    ``f·δ_i``, ``f`` = sensor side / ``crop`` per axis; the frame's window is therefore moved by
    ``(f − 1)·δ_i``, so that the scene inside it stays where the crop trajectory put it while
    the sensor pixels under it are those of a whole-sensor burst. Where the windows would not
    fit on the sensor together, the moves along that axis are shrunk until they do.
    """
    c = (crop - 1) / 2.0
    centre = np.array([c, c, 1.0])
    q = np.stack([np.linalg.solve(h, centre) for h in homographies])
    delta = q[:, 1::-1] / q[:, 2:3] - c  # (rows, columns)
    w, h = sensor_size
    moves = delta * (np.array([h, w], dtype=float) / crop - 1.0)
    moves -= moves[pivot]
    for axis, side in enumerate((h, w)):
        span = np.ptp(moves[:, axis])
        if span > side - crop:
            moves[:, axis] *= (side - crop) / span
    out = np.rint(moves).astype(int)
    for axis, side in enumerate((h, w)):  # rounding must not widen a shrunk span
        lo = out[:, axis].min()
        out[:, axis] = np.clip(out[:, axis], lo, lo + side - crop)
    return out


def make_burst(
    pool: ScenePool,
    cfg: BurstConfig,
    *,
    rng: np.random.Generator,
    units: UnitCache | None = None,
    unit: int | None = None,
    fpa_c: float | None = None,
) -> Burst:
    """One synthetic burst (see the module docstring).

    Parameters
    ----------
    pool : ScenePool
        Source maps.
    cfg : BurstConfig
        How to make it.
    rng : numpy.random.Generator
        Source of randomness: the same generator state gives the same burst.
    units : UnitCache, optional
        Cache of full-sensor units (made if not given).
    unit, fpa_c : optional
        Force the camera unit / the true FPA temperature (°C) instead of drawing them.
    """
    units = units or UnitCache(cfg.preset, cfg.sensor_size)
    n, s = cfg.n_frames, cfg.crop
    scene, _ = pool.draw(rng)
    motion = cfg.motions[int(rng.integers(len(cfg.motions)))]
    map_shape = (2 * s + 16, 2 * s + 16)
    if cfg.augment:
        scene = random_augment(scene, rng=rng) if min(scene.shape) >= 8 else scene
    big = _source_map(scene, map_shape, cfg, rng)
    if cfg.augment:
        big = _relevel(big, cfg, rng)
    m = cfg.walk_frames or n
    draw = trajectory.walk_homographies if motion == "walk" else trajectory.hover_homographies
    to_map = draw(m, (s, s), map_shape[::-1], rng=rng, overlap=cfg.overlap)
    to_map = to_map[m // 2 - n // 2 : m // 2 - n // 2 + n]
    pivot = n // 2
    truth = render_views(big, to_map, (s, s))

    u = int(cfg.units[int(rng.integers(len(cfg.units)))]) if unit is None else int(unit)
    full = units.get(u)
    sh, sw = full.shape
    h_true = trajectory.to_pivot(to_map, pivot)
    if cfg.sensor_motion:  # the frames' windows, relative to the pivot's: (N, 2) rows, columns
        moves = window_offsets(h_true, s, (sw, sh), pivot)
    else:
        moves = np.zeros((n, 2), dtype=int)
    lo, hi = moves.min(axis=0), moves.max(axis=0)
    top = int(rng.integers(-lo[0], sh - s - hi[0] + 1))
    left = int(rng.integers(-lo[1], sw - s - hi[1] + 1))
    # the union of the windows, with its FPN re-drawn once: a sensor pixel keeps its pattern
    # in every frame that it renders
    cam = full.crop(top + lo[0], left + lo[1], s + hi[0] - lo[0], s + hi[1] - lo[1])
    if cfg.redraw_column_fpn:
        cam = draw_pixel_fpn(redraw_column_fpn(cam, left + lo[1], rng), rng)
    if cfg.redraw_pixel_fpn:
        cam = redraw_pixel_fpn(cam, top + lo[0], left + lo[1], rng)
    fpa_true = float(rng.uniform(*cfg.fpa_range_c)) if fpa_c is None else float(fpa_c)
    housing = fpa_true - cam.thermal.fpa_self_heating_c
    # frame times since switch-on, for a family that drifts (its draw only then: the others'
    # bursts stay as they were)
    times = (WARMED_UP_S + rng.uniform(0.0, 3600.0) + np.arange(n) / BURST_FPS
             if cam.drifts else np.full(n, None))
    if cfg.sensor_motion:
        windows = [_without_defects(cam.crop(dy - lo[0], dx - lo[1], s, s)) for dy, dx in moves]
        raw = np.concatenate([render(w, truth[i : i + 1], fpa_true, housing_c=housing, rng=rng,
                                     time_s=times[i])
                              for i, w in enumerate(windows)])
        cam = windows[pivot]
    else:
        raw = render(cam, truth, fpa_true, housing_c=housing, rng=rng,
                     time_s=times if cam.drifts else None)
    fpa_read = float(fpa_sensor(np.array([fpa_true]), cam.thermal, rng=rng)[0])

    h_reg = trajectory.perturb_homographies(
        h_true,
        rng=rng,
        frame_size=(s, s),
        translation_px=cfg.translation_px,
        perspective_sigma=cfg.perspective_sigma,
        pivot=pivot,
    )
    filled, _ = fill_stuck_pixels(raw, h_reg)  # as the estimation pipeline does
    warped, valid = warp_to_pivot(filled, h_reg)
    frames_c = None
    if cfg.calibrated:  # each frame through the nominal model of the window that rendered it
        nominal = units.nominal(cfg.nominal_of)
        temps = np.empty(filled.shape, np.float32)
        for dy, dx in np.unique(moves, axis=0):  # one window for all frames without sensor_motion
            same = np.all(moves == (dy, dx), axis=1)
            temps[same] = calibrate_frames(nominal.crop(top + dy, left + dx, s, s),
                                           filled[same], fpa_read)
        frames_c, _ = warp_to_pivot(temps, h_reg)
    r2_windows = np.stack([sensor_r2(full.shape, top + dy, left + dx, (s, s)) for dy, dx in moves])
    return Burst(
        frames=warped,
        valid=valid,
        truth_c=truth[pivot],
        raw=raw,
        homographies=h_reg,
        fpa_c=fpa_read,
        unit=u,
        camera=cam,
        r2=r2_windows[pivot],
        r2_frames=frame_r2(r2_windows, h_reg, valid, pivot),
        frames_c=frames_c,
    )


def _without_defects(camera: CameraModel) -> CameraModel:
    return replace(camera, defects=np.zeros_like(camera.defects),
                   defect_counts=np.zeros_like(camera.defect_counts))


def make_bursts(
    pool: ScenePool,
    cfg: BurstConfig,
    *,
    seed: int,
    start: int,
    count: int,
    units: UnitCache | None = None,
) -> list[Burst]:
    """Bursts ``start … start + count − 1`` of the seeded stream ``seed``.

    Burst ``i`` depends only on ``(seed, i)``, so a training run resumed at any step sees the
    same data as one that never stopped.
    """
    units = units or UnitCache(cfg.preset, cfg.sensor_size)
    return [
        make_burst(pool, cfg, rng=np.random.default_rng([seed, i]), units=units)
        for i in range(start, start + count)
    ]
