"""A radiometric mosaic of a processed flight: one canvas of °C from the per-pivot maps.

``thermocal flight`` writes one temperature map per pivot (``OUT/temps/frame_NNNNNN.tiff``, and
its 1σ map ``frame_NNNNNN_sigma.tiff`` when the method has one); consecutive pivots of a pass
overlap. :func:`build_mosaic` puts them on one canvas:

1. **registration**: each map is registered to the one before it
   (:func:`thermocal.registration.register_sequence` on the maps, no fixed pattern: they are
   calibrated), and the transforms are chained to the first map's pixel grid. A map that does
   not register to its predecessor (ECC correlation below
   :data:`~thermocal.registration.sequence.MIN_CORRELATION`, a degenerate homography) is
   registered directly to the last map of the chains that grew last; when that fails too it
   starts a chain of its own. The longest chain is kept, the other maps are left out with the
   reason: a bad map in the middle of a pass is bridged, a bad first map is dropped. ECC's
   affine estimate of each pair is reduced to a rotation and a translation by default
   (``motion="rigid"``): its small scale bias would otherwise compound along the chain.
2. **robust mean**, tile by tile: the canvas is cut into tiles small enough that every view of a
   tile fits in ``memory_mb`` (a tile is split while its views would not), and each tile's views
   are warped (bilinear, ``cv2.warpPerspective``) and combined exactly, per pixel:

   * the median ``m`` and the scaled median absolute deviation ``s = 1.4826 MAD`` of the views;
   * the views with ``|x − m| <= clip_sigma · max(s, clip_floor_c)`` are kept and averaged.

   Why this estimator: a bad view is mostly a whole bad map (a wrong offset, a misregistered
   map) seen in a handful of views per pixel; the mean and standard deviation of so few views
   cannot flag it (with ``n`` views one outlier sits at most ``(n − 1)/√n`` standard deviations
   from their mean, under 3 for ``n <= 10``), while the median and MAD ignore up to half of
   them. Averaging the kept views recovers the efficiency of the mean, which the median alone
   lacks (its noise is 1.25 times larger). ``clip_floor_c`` keeps identical views (MAD = 0)
   together. Two views cannot outvote each other: both are kept. Tiles rather than a streaming
   approximation (Welford passes, a running median) because a tile's views are few and hold
   the exact median; memory is bounded by ``memory_mb``, the canvas layers (18 bytes a pixel)
   and a cache of the last 48 maps read, whatever the number of maps.
3. **uncertainty**, where every map used has a σ map: ``σ = max(sqrt(mean σ_i²), spread/√n)``
   over the kept views. The first term treats the views' errors as fully correlated -- they
   share the calibration, the FPA reading and, for consecutive pivots, frames -- so averaging
   does not shrink it; it is exact for a calibration-dominated σ and conservative by up to
   ``√n`` for the noise part. It is never below the smallest σ of the views kept (a view's
   calibration-level floor stays). The second term is the standard error that the views'
   disagreement shows, for where they disagree more than their σ says (misregistration).

Outputs, in ``OUT/mosaic/`` (written in a temporary folder and renamed into place when all
are done: a failed run leaves the previous mosaic, or nothing; the temporary folder a killed run
leaves, ``OUT/.mosaic.*``, is removed by the next)::

    temperature.tiff  float32 °C (Hc, Wc), the robust mean; NaN outside coverage
    views.tiff        uint16, the views kept per pixel (0 outside coverage)
    spread.tiff       float32 °C, the standard deviation of the kept views (ddof 1); NaN where
                      fewer than two were kept
    sigma.tiff        float32 °C, 1σ of the mosaic (above), when σ maps exist; NaN outside
    mosaic.png        a preview with a colour bar in °C
    mosaic.json       canvas size, the maps used (transforms, correlation, rejected share) and
                      left out (with the reason), options, seconds

NaN marks "no data", so the float layers are read with :func:`tifffile.imread`
(:func:`thermocal.io.recording.read_temperature_tiff` refuses NaN). A canvas pixel ``(x, y)``
is pixel ``(x, y) − offset_px`` of the first map used; ``to_canvas`` takes a map's pixel
``(x, y)`` to the canvas (the conventions of :mod:`thermocal.registration.warp`).
"""

