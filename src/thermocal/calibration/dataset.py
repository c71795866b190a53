"""Chamber datasets for calibration: scene temperatures, FPA rate, stability classes, set points.

A chamber session (:mod:`thermocal.io.chamber`) is a blackbody at set points while the chamber's
ambient drifts. Before a fit, every frame gets

- the blackbody-equivalent (radiance) temperature of the scene, °C: the blackbody's emissivity
  ``ε`` (file attribute ``blackbody_emissivity``, default 1) and the ambient it reflects give
  ``L(T_scene) = ε·L(T_bb) + (1 − ε)·L(T_amb)``;
- the FPA rate, °C/min (Lin et al. eq. 3: central differences of the FPA temperature, here
  divided by the time step, optionally smoothed by a local linear fit over ``smooth_s``);
- a stability class (Lin et al. §2.1): 0 stable, 1 relatively stable (< 0.5 °C/min),
  2 unstable (> 0.5 °C/min);
- the set-point visit (block) it belongs to, and whether it is usable (settled blackbody).

Frames are read chunk by chunk (:func:`iter_frames`), so sessions larger than memory can be fitted;
saturated frames (:data:`thermocal._validate.SATURATED_FRACTION` of their pixels at 0 or the top
count) are excluded and counted.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import SATURATED_FRACTION, clipped_mask, surely_unclipped
from thermocal.camera.presets import preset_band
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FitError, InvalidInputError
from thermocal.io.chamber import ChamberSession, LazyFrames
from thermocal.radiometry import TAU2, BandRadiance

STABLE, RELATIVELY_STABLE, UNSTABLE = 0, 1, 2
STABILITY_NAMES = ("stable", "relatively stable", "unstable")


def as_session(session: Any) -> ChamberSession:
    """A :class:`ChamberSession` from a session, a chamber ``.h5`` or an EnvChamberCtrl ``.npz``.

    Files are opened lazily (frames read chunk by chunk when fitted).
    """
    if isinstance(session, ChamberSession):
        return session
    if isinstance(session, str | os.PathLike):
        from thermocal.io.chamber import read_chamber
        from thermocal.io.envchamber import import_envchamberctrl_npz

        path = Path(session)
        if path.suffix.lower() == ".npz":
            return import_envchamberctrl_npz(path)
        return read_chamber(path, frames=False)
    raise InvalidInputError(
        f"session: expected a ChamberSession or a chamber file path, got {type(session).__name__}"
    )


def fpa_rate_c_per_min(fpa_c: Any, time_s: Any, *, smooth_s: float = 0.0) -> np.ndarray:
    """Rate of change of the FPA temperature, °C/min, ``(M,)`` (Lin et al. eq. 3).

    Eq. 3 takes the forward difference at the first frame, the central difference
    ``(T[i+1] − T[i−1]) / 2`` inside and the backward difference at the last frame; here each is
    divided by its time step (``numpy.gradient`` over ``time_s``) so that the rate is in °C/min
    whatever the frame rate. With ``smooth_s > 0`` the rate is instead the slope of a local
    least-squares line over the frames within ``± smooth_s / 2`` (a quantised, noisy FPA sensor
    makes raw differences noisy).
    """
    fpa = np.asarray(fpa_c, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if fpa.shape != t.shape or fpa.ndim != 1:
        raise InvalidInputError(f"fpa_c {fpa.shape} and time_s {t.shape} must be equal (M,)")
    if fpa.size < 2:
        return np.zeros_like(fpa)
    if np.any(np.diff(t) <= 0):
        raise InvalidInputError("time_s must increase strictly from frame to frame")
    if smooth_s <= 0:
        return 60.0 * np.gradient(fpa, t)
    # Local linear regression with sums over a sliding window (vectorised with cumulative sums).
    t0 = t - t[0]
    lo = np.searchsorted(t0, t0 - smooth_s / 2, side="left")
    hi = np.searchsorted(t0, t0 + smooth_s / 2, side="right")
    c1 = np.concatenate([[0.0], np.cumsum(np.ones_like(t0))])
    ct = np.concatenate([[0.0], np.cumsum(t0)])
    ctt = np.concatenate([[0.0], np.cumsum(t0 * t0)])
    cf = np.concatenate([[0.0], np.cumsum(fpa - fpa[0])])
    ctf = np.concatenate([[0.0], np.cumsum(t0 * (fpa - fpa[0]))])
    n, st, stt = c1[hi] - c1[lo], ct[hi] - ct[lo], ctt[hi] - ctt[lo]
    sf, stf = cf[hi] - cf[lo], ctf[hi] - ctf[lo]
    den = n * stt - st * st
    raw = 60.0 * np.gradient(fpa, t)
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = 60.0 * (n * stf - st * sf) / den
    return np.where((n >= 3) & (den > 0), slope, raw)


def lagged_rate(rate_c_per_min: Any, time_s: Any, tau_s: float) -> np.ndarray:
    """The FPA rate seen through a first-order lag of time constant ``tau_s`` (s), °C/min,
    ``(M,)``: ``y' = (r − y) / τ``, exact for a rate held between frames, starting from the first
    frame's rate (a recording taken as begun at a steady pace).

    What lags the FPA by ``τ`` (optics or housing radiating onto it through their own heat
    capacity) differs from it by ``−τ·y`` °C: a term in ``y`` is what a calibration needs for
    them, where the rate itself covers only what follows the FPA at once (Lin et al. eq. 2).
    Written by hand: scipy's ``lfilter`` needs equal time steps, and frames seldom have them.
    """
    r = np.asarray(rate_c_per_min, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if r.shape != t.shape or r.ndim != 1:
        raise InvalidInputError(f"rate {r.shape} and time_s {t.shape} must be equal (M,)")
    if not tau_s > 0:
        raise InvalidInputError(f"the lag's time constant must be > 0 s, got {tau_s}")
    out = np.empty_like(r)
    if r.size == 0:
        return out
    keep = np.exp(-np.diff(t, prepend=t[0]) / tau_s)
    y = r[0]
    for k in range(r.size):
        y = keep[k] * y + (1.0 - keep[k]) * r[k]
        out[k] = y
    return out


def fpa_pace(rate_c_per_min: Any, time_s: Any, lag_s: float) -> np.ndarray:
    """How fast the FPA has been changing, °C/min ``(M,)``: the larger of its present rate's
    magnitude and that of the rate seen through a lag of ``lag_s`` s (:func:`lagged_rate`),
    each recording on its own (a time that does not increase starts one). A frame just after
    a change is not settled though its rate is 0: what lags the FPA is still catching up.
    """
    r, lagged = _rate_and_lagged(rate_c_per_min, time_s, lag_s)
    return np.maximum(np.abs(r), np.abs(lagged))


def fpa_change(rate_c_per_min: Any, time_s: Any, lag_s: float) -> np.ndarray:
    """How far the FPA's pace is from steady, °C/min ``(M,)``: ``|r − y|``, its present rate
    less that rate seen through a lag of ``lag_s`` s (:func:`lagged_rate`), each recording on
    its own (a time that does not increase starts one). Large just after the FPA started or
    stopped changing, when what lags it is furthest from where a steady pace would hold it."""
    r, lagged = _rate_and_lagged(rate_c_per_min, time_s, lag_s)
    return np.abs(r - lagged)


def _rate_and_lagged(rate_c_per_min: Any, time_s: Any, lag_s: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The rates ``(M,)`` °C/min and :func:`lagged_rate` of each recording among them (a time
    that does not increase starts one)."""
    r = np.asarray(rate_c_per_min, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if r.shape != t.shape or r.ndim != 1:
        raise InvalidInputError(f"rate {r.shape} and time_s {t.shape} must be equal (M,)")
    lagged = r.copy()
    starts = np.r_[0, np.flatnonzero(np.diff(t) <= 0) + 1, r.size]
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        if b > a:
            lagged[a:b] = lagged_rate(r[a:b], t[a:b], lag_s)
    return r, lagged


def still_time(fpa_c: Any, time_s: Any, *, band_c: float, max_gap_s: float) -> np.ndarray:
    """How long each frame's FPA had stayed within ``band_c`` (°C) of its present temperature,
    s ``(M,)``: ``t[i] − t[j]`` for the earliest frame ``j`` from which every frame up to ``i``
    lies within the band, its recording's start at most (a gap between frames longer than
    ``max_gap_s``, s, starts a recording: what the FPA did then is not known). ``fpa_c`` and
    ``time_s`` ``(M,)``, in time order.

    Written by hand (binary lifting over sparse tables of running maxima and minima, all frames
    at once: O(M log M)): no library finds, for every element, the longest run behind it within
    a band of its own value.
    """
    f = np.asarray(fpa_c, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if f.shape != t.shape or f.ndim != 1:
        raise InvalidInputError(f"fpa_c {f.shape} and time_s {t.shape} must be equal (M,)")
    if np.any(np.diff(t) < 0):
        raise InvalidInputError("time_s must not decrease from frame to frame")
    n = f.size
    if n == 0:
        return np.zeros(0)
    recording = np.cumsum(np.diff(t, prepend=t[0]) > max_gap_s)
    first = np.searchsorted(recording, recording)  # each frame's recording's first frame
    tables = [(f, f)]  # level p: max and min of f[k : k + 2**p]
    while 2 ** len(tables) <= n:
        half = 2 ** (len(tables) - 1)
        hi, lo = tables[-1]
        tables.append((np.maximum(hi[:-half], hi[half:]), np.minimum(lo[:-half], lo[half:])))
    start = np.arange(n)
    top, bottom = f.copy(), f.copy()  # max and min of f[start : i + 1]
    for p in range(len(tables) - 1, -1, -1):
        hi, lo = tables[p]
        cand = start - 2**p
        ok = cand >= first
        k = np.where(ok, cand, 0)
        new_top, new_bottom = np.maximum(top, hi[k]), np.minimum(bottom, lo[k])
        ok &= (new_top <= f + band_c) & (new_bottom >= f - band_c)
        start = np.where(ok, cand, start)
        top, bottom = np.where(ok, new_top, top), np.where(ok, new_bottom, bottom)
    return t - t[start]


def classify_stability(
    rate_c_per_min: Any, *, stable_c_per_min: float = 0.05, unstable_c_per_min: float = 0.5
) -> np.ndarray:
    """Stability class of each frame, int8 ``(M,)``: 0 stable, 1 relatively stable, 2 unstable.

    Lin et al. call a frame stable at 0 °C/min; a real sensor never reads exactly 0, so
    ``|rate| ≤ stable_c_per_min`` counts as stable.
    """
    rate = np.abs(np.asarray(rate_c_per_min, dtype=np.float64))
    out = np.full(rate.shape, RELATIVELY_STABLE, dtype=np.int8)
    out[rate <= stable_c_per_min] = STABLE
    out[rate > unstable_c_per_min] = UNSTABLE
    return out


def setpoint_blocks(blackbody_c: Any) -> np.ndarray:
    """Index of the set-point visit (run of equal consecutive set points) of each frame."""
    bb = np.asarray(blackbody_c, dtype=np.float64)
    if bb.size == 0:
        return np.zeros(0, dtype=np.int64)
    change = np.r_[False, np.abs(np.diff(bb)) > 1e-6]
    return np.cumsum(change).astype(np.int64)


def scene_temperature_c(
    session: ChamberSession, *, emissivity: float | None = None, band: BandRadiance = TAU2
) -> np.ndarray:
    """Blackbody-equivalent (radiance) temperature of the scene of each frame, °C, ``(M,)``.

    ``emissivity`` defaults to the file's ``blackbody_emissivity`` (1 when absent); the reflected
    surround is the chamber ambient (``ambient_c``; ``housing_c`` or the blackbody itself when
    the file has no ambient series).
    """
    eps = float(
        session.attrs.get("blackbody_emissivity", 1.0) if emissivity is None else emissivity
    )
    if not 0.0 < eps <= 1.0:
        raise InvalidInputError(f"blackbody emissivity must be in (0, 1], got {eps}")
    bb = np.asarray(session.blackbody_c, dtype=np.float64)
    if eps == 1.0:
        return bb.copy()
    surround = session.ambient_c if session.ambient_c is not None else session.housing_c
    if surround is None:
        surround = bb
    radiance = eps * band.radiance(bb + ZERO_CELSIUS_K) + (1.0 - eps) * band.radiance(
        np.asarray(surround, dtype=np.float64) + ZERO_CELSIUS_K
    )
    return band.temperature(radiance) - ZERO_CELSIUS_K


@dataclass(frozen=True, eq=False)
class ChamberData:
    """A chamber session prepared for fitting (all series ``(M,)``).

    Attributes
    ----------
    session : ChamberSession
    scene_c : ndarray
        Blackbody-equivalent scene temperature, °C.
    fpa_c, time_s : ndarray
        FPA sensor reading, °C; time, s.
    fpa_rate_c_per_min : ndarray
        Smoothed FPA rate, °C/min.
    stability : ndarray of int8
        0 stable, 1 relatively stable, 2 unstable.
    block : ndarray of int
        Set-point visit of each frame.
    usable : ndarray of bool
        Frames after the blackbody settled (``settle_frames`` dropped after each set-point change).
    """

    session: ChamberSession
    scene_c: np.ndarray
    fpa_c: np.ndarray
    time_s: np.ndarray
    fpa_rate_c_per_min: np.ndarray
    stability: np.ndarray
    block: np.ndarray
    usable: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.fpa_c.shape[0])

    @property
    def frame_shape(self) -> tuple[int, int]:
        return self.session.frame_shape

    @property
    def setpoints_c(self) -> np.ndarray:
        """The distinct blackbody set points of the usable frames, °C (sorted)."""
        return np.unique(np.round(self.session.blackbody_c[self.usable], 6))

    def summary(self) -> dict[str, Any]:
        """Counts of frames per stability class, set points and the FPA range (for reports)."""
        counts = np.bincount(self.stability, minlength=3)
        return {
            "frames": self.n_frames,
            "usable_frames": int(self.usable.sum()),
            "setpoints_c": [float(v) for v in self.setpoints_c],
            "fpa_range_c": [float(self.fpa_c.min()), float(self.fpa_c.max())],
            "max_fpa_rate_c_per_min": float(np.abs(self.fpa_rate_c_per_min).max()),
            **{f"{name} frames": int(c) for name, c in zip(STABILITY_NAMES, counts, strict=True)},
        }


#: Window of the local line that gives a chamber session's FPA rate, s (a quantised, noisy
#: sensor makes raw differences noisy).
RATE_SMOOTH_S = 60.0


def recording_still_time(fpa_c: Any, time_s: Any, *, band_c: float, max_gap_s: float
                         ) -> np.ndarray | None:
    """How long a recording's FPA had held within ``band_c`` (°C) of its present temperature at
    each frame, s ``(M,)``: :func:`still_time` of the FPA averaged over the frames within
    ``± RATE_SMOOTH_S / 2`` (as its rate is smoothed: one excursion of a quantised, noisy sensor
    would end a stretch, so that the figure would depend on the frame rate), a gap longer than
    ``max_gap_s`` (s) between frames ending a stretch. None without FPA temperatures and frame
    times that increase, or for a constant FPA series: one value given for the whole recording
    (``--fpa-c``), not measured, says nothing of how still the FPA was."""
    if fpa_c is None or time_s is None or len(fpa_c) < 2:
        return None
    f = np.asarray(fpa_c, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if f.shape != t.shape or f.ndim != 1 or np.any(np.diff(t) <= 0) or np.ptp(f) == 0:
        return None
    # the mean over each frame's window, from cumulative sums (as fpa_rate_c_per_min's slope)
    lo = np.searchsorted(t, t - RATE_SMOOTH_S / 2, side="left")
    hi = np.searchsorted(t, t + RATE_SMOOTH_S / 2, side="right")
    sums = np.concatenate([[0.0], np.cumsum(f - f[0])])
    mean = f[0] + (sums[hi] - sums[lo]) / (hi - lo)
    return still_time(mean, t, band_c=band_c, max_gap_s=max_gap_s)


def recording_fpa_rates(fpa_c: Any, time_s: Any, *, smooth_s: float = RATE_SMOOTH_S
                        ) -> np.ndarray | None:
    """A recording's FPA rate at each frame, °C/min, smoothed over ``smooth_s`` s (default a
    chamber session's, :data:`RATE_SMOOTH_S`: what a calibration's uncertainty depends on),
    ``(M,)``; None without FPA temperatures and frame times, for a recording shorter than the
    smoothing window (``smooth_s``, at most :data:`RATE_SMOOTH_S`: a quantised sensor over a few
    seconds cannot tell a steady FPA from one changing by a degree a minute), or with times
    that do not increase (then σ is that of all rates)."""
    if (fpa_c is None or time_s is None or len(fpa_c) < 2
            or np.ptp(time_s) < min(smooth_s, RATE_SMOOTH_S)):
        return None
    try:
        return fpa_rate_c_per_min(fpa_c, time_s, smooth_s=smooth_s)
    except InvalidInputError:
        return None


def prepare_chamber(
    session: Any,
    *,
    rate_smooth_s: float = RATE_SMOOTH_S,
    settle_frames: int = 0,
    stable_c_per_min: float = 0.05,
    unstable_c_per_min: float = 0.5,
    emissivity: float | None = None,
    band: BandRadiance | None = None,
) -> ChamberData:
    """Prepare a chamber session (or file) for fitting; reads no frames.

    Parameters
    ----------
    session : ChamberSession or path
        The session, a chamber ``.h5`` or an EnvChamberCtrl ``.npz``.
    rate_smooth_s : float
        Window of the local linear fit of the FPA rate, s (0: raw Lin eq. 3).
    settle_frames : int
        Frames dropped after each blackbody set-point change (the blackbody settling).
    stable_c_per_min, unstable_c_per_min : float
        Thresholds of the stability classes, °C/min.
    emissivity : float, optional
        Blackbody emissivity; default the file's ``blackbody_emissivity`` (or 1).
    band : BandRadiance, optional
        The camera's spectral band, for a grey blackbody's reflected surround; default its
        family's where the file names one (``attrs["preset"]``, as the simulator writes),
        else ``tau2``'s (:func:`~thermocal.camera.presets.preset_band`).
    """
    if isinstance(session, ChamberData):
        return session
    s = as_session(session)
    if settle_frames < 0:
        raise InvalidInputError(f"settle_frames must be >= 0, got {settle_frames}")
    fpa = np.asarray(s.fpa_c, dtype=np.float64)
    t = np.asarray(s.time_s, dtype=np.float64)
    rate = fpa_rate_c_per_min(fpa, t, smooth_s=rate_smooth_s)
    block = setpoint_blocks(s.blackbody_c)
    first = np.r_[0, np.flatnonzero(np.diff(block)) + 1]
    pos = np.arange(block.size) - first[block]
    usable = pos >= settle_frames
    return ChamberData(
        session=s,
        scene_c=scene_temperature_c(
            s, emissivity=emissivity,
            band=preset_band(s.attrs.get("preset")) if band is None else band),
        fpa_c=fpa,
        time_s=t,
        fpa_rate_c_per_min=rate,
        stability=classify_stability(
            rate, stable_c_per_min=stable_c_per_min, unstable_c_per_min=unstable_c_per_min
        ),
        block=block,
        usable=usable,
        info={"rate_smooth_s": rate_smooth_s, "settle_frames": settle_frames,
              "stable_c_per_min": stable_c_per_min, "unstable_c_per_min": unstable_c_per_min},
    )


FRAME_SELECTIONS = ("stable", "settled", "all")


def stability_mask(data: ChamberData, frames: str) -> np.ndarray:
    """Frames to fit by FPA stability: ``"stable"``, ``"settled"`` (not unstable) or ``"all"``."""
    if frames == "stable":
        return data.stability == STABLE
    if frames == "settled":
        return data.stability != UNSTABLE
    if frames == "all":
        return np.ones(data.n_frames, dtype=bool)
    raise InvalidInputError(f"frames={frames!r}: choose from {', '.join(FRAME_SELECTIONS)}")


def describe_frames(data: ChamberData, frames: str) -> str:
    """Words for a frame selection of :func:`stability_mask` (``"stable"``, ...), with its
    threshold, for messages."""
    stable = float(data.info.get("stable_c_per_min", 0.05))
    unstable = float(data.info.get("unstable_c_per_min", 0.5))
    return {"stable": f"the stable frames (FPA rate within ±{stable:g} °C/min)",
            "settled": f"the settled frames (FPA rate within ±{unstable:g} °C/min)",
            "all": "the frames"}.get(frames, f"the {frames} frames")


def setpoints_of(data: ChamberData, mask: np.ndarray | None = None) -> np.ndarray:
    """The distinct blackbody set points of the usable frames in ``mask``, °C (sorted)."""
    sel = data.usable if mask is None else (data.usable & mask)
    return np.unique(np.round(data.session.blackbody_c[sel], 6))


def require_setpoints(
    data: ChamberData, n: int, method: str, mask: np.ndarray | None = None, *,
    frames: str = "the chamber data", record: str = "record more",
) -> None:
    """Raise :class:`FitError` unless the frames in ``mask`` cover at least ``n`` set points.

    ``frames`` names the frames of ``mask`` in the message, ``record`` says what to record.
    """
    found = setpoints_of(data, mask)
    if found.size < n:
        total = data.setpoints_c.size
        of = f" of the session's {total}" if total > found.size else ""
        raise FitError(
            f"{method} needs blackbody frames at >= {n} different set points, {frames} give "
            f"{found.size}{of} ({', '.join(f'{v:g}' for v in found) or 'none'} °C); {record}"
        )


#: Largest condition number of the normalised Vandermonde matrix of the FPA temperatures that a
#: polynomial fit in the FPA temperature accepts: 4 well-spread levels or a ramp give 6-8, the
#: frames at the two ends of a sawtooth or 3 plateaus for a cubic give 30-500.
MAX_FPA_CONDITION = 25.0


def fpa_condition(fpa_c: np.ndarray, degree: int) -> float:
    """Condition number of the normalised Vandermonde matrix of degree ``degree`` of the FPA
    temperatures ``fpa_c`` (°C, ``(K,)``): how well they determine a polynomial in them (inf
    for fewer distinct values than coefficients)."""
    fpa = np.asarray(fpa_c, dtype=np.float64)
    if fpa.size <= degree or np.ptp(fpa) == 0:
        return math.inf
    x = (fpa - fpa.mean()) / fpa.std()
    sv = np.linalg.svd(np.vander(x, degree + 1, increasing=True) / np.sqrt(x.size),
                       compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf


def require_fpa_span(data: ChamberData, span_c: float, method: str,
                     mask: np.ndarray | None = None, *, degree: int = 1,
                     frames: str = "the chamber data",
                     record: str = "record while the chamber's ambient changes") -> None:
    """Raise :class:`FitError` unless the FPA temperatures in ``mask`` span ``span_c`` °C and
    are spread over enough distinct levels for a polynomial of ``degree`` in them.

    ``frames`` names the frames of ``mask`` in the message, ``record`` says what to record.
    """
    sel = data.usable if mask is None else (data.usable & mask)
    fpa = data.fpa_c[sel]
    got = float(fpa.max() - fpa.min()) if fpa.size else 0.0
    whole = data.fpa_c[data.usable]
    total = float(np.ptp(whole)) if whole.size else 0.0
    of = f" of the session's {total:.2f} °C" if total > got + 0.5 else ""
    if got < span_c:
        raise FitError(
            f"{method} needs FPA temperatures spanning >= {span_c:g} °C, {frames} span "
            f"{got:.2f} °C{of}; {record}"
        )
    cond = fpa_condition(fpa, degree)
    if cond > MAX_FPA_CONDITION:
        raise FitError(
            f"{method} needs the FPA at >= {degree + 1} well-spread temperatures, but {frames} "
            f"hold it at fewer (condition {min(cond, 1e300):.0f}); record while the ambient "
            "passes through more levels, or fit frames='settled'"
        )


@dataclass
class FrameScan:
    """Saturation bookkeeping while frames stream by: clipped pixels per frame and per pixel."""

    shape: tuple[int, int]
    bit_depth: int = 14
    clipped_per_pixel: np.ndarray = field(init=False)
    excluded: list[int] = field(default_factory=list)
    n_seen: int = 0

    def __post_init__(self) -> None:
        self.clipped_per_pixel = np.zeros(self.shape, dtype=np.int64)

    def check(self, index: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """Return a bool ``(k,)`` of frames to keep; saturated frames (more than
        :data:`~thermocal._validate.SATURATED_FRACTION` of their pixels clipped) are recorded as
        excluded."""
        k = len(frames)
        flat = frames.reshape(k, -1)
        size = flat.shape[1]
        if surely_unclipped(flat, self.bit_depth):  # nothing to count
            self.n_seen += k
            return np.ones(k, dtype=bool)
        where = np.flatnonzero(clipped_mask(flat, self.bit_depth))
        # few pixels clip: count where they are rather than sum every pixel of every frame
        frame_of, pixel_of = np.divmod(where, size)
        keep = np.bincount(frame_of, minlength=k) / size <= SATURATED_FRACTION
        self.clipped_per_pixel += np.bincount(
            pixel_of[keep[frame_of]], minlength=self.clipped_per_pixel.size).reshape(self.shape)
        self.excluded.extend(int(i) for i in index[~keep])
        self.n_seen += int(keep.sum())
        return keep

    def saturated_pixels(self) -> np.ndarray:
        """Pixels clipped in more than half of the kept frames (stuck hot or dead), ``(H, W)``."""
        return self.clipped_per_pixel > 0.5 * max(self.n_seen, 1)

    def report(self) -> dict[str, Any]:
        return {
            "excluded_frames": len(self.excluded),
            "excluded_frame_indices": self.excluded[:50],
            "saturated_pixels": int(self.saturated_pixels().sum()),
        }


def iter_frames(
    session: ChamberSession, index: np.ndarray | None = None, *, chunk: int = 64,
    rows: np.ndarray | None = None,
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Yield ``(indices, frames)`` blocks of at most ``chunk`` frames (uint16 ``(k, H, W)``;
    with ``rows``, increasing row indices, only those rows: ``(k, R, W)``).

    ``index`` (sorted frame indices) restricts the frames read; lazily stored frames are read
    from the file block by block, the next one while the caller works on this one (two blocks
    in memory at most).
    """
    frames = session.frames
    n = session.n_frames
    idx = np.arange(n) if index is None else np.asarray(index, dtype=np.int64)
    if idx.size == 0:
        return
    blocks = [idx[start : start + chunk] for start in range(0, idx.size, chunk)]
    if isinstance(frames, LazyFrames):  # the next block is read while this one is used
        def read(sel: np.ndarray) -> np.ndarray:
            return frames[sel] if rows is None else frames.read_rows(sel, rows)

        with ThreadPoolExecutor(max_workers=1) as reader:
            ahead = reader.submit(read, blocks[0])
            for k, sel in enumerate(blocks):
                block = ahead.result()
                if k + 1 < len(blocks):
                    ahead = reader.submit(read, blocks[k + 1])
                yield sel, block
        return
    for sel in blocks:
        contiguous = sel[-1] - sel[0] + 1 == sel.size
        block = frames[sel[0] : sel[-1] + 1] if contiguous else frames[sel]
        yield sel, (block if rows is None else block[:, rows])


def group_means(
    data: ChamberData, groups: np.ndarray, n_groups: int, *, chunk: int = 64,
    scan: FrameScan | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Mean frame of each group, float64 ``(n_groups, H, W)``, and frames per group ``(n_groups,)``.

    ``groups[m]`` is the group of frame ``m`` (``-1``: not used). Saturated frames are left out.
    """
    groups = np.asarray(groups, dtype=np.int64)
    h, w = data.frame_shape
    sums = np.zeros((n_groups, h, w), dtype=np.float64)
    counts = np.zeros(n_groups, dtype=np.int64)
    scan = scan or FrameScan((h, w), data.session.bit_depth)
    used = np.flatnonzero(groups >= 0)
    for idx, block in iter_frames(data.session, used, chunk=chunk):
        keep = scan.check(idx, block)
        g = groups[idx][keep]
        block = block[keep]
        for gi in np.unique(g):  # a loop over groups (a few), never over pixels
            sel = g == gi
            sums[gi] += block[sel].sum(axis=0, dtype=np.float64)
            counts[gi] += int(sel.sum())
    if np.any(counts == 0):
        raise FitError(
            f"{int(np.sum(counts == 0))} set point(s) have no usable frame (all saturated?); "
            "record them again"
        )
    return sums / counts[:, None, None], counts
