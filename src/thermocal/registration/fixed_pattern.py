"""The fixed pattern of a moving camera's frames: what stays on the sensor while the scene moves.

Registration needs it removed first: on a Tau2-class core the per-pixel offset FPN (tens of
counts) and the column pattern (the column gain times the scene level, up to a few hundred
counts) are as strong as a scene's texture, and they sit at the same sensor position in every
frame, so every matcher votes for zero motion.

* :func:`estimate_fixed_pattern` -- for long recordings whose scene moves far (a UAV pass): a
  robust temporal mean of many frames spread over a long window, split into a column part, a
  smooth part and a per-pixel part (:class:`FixedPattern`).
* For short bursts (a few frames, tens of pixels of motion) the median keeps a "ghost" of the
  scene, so :mod:`thermocal.registration.burst` starts from it (or from its fine-scale part) and
  refines it jointly with the alignment: :func:`back_projected_pattern` is one Gauss-Seidel
  sweep of the least-squares fit ``frame_i = scene ∘ H_i + F`` for given homographies (the
  offset part of Hardie et al. 2000 restricted to registration), :func:`joint_residual` the
  misfit that tells a good set of homographies from a bad one.

All patterns are offsets in counts of the raw frames (dead and hot pixels included: they are
fixed too), ``(H, W)`` float32, mean zero: an offset-only estimate that serves registration, not
a calibration.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from thermocal._validate import frames_layout
from thermocal.errors import FileFormatError, InvalidInputError, ResolutionMismatchError

__all__ = [
    "FixedPattern",
    "as_fixed_pattern",
    "back_projected_pattern",
    "estimate_fixed_pattern",
    "initial_patterns",
    "joint_residual",
]

#: Sigma (pixels) of the Gaussian that separates the smooth part of a pattern.
LOW_SIGMA_PX = 16.0
#: Sigma (pixels) below which the temporal median of a burst is taken as fixed pattern
#: (``initial_patterns(..., "fine")``); coarser structure in a burst's median is mostly scene.
FINE_SIGMA_PX = 4.0


@dataclass(frozen=True, eq=False)
class FixedPattern:
    """A fixed-pattern (offset) estimate, counts, split into three parts.

    Attributes
    ----------
    column : numpy.ndarray, shape (W,), float32
        Column offsets (column FPN, including column gain times the mean scene level), mean
        zero.
    low : numpy.ndarray, shape (H, W), float32
        The smooth part (self-radiation and vignetting shading; Gaussian low-pass with sigma
        ``LOW_SIGMA_PX`` of what the columns leave), mean zero.
    pixel : numpy.ndarray, shape (H, W), float32
        The per-pixel rest.
    frames_used : int
        Number of frames the estimate came from.
    """

    column: np.ndarray
    low: np.ndarray
    pixel: np.ndarray
    frames_used: int = 0

    def __post_init__(self) -> None:
        shape = self.pixel.shape
        if self.pixel.ndim != 2 or self.low.shape != shape or self.column.shape != shape[1:]:
            raise InvalidInputError(
                f"FixedPattern: column {self.column.shape}, low {self.low.shape} and pixel "
                f"{self.pixel.shape} do not describe one (H, W) frame"
            )

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of the frames."""
        return self.pixel.shape  # type: ignore[return-value]

    @property
    def pattern(self) -> np.ndarray:
        """The whole pattern ``column + low + pixel``, ``(H, W)`` float32."""
        return (self.column[None, :] + self.low + self.pixel).astype(np.float32)

    def apply(
        self, frames: Any, *, parts: tuple[str, ...] = ("column", "low", "pixel")
    ) -> np.ndarray:
        """Frames with the pattern (or the named ``parts`` of it) subtracted, float32.

        Parameters
        ----------
        frames : array_like, shape (H, W) or (N, H, W)
            Raw counts or float. Never modified.
        parts : tuple of {"column", "low", "pixel"}
            Which parts to subtract.
        """
        arr = np.asarray(frames)
        if arr.ndim not in (2, 3) or arr.shape[-2:] != self.shape:
            raise ResolutionMismatchError(
                f"frames of shape {arr.shape} do not match the {self.shape[1]}x{self.shape[0]} "
                "fixed pattern"
            )
        unknown = set(parts) - {"column", "low", "pixel"}
        if unknown:
            raise InvalidInputError(f"parts: unknown {sorted(unknown)}; use column, low, pixel")
        total = np.zeros(self.shape, np.float32)
        if "column" in parts:
            total += self.column[None, :]
        if "low" in parts:
            total += self.low
        if "pixel" in parts:
            total += self.pixel
        return arr.astype(np.float32) - total

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (``.npz``, atomically); returns the path."""
        from thermocal.io.atomic import atomic_path

        out = Path(path)
        with atomic_path(out) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, kind=np.array("thermocal.FixedPattern"), column=self.column,
                     low=self.low, pixel=self.pixel, frames_used=np.array(self.frames_used))
        return out

    @classmethod
    def load(cls, path: str | Path) -> FixedPattern:
        """Read a pattern written by :meth:`save`."""
        try:
            with np.load(Path(path), allow_pickle=False) as z:
                if str(z["kind"]) != "thermocal.FixedPattern":
                    raise KeyError("kind")
                return cls(
                    column=z["column"].astype(np.float32),
                    low=z["low"].astype(np.float32),
                    pixel=z["pixel"].astype(np.float32),
                    frames_used=int(z["frames_used"]),
                )
        except FileNotFoundError:
            raise FileFormatError(f"{path}: no such file") from None
        except (KeyError, ValueError, OSError) as exc:
            raise FileFormatError(
                f"{path}: not a fixed-pattern file written by FixedPattern.save ({exc})"
            ) from None


def _split(average: np.ndarray, *, rows: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column, smooth and per-pixel parts of a temporal average (all mean zero)."""
    col = average.mean(axis=0)
    col = (col - col.mean()).astype(np.float32)
    rest = average - col[None, :]
    low = cv2.GaussianBlur(rest, (0, 0), LOW_SIGMA_PX, borderType=cv2.BORDER_REFLECT)
    pixel = rest - low
    if rows:
        # A camera moving along its rows leaves the scene's along-track structure in the average
        # as a pattern that varies from row to row only; the sensor's own pattern has none.
        pixel = pixel - pixel.mean(axis=1, keepdims=True)
    low = low - np.float32(low.mean())
    pixel = pixel - np.float32(pixel.mean())
    return col, low.astype(np.float32), pixel.astype(np.float32)