from __future__ import annotations

import contextlib
import re
import shutil
import tempfile
import time
import warnings
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import check_number
from thermocal.errors import FileFormatError, InvalidInputError, RegistrationError
from thermocal.pipeline.flight_log import read_log
from thermocal.registration.warp import translation

__all__ = ["MAX_CANVAS_PIXELS", "MOTIONS", "build_mosaic", "check_options"]

#: Motion models between consecutive maps (see :func:`build_mosaic`).
MOTIONS = ("rigid", "affine")

#: Largest canvas accepted (pixels): a pass of 10,000 maps of 640×512 at 27 px per map is
#: 140 million; beyond this a registration has drifted or the maps do not form one pass.
MAX_CANVAS_PIXELS = 2**28

_MAD_TO_SIGMA = 1.4826  # scale of the median absolute deviation of a normal distribution
_BYTES_PER_VIEW_PX = 32  # a tile's stacks (°C, masks) and the temporaries of the statistics
_TILE_PX = 512  # largest tile side
_MIN_TILE_PX = 16
_CACHE_MAPS = 48  # maps kept read between tiles (neighbouring tiles share most of their maps)
_PREVIEW_PX = 2000  # longest side of the preview image, pixels
#: A map's name in temps/, as the flight writes it (``frame_{pivot:06d}.tiff``).
_MAP_NAME = re.compile(r"frame_(\d{6,})\.tiff")
_STAGING = re.compile(r"\.mosaic\.(old\.)?[a-z0-9_]{8}")  # tempfile.mkdtemp's names
_REACH = 3  # chains a map may join (those that grew last)


@dataclass
class _Map:
    """One pivot's map on disk, and where it goes on the canvas once registered."""

    frame: int
    path: Path
    sigma_path: Path | None
    to_first: np.ndarray | None = None  # map pixel → first map's pixel
    registered_to: int | None = None
    correlation: float | None = None
    covered: int = 0  # view pixels on the canvas
    rejected: int = 0  # of them, clipped by the robust mean
    to_canvas: np.ndarray | None = None  # map pixel → canvas pixel


def check_options(*, clip_sigma: Any, clip_floor_c: Any, memory_mb: Any,
                  option: Any = str) -> tuple[float, float, float]:
    """:func:`build_mosaic`'s numbers checked and as floats; ``option(keyword)`` is the name a
    bad one is given by (the command line passes its option's)."""
    return (check_number(clip_sigma, option("clip_sigma"), low=0.0, low_open=True),
            check_number(clip_floor_c, option("clip_floor_c"), low=0.0),
            check_number(memory_mb, option("memory_mb"), low=16.0))


