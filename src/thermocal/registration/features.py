"""Pieces of the registration of raw 14-bit frames that carry fixed-pattern noise.

* **Robust normalisation** (:func:`normalise_frame`): a 3×3 median removes dead and hot pixels,
  a least-squares quadratic surface removes the radial self-radiation and vignetting pattern,
  the high-frequency part of the column medians removes the column FPN, a light blur damps the
  per-pixel FPN and noise, and a 1–99 percentile stretch maps the result to uint8.
* **Features**: SIFT or ORB keypoints from OpenCV, a ratio test with a mutual best match, a
  homography by RANSAC (``cv2.findHomography``, MAGSAC++ when available).
* **Checks** (:func:`check_homography`): a degenerate homography raises
  :class:`~thermocal.errors.RegistrationError` naming the frame and the reason.

Homographies follow :mod:`thermocal.registration.warp`: ``(3, 3)`` float64, pixel ``(x, y)`` of
the *moving* frame → pixel of the *fixed* frame, normalised so that ``h33 = 1``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy.ndimage import median_filter

from thermocal._validate import as_frames
from thermocal.errors import InvalidInputError, RegistrationError

__all__ = [
    "FrameFeatures",
    "as_frame",
    "check_homography",
    "detect_features",
    "make_detector",
    "match_features",
    "normalise_frame",
    "ransac_homography",
    "stretch_u8",
]

#: Fewest RANSAC inliers accepted for a homography (8 degrees of freedom, 4 points each 2).
MIN_INLIERS = 15
# RANSAC reprojection threshold, pixels.
_RANSAC_PX = 2.0
# Lowe's ratio test.
_RATIO = 0.8
#: Fewest pixels on a side of a frame to register.
MIN_FRAME_PX = 16
# Largest change of scale / perspective accepted between two frames of one burst.
_MAX_SCALE = 2.0
_MAX_PERSPECTIVE_PX = 0.25  # largest |h31|, |h32| times the frame diagonal


# --------------------------------------------------------------------------------------------
# normalisation
# --------------------------------------------------------------------------------------------


def as_frame(frame: Any, name: str) -> np.ndarray:
    """One ``(H, W)`` frame of numbers, at least :data:`MIN_FRAME_PX` on a side, finite."""
    return as_frames(frame, name, ndim=2, min_size=MIN_FRAME_PX, bit_depth=None)[0]


def _highpass(frame: np.ndarray) -> np.ndarray:
    """Dead pixels, the smooth radial pattern and column FPN removed; float32 (H, W)."""
    x = cv2.medianBlur(frame.astype(np.float32), 3)
    x -= _quadratic_surface(x)
    x -= _column_pattern(x)
    return x


def _column_pattern(x: np.ndarray) -> np.ndarray:
    """Column FPN of a frame, (1, W) float32: column medians minus their smooth trend.

    Column FPN is independent from column to column; the scene's column medians vary smoothly,
    so only the part of the medians that a 1-D median filter along the row does not follow is
    removed.
    """
    med = np.median(x, axis=0).astype(np.float32)
    trend = median_filter(med, size=9, mode="nearest")
    return (med - trend)[None, :]


_DESIGN: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}


def _quadratic_surface(x: np.ndarray) -> np.ndarray:
    """Least-squares quadratic surface in (x, y) through a frame, (H, W) float32.

    The radial self-radiation and vignetting patterns are polynomials in ``R²`` (Oz et al.
    eq. 16-17), i.e. quadratic in ``x, y`` to first order; a fitted surface removes them without
    the border artefacts of a large blur.
    """
    h, w = x.shape
    if (h, w) not in _DESIGN:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        xx = xx / w - 0.5
        yy = yy / h - 0.5
        basis = np.stack([np.ones_like(xx), xx, yy, xx * xx, xx * yy, yy * yy])  # (6, H, W)
        sub = basis[:, ::4, ::4].reshape(6, -1).T
        _DESIGN[(h, w)] = (basis, np.linalg.pinv(sub).astype(np.float32))
    basis, pinv = _DESIGN[(h, w)]
    coef = pinv @ x[::4, ::4].ravel()
    return np.tensordot(coef, basis, axes=1).astype(np.float32)


def normalise_frame(frame: Any, *, blur_sigma: float = 1.0) -> np.ndarray:
    """A raw frame made fit for matching: FPN and radial pattern removed, stretched to uint8.

    Parameters
    ----------
    frame : array_like, shape (H, W)
        Raw counts (uint16, 14-bit) or float. Never modified.
    blur_sigma : float
        Gaussian blur after the clean-up that damps per-pixel FPN and noise, pixels.

    Returns
    -------
    numpy.ndarray, shape (H, W), uint8
        Percentile 1 → 0, percentile 99 → 255.
    """
    return stretch_u8(_highpass(as_frame(frame, "frame")), blur_sigma)


def stretch_u8(x: np.ndarray, blur_sigma: float) -> np.ndarray:
    """A frame ``(H, W)`` blurred by ``blur_sigma`` px (0: none) and stretched from its 1st to
    99th percentile onto uint8, for the feature detectors."""
    if blur_sigma > 0:
        x = cv2.GaussianBlur(x, (0, 0), blur_sigma)
    lo, hi = np.percentile(x[::2, ::2], (1.0, 99.0))
    if hi <= lo:
        return np.zeros(x.shape, dtype=np.uint8)
    scale = 255.0 / (hi - lo)
    return np.clip((x - lo) * scale, 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------------------------
# features
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class FrameFeatures:
    """Keypoints of one normalised frame: ``points`` (K, 2) float32 (x, y), ``descriptors``."""

    image: np.ndarray
    points: np.ndarray
    descriptors: np.ndarray | None
    detector: str


_DETECTORS: dict[str, Any] = {}


def make_detector(name: str) -> Any:
    """The OpenCV detector ``"sift"`` or ``"orb"`` (made once per process)."""
    if name not in _DETECTORS:
        if name == "sift":
            _DETECTORS[name] = cv2.SIFT_create(nfeatures=1500, contrastThreshold=0.02)
        elif name == "orb":
            _DETECTORS[name] = cv2.ORB_create(nfeatures=2000, fastThreshold=10)
        else:  # pragma: no cover - guarded by BURST_METHODS
            raise InvalidInputError(f"unknown detector {name!r}")
    return _DETECTORS[name]


def detect_features(frame: Any, *, detector: str | None = "sift") -> FrameFeatures:
    """Normalise a raw frame and detect keypoints on it.

    Parameters
    ----------
    frame : array_like, shape (H, W)
        Raw counts or float.
    detector : {"sift", "orb", None}
        OpenCV detector; None computes only the normalised image (for ECC alone).

    Returns
    -------
    FrameFeatures
    """
    image = stretch_u8(_highpass(as_frame(frame, "frame")), 1.0)
    if detector is None:
        return FrameFeatures(image, np.zeros((0, 2), np.float32), None, "none")
    kps, desc = make_detector(detector).detectAndCompute(image, None)
    pts = np.array([k.pt for k in kps], dtype=np.float32).reshape(-1, 2)
    return FrameFeatures(image, pts, desc, detector)


def match_features(a: FrameFeatures, b: FrameFeatures) -> tuple[np.ndarray, np.ndarray]:
    """Matched points ``(M, 2)`` of a and of b: ratio test plus mutual best match."""
    if a.descriptors is None or b.descriptors is None or len(a.points) < 2 or len(b.points) < 2:
        return np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32)
    norm = cv2.NORM_L2 if a.detector == "sift" else cv2.NORM_HAMMING
    matcher = cv2.BFMatcher(norm)
    fwd = matcher.knnMatch(a.descriptors, b.descriptors, k=2)
    back = matcher.match(b.descriptors, a.descriptors)
    best_back = {m.queryIdx: m.trainIdx for m in back}
    ia, ib = [], []
    for pair in fwd:
        if len(pair) < 2:
            continue
        m, n = pair
        if m.distance < _RATIO * n.distance and best_back.get(m.trainIdx) == m.queryIdx:
            ia.append(m.queryIdx)
            ib.append(m.trainIdx)
    return a.points[ia], b.points[ib]


# --------------------------------------------------------------------------------------------
# checks
# --------------------------------------------------------------------------------------------


def _corners(w: int, h: int) -> np.ndarray:
    return np.array([[0.0, 0.0], [w - 1.0, 0.0], [w - 1.0, h - 1.0], [0.0, h - 1.0]])


def _map(h: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    hom = np.concatenate([pts, np.ones((len(pts), 1))], axis=1) @ h.T
    return hom[:, :2] / hom[:, 2:3], hom[:, 2]


def check_homography(h: np.ndarray, frame_size: tuple[int, int], name: str) -> np.ndarray:
    """Return ``h`` normalised (h33 = 1) or raise :class:`RegistrationError` if degenerate.

    Degenerate: not finite, near-singular, orientation flipped, area scaled by more than
    ``2²`` either way, perspective terms that bend the frame by more than a quarter of its
    diagonal, or a footprint that is not a convex quadrilateral in front of the camera.
    """
    w, hh = frame_size
    if h is None or not np.all(np.isfinite(h)) or abs(h[2, 2]) < 1e-12:
        raise RegistrationError(f"{name}: degenerate homography (not finite)")
    h = h / h[2, 2]
    det = float(np.linalg.det(h[:2, :2]))
    if not (1.0 / _MAX_SCALE**2 < det < _MAX_SCALE**2):
        raise RegistrationError(
            f"{name}: degenerate homography (area scale {det:.3g}; a flip, collapse or a zoom "
            f"beyond {_MAX_SCALE}x)"
        )
    diag = float(np.hypot(w, hh))
    if max(abs(h[2, 0]), abs(h[2, 1])) * diag > _MAX_PERSPECTIVE_PX:
        raise RegistrationError(f"{name}: degenerate homography (implausibly strong perspective)")
    xy, wz = _map(h, _corners(w, hh))
    if np.any(wz <= 0):
        raise RegistrationError(f"{name}: degenerate homography (frame maps behind the camera)")
    edges = np.roll(xy, -1, axis=0) - xy
    cross = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(
        edges, -1, axis=0
    )[:, 0]
    if not (np.all(cross > 0) or np.all(cross < 0)):
        raise RegistrationError(f"{name}: degenerate homography (the frame folds over itself)")
    return h


def ransac_homography(p_mov: np.ndarray, p_fix: np.ndarray) -> tuple[np.ndarray | None, int]:
    """Homography of matched points ``(K, 2)`` moving → fixed by RANSAC (MAGSAC++ where OpenCV
    has it) and its inlier count; ``(None, 0)`` when there is none."""
    if len(p_mov) < 4:
        return None, 0
    method = getattr(cv2, "USAC_MAGSAC", cv2.RANSAC)
    h, mask = cv2.findHomography(
        p_mov, p_fix, method, _RANSAC_PX, maxIters=2000, confidence=0.999
    )
    if h is None or mask is None:
        return None, 0
    return h, int(mask.sum())
