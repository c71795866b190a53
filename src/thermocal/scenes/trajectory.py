"""Camera trajectories over a temperature map: bursts of overlapping views, as homographies.

Every function here returns homographies ``M_i`` of shape ``(N, 3, 3)`` (float64) that map pixel
``(x, y)`` of frame ``i`` (``x`` = column, ``y`` = row, pixel centres at integers, frame size
``W x H``) to pixel coordinates of the map; :func:`to_pivot` turns them into frame-to-pivot
homographies. Sizes are ``(W, H)`` throughout (OpenCV order).

The sampling follows Oz et al. (IEEE TGRS 2023, §IV-D): a random walk across the map or a hover
above a random point, the views overlapping the pivot (middle) frame by 60-80 %, and an optional
registration error (uniform ±2 px translation, Gaussian noise N(0, 5e-5) on h31, h32); or a
straight UAV pass set by altitude, speed, frame rate and focal length (§V-A: 3.8 px per frame).

Each view is a similarity about the frame centre ``c = ((W-1)/2, (H-1)/2)``::

    M = T(position) @ R(theta) @ S(scale) @ T(-c)

with ``scale`` in map pixels per frame pixel; the UAV pass adds the projective effect of small
camera roll and pitch (``K R K^-1``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import brentq

from thermocal._validate import check_frame_index, check_rng
from thermocal.errors import InvalidInputError
from thermocal.registration.warp import (
    _check_frame_size,
    as_homographies,
    frame_corners,
    map_points,
)

__all__ = [
    "PERSPECTIVE_SIGMA",
    "choose_pivot",
    "ground_sampling_distance_m",
    "hover_homographies",
    "overlap_fraction",
    "perturb_homographies",
    "pixel_motion_per_frame",
    "to_pivot",
    "uav_homographies",
    "walk_homographies",
]

#: Standard deviation of the perturbation of h31, h32 in coordinates normalised to [-1, 1]
#: (Oz et al. §IV-D: N(0, 5e-5), read as a *variance* of 5e-5).
PERSPECTIVE_SIGMA = math.sqrt(5e-5)

_MAX_TRIES = 200


# --------------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------------


def _check_n(n: Any) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or int(n) < 1:
        raise InvalidInputError(f"n: expected a positive integer number of frames, got {n!r}")
    return int(n)


def _check_nonneg(value: Any, name: str, *, upper: float = math.inf) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}") from None
    if not (0.0 <= v < upper):
        raise InvalidInputError(f"{name}: expected 0 <= {name} < {upper}, got {value!r}")
    return v


def _check_positive(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise InvalidInputError(f"{name}: expected a finite value > 0, got {value!r}")
    return v


def _check_overlap(overlap: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in overlap)
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"overlap: expected (low, high) fractions, got {overlap!r}"
        ) from None
    if not (0.0 < lo <= hi < 1.0):
        raise InvalidInputError(f"overlap: expected 0 < low <= high < 1, got {overlap!r}")
    return lo, hi


def _similarity(
    cx: float, cy: float, theta: float, scale: float, frame_size: tuple[int, int]
) -> np.ndarray:
    """Frame → map similarity: the frame centre goes to ``(cx, cy)``, rotated by ``theta`` (rad)."""
    w, h = frame_size
    fx, fy = (w - 1) / 2.0, (h - 1) / 2.0
    c, s = scale * math.cos(theta), scale * math.sin(theta)
    return np.array(
        [
            [c, -s, cx - (c * fx - s * fy)],
            [s, c, cy - (s * fx + c * fy)],
            [0.0, 0.0, 1.0],
        ]
    )


def _normalise(h: np.ndarray) -> np.ndarray:
    """Divide each homography by its h33 (``(..., 3, 3)``)."""
    h33 = h[..., 2:3, 2:3]
    if np.any(np.abs(h33) < 1e-12):
        raise InvalidInputError("homography has h33 = 0; it cannot be normalised to h33 = 1")
    return h / h33


def _bounding_box(hs: np.ndarray, frame_size: tuple[int, int]) -> tuple[float, ...]:
    """``(xmin, xmax, ymin, ymax)`` over the mapped corners of all views."""
    xy, w = map_points(hs, frame_corners(frame_size))
    if np.any(w <= 0):
        return (-math.inf, math.inf, -math.inf, math.inf)
    return (xy[..., 0].min(), xy[..., 0].max(), xy[..., 1].min(), xy[..., 1].max())


def _place(
    rel: np.ndarray,
    frame_size: tuple[int, int],
    map_size: tuple[int, int],
    rng: np.random.Generator,
    margin: float = 1e-3,
) -> np.ndarray | None:
    """Translate views (relative to any origin) to a uniform random place inside the map.

    Returns None when they do not fit.
    """
    xmin, xmax, ymin, ymax = _bounding_box(rel, frame_size)
    wm, hm = map_size
    lo_x, hi_x = -xmin + margin, (wm - 1) - xmax - margin
    lo_y, hi_y = -ymin + margin, (hm - 1) - ymax - margin
    if hi_x < lo_x or hi_y < lo_y:
        return None
    tx, ty = rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y)
    shift = np.array([[1.0, 0.0, tx], [0.0, 1.0, ty], [0.0, 0.0, 1.0]])
    return shift @ rel


def _check_frame_fits(
    frame_size: tuple[int, int], map_size: tuple[int, int], scale_min: float
) -> None:
    """Raise when even a single unrotated view at the smallest scale cannot fit in the map."""
    w, h = frame_size
    wm, hm = map_size
    need_w = scale_min * (w - 1) + 1
    need_h = scale_min * (h - 1) + 1
    if wm < need_w or hm < need_h:
        raise InvalidInputError(
            f"map {wm}x{hm} is smaller than the {w}x{h} frames (a view needs at least "
            f"{math.ceil(need_w)}x{math.ceil(need_h)} map pixels); use a larger map"
        )


def _distance_for_overlap(
    target: float,
    direction: np.ndarray,
    pivot_m: np.ndarray,
    theta: float,
    scale: float,
    frame_size: tuple[int, int],
) -> float:
    """Distance (map px) along ``direction`` from the pivot centre where the overlap is ``target``.

    Root of :func:`overlap_fraction` − target (which falls monotonically with the distance).
    """
    w, h = frame_size
    c0 = pivot_m @ np.array([(w - 1) / 2.0, (h - 1) / 2.0, 1.0])
    inv_p = np.linalg.inv(pivot_m)

    def ov(d: float) -> float:
        x, y = c0[0] + d * direction[0], c0[1] + d * direction[1]
        m = _similarity(x, y, theta, scale, frame_size)
        return float(overlap_fraction(inv_p @ m, frame_size))

    hi = 2.0 * (w + h) * max(scale, 1.0)  # far enough for no overlap at all
    if ov(0.0) <= target:
        return 0.0
    # Brent's method: ~10 overlap evaluations where bisection to the same 1e-4 px needs ~25
    return float(brentq(lambda d: ov(d) - target, 0.0, hi, xtol=1e-4))


# --------------------------------------------------------------------------------------------
# overlap and pivot
# --------------------------------------------------------------------------------------------


def _clip_halfplane(poly: list[tuple[float, float]], a: float, b: float, c: float) -> list:
    """Keep the part of a convex polygon where ``a x + b y + c >= 0`` (Sutherland-Hodgman)."""
    out: list[tuple[float, float]] = []
    k = len(poly)
    for i in range(k):
        p, q = poly[i], poly[(i + 1) % k]
        dp = a * p[0] + b * p[1] + c
        dq = a * q[0] + b * q[1] + c
        if dp >= 0:
            out.append(p)
        if (dp > 0 > dq) or (dp < 0 < dq):
            t = dp / (dp - dq)
            out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    return out


def _polygon_area(poly: list[tuple[float, float]]) -> float:
    if len(poly) < 3:
        return 0.0
    p = np.asarray(poly)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _overlap_one(h: np.ndarray, w: int, hh: int) -> float:
    # Frame a's footprint: its pixels cover [-0.5, W - 0.5] x [-0.5, H - 0.5].
    rect = [(-0.5, -0.5), (w - 0.5, -0.5), (w - 0.5, hh - 0.5), (-0.5, hh - 0.5)]
    # Keep only the part in front of frame b (w > 0), then project it.
    scale = float(np.abs(h[2]).max())
    eps = 1e-9 * scale
    poly = _clip_halfplane(rect, h[2, 0], h[2, 1], h[2, 2] - eps)
    if len(poly) < 3:
        return 0.0
    proj = []
    for x, y in poly:
        z = h[2, 0] * x + h[2, 1] * y + h[2, 2]
        proj.append(
            ((h[0, 0] * x + h[0, 1] * y + h[0, 2]) / z, (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / z)
        )
    # Clip against frame b's footprint.
    for a, b, c in ((1, 0, 0.5), (-1, 0, w - 0.5), (0, 1, 0.5), (0, -1, hh - 0.5)):
        proj = _clip_halfplane(proj, a, b, c)
        if len(proj) < 3:
            return 0.0
    return min(1.0, _polygon_area(proj) / (w * hh))


def overlap_fraction(h_a_to_b: Any, frame_size: tuple[int, int]) -> float | np.ndarray:
    """Fraction of frame ``b`` covered by frame ``a``.

    Both frames are ``W x H`` pixels; each pixel covers a unit square around its centre, so a
    frame covers ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``. Frame ``a``'s footprint is mapped into
    ``b`` by ``h_a_to_b`` (exact polygon clipping in float64, the part with ``w <= 0`` removed) and
    intersected with ``b``'s footprint. A pure translation by ``(dx, dy)`` gives
    ``(1 - |dx|/W)(1 - |dy|/H)``.

    Parameters
    ----------
    h_a_to_b : array_like, shape (3, 3) or (N, 3, 3)
        Homography mapping pixels of frame ``a`` to frame ``b``.
    frame_size : tuple of int
        ``(W, H)``, pixels.

    Returns
    -------
    float or numpy.ndarray of shape (N,)
        Overlap fraction in ``[0, 1]`` (a float for one homography).
    """
    hs = as_homographies(h_a_to_b, "h_a_to_b")
    w, hh = _check_frame_size(frame_size)
    out = np.array([_overlap_one(m, w, hh) for m in hs])
    if np.ndim(h_a_to_b) == 2:
        return float(out[0])
    return out


def choose_pivot(homographies_to_map: Any, frame_size: tuple[int, int]) -> int:
    """Index of the frame with the largest total overlap with all the others.

    ``total_i = sum_{j != i} overlap_fraction(M_j^-1 M_i)`` (the fraction of each other frame
    that frame ``i`` covers). Ties (within 1e-9) go to the frame nearest the middle, ``N // 2``.

    Parameters
    ----------
    homographies_to_map : array_like, shape (N, 3, 3)
        Frame → map (or frame → any common plane) homographies.
    frame_size : tuple of int
        ``(W, H)``, pixels.

    Returns
    -------
    int
    """
    hs = as_homographies(homographies_to_map, "homographies_to_map")
    w, hh = _check_frame_size(frame_size)
    n = len(hs)
    inv = np.linalg.inv(hs)
    total = np.zeros(n)
    for i in range(n):
        for j in range(n):
            if i != j:
                total[i] += _overlap_one(inv[j] @ hs[i], w, hh)
    best = np.flatnonzero(total >= total.max() - 1e-9)
    return int(best[np.argmin(np.abs(best - n // 2))])


def to_pivot(homographies: Any, pivot: int) -> np.ndarray:
    """Frame → pivot homographies ``inv(M_pivot) @ M_i``, normalised so that h33 = 1.

    Parameters
    ----------
    homographies : array_like, shape (N, 3, 3)
        Frame → map homographies ``M_i``.
    pivot : int
        Index of the pivot frame.

    Returns
    -------
    numpy.ndarray, shape (N, 3, 3), float64
        ``H_i`` mapping pixel ``(x, y)`` of frame ``i`` to the pivot frame; ``H_pivot`` is exactly
        the identity.
    """
    hs = as_homographies(homographies)
    p = check_frame_index(pivot, len(hs))
    out = _normalise(np.linalg.inv(hs[p])[None] @ hs)
    out[p] = np.eye(3)
    return out


# --------------------------------------------------------------------------------------------
# trajectories
# --------------------------------------------------------------------------------------------


def walk_homographies(
    n: int,
    frame_size: tuple[int, int],
    map_size: tuple[int, int],
    *,
    rng: np.random.Generator,
    overlap: tuple[float, float] = (0.6, 0.8),
    rotation_deg: float = 2.0,
    scale_jitter: float = 0.02,
) -> np.ndarray:
    """A random walk across the map through a pivot (middle) view.

    The pivot is frame ``n // 2``. From it, two legs of the walk go out in (roughly) opposite
    directions, with random step lengths and a wandering heading; each leg is stretched so that
    its last view (an extreme of the walk) overlaps the pivot by a fraction drawn uniformly from
    ``overlap``. Views in between are closer to the pivot, so every view overlaps the pivot by at
    least ``overlap[0]`` (checked; a walk that fails is drawn again). Each view also gets a random
    rotation ``U(-rotation_deg, rotation_deg)`` and scale ``1 + U(-scale_jitter, scale_jitter)``
    (map pixels per frame pixel). The whole walk is placed at a uniform random position where
    every view lies inside the map.

    Parameters
    ----------
    n : int
        Number of frames.
    frame_size, map_size : tuple of int
        ``(W, H)`` of a frame and of the map, pixels.
    rng : numpy.random.Generator
        Source of randomness.
    overlap : (float, float)
        Range of the overlap fraction of the extreme views with the pivot, ``0 < low <= high < 1``.
    rotation_deg : float
        Largest rotation of a view, degrees.
    scale_jitter : float
        Largest relative change of scale of a view.

    Returns
    -------
    numpy.ndarray, shape (n, 3, 3), float64
        Frame → map homographies.

    Raises
    ------
    InvalidInputError
        Bad arguments, or a map too small for the frames or for the walk.
    """
    rng = check_rng(rng)
    n = _check_n(n)
    fs = _check_frame_size(frame_size)
    ms = _check_frame_size(map_size, "map_size")
    lo, hi = _check_overlap(overlap)
    rot = _check_nonneg(rotation_deg, "rotation_deg", upper=45.0)
    sj = _check_nonneg(scale_jitter, "scale_jitter", upper=0.5)
    _check_frame_fits(fs, ms, 1.0 - sj)
    pivot = n // 2
    counts = (pivot, n - 1 - pivot)  # views before / after the pivot

    for _ in range(_MAX_TRIES):
        thetas = np.radians(rng.uniform(-rot, rot, n))
        scales = 1.0 + rng.uniform(-sj, sj, n)
        m_p = _similarity(0.0, 0.0, thetas[pivot], scales[pivot], fs)
        phi = rng.uniform(0.0, 2.0 * math.pi)
        rel = np.empty((n, 3, 3))
        rel[pivot] = m_p
        for leg, k in enumerate(counts):
            if k == 0:
                continue
            heading = phi + (math.pi + rng.uniform(-0.25, 0.25) if leg == 0 else 0.0)
            e = np.array([math.cos(heading), math.sin(heading)])
            e_perp = np.array([-e[1], e[0]])
            idx = [pivot - j for j in range(1, k + 1)] if leg == 0 else list(range(pivot + 1, n))
            ext = idx[-1]
            target = rng.uniform(lo, hi)
            dist = _distance_for_overlap(target, e, m_p, thetas[ext], scales[ext], fs)
            steps = rng.uniform(0.5, 1.5, k)
            t = np.cumsum(steps) / steps.sum()  # 0 < t_1 < ... < t_k = 1
            # lateral wander: a random-walk bridge that is zero at the pivot and at the extreme
            walk = np.cumsum(rng.normal(0.0, 1.0, k))
            bridge = walk - t * walk[-1]
            amp = float(np.abs(bridge).max())
            if amp > 0:
                bridge *= rng.uniform(0.0, 0.08) * dist / amp
            for j, i in enumerate(idx):
                pos = t[j] * dist * e + bridge[j] * e_perp
                rel[i] = _similarity(pos[0], pos[1], thetas[i], scales[i], fs)
        hp = _normalise(np.linalg.inv(rel[pivot])[None] @ rel)
        ov = np.array([_overlap_one(hp[i], *fs) for i in range(n)])
        others = np.arange(n) != pivot
        if np.any(ov[others] < lo - 1e-6):
            continue
        placed = _place(rel, fs, ms, rng)
        if placed is not None:
            return placed
    raise InvalidInputError(
        f"map {ms[0]}x{ms[1]} is too small for a {n}-frame walk of {fs[0]}x{fs[1]} frames with "
        f"overlap {lo:g}-{hi:g}; use a map at least {2 * fs[0]}x{2 * fs[1]}"
    )


def hover_homographies(
    n: int,
    frame_size: tuple[int, int],
    map_size: tuple[int, int],
    *,
    rng: np.random.Generator,
    jitter_px: float = 3.0,
    rotation_deg: float = 1.0,
    scale_jitter: float = 0.01,
    overlap: tuple[float, float] | None = None,
) -> np.ndarray:
    """Views of a camera hovering above a random point of the map.

    The pivot (frame ``n // 2``) looks at a random point; every other view is displaced from it by
    a uniform ``±jitter_px`` in x and y, rotated by ``U(-rotation_deg, rotation_deg)`` and scaled
    by ``1 + U(-scale_jitter, scale_jitter)``. With ``overlap=(low, high)`` the hover drifts
    instead, as in Oz et al. §IV-D: each other view is displaced in a random direction so that it
    overlaps the pivot by a fraction drawn uniformly from ``overlap`` (``jitter_px`` is then
    unused).

    Parameters
    ----------
    n : int
        Number of frames.
    frame_size, map_size : tuple of int
        ``(W, H)`` of a frame and of the map, pixels.
    rng : numpy.random.Generator
        Source of randomness.
    jitter_px : float
        Largest displacement of a view from the pivot, map pixels (per axis).
    rotation_deg : float
        Largest rotation of a view, degrees.
    scale_jitter : float
        Largest relative change of scale.
    overlap : (float, float), optional
        Overlap range of a drifting hover.

    Returns
    -------
    numpy.ndarray, shape (n, 3, 3), float64
        Frame → map homographies.
    """
    rng = check_rng(rng)
    n = _check_n(n)
    fs = _check_frame_size(frame_size)
    ms = _check_frame_size(map_size, "map_size")
    jit = _check_nonneg(jitter_px, "jitter_px")
    rot = _check_nonneg(rotation_deg, "rotation_deg", upper=45.0)
    sj = _check_nonneg(scale_jitter, "scale_jitter", upper=0.5)
    ov_range = None if overlap is None else _check_overlap(overlap)
    _check_frame_fits(fs, ms, 1.0 - sj)
    pivot = n // 2

    for _ in range(_MAX_TRIES):
        thetas = np.radians(rng.uniform(-rot, rot, n))
        scales = 1.0 + rng.uniform(-sj, sj, n)
        m_p = _similarity(0.0, 0.0, thetas[pivot], scales[pivot], fs)
        rel = np.empty((n, 3, 3))
        for i in range(n):
            if i == pivot:
                rel[i] = m_p
                continue
            if ov_range is None:
                d = rng.uniform(-jit, jit, 2)
            else:
                phi = rng.uniform(0.0, 2.0 * math.pi)
                e = np.array([math.cos(phi), math.sin(phi)])
                target = rng.uniform(*ov_range)
                d = e * _distance_for_overlap(target, e, m_p, thetas[i], scales[i], fs)
            rel[i] = _similarity(d[0], d[1], thetas[i], scales[i], fs)
        placed = _place(rel, fs, ms, rng)
        if placed is not None:
            return placed
    raise InvalidInputError(
        f"map {ms[0]}x{ms[1]} is too small for a hover of {fs[0]}x{fs[1]} frames; use a larger map"
    )


def ground_sampling_distance_m(
    *, altitude_m: float = 50.0, focal_mm: float = 13.0, pitch_um: float = 17.0
) -> float:
    """Ground sampling distance of a nadir camera, metres per pixel: ``altitude * pitch / focal``.

    Parameters
    ----------
    altitude_m : float
        Height above ground, m.
    focal_mm : float
        Focal length, mm.
    pitch_um : float
        Detector pixel pitch, µm (Tau2: 17 µm).
    """
    alt = _check_positive(altitude_m, "altitude_m")
    f = _check_positive(focal_mm, "focal_mm")
    p = _check_positive(pitch_um, "pitch_um")
    return alt * (p * 1e-6) / (f * 1e-3)


def pixel_motion_per_frame(
    *,
    altitude_m: float = 50.0,
    speed_m_s: float = 7.5,
    fps: float = 30.0,
    focal_mm: float = 13.0,
    pitch_um: float = 17.0,
) -> float:
    """Image motion between consecutive frames of a nadir camera in straight flight, pixels.

    ``speed / fps / GSD`` with ``GSD = altitude * pitch / focal``. The defaults (50 m, 7.5 m/s,
    30 Hz, 13 mm, 17 µm) give 3.82 px/frame; Oz et al. §V-A (10 m/s, 9.8 mm lens, 4.4 mm per 256
    pixels, i.e. 17.19 µm) give 3.80 px/frame.

    Parameters
    ----------
    altitude_m : float
        Height above ground, m.
    speed_m_s : float
        Ground speed, m/s.
    fps : float
        Frame rate, Hz.
    focal_mm : float
        Focal length, mm.
    pitch_um : float
        Pixel pitch, µm.

    Returns
    -------
    float
        Pixels per frame.
    """
    gsd = ground_sampling_distance_m(altitude_m=altitude_m, focal_mm=focal_mm, pitch_um=pitch_um)
    speed = _check_nonneg(speed_m_s, "speed_m_s")
    rate = _check_positive(fps, "fps")
    return speed / rate / gsd


def uav_homographies(
    n: int,
    frame_size: tuple[int, int],
    map_size: tuple[int, int],
    *,
    altitude_m: float = 50.0,
    speed_m_s: float = 7.5,
    fps: float = 30.0,
    focal_mm: float = 13.0,
    pitch_um: float = 17.0,
    map_gsd_m: float | None = None,
    heading_deg: float | None = None,
    attitude_jitter_deg: float = 0.05,
    flight_axis: str = "x",
    crab_deg: float = 0.0,
    rng: np.random.Generator,
) -> np.ndarray:
    """A straight UAV pass over the map with a nadir camera.

    The camera moves ``speed / fps`` metres per frame, i.e. :func:`pixel_motion_per_frame` frame
    pixels, ``speed / fps / map_gsd_m`` map pixels. One frame pixel is ``GSD / map_gsd_m`` map
    pixels (1 with the default ``map_gsd_m = GSD``). Small attitude jitter (roll, pitch, yaw as a
    smooth AR(1) series with standard deviation ``attitude_jitter_deg``) shifts, rotates and
    slightly tilts each view (the tilt is the projective ``K R K^-1`` of a rotated camera,
    ``K`` with focal length ``focal / pitch`` pixels).

    Parameters
    ----------
    n : int
        Number of frames.
    frame_size, map_size : tuple of int
        ``(W, H)`` of a frame and of the map, pixels.
    altitude_m, speed_m_s, fps, focal_mm, pitch_um : float
        Flight and camera, see :func:`pixel_motion_per_frame`.
    map_gsd_m : float, optional
        Ground size of one map pixel, m (default: the camera GSD).
    heading_deg : float, optional
        Direction of flight on the map, degrees counter-clockwise from the map's +x axis as seen
        on screen (0: toward increasing columns, 90: toward decreasing rows); random if None.
    attitude_jitter_deg : float
        Standard deviation of roll, pitch and yaw, degrees.
    flight_axis : {"x", "y"}
        The frame axis that points along the flight: ``"x"`` (the frame's width, so that
        ``heading_deg=0`` leaves the frames aligned with the map) or ``"y"`` (the frame's height,
        as the Tau2 was mounted in Oz et al. §V-A: ground features then move down the frame).
    crab_deg : float
        The crab angle, degrees (−45 … 45): the airframe, and the camera with it, yawed against
        the track, as a crosswind holds a multirotor or a plane (a few degrees is common); the
        ground then drifts across the frame's lines at ``sin(crab)`` of its speed.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    numpy.ndarray, shape (n, 3, 3), float64
        Frame → map homographies.

    Raises
    ------
    InvalidInputError
        Bad arguments, or a map too small for the pass.
    """
    rng = check_rng(rng)
    n = _check_n(n)
    fs = _check_frame_size(frame_size)
    ms = _check_frame_size(map_size, "map_size")
    gsd = ground_sampling_distance_m(altitude_m=altitude_m, focal_mm=focal_mm, pitch_um=pitch_um)
    step_frame = pixel_motion_per_frame(
        altitude_m=altitude_m, speed_m_s=speed_m_s, fps=fps, focal_mm=focal_mm, pitch_um=pitch_um
    )
    map_gsd = gsd if map_gsd_m is None else _check_positive(map_gsd_m, "map_gsd_m")
    scale = gsd / map_gsd
    step_map = step_frame * scale
    jitter = _check_nonneg(attitude_jitter_deg, "attitude_jitter_deg", upper=10.0)
    if flight_axis not in ("x", "y"):
        raise InvalidInputError(f"flight_axis: expected 'x' or 'y', got {flight_axis!r}")
    if not (isinstance(crab_deg, int | float) and math.isfinite(crab_deg)
            and abs(crab_deg) <= 45.0):
        raise InvalidInputError(f"crab_deg: expected an angle within ±45°, got {crab_deg!r}")
    if heading_deg is not None:
        try:
            heading_fixed = float(heading_deg)
        except (TypeError, ValueError):
            raise InvalidInputError(
                f"heading_deg: expected a number, got {heading_deg!r}"
            ) from None
        if not math.isfinite(heading_fixed):
            raise InvalidInputError(f"heading_deg: expected a finite angle, got {heading_deg!r}")
    _check_frame_fits(fs, ms, scale)

    w, h = fs
    f_px = (focal_mm * 1e-3) / (pitch_um * 1e-6)
    k_mat = np.array([[f_px, 0.0, (w - 1) / 2.0], [0.0, f_px, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    k_inv = np.linalg.inv(k_mat)
    rho = 0.9
    tries = 1 if heading_deg is not None else _MAX_TRIES
    for _ in range(tries):
        heading = math.radians(heading_fixed if heading_deg is not None else rng.uniform(0, 360))
        # Frame rotation on the map so that the flight axis of the frame points along the heading
        # (screen angles: the direction vector on the map is (cos h, -sin h)).
        theta = (-heading if flight_axis == "x" else math.pi / 2 - heading) + math.radians(
            crab_deg)
        e = np.array([math.cos(heading), -math.sin(heading)])
        att = np.empty((n, 3))
        att[0] = rng.normal(0.0, 1.0, 3)
        for i in range(1, n):
            att[i] = rho * att[i - 1] + math.sqrt(1 - rho**2) * rng.normal(0.0, 1.0, 3)
        att = np.radians(att * jitter)
        rel = np.empty((n, 3, 3))
        for i in range(n):
            roll, pitch, yaw = att[i]
            pos = i * step_map * e
            sim = _similarity(pos[0], pos[1], theta + yaw, scale, fs)
            cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
            r_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
            r_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
            tilt = k_mat @ (r_y @ r_x) @ k_inv
            rel[i] = _normalise(sim @ tilt)
        placed = _place(rel, fs, ms, rng)
        if placed is not None:
            return placed
    raise InvalidInputError(
        f"map {ms[0]}x{ms[1]} is too small for a {n}-frame UAV pass of {fs[0]}x{fs[1]} frames "
        f"moving {step_map:.2f} map px per frame; the pass needs about "
        f"{math.ceil(fs[0] * scale + (n - 1) * step_map) + 2} map px along the flight"
    )


def perturb_homographies(
    h: Any,
    *,
    rng: np.random.Generator,
    frame_size: tuple[int, int],
    translation_px: float = 2.0,
    perspective_sigma: float = PERSPECTIVE_SIGMA,
    pivot: int | None = None,
) -> np.ndarray:
    """Add the registration error of Oz et al. §IV-D to frame → pivot homographies.

    For every homography except the pivot's:

    1. **Perspective**: in coordinates normalised to ``[-1, 1]`` over the frame, as kornia uses
       (``x_n = 2 x / (W - 1) - 1``, ``y_n = 2 y / (H - 1) - 1``, ``N`` that matrix), the
       homography ``N H N^-1`` (scaled to h33 = 1) gets ``e31, e32 ~ N(0, perspective_sigma^2)``
       added to h31 and h32. The paper's ``N(0, 5e-5)`` is read as a *variance* of ``5e-5``, so
       the default standard deviation is ``sqrt(5e-5) = 7.07e-3`` -- at a frame corner that moves
       a point by about 1 px on a 336x256 frame (a standard deviation of 5e-5 would be ~0.01 px,
       invisible; 5e-5 in pixel units would be absurd, ~3 % per 336 px). The result is converted
       back to pixel units: ``H' = N^-1 (N H N^-1 + E) N``.
    2. **Translation**: ``tx, ty ~ U(-translation_px, translation_px)`` pixels:
       ``H'' = T(tx, ty) @ H'``, so the warped frame is shifted by exactly ``(tx, ty)`` (for an
       affine ``H'`` this adds ``tx, ty`` to h13, h23).

    Parameters
    ----------
    h : array_like, shape (N, 3, 3) or (3, 3)
        Frame → pivot homographies (pixel units).
    rng : numpy.random.Generator
        Source of randomness.
    frame_size : tuple of int
        ``(W, H)`` of the frames, pixels (defines the normalised coordinates).
    translation_px : float
        Half-width of the uniform translation error, pixels.
    perspective_sigma : float
        Standard deviation of the h31, h32 error in normalised coordinates.
    pivot : int, optional
        Index of the pivot, left untouched. Default: every homography that is the identity
        (to 1e-12) is left untouched.

    Returns
    -------
    numpy.ndarray, shape like ``h``, float64
        Perturbed homographies (h33 = 1); the input is not modified.
    """
    rng = check_rng(rng)
    hs = _normalise(as_homographies(h, "h"))
    w, hh = _check_frame_size(frame_size)
    t = _check_nonneg(translation_px, "translation_px")
    sigma = _check_nonneg(perspective_sigma, "perspective_sigma")
    n = len(hs)
    if pivot is None:
        keep = np.all(np.abs(hs - np.eye(3)) <= 1e-12, axis=(1, 2))
    else:
        keep = np.zeros(n, dtype=bool)
        keep[check_frame_index(pivot, n)] = True
    sx = 2.0 / (w - 1) if w > 1 else 1.0
    sy = 2.0 / (hh - 1) if hh > 1 else 1.0
    norm = np.array([[sx, 0.0, -1.0], [0.0, sy, -1.0], [0.0, 0.0, 1.0]])
    norm_inv = np.linalg.inv(norm)
    out = hs.copy()
    e = rng.normal(0.0, sigma, (n, 2)) if sigma > 0 else np.zeros((n, 2))
    d = rng.uniform(-t, t, (n, 2)) if t > 0 else np.zeros((n, 2))
    for i in range(n):
        if keep[i]:
            continue
        hn = norm @ hs[i] @ norm_inv
        hn = hn / hn[2, 2]
        hn[2, 0] += e[i, 0]
        hn[2, 1] += e[i, 1]
        hp = norm_inv @ hn @ norm
        shift = np.array([[1.0, 0.0, d[i, 0]], [0.0, 1.0, d[i, 1]], [0.0, 0.0, 1.0]])
        out[i] = _normalise(shift @ _normalise(hp))
    as_homographies(out, "perturbed homographies")
    if np.ndim(h) == 2:
        return out[0]
    return out