def build_mosaic(
    out_dir: str | Path,
    *,
    clip_sigma: float = 3.0,
    clip_floor_c: float = 0.1,
    memory_mb: float = 512.0,
    motion: str = "rigid",
) -> dict[str, Any]:
    """Mosaic the temperature maps of a processed flight into ``out_dir/mosaic``.

    Parameters
    ----------
    out_dir : str or Path
        The output folder of ``thermocal flight`` (``log.jsonl`` and ``temps/``). Only
        ``out_dir/mosaic`` is written.
    clip_sigma : float
        Views further than ``clip_sigma`` robust standard deviations from the median of a
        pixel's views are left out of its mean (> 0).
    clip_floor_c : float
        Smallest robust standard deviation, °C (>= 0): views within ``clip_sigma ·
        clip_floor_c`` of the median are always kept.
    memory_mb : float
        Memory for one tile's views, MiB (>= 16); the canvas layers come on top (about
        18 bytes per canvas pixel).
    motion : {"rigid", "affine"}
        How consecutive maps may differ: a rotation and a translation (a nadir pass at a
        steady altitude; no scale drift along the chain), or ECC's affine transform.

    Returns
    -------
    dict
        What ``mosaic.json`` holds: ``canvas`` (``width``, ``height``, ``offset_px``,
        ``reference_frame``, ``covered_fraction``), ``maps_used`` (per map ``frame``,
        ``registered_to``, ``correlation``, ``to_canvas`` 3×3, ``views_rejected_fraction``),
        ``maps_left_out`` (``frame``, ``reason``), ``views`` (``max``, ``median``,
        ``rejected_fraction``), ``sigma`` (``written``, ``method`` or ``reason``),
        ``options``, ``files``, ``seconds`` (``registration``, ``mosaic``, ``writing``,
        ``total``).

    Raises
    ------
    InvalidInputError
        ``out_dir`` is not a flight output, has no temperature map, every registration failed,
        the canvas is implausibly large, or an option is out of range. Nothing is written.
    """
    started = time.perf_counter()
    out = Path(out_dir)
    if motion not in MOTIONS:
        raise InvalidInputError(f"motion {motion!r}: choose from {', '.join(MOTIONS)}")
    clip_sigma, clip_floor_c, memory_mb = check_options(
        clip_sigma=clip_sigma, clip_floor_c=clip_floor_c, memory_mb=memory_mb)
    maps, left_out = _flight_maps(out)
    shape = _first_shape(maps, left_out)
    t = time.perf_counter()
    used = _register_maps(maps, shape, left_out, motion)
    if len(used) < 2 <= len(maps):
        reasons = "; ".join(f"frame {e['frame']}: {e['reason']}" for e in left_out[:3])
        raise InvalidInputError(
            f"{out}: no map registers to another ({reasons}); the maps do not overlap or "
            "hold too little structure: process the flight with a smaller --stride"
        )
    offset, canvas_shape = _canvas(used, shape)
    seconds = {"registration": time.perf_counter() - t}
    t = time.perf_counter()
    layers = _combine(used, shape, canvas_shape, clip_sigma=clip_sigma,
                      clip_floor_c=clip_floor_c, memory_bytes=memory_mb * 2**20)
    seconds["mosaic"] = time.perf_counter() - t
    summary = _summary(out, used, left_out, offset, canvas_shape, layers,
                       {"clip_sigma": clip_sigma, "clip_floor_c": clip_floor_c,
                        "memory_mb": memory_mb, "motion": motion})
    summary["seconds"] = seconds
    _write_outputs(out / "mosaic", layers, summary, started)
    return summary


# --------------------------------------------------------------------------------------------
# the maps of a flight
# --------------------------------------------------------------------------------------------


def _flight_maps(out: Path) -> tuple[list[_Map], list[dict[str, Any]]]:
    """The maps the flight log says were made, in frame order, and the pivots without one."""
    log = out / "log.jsonl"
    if not out.is_dir() or not log.is_file() or not (out / "temps").is_dir():
        if out.exists() and not out.is_dir():  # a recording, given where its maps' folder goes
            raise InvalidInputError(
                f"{out}: is a file; mosaic takes the folder `thermocal flight {out} --out OUT` "
                "wrote (its OUT)")
        raise InvalidInputError(
            f"{out}: not the output of thermocal flight (no log.jsonl and temps/); run "
            f"'thermocal flight RECORDING --out {out}' first"
        )
    entries = read_log(log)
    maps, left_out = [], []
    for entry in entries:
        frame = entry["frame"]
        path = out / "temps" / f"frame_{frame:06d}.tiff"
        if "error" in entry:
            left_out.append({"frame": frame, "reason": f"no map: {entry['error']}"})
        elif not path.is_file():
            left_out.append({"frame": frame, "reason": f"no map: {path.name} is missing"})
        else:
            sigma = path.with_name(f"frame_{frame:06d}_sigma.tiff")
            if "sigma_mean_c" in entry and not sigma.is_file():  # the flight wrote one: lost
                left_out.append({"frame": frame, "reason": f"no σ: {sigma.name} is missing"})
                continue
            maps.append(_Map(frame, path, sigma if sigma.is_file() else None))
    logged = {entry["frame"] for entry in entries}
    unlogged = sorted(int(m[1]) for m in (_MAP_NAME.fullmatch(p.name)
                                          for p in (out / "temps").glob("frame_*.tiff"))
                      if m and int(m[1]) not in logged)
    if unlogged:  # a log cut short or edited: the maps are there, what made them is not
        warnings.warn(f"{len(unlogged)} map(s) in temps/ that log.jsonl does not list (frame "
                      f"{unlogged[0]}{', …' if len(unlogged) > 1 else ''}) left out: rerun "
                      "`thermocal flight` into this folder to log them again", stacklevel=2)
        left_out += [{"frame": k, "reason": "not in log.jsonl"} for k in unlogged]
    if not maps:
        raise InvalidInputError(
            f"{out}: no temperature map to mosaic ({len(entries)} pivots logged, none with a "
            "map); rerun thermocal flight and check its log.csv for the errors"
        )
    return maps, left_out