def estimate_fixed_pattern(
    frames: Any, *, max_frames: int = 256, clip_sigma: float = 5.0, remove_rows: bool = False
) -> FixedPattern:
    """Fixed pattern of a recording whose scene moves: a robust temporal mean of many frames.

    Averaged over frames spread along a long pass, what stays on the sensor stays and the scene
    averages to a smooth shading, as long as it has moved well beyond its own structure over the
    frames used (hundreds of pixels for a UAV pass at 3.8 px per frame). The mean is winsorised:
    deviations from the temporal median of the frames larger than ``clip_sigma`` times their
    robust spread (hot moving objects, dead frames) are clipped. The mean rather than the median:
    its estimation noise is smaller, and that noise, the same in every frame, pulls
    consecutive-frame registration toward zero motion (measured on a simulated 200-frame UAV pass
    over the aerial scene: 0.15 px corner error between consecutive frames with the mean, 0.22 px
    with the median of the same frames, 0.65 px with the median of 64 of them). Use it on a window
    of frames over which the camera's pattern does not drift; for a short burst (tens of pixels of
    motion) it keeps a ghost of the scene -- :func:`thermocal.registration.register_burst`
    refines it.

    Parameters
    ----------
    frames : array_like, shape (M, H, W)
        Raw frames (uint16 counts or float), ``M >= 3``; any indexable stack (numpy array,
        memory map, h5py dataset). Never modified.
    max_frames : int
        At most this many frames, evenly spaced over the stack, are used.
    clip_sigma : float
        Winsorisation threshold in robust standard deviations (``inf``: plain mean).
    remove_rows : bool
        Also remove row means from the per-pixel part (for a camera moving along its rows the
        scene's residue varies from row to row; the Tau2 has no row pattern).

    Returns
    -------
    FixedPattern

    Raises
    ------
    InvalidInputError
        Not a numeric ``(M, H, W)`` stack, fewer than 3 frames, NaN, bad options.
    """
    shape = getattr(frames, "shape", None)
    if shape is None:
        frames = np.asarray(frames)
        shape = frames.shape
    m = frames_layout(tuple(shape), getattr(frames, "dtype", np.float32), ndim=3,
                      min_frames=3)[0]
    if isinstance(max_frames, bool) or not isinstance(max_frames, int | np.integer) or (
        max_frames < 3
    ):
        raise InvalidInputError(f"max_frames: expected an integer >= 3, got {max_frames!r}")
    if not clip_sigma > 0:
        raise InvalidInputError(f"clip_sigma: expected a positive number, got {clip_sigma!r}")
    idx = np.unique(np.linspace(0, m - 1, min(m, int(max_frames))).round().astype(int))

    def frame(i: int) -> np.ndarray:
        f = np.asarray(frames[int(i)])
        if f.dtype.kind not in "biuf":
            raise InvalidInputError(f"frames: expected numbers, got dtype {f.dtype}")
        f = f.astype(np.float32)
        if not np.all(np.isfinite(f)):
            raise InvalidInputError(f"frames: frame {int(i)} contains NaN or infinite values")
        return f

    # robust centre and spread from at most 32 frames, then a running winsorised mean
    sub = np.stack([frame(i) for i in idx[:: max(1, len(idx) // 32)]])
    centre = np.median(sub, axis=0)
    spread = 1.4826 * float(np.median(np.abs(sub[:, ::4, ::4] - centre[::4, ::4])))
    limit = np.float32(clip_sigma * max(spread, 1e-6)) if np.isfinite(clip_sigma) else None
    acc = np.zeros(centre.shape, np.float64)
    for i in idx:
        dev = frame(i) - centre
        if limit is not None:
            np.clip(dev, -limit, limit, out=dev)
        acc += dev
    mean = (centre + acc / len(idx)).astype(np.float32)
    col, low, pixel = _split(mean, rows=bool(remove_rows))
    return FixedPattern(column=col, low=low, pixel=pixel, frames_used=len(idx))


def as_fixed_pattern(fixed_pattern: Any, shape: tuple[int, int]) -> FixedPattern:
    """``fixed_pattern`` (a :class:`FixedPattern` or an ``(H, W)`` array of counts) checked
    against the frame ``shape`` and returned as a :class:`FixedPattern`."""
    if isinstance(fixed_pattern, FixedPattern):
        fp = fixed_pattern
    else:
        arr = np.asarray(fixed_pattern, dtype=np.float32)
        if arr.ndim != 2:
            raise InvalidInputError(
                f"fixed_pattern: expected a FixedPattern or an (H, W) array, got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError("fixed_pattern: contains NaN or infinite values")
        zero = np.zeros(arr.shape, np.float32)
        fp = FixedPattern(column=zero[0].copy(), low=zero, pixel=arr - np.float32(arr.mean()))
    if fp.shape != shape:
        raise ResolutionMismatchError(
            f"fixed_pattern is {fp.shape[1]}x{fp.shape[0]} but the frames are "
            f"{shape[1]}x{shape[0]}"
        )
    return fp


# --------------------------------------------------------------------------------------------
# burst: joint estimate with the alignment
# --------------------------------------------------------------------------------------------


def initial_patterns(x: np.ndarray) -> dict[str, np.ndarray]:
    """Starting fixed patterns ``(H, W)`` for a burst ``x`` (float32 raw counts).

    ``"median"``: the temporal median (right for low-contrast scenes, where the scene's ghost in
    it is weak); ``"fine"``: its column part plus its structure finer than ``FINE_SIGMA_PX``
    (right for high-contrast scenes, whose ghost is coarse). For two frames, whose median is
    half of each scene, only the column pattern: ``"columns"``.
    """
    if len(x) < 3:
        cols = np.mean([_column_highpass(xi) for xi in x], axis=0)
        return {"columns": np.broadcast_to(cols, x.shape[1:]).astype(np.float32)}
    med = np.median(x, axis=0)
    col = np.median(x.mean(axis=1), axis=0)
    col = (col - col.mean())[None, :]
    rest = med - col
    fine = col + rest - cv2.GaussianBlur(rest, (0, 0), FINE_SIGMA_PX)
    return {
        "median": (med - med.mean()).astype(np.float32),
        "fine": (fine - fine.mean()).astype(np.float32),
    }


def _column_highpass(x: np.ndarray) -> np.ndarray:
    """Column means of one frame minus their smooth trend along the row, ``(1, W)``."""
    cm = x.mean(axis=0)[None, :].astype(np.float32)
    trend = cv2.GaussianBlur(cm, (0, 0), sigmaX=4.0, sigmaY=0.1, borderType=cv2.BORDER_REFLECT)
    return cm - trend


def _coverage(h: np.ndarray, shape: tuple[int, int], *, inverse: bool = False) -> np.ndarray:
    hh, w = shape
    flags = cv2.INTER_NEAREST | (cv2.WARP_INVERSE_MAP if inverse else 0)
    return cv2.warpPerspective(np.ones(shape, np.float32), h, (w, hh), flags=flags)


def _scene(x: np.ndarray, hs: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Average of the corrected frames on the pivot grid, and the number of frames per pixel."""
    n, hh, w = x.shape
    acc = np.zeros((hh, w), np.float32)
    cnt = np.zeros((hh, w), np.float32)
    for i in range(n):
        cov = _coverage(hs[i], (hh, w))
        acc += cv2.warpPerspective(
            x[i] - f, hs[i], (w, hh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        ) * cov
        cnt += cov
    return acc / np.maximum(cnt, 1.0), cnt


def back_projected_pattern(
    x: np.ndarray, hs: np.ndarray, f: np.ndarray, *, sweeps: int = 1
) -> np.ndarray:
    """Refine the fixed pattern ``f`` of burst ``x`` for frame → pivot homographies ``hs``.

    One sweep: the scene is the average of the corrected frames ``x_i − f`` on the pivot grid;
    the new pattern is the mean over frames of ``x_i − scene ∘ H_i`` where a frame sees the
    scene (``f`` is kept where none does). Repeated sweeps converge to the least-squares pattern
    for these homographies; two or three get most of the way.

    Parameters
    ----------
    x : numpy.ndarray, shape (N, H, W), float32
    hs : numpy.ndarray, shape (N, 3, 3)
    f : numpy.ndarray, shape (H, W), float32
    sweeps : int

    Returns
    -------
    numpy.ndarray, shape (H, W), float32, mean zero
    """
    n, hh, w = x.shape
    back_flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    for _ in range(sweeps):
        scene, cnt = _scene(x, hs, f)
        seen = (cnt > 0).astype(np.float32)
        facc = np.zeros((hh, w), np.float32)
        fcnt = np.zeros((hh, w), np.float32)
        for i in range(n):
            back = cv2.warpPerspective(scene, hs[i], (w, hh), flags=back_flags,
                                       borderMode=cv2.BORDER_REPLICATE)
            ok = cv2.warpPerspective(seen, hs[i], (w, hh),
                                     flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP)
            facc += (x[i] - back) * ok
            fcnt += ok
        out = np.where(fcnt > 0, facc / np.maximum(fcnt, 1.0), f)
        f = (out - out.mean()).astype(np.float32)
    return f


def joint_residual(x: np.ndarray, hs: np.ndarray, f: np.ndarray, *, highpass: float = 8.0) -> float:
    """Mean square misfit (counts²) of ``x_i ≈ scene ∘ H_i + f`` over pixels seen twice or more.

    Only structure finer than ``highpass`` (Gaussian sigma, pixels) counts: smooth patterns
    trade between the scene and ``f`` for any homographies. The right homographies explain every
    frame by one scene and one pattern; wrong ones leave the scene's edges in the misfit.
    """
    n, hh, w = x.shape
    scene, cnt = _scene(x, hs, f)
    seen = (cnt > 1).astype(np.float32)
    total = 0.0
    pixels = 0.0
    for i in range(n):
        back = cv2.warpPerspective(scene, hs[i], (w, hh), flags=cv2.INTER_LINEAR |
                                   cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)
        ok = cv2.warpPerspective(seen, hs[i], (w, hh),
                                 flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP)
        r = x[i] - f - back
        r -= cv2.GaussianBlur(r, (0, 0), highpass)
        total += float(np.sum(r * r * ok))
        pixels += float(ok.sum())
    return total / max(pixels, 1.0)
