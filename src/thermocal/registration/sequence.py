"""Registering a long recording frame by frame: each frame to the one before it.

For a recording of thousands of frames (a UAV pass at 3.8 px of motion per frame) the fixed
pattern is estimated from the recording itself -- the temporal median over a long window, where
the scene has moved far (:func:`~thermocal.registration.fixed_pattern.estimate_fixed_pattern`)
-- and removed; consecutive frames then overlap by 95 % or more and are aligned quickly:

1. **candidates**: the motion of the previous pair (a camera moves smoothly) and the two
   strongest phase-correlation peaks at half resolution;
2. **ECC** (``cv2.findTransformECC``, affine) at half resolution from the candidates (a few
   iterations each, the best continuing), then at full resolution. The previous pair's motion
   goes on alone when its first iterations already correlate at :data:`PREDICTION_ACCEPT`:
   the peaks are sought only when the motion changed.

Frame → pivot homographies for a burst inside the recording compose the chain
(:meth:`SequenceRegistration.to_pivot`); their error grows with the distance to the pivot (see
``benchmarks/registration.py``).

A pair whose correlation stays below :data:`MIN_CORRELATION` or whose homography is degenerate is
flagged (``ok`` False), not dropped: :meth:`SequenceRegistration.to_pivot` refuses to compose
through it.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

import numpy as np

import thermocal.registration._dense as dense
from thermocal._validate import check_frame_index, frames_layout
from thermocal.errors import InvalidInputError, RegistrationError
from thermocal.registration.features import MIN_FRAME_PX, check_homography
from thermocal.registration.fixed_pattern import (
    FixedPattern,
    as_fixed_pattern,
    estimate_fixed_pattern,
)
from thermocal.registration.warp import translation

__all__ = ["MIN_CORRELATION", "PREDICTION_ACCEPT", "SEGMENT_FRAMES", "SequenceRegistration",
           "register_sequence"]

#: Lowest ECC correlation accepted between consecutive FPN-corrected frames.
MIN_CORRELATION = 0.5
#: Frames per block that share one fixed-pattern estimate (when it is estimated here).
BLOCK_FRAMES = 512
#: Consecutive pairs registered in order, each pair's motion predicting the next; the segments
#: are the unit of parallel work. Fixed (not the number of workers), so that the homographies do
#: not depend on the machine.
SEGMENT_FRAMES = 128

_LEVEL = 1  # pyramid level of the coarse alignment
_HIGHPASS = 12.0  # px at that level
_BLUR = 1.0  # px at full resolution
_PEAKS = 2
#: Correlation at which the previous pair's motion, after its first ECC rounds at half
#: resolution, is taken without racing the phase-correlation peaks (a camera moves smoothly: on
#: the registration benchmark's UAV passes consecutive frames correlate at 0.997 or more, and
#: the race changed no homography by more than 0.01 px while costing a third of the time).
PREDICTION_ACCEPT = 0.9
_RACE = 5
_COARSE_ITERATIONS = 20
_FINE_ITERATIONS = 10


@dataclass(frozen=True, eq=False)
class SequenceRegistration:
    """Frame-to-previous homographies of a recording.

    Attributes
    ----------
    to_previous : numpy.ndarray, shape (M, 3, 3), float64
        Pixel ``(x, y)`` of frame ``k`` → pixel of frame ``k − 1``, ``h33 = 1``; the identity for
        ``k = 0``.
    correlation : numpy.ndarray, shape (M,), float64
        ECC correlation of FPN-corrected frame ``k`` with frame ``k − 1`` (1 for ``k = 0``; NaN
        for a pair not registered, see :func:`register_sequence`'s ``pairs``).
    ok : numpy.ndarray, shape (M,), bool
        Whether ``to_previous[k]`` is trusted: registered, correlation at least
        :data:`MIN_CORRELATION` and a plausible homography (True for ``k = 0``).
    fixed_pattern : FixedPattern
        The fixed-pattern estimate removed before aligning (the first block's when it was
        estimated block by block, see ``patterns``).
    patterns : tuple of FixedPattern
        One estimate per block of ``block`` frames (a single one when it was given).
    block : int
        Frames per block of ``patterns``.
    """

    to_previous: np.ndarray
    correlation: np.ndarray
    ok: np.ndarray
    fixed_pattern: FixedPattern
    patterns: tuple[FixedPattern, ...] = ()
    block: int = BLOCK_FRAMES

    def __len__(self) -> int:
        return len(self.to_previous)

    def chained_to(self, pivot: int) -> tuple[np.ndarray, np.ndarray]:
        """Every frame's homography to frame ``pivot`` at once, and which frames reach it.

        Returns
        -------
        homographies : numpy.ndarray, shape (M, 3, 3), float64
            Frame → pivot, composed along the chain (``h33 = 1``; meaningless where not
            ``reachable``). One pass over the chain, where :meth:`to_pivot` composes each
            frame's own.
        reachable : numpy.ndarray, shape (M,), bool
            No failed pair (``ok`` False) lies between the frame and the pivot.
        """
        m = len(self.to_previous)
        p = check_frame_index(pivot, m, within="the recording")
        chain = np.repeat(np.eye(3)[None], m, axis=0)  # frame k → frame 0
        for k in range(1, m):
            chain[k] = chain[k - 1] @ self.to_previous[k]
        homographies = np.linalg.inv(chain[p]) @ chain
        homographies /= homographies[:, 2:, 2:]
        failed = np.cumsum(~np.asarray(self.ok, bool))  # failed pairs up to each frame
        return homographies, failed == failed[p]

    def to_pivot(self, indices: Any, pivot: int) -> np.ndarray:
        """Homographies of frames ``indices`` to frame ``pivot``, composed along the chain.

        Parameters
        ----------
        indices : int or sequence of int
            Frame indices (any order, may include ``pivot``).
        pivot : int
            Index of the pivot frame.

        Returns
        -------
        numpy.ndarray, shape (n, 3, 3), float64
            ``H_i``: pixel of frame ``indices[i]`` → pixel of the pivot; the pivot's own is the
            identity. For ``i > pivot`` it is ``P[pivot+1] @ ... @ P[i]`` with ``P`` =
            ``to_previous``; for ``i < pivot`` the inverse of ``P[i+1] @ ... @ P[pivot]``.

        Raises
        ------
        RegistrationError
            The chain between a frame and the pivot passes through a pair that failed (``ok``
            False); the message names it.
        InvalidInputError
            An index outside the recording.
        """
        m = len(self.to_previous)
        idx = np.atleast_1d(np.asarray(indices))
        if idx.dtype.kind not in "iu" or idx.ndim != 1:
            raise InvalidInputError(f"indices: expected frame indices, got {indices!r}")
        for v in idx.tolist():
            check_frame_index(v, m, "frame", within="the recording")
        p = check_frame_index(pivot, m, within="the recording")
        out = np.empty((len(idx), 3, 3))
        for n, i in enumerate(idx.tolist()):
            lo, hi = min(i, p), max(i, p)
            bad = [k for k in range(lo + 1, hi + 1) if not self.ok[k]]
            if bad:
                k = bad[0]
                cc = self.correlation[k]
                why = ("that pair was not asked for" if np.isnan(cc) else
                       f"ECC correlation {cc:.2f}")
                raise RegistrationError(
                    f"frame {i} cannot be composed onto pivot {p}: frame {k} was not registered "
                    f"to frame {k - 1} ({why})"
                )
            h = np.eye(3)
            for k in range(lo + 1, hi + 1):
                h = h @ self.to_previous[k]
            if i < p:
                h = np.linalg.inv(h)
            out[n] = h / h[2, 2]
        return out


def _check_stack(frames: Any) -> tuple[Any, tuple[int, int, int]]:
    """A ``(M, H, W)`` recording (lazy ones are not read) and its shape; M >= 2 frames of at
    least :data:`~thermocal.registration.features.MIN_FRAME_PX` on a side."""
    shape = getattr(frames, "shape", None)
    dtype = getattr(frames, "dtype", None)
    if shape is None or dtype is None:
        frames = np.asarray(frames)
        shape, dtype = frames.shape, frames.dtype
    return frames, frames_layout(tuple(shape), dtype, ndim=3, min_frames=2,
                                 min_size=MIN_FRAME_PX)


class _Prepared:
    """A frame with its pattern removed, at half and at full resolution (ECC-ready)."""

    __slots__ = ("coarse", "fine")

    def __init__(self, frame: np.ndarray, pattern: np.ndarray) -> None:
        x = np.asarray(frame).astype(np.float32) - pattern
        if not np.all(np.isfinite(x)):
            raise InvalidInputError("frames: contain NaN or infinite values")
        self.fine = dense.prepare(x, blur=_BLUR)
        self.coarse = dense.prepare(dense.pyr_down(x, _LEVEL), highpass=_HIGHPASS)


def _pair(
    moving: _Prepared, fixed: _Prepared, prediction: np.ndarray | None, window: np.ndarray
) -> tuple[np.ndarray, float]:
    """Frame → previous frame: ``(h, correlation)``. The prediction's first ECC rounds at
    :data:`PREDICTION_ACCEPT` or above: it goes on alone; else it races the phase-correlation
    peaks (from its start again: those frames are aligned as before the shortcut)."""
    h = None
    if prediction is not None:
        raced, cc = dense.ecc(moving.coarse, fixed.coarse, dense.to_level(prediction, _LEVEL),
                              iterations=_RACE)
        if cc >= PREDICTION_ACCEPT:  # it goes on alone
            h = raced
            more = dense.ecc(moving.coarse, fixed.coarse, h,
                             iterations=_COARSE_ITERATIONS - _RACE)
            if more[1] > -1.0:
                h, cc = more
    if h is None:
        cands = [] if prediction is None else [dense.to_level(prediction, _LEVEL)]
        cands += [translation(dx, dy) for dx, dy in
                  dense.phase_peaks(moving.coarse, fixed.coarse, window, count=_PEAKS)]
        h, cc = dense.best_of(moving.coarse, fixed.coarse, cands,
                              iterations=_COARSE_ITERATIONS, race=_RACE)
    if h is None or cc <= -1.0:
        return np.eye(3), -1.0
    h = dense.from_level(h, _LEVEL)
    fine, fine_cc = dense.ecc(moving.fine, fixed.fine, h, iterations=_FINE_ITERATIONS)
    if fine_cc > -1.0:
        return fine, fine_cc
    return h, cc


def register_sequence(
    frames: Any,
    *,
    fixed_pattern: Any = None,
    block: int = BLOCK_FRAMES,
    workers: int | None = None,
    progress: Callable[[int], None] | None = None,
    pairs: Any = None,
) -> SequenceRegistration:
    """Register every frame of a recording to the frame before it (or only the pairs asked for).

    Parameters
    ----------
    frames : array_like, shape (M, H, W)
        Raw frames (uint16 counts or float), ``M >= 2``; any indexable stack (numpy array,
        memory map, h5py dataset), read a block at a time. Never modified.
    fixed_pattern : FixedPattern or array_like (H, W), optional
        The fixed pattern to remove (counts). None estimates it block by block from the
        recording (:func:`~thermocal.registration.fixed_pattern.estimate_fixed_pattern` over a
        window of ``block`` frames around each block); that needs the scene to move far within a
        block, as it does on a UAV pass.
    block : int
        Frames per block (one pattern estimate each).
    workers : int, optional
        Threads that register the segments of :data:`SEGMENT_FRAMES` frames in parallel
        (default: up to 2, the CPU count); the homographies do not depend on it.
    progress : callable, optional
        Called with the number of frames done after each block.
    pairs : array_like of bool, shape (M,), optional
        Which pairs to register: ``pairs[k]``, frame ``k`` to frame ``k − 1`` (None: every
        pair). A pair not asked for is left as the identity, ``ok`` False and correlation NaN
        (:meth:`SequenceRegistration.to_pivot` refuses to compose through it); a frame no pair
        asked for is not prepared. The pairs asked for are aligned as in a full run, the
        previous registered pair's motion predicting each (a camera moves smoothly), so their
        homographies differ from a full run's only by where ECC starts.

    Returns
    -------
    SequenceRegistration

    Raises
    ------
    InvalidInputError
        Not a numeric ``(M, H, W)`` stack, fewer than 2 frames, NaN, a bad pattern or block.
    ResolutionMismatchError
        A fixed pattern of another size than the frames.
    """
    frames, (m, hh, w) = _check_stack(frames)
    if isinstance(block, bool) or not isinstance(block, int | np.integer) or block < 2:
        raise InvalidInputError(f"block: expected an integer >= 2, got {block!r}")
    block = int(block)
    n_workers = dense.check_workers(workers)
    wanted = _pairs_mask(pairs, m)
    starts = list(range(0, m, block))
    if fixed_pattern is not None:
        given = as_fixed_pattern(fixed_pattern, (hh, w))
        patterns = [given] * len(starts)
    else:
        if m < 3:
            raise InvalidInputError(
                "frames: two frames are too few to estimate the fixed pattern; pass fixed_pattern"
            )
        patterns = []
        for s in starts:
            lo = max(0, min(s - block // 2, m - 2 * block))
            hi = min(m, lo + 2 * block)
            patterns.append(estimate_fixed_pattern(_Window(frames, lo, hi)))

    to_prev = np.repeat(np.eye(3)[None], m, axis=0)
    corr = np.where(wanted, 1.0, np.nan)
    ok = wanted.copy()
    window = dense.hanning(((hh + 1) // 2, (w + 1) // 2))

    # segments of at most SEGMENT_FRAMES frames within the blocks: (start, end, block)
    segments = [(a, min(a + SEGMENT_FRAMES, s + block, m), b) for b, s in enumerate(starts)
                for a in range(s, min(s + block, m), SEGMENT_FRAMES)]

    def run_segment(seg: tuple[int, int, int]) -> int:
        s, e, b = seg
        pat = patterns[b].pattern
        prev, prediction = None, None  # prev: frame k − 1 prepared, when it was
        for k in range(max(1, s), e):
            if not wanted[k]:
                prev = None
                continue
            if prev is None:
                prev = _Prepared(frames[k - 1], pat)
            cur = _Prepared(frames[k], pat)
            h, cc = _pair(cur, prev, prediction, window)
            good = cc >= MIN_CORRELATION
            if good:
                try:
                    h = check_homography(h, (w, hh), f"frame {k} (to frame {k - 1})")
                except RegistrationError:
                    good = False
            to_prev[k], corr[k], ok[k] = h, cc, good
            prediction = h if good else None
            prev = cur
        return e - s

    if n_workers <= 1 or len(segments) == 1:
        for seg in segments:
            done = run_segment(seg)
            if progress is not None:
                progress(done)
    else:
        with ThreadPoolExecutor(max_workers=min(n_workers, len(segments))) as pool:
            for fut in as_completed([pool.submit(run_segment, seg) for seg in segments]):
                done = fut.result()
                if progress is not None:
                    progress(done)
    to_prev[0] = np.eye(3)
    corr[0], ok[0] = 1.0, True
    return SequenceRegistration(
        to_previous=to_prev, correlation=corr, ok=ok, fixed_pattern=patterns[0],
        patterns=tuple(patterns), block=block,
    )


def _pairs_mask(pairs: Any, m: int) -> np.ndarray:
    """``pairs`` (None: all) as a bool mask of the ``m`` frames' pairs to register."""
    if pairs is None:
        return np.ones(m, dtype=bool)
    mask = np.asarray(pairs)
    if mask.dtype != bool or mask.shape != (m,):
        raise InvalidInputError(f"pairs: expected {m} booleans (one per frame), got "
                                f"{mask.dtype} of shape {mask.shape}")
    return mask


class _Window:
    """Frames ``lo … hi − 1`` of an indexable stack, indexable from 0 (no copy)."""

    def __init__(self, frames: Any, lo: int, hi: int) -> None:
        self.frames, self.lo = frames, lo
        self.shape = (hi - lo, *tuple(frames.shape[1:]))

    def __getitem__(self, i: int) -> np.ndarray:
        return np.asarray(self.frames[self.lo + int(i)])
