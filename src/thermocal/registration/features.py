"""Homographies between raw 14-bit frames that carry fixed-pattern noise.

The pipeline of :func:`register_pair` (and of :func:`thermocal.registration.register_burst`):

1. **Robust normalisation** (:func:`normalise_frame`): a 3×3 median removes dead and hot pixels;
   a large-scale background (a wide Gaussian blur) removes the radial self-radiation and
   vignetting pattern; the per-column median removes the column FPN; a light blur damps the
   per-pixel FPN and temporal noise; a 1–99 percentile stretch maps the result to uint8. The
   fixed pattern is tied to the sensor, not the scene: left in, it pulls every match towards the
   identity.
2. **Features**: SIFT (default, sub-pixel keypoints) or ORB keypoints and descriptors from
   OpenCV, matched with a ratio test and cross-checked, then a homography by RANSAC
   (``cv2.findHomography``, MAGSAC++ when available).
3. **ECC refinement** (``cv2.findTransformECC``, Evangelidis & Psarakis 2008) of the feature
   homography on the normalised float images, kept only when it converges and stays close to
   the feature estimate.
4. **Checks**: too few inliers, a degenerate homography (near-singular, flipped, strongly
   scaled or projective, a footprint that folds) or a frame without texture raise
   :class:`~thermocal.errors.RegistrationError` naming the frame and the reason; nothing is
   ever returned as garbage.

Homographies follow :mod:`thermocal.registration.warp`: ``(3, 3)`` float64, pixel ``(x, y)`` of
the *moving* frame → pixel of the *fixed* frame, normalised so that ``h33 = 1``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from thermocal.errors import InvalidInputError, RegistrationError, ResolutionMismatchError

__all__ = [
    "METHODS",
    "FrameFeatures",
    "check_homography",
    "detect_features",
    "normalise_frame",
    "register_pair",
    "texture_ratio",
]

#: Registration methods: feature detector, and whether ECC refines the result.
METHODS = {
    "auto": ("sift", True),
    "sift": ("sift", False),
    "sift-ecc": ("sift", True),
    "orb": ("orb", False),
    "orb-ecc": ("orb", True),
    "ecc": (None, True),
}

#: Fewest RANSAC inliers accepted for a homography (8 degrees of freedom, 4 points each 2).
MIN_INLIERS = 15
#: Smallest texture ratio (see :func:`texture_ratio`) of a frame that can be registered.
MIN_TEXTURE = 0.35
# RANSAC reprojection threshold, pixels.
_RANSAC_PX = 2.0
# Lowe's ratio test.
_RATIO = 0.8
# Largest change of scale / perspective accepted between two frames of one burst.
_MAX_SCALE = 2.0
_MAX_PERSPECTIVE_PX = 0.25  # largest |h31|, |h32| times the frame diagonal
# Matches that move less than this are taken as fixed-pattern matches, pixels.
_STILL_PX = 1.0
# ECC: largest move of a corner away from the feature estimate that is still believed, pixels.
_ECC_MAX_SHIFT_PX = 3.0


# --------------------------------------------------------------------------------------------
# normalisation
# --------------------------------------------------------------------------------------------


def _as_frame(frame: Any, name: str) -> np.ndarray:
    arr = np.asarray(frame)
    if arr.dtype.kind not in "biuf":
        raise InvalidInputError(f"{name}: expected numbers, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise InvalidInputError(f"{name}: expected one (H, W) frame, got shape {arr.shape}")
    if min(arr.shape) < 16:
        raise InvalidInputError(f"{name}: frame {arr.shape[1]}x{arr.shape[0]} is too small to "
                                "register (at least 16x16 pixels)")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name}: contains NaN or infinite values")
    return arr


def _highpass(frame: np.ndarray) -> np.ndarray:
    """Dead pixels, large-scale background and column FPN removed; float32 (H, W)."""
    x = frame.astype(np.float32)
    x = cv2.medianBlur(x, 3)
    h, w = x.shape
    sigma_bg = 0.08 * max(h, w)  # ~27 px at 336: far larger than scene features used
    background = cv2.GaussianBlur(x, (0, 0), sigma_bg, borderType=cv2.BORDER_REFLECT)
    x -= background
    x -= np.median(x, axis=0, keepdims=True)
    return x


def texture_ratio(frame: Any) -> float:
    """How much spatially correlated (scene) structure a raw frame has beyond white FPN and noise.

    ``std(blur(x)) / std(x − blur(x))`` of the high-passed frame ``x`` (background and column
    FPN removed), with a Gaussian blur of σ = 2 px. White noise gives about 0.14; a frame with
    scene content that features can lock onto gives well above 1.

    Parameters
    ----------
    frame : array_like, shape (H, W)
        Raw counts or any float frame.

    Returns
    -------
    float
    """
    return _texture(_highpass(_as_frame(frame, "frame")))


def _texture(x: np.ndarray) -> float:
    smooth = cv2.GaussianBlur(x, (0, 0), 2.0)
    rough = float(np.std(x - smooth))
    s = float(np.std(smooth))
    if rough == 0.0:
        return 0.0 if s == 0.0 else float("inf")
    return s / rough


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
    return _stretch(_highpass(_as_frame(frame, "frame")), blur_sigma)


def _stretch(x: np.ndarray, blur_sigma: float) -> np.ndarray:
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
    texture: float


_DETECTORS: dict[str, Any] = {}


def _detector(name: str) -> Any:
    if name not in _DETECTORS:
        if name == "sift":
            _DETECTORS[name] = cv2.SIFT_create(nfeatures=1500, contrastThreshold=0.02)
        elif name == "orb":
            _DETECTORS[name] = cv2.ORB_create(nfeatures=2000, fastThreshold=10)
        else:  # pragma: no cover - guarded by METHODS
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
    x = _highpass(_as_frame(frame, "frame"))
    image = _stretch(x, 2.0)
    tex = _texture(x)
    if detector is None:
        return FrameFeatures(image, np.zeros((0, 2), np.float32), None, "none", tex)
    kps, desc = _detector(detector).detectAndCompute(image, None)
    pts = np.array([k.pt for k in kps], dtype=np.float32).reshape(-1, 2)
    return FrameFeatures(image, pts, desc, detector, tex)


def _match(a: FrameFeatures, b: FrameFeatures) -> tuple[np.ndarray, np.ndarray]:
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


def _overlap_ok(h: np.ndarray, frame_size: tuple[int, int]) -> bool:
    """True when the moving frame's centre region lands at least partly inside the fixed frame."""
    w, hh = frame_size
    xy, _ = _map(h, _corners(w, hh))
    return bool(
        xy[:, 0].max() > 0.05 * w
        and xy[:, 0].min() < 0.95 * w
        and xy[:, 1].max() > 0.05 * hh
        and xy[:, 1].min() < 0.95 * hh
    )