def _read(path: Path, shape: tuple[int, int] | None) -> np.ndarray:
    """A map (float32 (H, W), finite) of ``shape``; FileFormatError otherwise."""
    from thermocal.io.recording import read_temperature_tiff

    arr = read_temperature_tiff(path)
    if arr.ndim != 2 or (shape is not None and arr.shape != shape):
        got = "x".join(map(str, arr.shape[::-1]))
        raise FileFormatError(f"{path.name}: a {got} image, not a {shape[1]}x{shape[0]} map"
                              if shape else f"{path.name}: not one 2-D map")
    return arr


def _first_shape(maps: list[_Map], left_out: list[dict[str, Any]]) -> tuple[int, int]:
    """The size of the first readable map; unreadable ones before it are left out."""
    while maps:
        try:
            return _read(maps[0].path, None).shape
        except FileFormatError as exc:
            left_out.append({"frame": maps[0].frame, "reason": f"unreadable: {exc}"})
            maps.pop(0)
    raise InvalidInputError("no readable temperature map to mosaic; rerun thermocal flight")


class _LazyMaps:
    """The maps as an indexable ``(M, H, W)`` stack for :func:`register_sequence`, read one at a
    time; an unreadable map reads as noise (its pairs fail) and is recorded in ``bad``."""

    def __init__(self, maps: list[_Map], shape: tuple[int, int]) -> None:
        self.maps, self.shape, self.dtype = maps, (len(maps), *shape), np.dtype(np.float32)
        self.bad: dict[int, str] = {}

    def __getitem__(self, i: int) -> np.ndarray:
        try:
            return _read(self.maps[int(i)].path, self.shape[1:])
        except FileFormatError as exc:
            self.bad[int(i)] = f"unreadable: {exc}"
            return _flat(self.shape[1:], float(i))


def _flat(shape: tuple[int, int], seed: float) -> np.ndarray:
    """A structureless stand-in for an unreadable map (registers to nothing)."""
    return np.random.default_rng(int(seed)).normal(20.0, 1.0, shape).astype(np.float32)


def _register_maps(maps: list[_Map], shape: tuple[int, int], left_out: list[dict[str, Any]],
                   motion: str) -> list[_Map]:
    """Register the maps into chains and keep the longest: the maps kept, in order, each with
    its transform to the chain's first map. The others are appended to ``left_out`` with the
    reason.

    Map ``k`` joins the chain whose last map it registers to, trying the :data:`_REACH` chains
    that grew last, the most recent first (its predecessor's pair from the sequence, else a
    direct registration); when it registers to none it starts a chain of its own. A bad map
    in the middle of a pass is thereby bridged, and a bad first map does not sink the pass.
    """
    from thermocal.registration import register_sequence

    zero = np.zeros(shape, np.float32)  # calibrated maps: no fixed pattern to remove
    stack = _LazyMaps(maps, shape)
    seq = register_sequence(stack, fixed_pattern=zero) if len(maps) > 1 else None
    chains: list[list[int]] = []
    why: dict[int, str] = {}  # why a map starts a chain
    ended: dict[int, str] = {}  # why a chain's last map got no successor: the next one's failure
    for k, m in enumerate(maps):
        if k in stack.bad:
            left_out.append({"frame": m.frame, "reason": stack.bad[k]})
            continue
        for chain in sorted(chains, key=lambda c: c[-1], reverse=True)[:_REACH]:
            a = chain[-1]
            if a == k - 1 and seq.ok[k]:
                h, cc, ok = seq.to_previous[k], float(seq.correlation[k]), True
            else:
                direct = register_sequence(np.stack([stack[a], stack[k]]), fixed_pattern=zero)
                h, cc, ok = direct.to_previous[1], float(direct.correlation[1]), direct.ok[1]
            if ok:
                h = _rigid(h, shape) if motion == "rigid" else h
                m.to_first = maps[a].to_first @ h
                m.to_first /= m.to_first[2, 2]
                m.registered_to, m.correlation = maps[a].frame, cc
                chain.append(k)
                break
            failure = _failure(h, cc, shape, m.frame, maps[a].frame)
            why.setdefault(k, failure)
            ended.setdefault(a, f"map {m.frame} does not register to it ({failure})")
        else:
            m.to_first = np.eye(3)
            chains.append([k])
    main = max(chains, key=len)
    for chain in chains:
        if chain is main:
            continue
        for k in chain:
            if k != chain[0]:
                reason = f"registered to map {maps[k].registered_to}, which is left out"
            else:  # its own failure, else the one that ended its chain
                reason = why.get(k) or ended.get(chain[-1], "no later map registers to it")
            left_out.append({"frame": maps[k].frame, "reason": reason})
    left_out.sort(key=lambda e: e["frame"])
    return [maps[k] for k in main]


