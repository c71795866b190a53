"""Rendering views of a temperature map and warping frames onto the pivot frame.

Conventions
-----------
A homography is a ``(3, 3)`` float64 matrix that maps pixel ``(x, y)`` of one image (``x`` =
column, ``y`` = row, pixel centres at integer coordinates) to pixel coordinates of another::

    [x', y', w']^T = H @ [x, y, 1]^T,      (x'/w', y'/w') is the mapped point.

A stack of them is ``(N, 3, 3)``. ``frame_size`` is always ``(W, H)`` (OpenCV order), an array
shape is always ``(H, W)`` (numpy order).

Validity of a warped pixel: a pixel of the output is *valid* when the point it samples in the source
lies inside the source frame so that every neighbour with a non-zero interpolation weight is a real
source pixel -- for linear interpolation, ``0 <= x <= W - 1`` and ``0 <= y <= H - 1`` (the four
bilinear neighbours, at integer coordinates only the ones that carry weight). Nothing outside that
is extrapolated silently: invalid output pixels are set to 0 (as kornia's zero padding does) and
flagged False in the mask.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from thermocal._validate import as_frames, as_temperature_c
from thermocal.errors import InvalidInputError

__all__ = [
    "translation",
    "INTERPOLATIONS",
    "as_homographies",
    "frame_corners",
    "map_points",
    "render_views",
    "warp_to_pivot",
]

#: Interpolation names accepted by :func:`warp_to_pivot`, with their OpenCV flag.
INTERPOLATIONS = {
    "nearest": cv2.INTER_NEAREST,
    "linear": cv2.INTER_LINEAR,
    "cubic": cv2.INTER_CUBIC,
}

# Largest condition number accepted for a homography before it counts as singular.
_MAX_CONDITION = 1e12
# Tolerance (pixels) on the "inside the source" tests, for floating-point round-off.
_EDGE_TOL_PX = 1e-6


def as_homographies(h: Any, name: str = "homographies", *, n: int | None = None) -> np.ndarray:
    """Validate homographies and return them as a ``(N, 3, 3)`` float64 array (a copy).

    Parameters
    ----------
    h : array_like, shape (3, 3) or (N, 3, 3)
        Homographies; a single one becomes ``N = 1``.
    name : str
        Name used in error messages.
    n : int, optional
        Required number of homographies.

    Returns
    -------
    numpy.ndarray, shape (N, 3, 3), float64

    Raises
    ------
    InvalidInputError
        Not numeric, not ``(3, 3)`` / ``(N, 3, 3)``, NaN or infinite entries, a singular matrix
        (condition number above 1e12), or not ``n`` of them.
    """
    try:
        arr = np.array(h, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected numbers in a (N, 3, 3) array") from None
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[1:] != (3, 3):
        raise InvalidInputError(
            f"{name}: expected (3, 3) or (N, 3, 3) homographies, got shape {np.shape(h)}"
        )
    if arr.shape[0] == 0:
        raise InvalidInputError(f"{name}: no homographies given")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name}: homographies contain NaN or infinite values")
    cond = np.linalg.cond(arr)
    bad = np.flatnonzero(~(cond < _MAX_CONDITION))
    if bad.size:
        raise InvalidInputError(
            f"{name}: homography {int(bad[0])} is singular (condition number {cond[bad[0]]:.3g}); "
            "a homography must be invertible"
        )
    if n is not None and arr.shape[0] != n:
        raise InvalidInputError(
            f"{name}: expected {n} homographies (one per frame), got {len(arr)}"
        )
    return arr


def _check_frame_size(frame_size: Any, name: str = "frame_size") -> tuple[int, int]:
    """Return ``(W, H)`` as two positive ints, or raise :class:`InvalidInputError`."""
    try:
        w, h = frame_size
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected (width, height), got {frame_size!r}") from None
    for v in (w, h):
        if isinstance(v, bool) or not float(v).is_integer() or int(v) < 1:
            raise InvalidInputError(f"{name}: width and height must be positive integers, got "
                                    f"{frame_size!r}")
    return int(w), int(h)


def translation(dx: float, dy: float) -> np.ndarray:
    """The homography (3, 3) of a translation by ``(dx, dy)`` pixels."""
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def frame_corners(frame_size: tuple[int, int]) -> np.ndarray:
    """Centres of the four corner pixels of a ``(W, H)`` frame, ``(4, 2)`` float64 ``(x, y)``.

    Order: top-left, top-right, bottom-right, bottom-left.
    """
    w, h = frame_size
    return np.array([[0.0, 0.0], [w - 1.0, 0.0], [w - 1.0, h - 1.0], [0.0, h - 1.0]])


def map_points(h: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Map points ``(..., 2)`` through homographies ``(3, 3)`` or ``(N, 3, 3)``.

    Returns
    -------
    xy : numpy.ndarray
        Mapped points, ``(P, 2)`` for one homography, ``(N, P, 2)`` for a stack.
    w : numpy.ndarray
        The homogeneous coordinate of each mapped point (``<= 0``: behind the view).
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    hom = np.concatenate([pts, np.ones((len(pts), 1))], axis=1)  # (P, 3)
    out = np.asarray(h, dtype=np.float64) @ hom.T  # (..., 3, P)
    out = np.moveaxis(out, -2, -1)  # (..., P, 3)
    w = out[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = out[..., :2] / w[..., None]
    return xy, w


def render_views(map_c: Any, homographies: Any, frame_size: tuple[int, int]) -> np.ndarray:
    """Render the scene seen by each frame: ``frame_i(x, y) = map(M_i @ (x, y))``.

    Parameters
    ----------
    map_c : array_like, shape (Hm, Wm)
        Temperature map, °C (any float; finite, above absolute zero).
    homographies : array_like, shape (N, 3, 3) or (3, 3)
        ``M_i`` mapping pixel ``(x, y)`` of frame ``i`` to map pixel coordinates.
    frame_size : tuple of int
        ``(W, H)`` of the frames, pixels.

    Returns
    -------
    numpy.ndarray, shape (N, H, W), float32
        The scene in each frame's view, °C (bilinear interpolation of the map). A single
        ``(3, 3)`` homography gives ``(1, H, W)``.

    Raises
    ------
    InvalidInputError
        Bad map or homographies, or a view that leaves the map (some frame pixel would sample
        outside ``[0, Wm - 1] x [0, Hm - 1]``): make the map larger or the trajectory smaller.
    """
    m = as_temperature_c(map_c, "map_c", ndim=2)
    hs = as_homographies(homographies)
    w, h = _check_frame_size(frame_size)
    hm, wm = m.shape
    xy, wz = map_points(hs, frame_corners((w, h)))
    tol = 1e-3
    for i in range(len(hs)):
        if (
            np.any(wz[i] <= 0)
            or xy[i, :, 0].min() < -tol
            or xy[i, :, 0].max() > wm - 1 + tol
            or xy[i, :, 1].min() < -tol
            or xy[i, :, 1].max() > hm - 1 + tol
        ):
            raise InvalidInputError(
                f"view {i} leaves the {wm}x{hm} map (its corners map to x "
                f"{xy[i, :, 0].min():.1f}..{xy[i, :, 0].max():.1f}, y "
                f"{xy[i, :, 1].min():.1f}..{xy[i, :, 1].max():.1f}); use a larger map or keep "
                "the trajectory inside it"
            )
    src = m if m.dtype == np.float32 else m.astype(np.float32)
    out = np.empty((len(hs), h, w), dtype=np.float32)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    for i in range(len(hs)):
        cv2.warpPerspective(
            src, hs[i], (w, h), dst=out[i], flags=flags, borderMode=cv2.BORDER_REFLECT
        )
    return out


def _as_frame_stack(frames: Any) -> np.ndarray:
    """Frames as ``(N, H, W)`` numeric, finite (never copied unless needed)."""
    return as_frames(frames, bit_depth=None)


def warp_to_pivot(
    frames: Any,
    homographies_to_pivot: Any,
    *,
    interpolation: str = "linear",
) -> tuple[np.ndarray, np.ndarray]:
    """Warp every frame of a burst onto the pivot frame's pixel grid.

    Parameters
    ----------
    frames : array_like, shape (N, H, W)
        Frames (uint16 raw counts or float, e.g. °C). Never modified.
    homographies_to_pivot : array_like, shape (N, 3, 3)
        ``H_i`` mapping pixel ``(x, y)`` of frame ``i`` to the pivot frame (the pivot's own is the
        identity).
    interpolation : {"linear", "nearest", "cubic"}
        How a frame is sampled at non-integer positions.

    Returns
    -------
    warped : numpy.ndarray, shape (N, H, W), float32
        ``warped[i](p) = frames[i](H_i^-1 p)`` in the units of ``frames``; 0 where not valid.
    valid : numpy.ndarray, shape (N, H, W), bool
        True where the source frame really covers the pivot pixel: every interpolation neighbour
        with a non-zero weight is inside frame ``i`` (linear: the sample point lies in
        ``[0, W-1] x [0, H-1]``; cubic: in ``[1, W-2] x [1, H-2]``; nearest: the rounded point is
        inside). A frame whose homography is the identity (the pivot) is returned unchanged with
        an all-True mask.

    Raises
    ------
    InvalidInputError
        Bad frames (not numeric, NaN), homographies that are not ``(N, 3, 3)``, singular or not
        one per frame, or an unknown interpolation.
    """
    if interpolation not in INTERPOLATIONS:
        raise InvalidInputError(
            f"interpolation {interpolation!r}: choose from {', '.join(INTERPOLATIONS)}"
        )
    arr = _as_frame_stack(frames)
    n, h, w = arr.shape
    hs = as_homographies(homographies_to_pivot, "homographies_to_pivot", n=n)

    if interpolation == "nearest":
        lo, hi_x, hi_y = -0.5, w - 0.5, h - 0.5
        strict = True
    else:
        margin = 1.0 if interpolation == "cubic" else 0.0
        lo = margin - _EDGE_TOL_PX
        hi_x = w - 1 - margin + _EDGE_TOL_PX
        hi_y = h - 1 - margin + _EDGE_TOL_PX
        strict = False
    flags = INTERPOLATIONS[interpolation] | cv2.WARP_INVERSE_MAP
    xs = np.arange(w, dtype=np.float64)[None, :]
    ys = np.arange(h, dtype=np.float64)[:, None]
    eye = np.eye(3)

    warped = np.empty((n, h, w), dtype=np.float32)
    valid = np.empty((n, h, w), dtype=bool)
    for i in range(n):
        hi = hs[i] / hs[i, 2, 2] if hs[i, 2, 2] != 0 else hs[i]
        if np.allclose(hi, eye, rtol=0.0, atol=1e-12):
            warped[i] = arr[i]
            valid[i] = True
            continue
        inv = np.linalg.inv(hs[i])  # pivot pixel -> source pixel
        src = arr[i] if arr.dtype == np.float32 else arr[i].astype(np.float32)
        cv2.warpPerspective(
            src, inv, (w, h), dst=warped[i], flags=flags, borderMode=cv2.BORDER_REPLICATE
        )
        wz = inv[2, 0] * xs + inv[2, 1] * ys + inv[2, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            sx = (inv[0, 0] * xs + inv[0, 1] * ys + inv[0, 2]) / wz
            sy = (inv[1, 0] * xs + inv[1, 1] * ys + inv[1, 2]) / wz
        if strict:
            ok = (wz > 0) & (sx > lo) & (sx < hi_x) & (sy > lo) & (sy < hi_y)
        else:
            ok = (wz > 0) & (sx >= lo) & (sx <= hi_x) & (sy >= lo) & (sy <= hi_y)
        valid[i] = ok
        warped[i][~ok] = 0.0
    return warped, valid
