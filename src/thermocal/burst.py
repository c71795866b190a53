"""Bursts of overlapping frames without a network (numpy and OpenCV only).

Validation of a raw burst (:func:`check_burst`), its registration onto the pivot frame
(:func:`register`), the overlap and FPA checks, and eq. 9 of Oz et al. (:func:`naive_mean`: the
registered average of a per-frame calibration). The network (:mod:`thermocal.nn.infer`) builds on
these; :func:`estimate_file` is ``thermocal estimate`` and imports torch only for the network
methods.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import as_frames
from thermocal.errors import InvalidInputError, RegistrationError, ResolutionMismatchError
from thermocal.registration.warp import as_homographies, warp_to_pivot

__all__ = [
    "MIN_OVERLAP",
    "SATURATED_FRACTION",
    "Estimate",
    "check_burst",
    "check_overlap",
    "estimate_file",
    "fill_stuck_pixels",
    "fpa_value",
    "naive_mean",
    "prepare",
    "register",
    "scene_motion_px",
    "stuck_pixels",
]

#: A frame with more than this fraction of its pixels at 0 or at the largest count is saturated.
SATURATED_FRACTION = 0.02
#: Every frame must see at least this fraction of the pivot frame.
MIN_OVERLAP = 0.1


class Estimate:
    """A burst's pivot-frame temperature, from :func:`naive_mean` or the network
    (:func:`thermocal.nn.infer.estimate_burst`).

    Attributes
    ----------
    temperature_c : (H, W) float32
        Estimated scene temperature of the pivot frame, °C.
    coverage : (H, W) int
        How many frames see each pivot pixel.
    homographies : (N, 3, 3) float64
        Frame → pivot homographies used.
    pivot : int
    """

    def __init__(
        self, temperature_c: np.ndarray, coverage: np.ndarray, homographies: np.ndarray, pivot: int
    ) -> None:
        self.temperature_c = temperature_c
        self.coverage = coverage
        self.homographies = homographies
        self.pivot = pivot


def check_burst(
    frames: Any, *, bit_depth: int = 14, name: str = "frames", registered: bool = False
) -> np.ndarray:
    """Validate a raw burst: ``(N, H, W)`` counts, no saturated or dead frames.

    Raises :class:`InvalidInputError` for saturated frames (more than 2 % of the pixels at 0 or
    at ``2**bit_depth − 1``) or constant frames. For ``registered`` frames, 0 marks pixels a
    frame does not cover: they are not counted.
    """
    arr = as_frames(frames, name)
    top = 2**bit_depth - 1
    for k, f in enumerate(arr):
        covered = np.count_nonzero(f > 0) if registered else f.size
        n_pix = max(covered, 1)
        sat = np.count_nonzero(f >= top) / n_pix
        low = 0.0 if registered else np.count_nonzero(f <= 0) / n_pix
        if sat > SATURATED_FRACTION or low > SATURATED_FRACTION:
            which = f"{100 * sat:.0f} % at {top}" if sat >= low else f"{100 * low:.0f} % at 0"
            raise InvalidInputError(
                f"{name}: frame {k} is saturated ({which}); use frames within the sensor's range"
            )
        if covered == 0 or float(f.max()) == float(f[f > 0].min() if registered else f.min()):
            raise InvalidInputError(f"{name}: frame {k} is constant (a dead or blank frame)")
    return arr


def scene_motion_px(homographies: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """How far the scene moves under each sensor pixel during a burst, px, ``(H, W)`` float32.

    ``homographies`` map each frame's pixels onto the pivot frame: pixel ``p`` of frame ``k`` sees
    the scene point the pivot sees at ``H_k p``, so the largest ``|H_k p − p|`` over the frames is
    how far the scene slid under ``p``.
    """
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    pts = np.stack([xs.ravel(), ys.ravel(), np.ones(h * w)])
    out = np.zeros(h * w)
    for hk in np.asarray(homographies, dtype=np.float64):
        q = hk @ pts
        out = np.maximum(out, np.hypot(q[0] / q[2] - pts[0], q[1] / q[2] - pts[1]))
    return out.reshape(h, w).astype(np.float32)


def stuck_pixels(
    frames: Any,
    homographies: Any = None,
    *,
    min_counts: float = 100.0,
    k: float = 10.0,
    min_motion_px: float = 2.0,
) -> np.ndarray:
    """Defective pixels of a raw burst, ``(H, W)`` bool.

    A stuck hot or dead pixel stays at its place on the sensor while the scene moves under it,
    so it differs from the median of its 3×3 neighbours in every frame, where a small hot object
    moves away. A pixel is flagged when, in every frame, it differs from that median by more than
    ``min_counts`` and ``k`` robust standard deviations of the frame's differences, and (given
    the frame → pivot ``homographies``) the scene slid at least ``min_motion_px`` under it
    (:func:`scene_motion_px`): a static scene's point sources and thin lines are not defects.
    Without homographies the scene is taken to move. Bursts of fewer than 3 frames give none.
    """
    import cv2  # a 3×3 median of float32 frames

    arr = np.asarray(frames)
    out = np.zeros(arr.shape[1:], dtype=bool)
    if arr.shape[0] < 3:
        return out
    out[:] = True
    for f in arr:
        f = f.astype(np.float32)
        d = np.abs(f - cv2.medianBlur(f, 3))
        out &= d > max(min_counts, k * 1.4826 * float(np.median(d)))
    if homographies is not None and out.any():
        out &= scene_motion_px(homographies, out.shape) >= min_motion_px
    return out


def fill_stuck_pixels(frames: Any, homographies: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """A copy of a raw burst ``(N, H, W)`` with its :func:`stuck_pixels` replaced by the median
    of their good 3×3 neighbours (rounded for integer frames), and their mask ``(H, W)``. Every
    other pixel and the dtype are kept."""
    from thermocal.calibration.base import fill_bad_pixels

    arr = np.asarray(frames)
    out = arr.copy()
    bad = stuck_pixels(arr, homographies)
    if bad.any():
        filled = fill_bad_pixels(arr.astype(np.float32), bad)[:, bad]
        if np.issubdtype(arr.dtype, np.integer):
            filled = np.rint(filled)
        out[:, bad] = filled.astype(arr.dtype)
    return out, bad


def prepare(
    frames: np.ndarray,
    *,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
    fill_defects: bool = True,
    transform: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """:func:`register` a checked raw burst, replacing its stuck pixels (``fill_defects``; not
    for ``registered`` frames, where they no longer stay in place) before the frames are warped.

    ``transform`` maps those raw frames ``(N, H, W)`` to the ``(N, H, W)`` array warped in their
    place (a calibration of each pixel where it lies on the sensor), without changing its input
    (with ``fill_defects=False`` that is the caller's array); not for ``registered`` frames.

    Returns ``(frames, warped, valid, homographies, pivot)``: the raw frames with their stuck
    pixels replaced, and the registration of those frames (or of their ``transform``).
    """
    if registered:
        if transform is not None:
            raise InvalidInputError(
                "each frame is calibrated where it lies on the sensor, before registration: give "
                "the burst as recorded (not --registered)"
            )
        return (frames, *register(frames, pivot=pivot, registered=registered,
                                  homographies=homographies))
    hs, p = _homographies(frames, _pivot_index(pivot, frames.shape[0]), homographies)
    if fill_defects:
        frames, _ = fill_stuck_pixels(frames, hs)
    warped, valid = warp_to_pivot(frames if transform is None else transform(frames), hs)
    return frames, warped, valid, hs, p


def _pivot_index(pivot: int | None, n: int) -> int:
    """The pivot frame's index (default the middle one), checked against ``n`` frames."""
    if pivot is None:
        pivot = n // 2
    if not 0 <= pivot < n:
        raise InvalidInputError(f"pivot {pivot} is not a frame index (0 … {n - 1})")
    return pivot


def _homographies(frames: np.ndarray, pivot: int, homographies: Any) -> tuple[np.ndarray, int]:
    """Frame → pivot homographies: ``homographies`` checked, or found by ``register_burst``."""
    n = frames.shape[0]
    if homographies is not None:
        return as_homographies(homographies, n=n), pivot
    try:
        from thermocal.registration import register_burst
    except ImportError:
        raise RegistrationError(
            "burst registration is not available in this installation; register the frames "
            "yourself and pass --registered"
        ) from None
    reg = register_burst(frames, pivot=pivot)
    return as_homographies(reg.homographies, n=n), int(reg.pivot)


def register(
    frames: np.ndarray,
    *,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Warp a burst onto its pivot: ``(warped float32, valid bool, homographies, pivot)``.

    Known frame → pivot ``homographies`` are used as given. ``registered=True`` takes the frames
    as already registered (identity homographies; pixels at 0 counts are taken as not covered).
    Otherwise :func:`thermocal.registration.register_burst` finds the homographies.
    """
    n = frames.shape[0]
    pivot = _pivot_index(pivot, n)
    if registered and homographies is None:
        hs = np.repeat(np.eye(3)[None], n, axis=0)
        warped = frames.astype(np.float32)
        valid = frames > 0
        valid[pivot] = True
        return warped, valid, hs, pivot
    hs, pivot = _homographies(frames, pivot, homographies)
    warped, valid = warp_to_pivot(frames, hs)
    return warped, valid, hs, pivot


def check_overlap(valid: np.ndarray, pivot: int) -> None:
    """Every frame must see at least :data:`MIN_OVERLAP` of the pivot frame (``valid`` is
    ``(N, H, W)``); raises :class:`RegistrationError` otherwise."""
    frac = valid.reshape(valid.shape[0], -1).mean(axis=1)
    for k, f in enumerate(frac):
        if k != pivot and f < MIN_OVERLAP:
            raise RegistrationError(
                f"frame {k} overlaps the pivot frame {pivot} by only {100 * f:.0f} %; a burst "
                f"needs overlapping views (at least {100 * MIN_OVERLAP:.0f} %)"
            )


def fpa_value(fpa_c: Any, n: int) -> float:
    """One FPA temperature for a burst, °C: the mean of one value or one per frame."""
    if fpa_c is None:
        raise InvalidInputError(
            "no FPA temperature: give --fpa-c or a sidecar JSON with fpa_c (the network needs it)"
        )
    arr = np.asarray(fpa_c, dtype=np.float64).ravel()
    if arr.size not in (1, n) or not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"fpa_c: expected one finite value or {n}, got {arr.size}")
    value = float(arr.mean())
    if not -60.0 <= value <= 120.0:
        raise InvalidInputError(f"fpa_c: {value:.1f} °C is not a plausible FPA temperature")
    return value


def naive_mean(
    frames: Any,
    calibration: Any,
    *,
    fpa_c: Any = None,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
    fill_defects: bool = True,
) -> Estimate:
    """Eq. 9: the registered average of the per-frame temperatures given by a calibration.

    Every frame goes through ``calibration.apply(frames, fpa_c=…)`` (°C), is warped onto the
    pivot, and the valid values of each pivot pixel are averaged. With ``fill_defects`` the
    burst's stuck pixels are first replaced by their neighbours' median (:func:`prepare`), as
    for the network.
    """
    arr = check_burst(frames, registered=registered)
    if calibration.shape != arr.shape[1:]:
        raise ResolutionMismatchError(
            f"frames are {arr.shape[2]}x{arr.shape[1]} but the calibration is "
            f"{calibration.shape[1]}x{calibration.shape[0]}"
        )
    arr, _, valid, hs, p = prepare(arr, pivot=pivot, registered=registered,
                                   homographies=homographies, fill_defects=fill_defects)
    check_overlap(valid, p)
    temps = calibration.apply(arr, fpa_c=fpa_c)
    warped_t, valid_t = warp_to_pivot(temps, hs)
    valid_t &= valid
    count = valid_t.sum(axis=0)
    mean = (warped_t * valid_t).sum(axis=0) / np.maximum(count, 1)
    return Estimate(mean.astype(np.float32), count, hs, p)


def estimate_file(
    frames_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    fpa_c: float | None = None,
    method: str = "kpn",
    model_path: str | os.PathLike[str] | None = None,
    pivot: int | None = None,
    registered: bool = False,
    calibration: str | os.PathLike[str] | None = None,
) -> Path:
    """``thermocal estimate``: read a recording, estimate the pivot's temperature, write it.

    The output (float32 °C TIFF, ``(H, W)``) is written atomically and only after every check.
    """
    from thermocal.io.recording import read_recording, write_temperature_tiff

    out = Path(out)
    if out.suffix.lower() not in (".tif", ".tiff"):
        raise InvalidInputError(f"{out}: the output must be a .tiff file")
    if not out.parent.is_dir():
        raise InvalidInputError(f"{out.parent}: output folder does not exist")
    if method == "mean" and calibration is None:
        raise InvalidInputError(
            "--method mean needs a per-pixel calibration: give --calibration CAL.h5"
        )
    rec = read_recording(frames_path, fpa_c=fpa_c)
    fpa = rec.fpa_c
    if method == "mean":
        from thermocal.calibration import load_any_calibration

        cal = load_any_calibration(calibration)
        result = naive_mean(rec.frames, cal, fpa_c=fpa, pivot=pivot, registered=registered)
    else:
        from thermocal.nn.infer import estimate_burst, shipped_model_path
        from thermocal.nn.train import load_model

        path = Path(model_path) if model_path is not None else shipped_model_path(method)
        model, norm, _ = load_model(path)
        expected = "kpn" if method == "kpn" else method
        if model.config.variant != expected:
            raise InvalidInputError(
                f"{path} holds a {model.config.variant} model, not {method}; pass the right "
                "--model or --method"
            )
        result = estimate_burst(
            rec.frames, fpa, model=model, norm=norm, pivot=pivot, registered=registered
        )
    write_temperature_tiff(out, result.temperature_c)
    return out