def _rigid(h: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The rotation and translation nearest to the affine part of ``h`` (polar decomposition,
    :func:`scipy.linalg.polar`) that takes the map's centre where ``h`` does.

    ECC's affine fit of a pair carries a small scale bias (+0.04 % per pair on the 112×80 maps
    of the tests); chained over a pass it grows without bound, while a nadir camera at a steady
    altitude sees consecutive maps a rotation and a translation apart.
    """
    from scipy.linalg import polar

    rotation = polar(h[:2, :2])[0]
    centre = np.array([(shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0, 1.0])
    target = h @ centre
    out = np.eye(3)
    out[:2, :2] = rotation
    out[:2, 2] = target[:2] / target[2] - rotation @ centre[:2]
    return out


def _failure(h: np.ndarray, cc: float, shape: tuple[int, int], frame: int, anchor: int) -> str:
    """Why map ``frame`` did not register to map ``anchor``."""
    from thermocal.registration.features import check_homography
    from thermocal.registration.sequence import MIN_CORRELATION

    if cc < MIN_CORRELATION:
        return (f"registration failed: ECC correlation {cc:.2f} with map {anchor} "
                f"(< {MIN_CORRELATION})")
    try:
        check_homography(h, (shape[1], shape[0]), f"to map {anchor}")
    except RegistrationError as exc:
        return f"registration failed: {exc}"
    return f"registration failed with map {anchor}"  # pragma: no cover - ok is one of the two


def _canvas(used: list[_Map], shape: tuple[int, int]) -> tuple[np.ndarray, tuple[int, int]]:
    """The offset ``(x0, y0)`` of the first map on the canvas and the canvas shape ``(H, W)``."""
    from thermocal.registration.warp import frame_corners, map_points

    corners = frame_corners((shape[1], shape[0]))
    xy = np.concatenate([map_points(m.to_first, corners)[0] for m in used])
    lo, hi = np.floor(xy.min(axis=0)), np.ceil(xy.max(axis=0))
    width, height = (hi - lo + 1).astype(np.int64)
    if width * height > MAX_CANVAS_PIXELS:
        raise InvalidInputError(
            f"the canvas would be {width}x{height} pixels: the registration drifted or the maps "
            "are not one pass; mosaic a part of the flight (a shorter recording)"
        )
    offset = -lo
    for m in used:
        m.to_canvas = translation(*offset) @ m.to_first
    return offset, (int(height), int(width))


# --------------------------------------------------------------------------------------------
# the robust mean, tile by tile
# --------------------------------------------------------------------------------------------


@dataclass
class _Layers:
    temperature: np.ndarray
    views: np.ndarray
    spread: np.ndarray
    sigma: np.ndarray | None
    sigma_reason: str | None


def _combine(used: list[_Map], shape: tuple[int, int], canvas_shape: tuple[int, int], *,
             clip_sigma: float, clip_floor_c: float, memory_bytes: float) -> _Layers:
    """The canvas layers from the registered maps (see the module's notes)."""
    with_sigma = all(m.sigma_path is not None for m in used)
    reason = None if with_sigma else (
        "no σ maps" if all(m.sigma_path is None for m in used)
        else "some maps used have no σ map")
    hc, wc = canvas_shape
    layers = _Layers(np.full(canvas_shape, np.nan, np.float32), np.zeros(canvas_shape, np.uint16),
                     np.full(canvas_shape, np.nan, np.float32),
                     np.full(canvas_shape, np.nan, np.float32) if with_sigma else None, reason)
    boxes = np.array([_box(m.to_canvas, shape) for m in used])  # x0, y0, x1, y1
    cache = _MapCache(shape, with_sigma)
    for x0, y0, x1, y1, idx in _tiles(boxes, (wc, hc), memory_bytes, with_sigma):
        _combine_tile(layers, [used[i] for i in idx], cache, (x0, y0, x1, y1),
                      clip_sigma=clip_sigma, clip_floor_c=clip_floor_c, with_sigma=with_sigma)
    return layers


def _box(to_canvas: np.ndarray, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """The canvas pixels ``[x0, x1) × [y0, y1)`` a map can cover."""
    from thermocal.registration.warp import frame_corners, map_points

    xy = map_points(to_canvas, frame_corners((shape[1], shape[0])))[0]
    lo, hi = np.floor(xy.min(axis=0)).astype(int), np.ceil(xy.max(axis=0)).astype(int) + 1
    return int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1])


