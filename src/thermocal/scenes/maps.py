"""Large temperature maps for simulated flights: resizing, augmentation and cropping.

All functions take a 2-D temperature map in °C (finite, above absolute zero), return a new
float32 ``(H, W)`` array and never modify their input. Shapes are ``(H, W)`` (numpy order).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from thermocal._validate import as_temperature_c
from thermocal.errors import InvalidInputError

__all__ = ["augment", "crop", "make_map", "random_augment"]


def _check_shape(shape: Any, name: str = "shape") -> tuple[int, int]:
    try:
        h, w = shape
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected (height, width), got {shape!r}") from None
    for v in (h, w):
        if isinstance(v, bool) or not float(v).is_integer() or int(v) < 1:
            raise InvalidInputError(
                f"{name}: height and width must be positive integers, got {shape!r}"
            )
    return int(h), int(w)


def make_map(scene_c: Any, shape: tuple[int, int], *, scale: float | None = None) -> np.ndarray:
    """Make a map of ``shape`` from a (possibly small) scene: resize keeping aspect, centre-crop.

    The scene is resized by one factor for both axes (cubic interpolation when enlarging, area
    averaging when shrinking, none at factor 1) so that it covers ``shape``, then the centre is
    cropped. Cubic overshoot at sharp edges is clipped to the scene's temperature range, so the map
    never holds temperatures the scene does not.

    Parameters
    ----------
    scene_c : array_like, shape (h, w)
        Scene temperature, °C.
    shape : tuple of int
        ``(H, W)`` of the map, pixels.
    scale : float, optional
        Resize factor (map pixels per scene pixel). Default: the smallest factor that covers
        ``shape``, ``max(H / h, W / w)``. A factor too small to cover ``shape`` is an error.

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        Map temperature, °C.

    Raises
    ------
    InvalidInputError
        A scene that is not 2-D, not finite or at/below absolute zero; a bad shape; a scale that
        is not positive or too small to cover ``shape``.
    """
    scene = as_temperature_c(scene_c, "scene_c", ndim=2)
    if scene.size == 0:
        raise InvalidInputError(f"scene_c: empty scene (shape {scene.shape})")
    hh, ww = _check_shape(shape)
    h0, w0 = scene.shape
    cover = max(hh / h0, ww / w0)
    if scale is None:
        s = cover
    else:
        try:
            s = float(scale)
        except (TypeError, ValueError):
            raise InvalidInputError(f"scale: expected a number, got {scale!r}") from None
        if not (math.isfinite(s) and s > 0):
            raise InvalidInputError(f"scale: expected a finite factor > 0, got {scale!r}")
        if s < cover * (1 - 1e-9):
            raise InvalidInputError(
                f"scale {s:g} makes the {w0}x{h0} scene {w0 * s:.0f}x{h0 * s:.0f}, smaller than "
                f"the requested {ww}x{hh} map; use scale >= {cover:.6g} or scale=None"
            )
    new_w = max(ww, int(round(w0 * s)))
    new_h = max(hh, int(round(h0 * s)))
    src = scene.astype(np.float32, copy=False)
    if (new_w, new_h) == (w0, h0):
        big = src
    elif s > 1:
        big = cv2.resize(src, (new_w, new_h), interpolation=cv2.INTER_CUBIC)
        big = np.clip(big, float(src.min()), float(src.max()))
    else:
        big = cv2.resize(src, (new_w, new_h), interpolation=cv2.INTER_AREA)
    top = (new_h - hh) // 2
    left = (new_w - ww) // 2
    return np.array(big[top : top + hh, left : left + ww], dtype=np.float32, copy=True)


def make_long_map(scene_c: Any, shape: tuple[int, int]) -> np.ndarray:
    """A map of ``shape = (H, W)`` much wider than tall (a long UAV pass) from a scene.

    The scene is resized so that it covers the height ``H`` (and at least its own aspect's
    width), then mirror-tiled along the width: no scene is blown up to tens of thousands of
    pixels to cover a long strip. Returns float32 °C ``(H, W)``.
    """
    scene = as_temperature_c(scene_c, "scene_c", ndim=2)
    hh, ww = _check_shape(shape)
    h0, w0 = scene.shape
    if w0 * hh / h0 >= ww:
        return make_map(scene, shape)
    strip = make_map(scene, (hh, max(1, int(round(w0 * hh / h0)))))
    reps = -(-ww // strip.shape[1])
    tiles = [strip if k % 2 == 0 else strip[:, ::-1] for k in range(reps)]
    return np.ascontiguousarray(np.concatenate(tiles, axis=1)[:, :ww])


def augment(
    map_c: Any, *, k_rot90: int = 0, flip_h: bool = False, flip_v: bool = False
) -> np.ndarray:
    """Flip and rotate a map by multiples of 90° (the augmentations of Oz et al. §IV-D).

    Order: horizontal flip (mirror left-right), vertical flip (upside down), then ``k_rot90``
    counter-clockwise quarter turns (:func:`numpy.rot90`).

    Parameters
    ----------
    map_c : array_like, shape (H, W)
        Temperature map, °C.
    k_rot90 : int
        Number of quarter turns (any integer; taken modulo 4).
    flip_h, flip_v : bool
        Mirror left-right / upside down.

    Returns
    -------
    numpy.ndarray, shape (H, W) or (W, H) for odd ``k_rot90``, float32
    """
    m = as_temperature_c(map_c, "map_c", ndim=2)
    if isinstance(k_rot90, bool) or not isinstance(k_rot90, int | np.integer):
        raise InvalidInputError(f"k_rot90: expected an integer, got {k_rot90!r}")
    for name, v in (("flip_h", flip_h), ("flip_v", flip_v)):
        if not isinstance(v, bool | np.bool_):
            raise InvalidInputError(f"{name}: expected True or False, got {v!r}")
    out = m
    if flip_h:
        out = out[:, ::-1]
    if flip_v:
        out = out[::-1, :]
    out = np.rot90(out, int(k_rot90) % 4)
    return np.array(out, dtype=np.float32, order="C", copy=True)


def random_augment(map_c: Any, *, rng: np.random.Generator) -> np.ndarray:
    """:func:`augment` with ``k_rot90 ~ U{0..3}`` and each flip with probability 1/2.

    Parameters
    ----------
    map_c : array_like, shape (H, W)
        Temperature map, °C.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    numpy.ndarray, float32
        The augmented map (``(H, W)`` or ``(W, H)``).
    """
    if not isinstance(rng, np.random.Generator):
        raise InvalidInputError(
            f"rng: expected a numpy.random.Generator, got {type(rng).__name__}"
        )
    k = int(rng.integers(0, 4))
    fh, fv = (bool(b) for b in rng.random(2) < 0.5)
    return augment(map_c, k_rot90=k, flip_h=fh, flip_v=fv)


def crop(map_c: Any, top_left: tuple[int, int], shape: tuple[int, int]) -> np.ndarray:
    """Cut ``shape`` pixels out of a map, starting at ``top_left``.

    Parameters
    ----------
    map_c : array_like, shape (Hm, Wm)
        Temperature map, °C.
    top_left : tuple of int
        ``(row, col)`` of the first pixel (numpy order, like ``shape``).
    shape : tuple of int
        ``(H, W)`` of the crop.

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        A copy of ``map_c[row:row + H, col:col + W]``.

    Raises
    ------
    InvalidInputError
        A crop that does not lie wholly inside the map.
    """
    m = as_temperature_c(map_c, "map_c", ndim=2)
    hh, ww = _check_shape(shape)
    try:
        r, c = top_left
    except (TypeError, ValueError):
        raise InvalidInputError(f"top_left: expected (row, col), got {top_left!r}") from None
    for v in (r, c):
        if isinstance(v, bool) or not float(v).is_integer():
            raise InvalidInputError(f"top_left: expected integer (row, col), got {top_left!r}")
    r, c = int(r), int(c)
    hm, wm = m.shape
    if r < 0 or c < 0 or r + hh > hm or c + ww > wm:
        raise InvalidInputError(
            f"crop of {ww}x{hh} at (row {r}, col {c}) leaves the {wm}x{hm} map; keep "
            f"0 <= row <= {hm - hh} and 0 <= col <= {wm - ww}"
        )
    return np.array(m[r : r + hh, c : c + ww], dtype=np.float32, copy=True)
