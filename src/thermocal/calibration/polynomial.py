"""Per-pixel polynomial model (Nugent et al. 2013; Oz et al. eq. 13–18) and its radial fit.

Per pixel p (Oz et al. eq. 13, with the FPA temperature for the ambient, expanded around
``t_ref_c`` for conditioning, ``Δ = t_fpa − t_ref_c``)::

    I_p = Σ_{i=0}^{3} g_{i,p} · Δ^i · S(T_scene) + Σ_{i=0}^{3} d_{i,p} · Δ^i

The scene term ``S`` is selectable: ``"t4"`` = ``T⁴`` with ``T`` in K (the paper), ``"linear"``
= ``T`` in °C, ``"radiance"`` = band radiance ``L(T)`` in W·m⁻²·sr⁻¹ (then ``g``/``d`` are the
:class:`~thermocal.camera.model.CameraModel` gain/offset cubics). Every pixel shares one design
matrix (the blackbody is uniform), so the least-squares problem (eq. 14–15) is solved for all
pixels at once from normal equations accumulated chunk by chunk over the frames: memory is bounded
by one chunk, whatever the session length. Inversion to temperature is closed form per term.

The radial fit (eq. 16–17) replaces each coefficient map by a polynomial in the distance ``R``
from the frame centre (axes −0.5…0.5): a low-frequency, unit-independent model (no FPN, no
defects) used to make the network's training data (:func:`camera_model_from_chamber`).
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.calibration.base import (
    band_for,
    calibration_info,
    check_frames,
    fill_bad_pixels,
    require_fpa,
    robust_outliers,
    warn_outside_range,
)
from thermocal.calibration.dataset import (
    ChamberData,
    FrameScan,
    describe_frames,
    iter_frames,
    prepare_chamber,
    require_fpa_span,
    require_setpoints,
    stability_mask,
)
from thermocal.calibration.store import (
    FPA_LIMITS_C,
    FileLayout,
    StoredCalibration,
    StoredCalibrationMixin,
    check_band,
    check_offsets,
    check_response,
    check_scalar,
    damaged,
)
from thermocal.camera.model import horner
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.cores import available_cores
from thermocal.errors import FitError, InvalidInputError
from thermocal.radiometry import BandRadiance

METHOD = "polynomial"
SCENE_TERMS = ("t4", "linear", "radiance")
ORDER = 3


def scene_term(temp_c: Any, kind: str, band: BandRadiance) -> np.ndarray:
    """The scene term ``S(T)`` of the model for temperatures in °C (float64)."""
    t = np.asarray(temp_c, dtype=np.float64)
    if kind == "t4":
        return (t + ZERO_CELSIUS_K) ** 4
    if kind == "linear":
        return t.copy()
    if kind == "radiance":
        return np.asarray(band.radiance(t + ZERO_CELSIUS_K), dtype=np.float64)
    raise InvalidInputError(f"unknown scene term {kind!r}; choose from {', '.join(SCENE_TERMS)}")


@dataclass(frozen=True, eq=False)
class PolynomialCalibration(StoredCalibrationMixin):
    """The fitted per-pixel polynomial model.

    Attributes
    ----------
    gain, offset : (4, H, W) float32
        ``g_i`` (counts per unit of the scene term) and ``d_i`` (counts), coefficients of
        ``Δ^i``, ``Δ = t_fpa − t_ref_c`` in °C.
    bad : (H, W) bool
        Pixels whose fit is unusable (defects, outliers); filled from their neighbours.
    residual_rms : (H, W) float32
        RMS residual of the fit, counts.
    t_ref_c : float
        Expansion point of the FPA polynomials, °C.
    scene_term : {"t4", "linear", "radiance"}
    fpa_range_c : (float, float)
        FPA temperatures covered by the fit, °C.
    radial_coefficients : (8, M+1) array or None
        For a radial model: ``m_j`` of each map (gain rows first), as in Oz et al. eq. 17.
    """

    gain: np.ndarray
    offset: np.ndarray
    bad: np.ndarray
    residual_rms: np.ndarray
    t_ref_c: float
    scene_term: str
    fpa_range_c: tuple[float, float]
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    radial_coefficients: np.ndarray | None = None
    radial_centre: tuple[float, float] = (0.0, 0.0)
    info: dict[str, Any] = field(default_factory=dict)

    method = METHOD
    _layout = FileLayout(
        methods=(METHOD,),
        arrays={"gain": np.float32, "offset": np.float32, "bad": bool,
                "residual_rms": np.float32},
        metadata={"t_ref_c": float, "scene_term": str, "band_m": tuple, "radial_centre": tuple},
        optional_arrays=("radial_coefficients",), optional_metadata=("radial_centre",),
        stacks={"gain": ORDER + 1, "offset": ORDER + 1},
    )

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape ``(H, W)``."""
        return self.bad.shape  # type: ignore[return-value]

    @property
    def band(self) -> BandRadiance:
        return band_for(tuple(self.band_m))

    def expected_counts(self, scene_c: Any, fpa_c: float) -> np.ndarray:
        """Model output (counts, float32 ``(H, W)``) for a scene (°C, scalar or ``(H, W)``)."""
        s = scene_term(scene_c, self.scene_term, self.band).astype(np.float32)
        dt = float(fpa_c) - self.t_ref_c
        return horner(self.gain, dt) * s + horner(self.offset, dt)

    def apply(self, frames: Any, *, fpa_c: Any = None, time_s: Any = None) -> np.ndarray:
        """Scene temperature, °C, float32 ``(N, H, W)``, from raw counts and the FPA temperature.

        Parameters
        ----------
        frames : (N, H, W) or (H, W) raw counts
        fpa_c : float or (N,) array
            FPA temperature of each frame, °C (required).
        time_s : ignored
        """
        counts = check_frames(frames, self.shape)
        fpa = require_fpa(fpa_c, len(counts), METHOD)
        warn_outside_range(fpa, self.fpa_range_c, METHOD)
        n = len(counts)
        out = np.empty(counts.shape, dtype=np.float32)
        pixels = out[0].size if n else 0
        gain = self.gain.reshape(ORDER + 1, -1).astype(np.float32, copy=False)
        offset = self.offset.reshape(ORDER + 1, -1).astype(np.float32, copy=False)
        powers = (np.asarray(fpa, dtype=np.float64)[:, None] - self.t_ref_c) ** np.arange(
            ORDER + 1)  # (N, 4): the FPA polynomials of many frames as one product
        flat = out.reshape(n, pixels)
        step = max(1, _APPLY_BLOCK // max(pixels, 1))
        for a in range(0, n, step):  # blocks of frames: bounded memory, few Python steps
            p = powers[a:a + step].astype(np.float32)
            s = counts[a:a + step].reshape(-1, pixels).astype(np.float32)
            s -= p @ offset
            s /= p @ gain
            flat[a:a + step] = _invert_scene(s, self.scene_term, self.band)
        return fill_bad_pixels(out, self.bad)

    def radial(self, *, order: int = 4, centre: tuple[float, float] = (0.0, 0.0)
               ) -> PolynomialCalibration:
        """The radial fit of this model (Oz et al. eq. 16–17): maps → ``Σ_j m_j R^j``.

        Fitted by least squares over the good pixels, all eight maps at once. The result has no
        defects and no per-pixel FPN: a low-frequency model of the camera family.
        """
        if order < 0 or order > 12:
            raise InvalidInputError(f"radial order must be 0…12, got {order}")
        from thermocal.camera.presets import radial_map

        r = radial_map(self.shape, centre).astype(np.float64)
        basis = np.stack([r**j for j in range(order + 1)], axis=-1)  # (H, W, M+1)
        good = ~self.bad
        maps = np.concatenate([self.gain, self.offset]).astype(np.float64)  # (8, H, W)
        coef, *_ = np.linalg.lstsq(basis[good], maps[:, good].T, rcond=None)  # (M+1, 8)
        fitted = np.einsum("hwj,jm->mhw", basis, coef).astype(np.float32)
        return replace(
            self,
            gain=fitted[: ORDER + 1],
            offset=fitted[ORDER + 1 :],
            bad=np.zeros(self.shape, dtype=bool),
            radial_coefficients=coef.T.copy(),
            radial_centre=(float(centre[0]), float(centre[1])),
            info=self.info | {"radial_order": order},
        )

    @classmethod
    def _check_stored(cls, stored: StoredCalibration, path: str | Path) -> None:
        scene = stored.metadata.get("scene_term")
        if scene not in SCENE_TERMS:
            raise damaged(path, METHOD, f"unknown scene term {scene!r:.40}")

    @classmethod
    def _check_fields(cls, kw: dict[str, Any], stored: StoredCalibration,
                      path: str | Path) -> None:
        """Beyond finiteness: the band within :data:`~thermocal.calibration.store.BAND_LIMITS_M`
        and ``t_ref_c`` within :data:`~thermocal.calibration.store.FPA_LIMITS_C`; at nine FPA
        temperatures across the fitted range and at ``t_ref_c`` (enough points to bound a cubic
        between them), every pixel's gain polynomial gives a 0 → 100 °C response of
        :data:`~thermocal.calibration.store.RESPONSE_LIMITS_COUNTS`, of the same sign on every
        pixel (the fit marks a pixel whose ``g_0`` has the other sign bad and gives it the
        median gain), and its offset polynomial stays within
        :data:`~thermocal.calibration.store.OFFSET_LIMIT_COUNTS`; residuals ``>= 0``; a radial
        model's coefficients ``(8, M+1)``, ``M <= 12`` (what :meth:`radial` allows), finite, its
        centre within ±1 (the axes run −0.5…0.5)."""
        super()._check_fields(kw, stored, path)
        check_band(kw["band_m"], path, METHOD)
        check_scalar(kw["t_ref_c"], "t_ref_c", *FPA_LIMITS_C, path, METHOD, unit="°C")
        if np.any(kw["residual_rms"] < 0):
            raise damaged(path, METHOD, "a negative residual")
        band = band_for(tuple(kw["band_m"]))
        span = float(scene_term(100.0, kw["scene_term"], band)
                     - scene_term(0.0, kw["scene_term"], band))
        gain = kw["gain"].astype(np.float64)
        offset = kw["offset"].astype(np.float64)
        t_ref = float(kw["t_ref_c"])
        for fpa in (*np.linspace(*kw["fpa_range_c"], 9), t_ref):
            where = f"at FPA {fpa:.2f} °C"
            check_response(horner(gain, fpa - t_ref) * span, path, METHOD, where)
            check_offsets(horner(offset, fpa - t_ref), f"offset {where}", path, METHOD)
        coef = kw.get("radial_coefficients")
        if coef is not None:
            c = np.asarray(coef)
            if (c.ndim != 2 or c.shape[0] != 2 * (ORDER + 1) or not 1 <= c.shape[1] <= 13
                    or c.dtype.kind not in "iuf" or not np.all(np.isfinite(c))):
                raise damaged(path, METHOD, f"radial coefficients of shape {c.shape}, expected "
                                            "(8, M+1) with M <= 12, finite")
        centre = kw.get("radial_centre", (0.0, 0.0))
        if len(centre) != 2:
            raise damaged(path, METHOD, f"radial_centre = {centre!r:.40}, expected (x, y)")
        for v in centre:
            check_scalar(v, "radial_centre", -1.0, 1.0, path, METHOD)


#: Values (frames × pixels) :meth:`PolynomialCalibration.apply` works on at once.
_APPLY_BLOCK = 1 << 21


def _invert_scene(s: np.ndarray, kind: str, band: BandRadiance) -> np.ndarray:
    """Temperature (°C, float32) from the scene term ``S`` (float32, modified in place)."""
    if kind == "linear":
        return s
    if kind == "t4":
        np.maximum(s, np.float32(1e4), out=s)  # 10 K⁴: keeps the root real for broken pixels
        return np.sqrt(np.sqrt(s)) - np.float32(ZERO_CELSIUS_K)
    lo, hi = band.radiance_range
    np.clip(s, lo, hi, out=s)
    return band.temperature(s) - np.float32(ZERO_CELSIUS_K)


#: Pixels of a block accumulated at once: a tile of centred counts stays in the core's cache
#: between its three uses (64 frames × 4096 pixels × 4 bytes = 1 MB).
_TILE_PIXELS = 4096


def _accumulate(counts: np.ndarray, at: np.ndarray, ref: np.ndarray, aty: np.ndarray,
                yy: np.ndarray, part: slice) -> None:
    """Add one block's normal-equation sums over the pixels ``part`` to ``aty`` ``(K, P)`` and
    ``yy`` ``(P,)`` (float64, in place): ``at @ y`` and ``Σ y²`` of the centred counts
    ``y = counts − ref`` (``counts`` ``(k, P)`` uint16, ``at`` ``(K, k)`` and ``ref`` ``(P,)``
    float32), tile by tile so that each tile is read from memory once (by hand: numpy has no
    fused pass for the three, and BLAS sees each tile while it is in cache)."""
    k = counts.shape[0]
    y_buf = np.empty((k, _TILE_PIXELS), dtype=np.float32)
    y64_buf = np.empty((k, _TILE_PIXELS), dtype=np.float64)
    for p0 in range(part.start, part.stop, _TILE_PIXELS):
        p1 = min(p0 + _TILE_PIXELS, part.stop)
        y, y64 = y_buf[:, : p1 - p0], y64_buf[:, : p1 - p0]
        np.subtract(counts[:, p0:p1], ref[p0:p1], out=y, dtype=np.float32)  # centred counts
        aty[:, p0:p1] += at @ y
        # Σ y² in float64: the residual is what is left of it after the fit, 1e-5 of it
        np.copyto(y64, y)
        yy[p0:p1] += np.einsum("kp,kp->p", y64, y64)


def polynomial(
    session: Any,
    *,
    scene: str = "t4",
    t_ref_c: float | None = None,
    frames: str = "stable",
    frame_mask: np.ndarray | None = None,
    outlier_mads: float = 10.0,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    chunk: int = 64,
    progress: Any = None,
) -> PolynomialCalibration:
    """Fit the per-pixel polynomial model to a chamber session (Oz et al. eq. 13–15).

    Parameters
    ----------
    session : ChamberSession, ChamberData or path
    scene : {"t4", "linear", "radiance"}
        The scene term.
    t_ref_c : float, optional
        Expansion point of the FPA polynomials, °C (default: the middle of the FPA range).
    frames : {"stable", "settled", "all"}
        Which frames to fit by FPA stability: only stable ones (``|rate| ≤ 0.05`` °C/min, the
        default), stable and relatively stable ones (≤ 0.5 °C/min), or all. The model has no
        transient term: frames taken while the FPA changes bias it.
    frame_mask : (M,) bool, optional
        Restrict the fit to these frames (e.g. to hold set points out).
    outlier_mads : float
        Pixels whose gain or residual lies more than this many MADs from the median are bad.
    chunk : int
        Frames per block read and accumulated (bounds memory).
    progress : callable, optional
        ``progress(k)`` after each block of ``k`` frames.

    Raises
    ------
    FitError
        Fewer than 2 set points, or an FPA range under 4 °C (a cubic in the FPA temperature).
    """
    if scene not in SCENE_TERMS:
        raise InvalidInputError(
            f"unknown scene term {scene!r}; choose from {', '.join(SCENE_TERMS)}"
        )
    data = prepare_chamber(session)
    sel = data.usable & stability_mask(data, frames)
    if frame_mask is not None:
        mask = np.asarray(frame_mask, dtype=bool)
        if mask.shape != sel.shape:
            raise InvalidInputError(f"frame_mask: expected {sel.shape}, got {mask.shape}")
        sel &= mask
    what = describe_frames(data, frames) + (" in frame_mask" if frame_mask is not None else "")
    require_setpoints(data, 2, "the polynomial model", sel, frames=what)
    require_fpa_span(
        data, 4.0, "the polynomial model (cubic in the FPA temperature)", sel, degree=3,
        frames=what, record=(
            "record the FPA held still at >= 4 temperatures (the ambient in steps, each held "
            "until the FPA settles), or fit frames='settled'" if frames == "stable" else
            "record while the chamber's ambient changes"),
    )
    band = band_for(tuple(band_m))
    fpa = data.fpa_c
    used = np.flatnonzero(sel)
    lo, hi = float(fpa[used].min()), float(fpa[used].max())
    ref = 0.5 * (lo + hi) if t_ref_c is None else float(t_ref_c)

    # Design (Oz eq. 14) in centred, scaled variables for conditioning; converted back below.
    s_all = scene_term(data.scene_c, scene, band)
    s_mean = float(s_all[used].mean())
    s_scale = float(np.abs(s_all[used] - s_mean).max()) or 1.0
    d_scale = float(np.abs(fpa[used] - ref).max()) or 1.0
    s_t = (s_all - s_mean) / s_scale
    d_t = (fpa - ref) / d_scale
    powers = np.stack([d_t**i for i in range(ORDER + 1)], axis=1)  # (M, 4)
    design = np.concatenate([powers * s_t[:, None], powers], axis=1)  # (M, 8)

    h, w = data.frame_shape
    n_pix = h * w
    k_cols = design.shape[1]
    ata = np.zeros((k_cols, k_cols))
    aty = np.zeros((k_cols, n_pix))
    yy = np.zeros(n_pix)
    ref_counts: np.ndarray | None = None
    scan = FrameScan((h, w), data.session.bit_depth)
    from threadpoolctl import threadpool_limits  # here: only a fit pays for its import

    # the sums of each block over pixel ranges on the CPU's cores (numpy frees the GIL), BLAS
    # on one thread in each: its own threads would fight ours for the same cores
    width = -(-n_pix // available_cores())
    parts = [slice(p0, min(p0 + width, n_pix)) for p0 in range(0, n_pix, width)]
    with (ThreadPoolExecutor(max_workers=len(parts)) as pool,
          threadpool_limits(limits=1, user_api="blas")):
        for idx, block in iter_frames(data.session, used, chunk=chunk):
            keep = scan.check(idx, block)
            if keep.any():
                counts = (block if keep.all() else block[keep]).reshape(-1, n_pix)  # no copy
                if ref_counts is None:
                    ref_counts = counts[0].astype(np.float32)
                a = design[idx[keep]]
                ata += a.T @ a
                at = np.ascontiguousarray(a.T, dtype=np.float32)
                list(pool.map(lambda part, c=counts, at=at, ref=ref_counts: _accumulate(
                    c, at, ref, aty, yy, part), parts))
            if progress is not None:
                progress(len(idx))
    if ref_counts is None or scan.n_seen < k_cols:
        raise FitError(
            f"the polynomial model needs at least {k_cols} unsaturated frames, got {scan.n_seen}"
        )
    try:
        coef = np.linalg.solve(ata, aty)  # (8, P), scaled variables
    except np.linalg.LinAlgError:
        raise FitError(
            "the polynomial model is singular for these frames: record more set points at "
            "more FPA temperatures"
        ) from None
    rss = yy - 2 * np.einsum("kp,kp->p", coef, aty) + np.einsum("kp,kl,lp->p", coef, ata, coef)
    residual_rms = np.sqrt(np.maximum(rss, 0) / max(scan.n_seen - k_cols, 1))

    # Back to physical units: S = s_mean + s_scale·s̃, Δ = d_scale·Δ̃, counts = ref + y.
    pw = d_scale ** -np.arange(ORDER + 1, dtype=np.float64)
    g = coef[: ORDER + 1] / s_scale * pw[:, None]
    d = coef[ORDER + 1 :] * pw[:, None] - g * s_mean
    d[0] += ref_counts
    gain = g.reshape(ORDER + 1, h, w)
    offset = d.reshape(ORDER + 1, h, w)
    rms_map = residual_rms.reshape(h, w)
    g0 = gain[0]
    sign = np.sign(np.median(g0))
    bad = scan.saturated_pixels() | (g0 * sign <= 0)
    bad |= robust_outliers(g0, mads=outlier_mads, valid=~bad)
    med_rms = float(np.median(rms_map[~bad])) if (~bad).any() else 0.0
    bad |= rms_map > max(5.0 * med_rms, med_rms + outlier_mads * 1.4826 * float(
        np.median(np.abs(rms_map[~bad] - med_rms))) if (~bad).any() else 0.0)
    if bad.mean() > 0.5:
        raise FitError("the polynomial model: more than half of the pixels did not respond")
    # Bad pixels get the median gain (their output is filled from neighbours): no division by 0.
    gain[:, bad] = np.median(gain[:, ~bad], axis=1)[:, None]
    info = calibration_info(data.session) | scan.report() | {
        "frames_used": scan.n_seen,
        "setpoints_c": [float(v) for v in np.unique(np.round(data.session.blackbody_c[used], 6))],
        "bad_pixels": int(bad.sum()),
        "median_residual_counts": med_rms,
    }
    return PolynomialCalibration(
        gain=gain.astype(np.float32),
        offset=offset.astype(np.float32),
        bad=bad,
        residual_rms=rms_map.astype(np.float32),
        t_ref_c=ref,
        scene_term=scene,
        fpa_range_c=(lo, hi),
        band_m=tuple(band_m),
        info=info,
    )


def estimate_noise_sigma(data: ChamberData, *, max_pairs: int = 32) -> float:
    """Temporal noise of the camera, counts: from differences of consecutive frames.

    Pairs of consecutive usable frames of the same set-point visit; the spatial median of each
    difference (the drift between them) is removed and the robust spread (1.4826·MAD) divided by
    √2. Returns the median over at most ``max_pairs`` pairs.
    """
    same = (np.diff(data.block) == 0) & data.usable[1:] & data.usable[:-1]
    starts = np.flatnonzero(same)
    if starts.size == 0:
        raise FitError("no two consecutive frames at one set point: cannot estimate the noise")
    starts = starts[np.linspace(0, starts.size - 1, min(max_pairs, starts.size)).astype(int)]
    idx = np.unique(np.concatenate([starts, starts + 1]))
    frames = {int(i): f for i, f in zip(*_read(data, idx), strict=True)}
    sigmas = []
    for i in starts:
        diff = frames[int(i) + 1].astype(np.float32) - frames[int(i)].astype(np.float32)
        diff -= np.median(diff)
        sigmas.append(1.4826 * float(np.median(np.abs(diff))) / np.sqrt(2.0))
    return float(np.median(sigmas))


def _read(data: ChamberData, idx: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    out: list[np.ndarray] = []
    for _, block in iter_frames(data.session, idx, chunk=64):
        out.extend(block)
    return idx, out


def fpn_spread(cal: PolynomialCalibration, smooth: PolynomialCalibration) -> dict[str, float]:
    """How far a unit's per-pixel maps stray from their radial fit ``smooth``: its pixel FPN.

    The per-column part (each column's median) is set aside (eq. 19 draws column FPN of its own);
    what is left are robust standard deviations (1.4826 × MAD over the good pixels, so that a few
    defects do not count) of the offset at ``t_ref_c`` and of the responsivity relative to the
    radial fit.

    Returns
    -------
    dict
        ``offset_sigma_counts`` (counts) and ``gain_sigma`` (relative).
    """
    good = ~cal.bad
    d = np.where(good, cal.offset[0] - smooth.offset[0], np.nan)
    q = np.where(good, cal.gain[0] / smooth.gain[0], np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # columns of bad pixels alone: NaN
        d -= np.nanmedian(d, axis=0)
        q = q / np.nanmedian(q, axis=0) - 1.0
    out = {}
    for name, x in (("offset_sigma_counts", d), ("gain_sigma", q)):
        x = x[np.isfinite(x)]
        if x.size < 2:
            raise InvalidInputError("the chamber fit has too few good pixels to measure its FPN")
        out[name] = float(1.4826 * np.median(np.abs(x - np.median(x))))
    return out


def camera_model_from_chamber(
    session: Any,
    *,
    radial: bool = True,
    radial_order: int = 4,
    t_ref_c: float = 25.0,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    chunk: int = 64,
) -> Any:
    """A :class:`~thermocal.camera.model.CameraModel` fitted to a user's chamber session.

    Fits the polynomial model with the band-radiance scene term, so that ``g_i``/``d_i`` are the
    model's gain/offset cubics around ``t_ref_c``; the housing and transient terms are zero (not
    separable from chamber data of a uniform blackbody), the temporal noise is estimated from
    consecutive frames (:func:`estimate_noise_sigma`), defects are the pixels the fit marked bad
    (stuck at their fitted level). With ``radial=True`` the per-pixel maps are replaced by their
    radial fit (Oz et al. §IV-C): a unit-independent, low-frequency model without defects; the
    spread of the pixel FPN it drops is kept in ``info["pixel_fpn"]`` (:func:`fpn_spread`), so that
    training can draw random FPN of this camera's size (Oz et al.: "Random FPN and Gaussian noise
    were added to the model during training").

    Parameters
    ----------
    session : ChamberSession, ChamberData or path
    radial : bool
        Replace the per-pixel maps by their radial fit of order ``radial_order``.
    t_ref_c : float
        Expansion point of the polynomials, °C (the camera model's ``t_ref_c``).
    """
    from thermocal.camera.model import CameraModel

    data = prepare_chamber(session)
    cal = polynomial(data, scene="radiance", t_ref_c=t_ref_c, band_m=band_m, chunk=chunk)
    sigma = estimate_noise_sigma(data)
    bit_depth = data.session.bit_depth
    fpn = None
    if radial:
        smooth = cal.radial(order=radial_order)
        fpn = fpn_spread(cal, smooth)
        cal = smooth
    defects = cal.bad.copy()
    defect_counts = np.zeros(cal.shape, dtype=np.uint16)
    defect_counts[defects] = np.clip(np.rint(cal.offset[0][defects]), 0, 2**bit_depth - 1)
    gain = cal.gain.copy()
    gain[:, defects] = 0.0
    info = {
        "source": "camera_model_from_chamber",
        "radial": radial,
        "chamber": {k: v for k, v in calibration_info(data.session).items()},
        "fpa_range_c": list(cal.fpa_range_c),
        "median_residual_counts": cal.info.get("median_residual_counts"),
    }
    if fpn is not None:
        info["pixel_fpn"] = fpn
    return CameraModel(
        gain=gain,
        offset=cal.offset.copy(),
        housing=np.zeros(cal.shape, dtype=np.float32),
        transient=np.zeros(cal.shape, dtype=np.float32),
        defects=defects,
        defect_counts=defect_counts,
        noise_sigma=sigma,
        t_ref_c=cal.t_ref_c,
        band=band_for(tuple(band_m)),
        bit_depth=bit_depth,
        info=info,
    )