def _tiles(boxes: np.ndarray, size: tuple[int, int], memory_bytes: float,
           with_sigma: bool) -> Iterator[tuple[int, int, int, int, np.ndarray]]:
    """Tiles ``(x0, y0, x1, y1, maps overlapping)`` covering the canvas, along its long side
    first (so that neighbouring tiles share their maps), each split in four while its views
    would take more than ``memory_bytes``."""
    wc, hc = size
    per_px = _BYTES_PER_VIEW_PX + (12 if with_sigma else 0)  # σ stack and its square
    starts = [(x, y) for x in range(0, wc, _TILE_PX) for y in range(0, hc, _TILE_PX)]
    if hc > wc:
        starts.sort(key=lambda s: (s[1], s[0]))
    todo = [(x, y, min(wc, x + _TILE_PX), min(hc, y + _TILE_PX)) for x, y in starts]
    while todo:
        x0, y0, x1, y1 = todo.pop(0)
        idx = np.flatnonzero((boxes[:, 0] < x1) & (boxes[:, 2] > x0) & (boxes[:, 1] < y1)
                             & (boxes[:, 3] > y0))
        if not len(idx):
            continue
        if len(idx) * (x1 - x0) * (y1 - y0) * per_px > memory_bytes and (
                min(x1 - x0, y1 - y0) > _MIN_TILE_PX):
            xm, ym = (x0 + x1) // 2, (y0 + y1) // 2
            todo[:0] = [(x0, y0, xm, ym), (xm, y0, x1, ym), (x0, ym, xm, y1), (xm, ym, x1, y1)]
            continue
        yield x0, y0, x1, y1, idx


class _MapCache:
    """The last :data:`_CACHE_MAPS` maps read, each as ``(H, W, C)`` float32: °C, its σ when
    asked for, and ones (the coverage channel of :func:`_warp`)."""

    def __init__(self, shape: tuple[int, int], with_sigma: bool) -> None:
        self.shape, self.with_sigma = shape, with_sigma
        self._items: OrderedDict[int, np.ndarray] = OrderedDict()

    def get(self, m: _Map) -> np.ndarray:
        if m.frame in self._items:
            self._items.move_to_end(m.frame)
            return self._items[m.frame]
        layers = [_read(m.path, self.shape)]
        if self.with_sigma and m.sigma_path is not None:
            layers.append(_read(m.sigma_path, self.shape))
        layers.append(np.ones(self.shape, np.float32))
        arr = self._items[m.frame] = np.dstack(layers)
        if len(self._items) > _CACHE_MAPS:
            self._items.popitem(last=False)
        return arr