# --------------------------------------------------------------------------------------------
# pair registration
# --------------------------------------------------------------------------------------------


def _near_identity(h: np.ndarray, frame_size: tuple[int, int]) -> bool:
    """True when every corner moves by less than ``_STILL_PX`` under ``h``."""
    c = _corners(*frame_size)
    return bool(np.linalg.norm(_map(h / h[2, 2], c)[0] - c, axis=1).max() < _STILL_PX)


def _ransac(p_mov: np.ndarray, p_fix: np.ndarray) -> tuple[np.ndarray | None, int]:
    if len(p_mov) < 4:
        return None, 0
    method = getattr(cv2, "USAC_MAGSAC", cv2.RANSAC)
    h, mask = cv2.findHomography(
        p_mov, p_fix, method, _RANSAC_PX, maxIters=2000, confidence=0.999
    )
    if h is None or mask is None:
        return None, 0
    return h, int(mask.sum())


def _ecc_refine(
    moving: FrameFeatures, fixed: FrameFeatures, h: np.ndarray, *, iterations: int = 30
) -> np.ndarray | None:
    """ECC refinement of ``h`` (moving → fixed); None when it does not converge or runs away."""
    tmpl = cv2.GaussianBlur(fixed.image.astype(np.float32), (0, 0), 1.0)
    inp = cv2.GaussianBlur(moving.image.astype(np.float32), (0, 0), 1.0)
    warp = np.linalg.inv(h).astype(np.float32)  # ECC warps fixed pixels into the moving frame
    warp /= warp[2, 2]
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, iterations, 1e-4)
    try:
        _, warp = cv2.findTransformECC(
            tmpl, inp, warp, cv2.MOTION_HOMOGRAPHY, criteria, None, 1
        )
    except cv2.error:
        return None
    try:
        refined = np.linalg.inv(warp.astype(np.float64))
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(refined)):
        return None
    refined /= refined[2, 2]
    hh, w = fixed.image.shape
    c = _corners(w, hh)
    shift = np.linalg.norm(_map(refined, c)[0] - _map(h, c)[0], axis=1).max()
    return refined if shift <= _ECC_MAX_SHIFT_PX else None


