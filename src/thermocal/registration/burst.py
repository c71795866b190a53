"""Registering a burst of raw frames to its pivot frame.

:func:`register_burst` detects features once per frame (:mod:`thermocal.registration.features`),
registers every frame to a reference frame (the middle one), picks as pivot the frame with the
largest total overlap with the others (:func:`thermocal.scenes.trajectory.choose_pivot`, ties to
the middle frame) and, when that is not the reference, registers every frame directly to it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError, RegistrationError
from thermocal.registration.features import (
    _as_frame,
    _detector_of,
    _register_features,
    detect_features,
)

__all__ = ["BurstRegistration", "register_burst"]


@dataclass(frozen=True, eq=False)
class BurstRegistration:
    """Homographies of a burst to its pivot frame.

    Attributes
    ----------
    homographies : numpy.ndarray, shape (N, 3, 3), float64
        Pixel ``(x, y)`` of frame ``i`` → pixel of the pivot frame, ``h33 = 1``; the pivot's own
        is exactly the identity.
    pivot : int
        Index of the pivot frame.
    inliers : numpy.ndarray, shape (N,), int
        RANSAC inliers of each frame's match to the pivot (0 for the pivot itself and for
        ECC-only registration).
    method : str
        Registration method used (see :data:`thermocal.registration.features.METHODS`).
    """

    homographies: np.ndarray
    pivot: int
    inliers: np.ndarray
    method: str

    def warp(self, frames: Any, *, interpolation: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """Warp ``frames`` (N, H, W) onto the pivot grid: ``(warped float32, valid bool)``.

        See :func:`thermocal.registration.warp.warp_to_pivot`.
        """
        from thermocal.registration.warp import warp_to_pivot

        return warp_to_pivot(frames, self.homographies, interpolation=interpolation)


def _as_burst(frames: Any) -> np.ndarray:
    arr = np.asarray(frames)
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"frames: expected raw counts or floats, got dtype {arr.dtype}")
    if arr.ndim != 3:
        raise InvalidInputError(f"frames: expected a (N, H, W) burst, got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise InvalidInputError("frames: the burst is empty")
    for i in range(arr.shape[0]):
        _as_frame(arr[i], f"frame {i}")
    return arr


def _check_pivot(pivot: Any, n: int) -> int:
    if isinstance(pivot, bool) or not isinstance(pivot, int | np.integer):
        raise InvalidInputError(f"pivot: expected a frame index, got {pivot!r}")
    if not 0 <= int(pivot) < n:
        raise InvalidInputError(f"pivot: {pivot} is not a frame index (0..{n - 1})")
    return int(pivot)


def register_burst(
    frames: Any, *, pivot: int | None = None, method: str = "auto"
) -> BurstRegistration:
    """Register every frame of a burst to its pivot frame.

    Parameters
    ----------
    frames : array_like, shape (N, H, W)
        Raw frames (uint16 14-bit counts, or float). Never modified.
    pivot : int, optional
        Index of the pivot frame. None chooses the frame with the largest total overlap with
        the others (the middle one, ``N // 2``, on a tie).
    method : {"auto", "sift", "sift-ecc", "orb", "orb-ecc", "ecc"}
        See :func:`thermocal.registration.register_pair`.

    Returns
    -------
    BurstRegistration

    Raises
    ------
    RegistrationError
        A frame that cannot be registered to the pivot (too few inliers, degenerate homography,
        uniform frame); the message names the frame and the reason.
    InvalidInputError
        Not a numeric ``(N, H, W)`` burst, NaN, a bad pivot index or an unknown method.
    """
    detector, refine = _detector_of(method)
    arr = _as_burst(frames)
    n, hh, w = arr.shape
    if pivot is not None:
        pivot = _check_pivot(pivot, n)
    feats = [detect_features(arr[i], detector=detector) for i in range(n)]

    def register_all(ref: int, initial: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        hs = np.repeat(np.eye(3)[None], n, axis=0)
        inl = np.zeros(n, dtype=int)
        for i in range(n):
            if i == ref:
                continue
            hs[i], inl[i] = _register_features(
                feats[i],
                feats[ref],
                refine=refine,
                name=f"frame {i} (to pivot {ref})",
                initial=None if initial is None else initial[i],
            )
        return hs, inl

    ref = n // 2 if pivot is None else pivot
    hs, inliers = register_all(ref)
    if pivot is None and n > 2:
        from thermocal.scenes.trajectory import choose_pivot

        best = choose_pivot(hs, (w, hh))
        if best != ref:
            composed = np.linalg.inv(hs[best])[None] @ hs
            composed /= composed[:, 2:3, 2:3]
            try:
                hs, inliers = register_all(best, initial=composed)
            except RegistrationError:
                # Direct matches to the better pivot failed; the chain through the middle frame
                # is made of registrations that all passed their checks.
                hs = composed
                inliers = np.minimum(inliers, inliers[best])
            ref = best
    hs[ref] = np.eye(3)
    inliers[ref] = 0
    return BurstRegistration(homographies=hs, pivot=int(ref), inliers=inliers, method=method)