def _warp(src: np.ndarray, to_tile: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """The channels of ``src`` ``(H, W, C)`` but the last seen on a tile of ``size = (w, h)``
    (bilinear), ``(C − 1, h, w)``, NaN where a sample needs a pixel outside ``src``: the last
    channel, ones, warped with a zero border sums to one only where every neighbour with a
    weight lies inside (one ``cv2.warpPerspective`` call for all channels)."""
    import cv2

    out = cv2.warpPerspective(src, to_tile, size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    values = np.moveaxis(out[..., :-1], -1, 0)
    values[:, out[..., -1] < 1.0 - 1e-4] = np.nan
    return values


def _nanmedian0(stack: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The median over axis 0 of ``stack`` ``(V, h, w)`` ignoring NaN, ``n`` ``(h, w)`` the
    values that are not NaN (NaN where there are none).

    By hand: :func:`numpy.nanmedian` over a short axis takes a slow path, seven times slower
    than one sort (which puts NaN last; along the contiguous axis) and a pick by ``n``.
    """
    ordered = np.sort(np.moveaxis(stack, 0, -1), axis=-1)
    lo = np.take_along_axis(ordered, (np.maximum(n - 1, 0) // 2)[..., None], axis=-1)[..., 0]
    hi = np.take_along_axis(ordered, (n // 2)[..., None], axis=-1)[..., 0]
    return np.where(n > 0, 0.5 * (lo + hi), np.nan)


def _combine_tile(layers: _Layers, maps: list[_Map], cache: _MapCache,
                  box: tuple[int, int, int, int], *, clip_sigma: float, clip_floor_c: float,
                  with_sigma: bool) -> None:
    """Fill the canvas layers over ``box = (x0, y0, x1, y1)`` from the views of ``maps``."""
    x0, y0, x1, y1 = box
    size = (x1 - x0, y1 - y0)
    shift = translation(-x0, -y0)
    temps = np.empty((len(maps), size[1], size[0]), np.float32)
    sigmas = np.empty_like(temps) if with_sigma else None
    for v, m in enumerate(maps):
        warped = _warp(cache.get(m), shift @ m.to_canvas, size)
        temps[v] = warped[0]
        if sigmas is not None:
            sigmas[v] = warped[1]
    covered = ~np.isnan(temps)
    n_covered = covered.sum(axis=0)
    median = _nanmedian0(temps, n_covered)
    deviation = np.abs(temps - median)
    scale = _MAD_TO_SIGMA * _nanmedian0(deviation, n_covered)
    kept = deviation <= clip_sigma * np.maximum(scale, clip_floor_c)  # False where NaN
    del deviation
    n = kept.sum(axis=0)
    for v, m in enumerate(maps):
        m.covered += int(covered[v].sum())
        m.rejected += int(covered[v].sum() - kept[v].sum())
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = temps.sum(axis=0, where=kept) / n
        temps -= mean  # the residuals, in place (temps is this tile's own stack)
        np.square(temps, out=temps)
        spread = np.sqrt(temps.sum(axis=0, where=kept) / (n - 1))
    spread[n < 2] = np.nan
    region = np.s_[y0:y1, x0:x1]
    layers.temperature[region] = np.where(n > 0, mean, np.nan)
    layers.views[region] = np.minimum(n, np.iinfo(np.uint16).max)
    layers.spread[region] = spread
    if sigmas is not None and layers.sigma is not None:
        np.square(sigmas, out=sigmas)
        with np.errstate(invalid="ignore", divide="ignore"):
            rms = np.sqrt(sigmas.sum(axis=0, where=kept) / n)
        sigma = np.fmax(rms, spread / np.sqrt(n))  # fmax: the spread is NaN for one view
        layers.sigma[region] = np.where(n > 0, sigma, np.nan)


# --------------------------------------------------------------------------------------------
# outputs
# --------------------------------------------------------------------------------------------


def _summary(out: Path, used: list[_Map], left_out: list[dict[str, Any]], offset: np.ndarray,
             canvas_shape: tuple[int, int], layers: _Layers,
             options: dict[str, float]) -> dict[str, Any]:
    covered = layers.views > 0
    views = layers.views[covered]
    total = sum(m.covered for m in used)
    rejected = sum(m.rejected for m in used)
    sigma_method = ("max(sqrt(mean of the kept views' sigma^2), spread / sqrt(views)): the "
                    "views' errors taken as fully correlated")
    return {
        "flight": str(out),
        "canvas": {"width": canvas_shape[1], "height": canvas_shape[0],
                   "offset_px": [float(v) for v in offset],
                   "reference_frame": used[0].frame,
                   "covered_fraction": float(covered.mean())},
        "maps_used": [
            {"frame": m.frame, "registered_to": m.registered_to, "correlation": m.correlation,
             "to_canvas": m.to_canvas.tolist(),
             "views_rejected_fraction": m.rejected / m.covered if m.covered else 0.0}
            for m in used],
        "maps_left_out": left_out,
        "views": {"max": int(views.max()) if views.size else 0,
                  "median": float(np.median(views)) if views.size else 0.0,
                  "rejected_fraction": rejected / total if total else 0.0},
        "sigma": ({"written": True, "method": sigma_method} if layers.sigma is not None
                  else {"written": False, "reason": layers.sigma_reason}),
        "robust_mean": "median-centred clipped mean: views within clip_sigma * max(1.4826 MAD, "
                       "clip_floor_c) of the median, averaged",
        "options": options,
        "files": {"temperature": "temperature.tiff", "views": "views.tiff",
                  "spread": "spread.tiff", "preview": "mosaic.png",
                  **({"sigma": "sigma.tiff"} if layers.sigma is not None else {})},
    }


#: What each layer's TIFF says of itself (its ImageDescription, as the maps' do:
#: :data:`~thermocal.io.recording.TEMPERATURE_ABOUT`).
_ABOUT: dict[str, dict[str, str]] = {
    "temperature": {"quantity": "temperature, median-clipped mean of the maps' views",
                    "unit": "degC", "sigma": "sigma.tiff"},
    "views": {"quantity": "number of maps seeing each pixel", "unit": "count"},
    "spread": {"quantity": "standard deviation between the maps' views", "unit": "degC"},
    "sigma": {"quantity": "standard uncertainty (1 sigma) of temperature.tiff", "unit": "degC"},
}


def _write_outputs(target: Path, layers: _Layers, summary: dict[str, Any],
                   started: float) -> None:
    """Write every output into a temporary folder beside ``target`` and rename it into place
    (a previous mosaic is replaced only once the new one is complete); ``summary["seconds"]``
    gets the writing and the total (since ``started``, a :func:`time.perf_counter`)."""
    import tifffile

    from thermocal.io.atomic import ensure_output_dir, staging_folder, write_json_atomic
    from thermocal.plotting import save_figure, temperature_figure

    ensure_output_dir(target.parent)
    t = time.perf_counter()
    for stale in target.parent.glob(".mosaic.*"):  # folders a killed run left behind
        if _STAGING.fullmatch(stale.name) and stale.is_dir() and not stale.is_symlink():
            shutil.rmtree(stale, ignore_errors=True)
    staging = staging_folder(target.parent, ".mosaic.")  # read as other output folders are
    try:
        arrays = {"temperature": layers.temperature, "views": layers.views,
                  "spread": layers.spread, "sigma": layers.sigma}
        for name, arr in arrays.items():
            if arr is not None:
                tifffile.imwrite(staging / f"{name}.tiff", arr, photometric="minisblack",
                                 bigtiff=arr.nbytes > 2**31, metadata=_ABOUT[name] | (
                                     {"sigma": "none"} if layers.sigma is None else {}))
        step = max(1, -(-max(layers.temperature.shape) // _PREVIEW_PX))
        shown = layers.temperature[::step, ::step]  # a preview: every step-th pixel
        fig = temperature_figure(np.nan_to_num(shown, nan=float(np.nanmedian(shown))),
                                 title=f"mosaic of {len(summary['maps_used'])} maps (°C)")
        fig.axes[0].images[0].set_data(np.ma.masked_invalid(shown))  # no data: blank
        save_figure(fig, staging / "mosaic.png")
        now = time.perf_counter()
        summary["seconds"] |= {"writing": now - t, "total": now - started}
        write_json_atomic(staging / "mosaic.json", summary)
        _replace_dir(staging, target)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _replace_dir(new: Path, target: Path) -> None:
    """Rename the folder ``new`` onto ``target``, removing a previous ``target`` after."""
    if target.is_symlink() or (target.exists() and not target.is_dir()):
        raise InvalidInputError(f"{target}: exists and is not a folder; move it away")
    old = None
    if target.exists():
        old = Path(tempfile.mkdtemp(prefix=".mosaic.old.", dir=target.parent))
        target.rename(old / "mosaic")
    new.rename(target)
    if old is not None:
        with contextlib.suppress(OSError):
            shutil.rmtree(old)