def _register_features(
    moving: FrameFeatures,
    fixed: FrameFeatures,
    *,
    refine: bool,
    name: str,
    initial: np.ndarray | None = None,
) -> tuple[np.ndarray, int]:
    """Homography moving → fixed from prepared features, with the checks; ``(H, inliers)``."""
    hh, w = fixed.image.shape
    size = (w, hh)
    for feats, label in ((moving, "moving"), (fixed, "fixed")):
        if feats.texture < MIN_TEXTURE:
            raise RegistrationError(
                f"{name}: the {label} frame is uniform (texture ratio {feats.texture:.2f} < "
                f"{MIN_TEXTURE}); there is no scene structure to align"
            )
    if moving.detector == "none":
        if initial is None:
            initial = np.eye(3)
        h = _ecc_refine(moving, fixed, initial, iterations=100)
        if h is None:
            raise RegistrationError(f"{name}: ECC did not converge from the initial guess")
        return check_homography(h, size, name), 0
    p_mov, p_fix = _match(moving, fixed)
    h, inliers = _ransac(p_mov, p_fix)
    if h is not None and _near_identity(h, size):
        # The fixed pattern is tied to the sensor: its features always vote for the identity.
        # A consistent set of matches that moves is the scene; prefer it when there is one.
        moved = np.linalg.norm(p_mov - p_fix, axis=1) > _STILL_PX
        h2, inliers2 = _ransac(p_mov[moved], p_fix[moved])
        if h2 is not None and inliers2 >= MIN_INLIERS and not _near_identity(h2, size):
            h, inliers = h2, inliers2
    if h is None or inliers < MIN_INLIERS:
        raise RegistrationError(
            f"{name}: too few inliers ({inliers} of {len(p_mov)} matches, need {MIN_INLIERS}); "
            "the frames may not overlap or lack texture"
        )
    h = check_homography(h, size, name)
    if not _overlap_ok(h, size):
        raise RegistrationError(f"{name}: degenerate homography (the frames do not overlap)")
    if refine:
        refined = _ecc_refine(moving, fixed, h)
        if refined is not None:
            h = check_homography(refined, size, name)
    return h, inliers


def _detector_of(method: str) -> tuple[str | None, bool]:
    if method not in METHODS:
        raise InvalidInputError(
            f"registration method {method!r}: choose from {', '.join(METHODS)}"
        )
    return METHODS[method]


def register_pair(
    moving: Any, fixed: Any, *, method: str = "auto"
) -> tuple[np.ndarray, int]:
    """Homography that maps pixels of ``moving`` onto ``fixed``.

    Parameters
    ----------
    moving, fixed : array_like, shape (H, W)
        Raw frames (uint16 14-bit counts or float), same size. Never modified.
    method : {"auto", "sift", "sift-ecc", "orb", "orb-ecc", "ecc"}
        Features (SIFT or ORB + RANSAC), optionally refined by ECC; ``"auto"`` is SIFT + ECC;
        ``"ecc"`` is ECC alone from the identity (small motion only).

    Returns
    -------
    h : numpy.ndarray, shape (3, 3), float64
        Pixel ``(x, y)`` of ``moving`` → pixel of ``fixed``; ``h[2, 2] = 1``.
    inliers : int
        RANSAC inliers of the feature match (0 for ``"ecc"``).

    Raises
    ------
    RegistrationError
        Too few inliers, a degenerate homography or a uniform frame.
    InvalidInputError, ResolutionMismatchError
        Frames that are not 2-D numeric, hold NaN, or differ in size.
    """
    detector, refine = _detector_of(method)
    a = _as_frame(moving, "moving")
    b = _as_frame(fixed, "fixed")
    if a.shape != b.shape:
        raise ResolutionMismatchError(
            f"moving is {a.shape[1]}x{a.shape[0]} but fixed is {b.shape[1]}x{b.shape[0]}"
        )
    fa = detect_features(a, detector=detector)
    fb = detect_features(b, detector=detector)
    return _register_features(fa, fb, refine=refine, name="moving frame")
