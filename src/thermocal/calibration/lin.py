"""Lin, Westfeld & Maas: shutter-less correction under fast-changing FPA temperature.

Per pixel, from the raw counts ``G0`` at FPA temperature ``T0`` (°C) changing at ``r`` °C/min:

1. eq. 1, projection to a reference FPA temperature ``T_ref`` with a 2nd-order polynomial fitted
   on stable frames: ``Gc = a·(T_ref² − T0²) + b·(T_ref − T0) + G0``;
2. eq. 2–3, removal of the fast-change deviation with a 3rd-order polynomial in the FPA rate
   fitted on the unstable and relatively stable frames: ``Gf = Gc − (m·r³ + n·r² + p·r)``. Lin et
   al. use the temporal difference per frame (eq. 3); here it is divided by the time step
   (°C/min, :func:`~thermocal.calibration.dataset.fpa_rate_c_per_min`) so the coefficients do
   not depend on the frame rate;
3. eq. 4–5, the Planck curve ``V = R / (exp(B/T) − F) + O`` fitted with
   :func:`scipy.optimize.curve_fit` on ≥ 4 blackbody temperatures, and its inverse
   ``T = B / ln(R / (V − O) + F)`` (K). ``B`` and ``F`` are fitted on the array mean; ``R`` and
   ``O`` per pixel (linear least squares once ``B`` and ``F`` are known), which also removes the
   fixed-pattern noise the FLIR Ax65 of the paper removes internally.

**Extension ``lin-level``** (not in the paper; ``lin(..., level=True)``). A microbolometer's
responsivity changes with the FPA temperature (the tau2 preset: −0.4 %/°C), so the FPA slope of
the counts depends on the scene level: a per-pixel ``(a, b)`` fitted over all set points is right
only near their mean and leaves errors that grow with the distance from it and with
``|T0 − T_ref|``.
The extension makes eq. 1's coefficients linear in the scene's band radiance ``ℓ`` (relative to
the set points' mean), fitted on the same stable frames at ≥ 2 blackbody temperatures:
``Gc = G0 + (a + a1·ℓ)·(T_ref² − T0²) + (b + b1·ℓ)·(T_ref − T0)``. At apply time ``ℓ`` of each
pixel is read off its own corrected counts, ``ℓ = (Gf − c)/g`` (``c``, ``g``: the pixel's counts at
the mean level and its responsivity at ``T_ref``, from the set-point levels), which makes
``Gf = (U·g − W·c)/(g − W)`` in closed form, ``U`` being the paper's ``Gf`` and ``W = a1·(T_ref² −
T0²) + b1·(T_ref − T0)``. Eq. 2–5 are unchanged.

**Extension ``lin-lag``** (not in the paper; ``lin(..., level=True, rate_lags_s=RATE_LAGS_S)``).
Eq. 2 sees only the FPA's own rate, which is all that a camera whose optics and housing follow
the FPA at once needs. Optics that lag the FPA by a time constant ``τ`` sit ``−τ·y_τ`` °C from it,
``y_τ`` being the FPA rate through a first-order lag of ``τ``
(:func:`~thermocal.calibration.dataset.lagged_rate`); their radiance onto the FPA, and a
transient that builds up and dies away, follow the rate's *history*, not its present value. A
cubic in the present rate fitted where the session's FPA changed (its ambient steps, one pace of
sawtooth) then misses at any other pace: 3.1 °C on the ``boson`` preset's held-out 1 °C/min
sawtooth (``benchmarks/physics.py``). The extension adds to eq. 2 the lagged rates of
:data:`RATE_LAGS_S` and their products with ``T0 − T_ref`` (the radiance of what lags changes
with the FPA temperature): ``Gf = Gc − (m·r³ + n·r² + p·r) − Σ_τ (q_τ + q'_τ·(T0 − T_ref))·y_τ``.
Frames the FPA holds still while what lags it still moves are eq. 1's, so eq. 1 is refitted
on its stable frames less eq. 2's terms, and eq. 2 again, :data:`LAG_SWEEPS` times (fitting
the lag terms with eq. 1 instead confounds them with it where the optics follow the FPA at
once: 0.10 against 0.065 °C on ``tau2``'s held-out sawtooth). The lags are a fixed,
log-spaced basis (a lag between them is a mix of its neighbours), chosen on the chamber sessions
of ``benchmarks/physics.py`` by their in-sample error, not set to a preset's time constants
(``tau2``: 60 and 300 s; ``boson``: 45, 180 and 240 s). Each recording is taken to begin at a
steady pace (the lagged rates start at the first frame's rate).

In a chamber the blackbody visits several set points; each set point's level is a free intercept
of the per-pixel regressions (fixed effects), so (a, b) and (m, n, p) are shared by all set points
as the paper assumes ("without the requirement of specific blackbody temperature"). All pixels
share the regressors, so each regression is solved for all pixels at once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from scipy.optimize import curve_fit

from thermocal.calibration.base import (
    band_for,
    calibration_info,
    check_frames,
    fill_bad_pixels,
    per_frame_series,
    require_fpa,
    robust_outliers,
    warn_outside_range,
)
from thermocal.calibration.dataset import (
    STABLE,
    FrameScan,
    describe_frames,
    iter_frames,
    lagged_rate,
    prepare_chamber,
    recording_fpa_rates,
    require_fpa_span,
    require_setpoints,
)
from thermocal.calibration.store import (
    FPA_LIMITS_C,
    FileLayout,
    StoredCalibration,
    StoredCalibrationMixin,
    check_offsets,
    check_response,
    check_scalar,
    damaged,
)
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FitError, InvalidInputError
from thermocal.threads import caught_warnings

METHOD = "lin"
METHOD_LEVEL = "lin-level"
METHOD_LAG = "lin-lag"
METHODS = (METHOD, METHOD_LEVEL, METHOD_LAG)

#: The lags of the ``lin-lag`` extension's rate terms, s (see the module docstring).
RATE_LAGS_S = (30.0, 120.0, 480.0)
#: Times ``lin-lag`` refits eq. 1 and eq. 2 in turn (each on what the other leaves; the error
#: on ``benchmarks/physics.py``'s held-out runs settles after two).
LAG_SWEEPS = 2


def planck_counts(temp_k: Any, r: Any, b: float, f: float, o: Any) -> Any:
    """Lin et al. eq. 4: counts ``V = R / (exp(B / T) − F) + O`` for ``T`` in K."""
    return r / (np.exp(b / np.asarray(temp_k, dtype=np.float64)) - f) + o


def planck_temperature_k(counts: Any, r: Any, b: float, f: float, o: Any) -> Any:
    """Lin et al. eq. 5: ``T = B / ln(R / (V − O) + F)``, K (invalid counts give NaN)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return b / np.log(r / (counts - o) + f)


def fit_planck_curve(temp_k: Any, counts: Any) -> tuple[float, float, float, float]:
    """Fit ``(R, B, F, O)`` of eq. 4 to ≥ 4 (temperature K, counts) pairs with scipy.

    Raises
    ------
    FitError
        With fewer than 4 distinct temperatures, or when the fit does not converge.
    """
    t = np.asarray(temp_k, dtype=np.float64)
    v = np.asarray(counts, dtype=np.float64)
    if np.unique(np.round(t, 3)).size < 4:
        raise FitError(
            f"the Planck curve (Lin et al. eq. 4) needs >= 4 blackbody temperatures, got "
            f"{np.unique(np.round(t, 3)).size}"
        )
    b0, f0 = 1430.0, 1.0  # B ≈ c2 / λ at the middle of the 7.5–13.5 µm band
    basis = np.stack([1.0 / (np.exp(b0 / t) - f0), np.ones_like(t)], axis=1)
    (r0, o0), *_ = np.linalg.lstsq(basis, v, rcond=None)
    try:
        # its covariance is not used: scipy's warning that it cannot be estimated (four set
        # points for four coefficients) said nothing a user could act on
        with caught_warnings():
            popt, _ = curve_fit(
                lambda tt, r, b, f, o: planck_counts(tt, r, b, f, o), t, v,
                p0=[r0, b0, f0, o0], maxfev=20000,
            )
    except (RuntimeError, ValueError) as exc:
        raise FitError(f"the Planck curve fit did not converge ({exc})") from None
    if not np.all(np.isfinite(popt)):
        raise FitError("the Planck curve fit gave non-finite coefficients")
    return tuple(float(p) for p in popt)  # type: ignore[return-value]


_LEVEL_ARRAYS = dict.fromkeys(("a1", "b1", "level_counts", "level_gain"), np.float32)


@dataclass(frozen=True, eq=False)
class LinCalibration(StoredCalibrationMixin):
    """Fitted Lin et al. model; maps ``(H, W)`` float32, ``B`` (K) and ``F`` scalars.

    ``a`` (counts/°C²), ``b`` (counts/°C): eq. 1; ``m, n, p`` (counts per (°C/min)^i): eq. 2;
    ``r`` and ``o`` (counts): eq. 4 per pixel. The ``lin-level`` extension adds ``a1``, ``b1``
    (eq. 1's coefficients per W·m⁻²·sr⁻¹ of scene level), ``level_counts`` (counts at the mean
    set-point level at ``T_ref``) and ``level_gain`` (counts per W·m⁻²·sr⁻¹ at ``T_ref``); all
    ``None`` for the paper's method. The ``lin-lag`` extension adds ``lag`` ``(2K, H, W)``:
    counts per °C/min of the FPA rate through each lag of ``rate_lags_s`` (K of them, s), then
    per °C/min·°C of the same times ``T0 − T_ref``.
    """

    a: np.ndarray
    b: np.ndarray
    m: np.ndarray
    n: np.ndarray
    p: np.ndarray
    r: np.ndarray
    o: np.ndarray
    bad: np.ndarray
    planck_b: float
    planck_f: float
    t_ref_c: float
    fpa_range_c: tuple[float, float]
    rate_smooth_s: float = 60.0
    max_rate_c_per_min: float = 1.0
    info: dict[str, Any] = field(default_factory=dict)
    a1: np.ndarray | None = None
    b1: np.ndarray | None = None
    level_counts: np.ndarray | None = None
    level_gain: np.ndarray | None = None
    lag: np.ndarray | None = None
    rate_lags_s: tuple[float, ...] = ()

    _layout = FileLayout(
        methods=METHODS,
        arrays=dict.fromkeys(("a", "b", "m", "n", "p", "r", "o"), np.float32) | {"bad": bool},
        metadata=dict.fromkeys(("planck_b", "planck_f", "t_ref_c", "rate_smooth_s",
                                "max_rate_c_per_min"), float) | {
            "rate_lags_s": lambda v: tuple(float(x) for x in v)},
        optional_metadata=("rate_lags_s",),
        method_arrays={METHOD_LEVEL: _LEVEL_ARRAYS,
                       METHOD_LAG: _LEVEL_ARRAYS | {"lag": np.float32}},
        stacks={"lag": 2 * len(RATE_LAGS_S)},
    )

    @classmethod
    def _check_fields(cls, kw: dict[str, Any], stored: StoredCalibration,
                      path: str | Path) -> None:
        """Beyond finiteness: ``t_ref_c`` within :data:`~thermocal.calibration.store.FPA_LIMITS_C`;
        ``100 <= B <= 1e5`` K (``B ≈ c2/λ``: 480…14400 K for bands of 1…30 µm, with room for
        the fit); ``F < exp(B / 373.15 K)``, so that the Planck curve has no pole below 100 °C
        (the counts would be infinite there); every pixel's 0 → 100 °C response
        ``R · (P(100 °C) − P(0 °C))``, ``P(T) = 1/(exp(B/T) − F)``, of
        :data:`~thermocal.calibration.store.RESPONSE_LIMITS_COUNTS` and of one sign (the fit
        gives the pixels whose ``R`` has the other sign the median); ``|O|`` within
        :data:`~thermocal.calibration.store.OFFSET_LIMIT_COUNTS`; ``rate_smooth_s`` in
        [0, 1 day] s, ``max_rate_c_per_min`` in [0, 1000] °C/min; lin-level and lin-lag:
        ``level_gain > 0`` (the fit gives the others the median) and ``|level_counts|`` within
        the offset limit; lin-lag: one lag in (0, 1 day] s per pair of ``lag`` maps."""
        super()._check_fields(kw, stored, path)
        m = stored.method
        check_scalar(kw["t_ref_c"], "t_ref_c", *FPA_LIMITS_C, path, m, unit="°C")
        check_scalar(kw["planck_b"], "planck_b", 100.0, 1e5, path, m, unit="K")
        b = float(kw["planck_b"])
        check_scalar(kw["planck_f"], "planck_f", -np.inf, float(np.exp(b / 373.15)), path, m,
                     low_open=True)
        f = float(kw["planck_f"])
        hot, cold = (1.0 / (np.exp(b / t) - f) for t in (ZERO_CELSIUS_K + 100.0, ZERO_CELSIUS_K))
        check_response(kw["r"].astype(np.float64) * (hot - cold), path, m, "(R)")
        check_offsets(kw["o"], "o", path, m)
        check_scalar(kw["rate_smooth_s"], "rate_smooth_s", 0.0, 86400.0, path, m, unit="s")
        check_scalar(kw["max_rate_c_per_min"], "max_rate_c_per_min", 0.0, 1000.0, path, m)
        if m in (METHOD_LEVEL, METHOD_LAG):
            if not np.all(kw["level_gain"] > 0):
                raise damaged(path, m, "a level_gain is not positive")
            check_offsets(kw["level_counts"], "level_counts", path, m)
        if m == METHOD_LAG:
            lags = kw.get("rate_lags_s", ())
            if 2 * len(lags) != len(kw["lag"]) or not all(0 < v <= 86400.0 for v in lags):
                raise damaged(path, m, f"rate_lags_s {lags!r:.60} do not match its lag maps")

    @property
    def method(self) -> str:
        """``"lin"`` (the paper), ``"lin-level"`` (eq. 1 linear in the scene level) or
        ``"lin-lag"`` (lin-level with lagged rates)."""
        if self.a1 is None:
            return METHOD
        return METHOD_LEVEL if self.lag is None else METHOD_LAG

    @property
    def shape(self) -> tuple[int, int]:
        return self.bad.shape  # type: ignore[return-value]

    def corrected_counts(self, frames: Any, fpa_c: np.ndarray, rate: np.ndarray,
                         time_s: np.ndarray | None = None,
                         lag_rates: np.ndarray | None = None) -> np.ndarray:
        """``Gf`` of eq. 2 for raw counts ``(N, H, W)``, float32 (``time_s``: the frame times the
        lagged rates need, s; ``lag_rates`` ``(N, K)`` °C/min: those rates as given, from a
        longer recording)."""
        counts = np.asarray(frames)
        if self.lag is not None:
            lags = (lag_rates if lag_rates is not None else _lagged_rates(
                rate, np.arange(len(rate)) if time_s is None else time_s, self.rate_lags_s))
        out = np.empty(counts.shape, dtype=np.float32)
        tr = np.float32(self.t_ref_c)
        for k, frame in enumerate(counts):
            t0 = np.float32(fpa_c[k])
            rk = np.float32(rate[k])
            g = frame.astype(np.float32)
            g += self.a * (tr * tr - t0 * t0) + self.b * (tr - t0)
            g -= ((self.m * rk + self.n) * rk + self.p) * rk
            if self.lag is not None:  # the lagged rates and their change with the FPA
                for j, yj in enumerate(np.concatenate([lags[k], lags[k] * (t0 - tr)])):
                    g -= np.float32(yj) * self.lag[j]
            if self.a1 is not None:  # lin-level: Gf = U + ℓ·W with ℓ = (Gf − c)/g, solved
                w = self.a1 * (tr * tr - t0 * t0) + self.b1 * (tr - t0)
                g = (g * self.level_gain - w * self.level_counts) / (self.level_gain - w)
            out[k] = g
        return out

    #: ``apply`` takes the frames' FPA rate from their recording (``fpa_rate_c_per_min``).
    takes_fpa_rate: ClassVar[bool] = True

    def apply(self, frames: Any, *, fpa_c: Any = None, time_s: Any = None,
              frame_rate_hz: float | None = None,
              fpa_rate_c_per_min: Any = None, fpa_lag_rates_c_per_min: Any = None
              ) -> np.ndarray:
        """Scene temperature, °C, float32 ``(N, H, W)``.

        ``fpa_c`` (°C per frame) is required; ``time_s`` gives the FPA rate (eq. 3; with the
        smoothing of the fit). Without ``time_s``, ``frame_rate_hz`` sets the frame times;
        without either, a single FPA value or a single frame is taken as stable (rate 0), as
        is a recording shorter than the smoothing window (``rate_smooth_s``: a burst of a
        second cannot tell its rate from the sensor's quantisation). ``fpa_rate_c_per_min``
        (°C/min, one or one per frame): the rate the frames' recording measured over a longer
        span (a flight's burst), used instead; the lagged rates (lin-lag) then start steady at
        it (a burst has no history) unless ``fpa_lag_rates_c_per_min`` gives them: °C/min,
        ``(K,)`` or ``(N, K)``, the FPA rate through each of the calibration's ``rate_lags_s``
        from the frames' whole recording (:func:`~thermocal.estimation.paces.recording_paces`).
        """
        counts = check_frames(frames, self.shape)
        nfr = len(counts)
        fpa = require_fpa(fpa_c, nfr, self.method)
        warn_outside_range(fpa, self.fpa_range_c, self.method)
        if time_s is None and frame_rate_hz is not None:
            time_s = np.arange(nfr) / float(frame_rate_hz)
        if fpa_rate_c_per_min is not None:
            rate = np.broadcast_to(np.asarray(fpa_rate_c_per_min, np.float64).reshape(-1),
                                   (nfr,)).copy()
            if not np.all(np.isfinite(rate)):
                raise InvalidInputError("lin: fpa_rate_c_per_min must be finite")
            t = (None if time_s is None
                 else per_frame_series(time_s, nfr, "time_s", temperature=False))
        elif time_s is None:
            if nfr > 1 and np.ptp(fpa) > 0:
                raise InvalidInputError(
                    "lin: the FPA rate needs the time of each frame (sidecar 'time_s')"
                )
            rate, t = np.zeros(nfr), None
        else:
            t = per_frame_series(time_s, nfr, "time_s", temperature=False)
            # a recording too short (or with repeated times) to measure a rate: taken as
            # steady, its rate unknown as σ has it (0.01 °C steps over a second said −1.2 °C/min)
            rate = recording_fpa_rates(fpa, t, smooth_s=self.rate_smooth_s)
            rate = np.zeros(nfr) if rate is None else rate
        lag_rates = None
        if fpa_lag_rates_c_per_min is not None and self.lag is not None:
            k = len(self.rate_lags_s)
            given = np.asarray(fpa_lag_rates_c_per_min, np.float64)
            if given.shape not in ((k,), (nfr, k)) or not np.all(np.isfinite(given)):
                raise InvalidInputError(f"lin-lag: fpa_lag_rates_c_per_min must be {k} finite "
                                        f"rates (one per lag) or {nfr}×{k}, got {given.shape}")
            lag_rates = np.broadcast_to(given, (nfr, k))
        gf = self.corrected_counts(counts, fpa, rate, t, lag_rates)
        out = np.empty_like(gf)
        b, f = np.float32(self.planck_b), np.float32(self.planck_f)
        zero_c = np.float32(ZERO_CELSIUS_K)
        for k in range(nfr):
            # counts at or below the Planck offset O have no temperature (radiance ≤ 0): the
            # coldest the formula gives, not the hottest a negative R/(S−O) would clip to
            # (another camera's dead pixels read 1.5e9 °C before)
            den = np.maximum(gf[k] - self.o, np.float32(1e-3))
            arg = self.r / den + f
            out[k] = b / np.log(np.maximum(arg, np.float32(1.0 + 1e-6))) - zero_c
        return fill_bad_pixels(out, self.bad)


def _within_solve(
    xx: np.ndarray, xy: np.ndarray, n_s: np.ndarray, xbar_s: np.ndarray, ybar_s: np.ndarray
) -> np.ndarray:
    """Fixed-effects least squares: shared slopes ``(K, P)`` with one intercept per group.

    ``xx`` = Σ x xᵀ ``(K, K)``, ``xy`` = Σ x y ``(K, P)`` over all frames; per group s: ``n_s``
    frames, mean regressors ``xbar_s`` ``(S, K)`` and mean counts ``ybar_s`` ``(S, P)``.
    """
    wxx = xx - np.einsum("s,sk,sl->kl", n_s, xbar_s, xbar_s)
    wxy = xy - np.einsum("s,sk,sp->kp", n_s, xbar_s, ybar_s)
    try:
        return np.linalg.solve(wxx, wxy)
    except np.linalg.LinAlgError:
        raise FitError("lin: singular regression; record more FPA temperatures") from None


def lin(
    session: Any,
    *,
    fpa_ref_c: float | None = None,
    rate_smooth_s: float = 60.0,
    outlier_mads: float = 10.0,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    chunk: int = 64,
    level: bool = False,
    rate_lags_s: tuple[float, ...] = (),
) -> LinCalibration:
    """Fit Lin et al. to a chamber session (``level=True``: the ``lin-level`` extension; with
    ``rate_lags_s`` as well, ``lin-lag``).

    Parameters
    ----------
    session : ChamberSession, ChamberData or path
        Needs stable frames at ≥ 3 FPA temperatures spanning ≥ 2 °C (eq. 1), unstable frames
        (eq. 2; without them m = n = p = 0) and ≥ 4 blackbody set points (eq. 4).
    fpa_ref_c : float, optional
        Reference FPA temperature, °C; default the median of the stable frames'.
    rate_smooth_s : float
        Window of the FPA-rate estimate, s (0: raw eq. 3).
    level : bool
        Make eq. 1's coefficients linear in the scene level (the ``lin-level`` extension, see
        the module docstring); False is the paper's method.
    rate_lags_s : tuple of float
        With ``level``: the lags of the ``lin-lag`` extension's rate terms, s
        (:data:`RATE_LAGS_S`, the only ones its files hold); empty for the other methods.
    """
    if rate_lags_s and (not level or len(rate_lags_s) != len(RATE_LAGS_S)):
        raise InvalidInputError(f"lin: lagged rates need level=True and {len(RATE_LAGS_S)} "
                                f"lags (as lin-lag's files hold), got {rate_lags_s!r}")
    data = prepare_chamber(session, rate_smooth_s=rate_smooth_s)
    band = band_for(tuple(band_m))
    stable = data.usable & (data.stability == STABLE)
    lags = _lagged_rates(data.fpa_rate_c_per_min, data.time_s, rate_lags_s)
    what = describe_frames(data, "stable")
    require_setpoints(data, 4, "lin (the Planck curve of eq. 4)", stable, frames=what,
                      record="record >= 4 set points with the FPA held still")
    require_fpa_span(data, 2.0, "lin (eq. 1, from stable frames)", stable, degree=2,
                     frames=what, record="record the FPA held still at >= 3 temperatures (the "
                     "ambient in steps, each held until the FPA settles)")
    ref = float(np.median(data.fpa_c[stable])) if fpa_ref_c is None else float(fpa_ref_c)
    bb = np.round(data.session.blackbody_c, 6)
    points, group = np.unique(bb, return_inverse=True)
    n_groups = points.size
    # Radiance of each frame's scene, and a global responsivity to refer every frame of a set
    # point to that set point's mean radiance (the grey blackbody reflects a drifting ambient).
    rad = np.asarray(band.radiance(data.scene_c + ZERO_CELSIUS_K), dtype=np.float64)
    rad_s = np.array([rad[group == g].mean() for g in range(n_groups)])
    dt = data.fpa_c - ref
    # scene level of each frame (its set point's mean radiance) around the set points' mean
    level_c = float(rad_s[np.unique(group[stable])].mean())
    ell = rad_s[group] - level_c
    h, w = data.frame_shape
    npix = h * w
    scan = FrameScan((h, w), data.session.bit_depth)
    all_idx = np.flatnonzero(data.usable)

    # pass 1: eq. 1 on stable frames (regressors Δ², Δ; lin-level: also ℓ·Δ², ℓ·Δ), and
    # set-point means for the gain.
    x1 = np.stack([dt**2, dt] + ([ell * dt**2, ell * dt] if level else []), axis=1)
    sums1 = _GroupSums(x1.shape[1], n_groups, npix)
    ref_counts: np.ndarray | None = None
    kept = np.zeros(data.n_frames, dtype=bool)
    for idx, block in iter_frames(data.session, all_idx, chunk=chunk):
        keep = scan.check(idx, block)
        y = block.reshape(len(block), -1).astype(np.float32)
        if ref_counts is None:
            ref_counts = y[0].copy()
        y -= ref_counts
        kept[idx[keep]] = True
        st = keep & stable[idx]
        if st.any():
            sums1.add(x1[idx[st]], y[st], group[idx[st]])
    assert ref_counts is not None
    have = sums1.n > 0
    # global responsivity (counts per W·m⁻²·sr⁻¹) from the stable set-point means
    gain = float(np.polyfit(rad_s[have], sums1.ysum[have].mean(axis=1) / sums1.n[have], 1)[0])
    # refer counts to the set point's mean radiance: y' = y − gain·(L − L_s)
    shift = gain * (rad - rad_s[group])
    ab = _fixed_effects(x1, stable & kept, group, sums1, shift)

    # pass 2: eq. 2 on every frame (stable ones anchor each set point's level), rate regressors
    # (lin-lag: and the lagged rates, alone and times Δ).
    rate = data.fpa_rate_c_per_min
    x2 = np.concatenate([np.stack([rate**3, rate**2, rate], axis=1), lags,
                         lags * dt[:, None]], axis=1)
    use2 = kept.copy()
    unstable_frames = int((data.stability[use2] != STABLE).sum())

    def rate_pass(ab: np.ndarray) -> tuple[np.ndarray, _GroupSums]:
        """Eq. 2's coefficients ``(K2, P)`` on the frames projected with eq. 1's ``ab``."""
        sums2 = _GroupSums(x2.shape[1], n_groups, npix)
        for idx, block in iter_frames(data.session, np.flatnonzero(use2), chunk=chunk):
            y = block.reshape(len(block), -1).astype(np.float32) - ref_counts
            y -= _eq1_counts(ab, dt[idx], ell[idx] if level else None)  # to the reference
            y -= shift[idx].astype(np.float32)[:, None]
            sums2.add(x2[idx], y, group[idx])
        if unstable_frames >= 3 and np.ptp(rate[use2]) > 0.1:
            return sums2.solve(), sums2
        return np.zeros((x2.shape[1], npix)), sums2

    mnp, sums2 = rate_pass(ab)
    for _ in range(LAG_SWEEPS if rate_lags_s else 0):
        # what lags the FPA still moves on some of eq. 1's stable frames: eq. 1 again on the
        # stable frames less eq. 2's terms, then eq. 2 again (fitting the lag terms with eq. 1
        # instead confounds them with it on a camera whose optics follow the FPA at once)
        sums1 = _GroupSums(x1.shape[1], n_groups, npix)
        for idx, block in iter_frames(data.session, np.flatnonzero(stable & kept), chunk=chunk):
            y = block.reshape(len(block), -1).astype(np.float32) - ref_counts
            y -= (x2[idx] @ mnp).astype(np.float32)
            sums1.add(x1[idx], y, group[idx])
        ab = _fixed_effects(x1, stable & kept, group, sums1, shift)
        mnp, sums2 = rate_pass(ab)
    a_c, b_c = ab[0], ab[1]  # centred: G0 = c_s + a_c·Δ² + b_c·Δ (+ ℓ·(a1_c·Δ² + b1_c·Δ))
    a1_c, b1_c = (ab[2], ab[3]) if level else (np.zeros(npix), np.zeros(npix))
    ysum2, n2, xsum2 = sums2.ysum, sums2.n, sums2.xsum
    # each set point's level at the reference, rate 0 (eq. 2 applied), from all its frames
    sp_level = (ysum2 - np.einsum("sk,kp->sp", xsum2, mnp)) / np.maximum(n2, 1)[:, None]
    sp_level += ref_counts[None].astype(np.float64)
    t_k = np.asarray(band.temperature(rad_s), dtype=np.float64)
    have = n2 > 0
    planck_r, planck_b, planck_f, planck_o = fit_planck_curve(
        t_k[have], sp_level[have].mean(axis=1)
    )
    basis = np.stack([1.0 / (np.exp(planck_b / t_k[have]) - planck_f), np.ones(have.sum())], 1)
    ro, *_ = np.linalg.lstsq(basis, sp_level[have], rcond=None)  # (2, P): per-pixel R, O
    r_map, o_map = ro[0].reshape(h, w), ro[1].reshape(h, w)
    bad = scan.saturated_pixels() | (np.sign(r_map) != np.sign(planck_r))
    bad |= robust_outliers(r_map, mads=outlier_mads, valid=~bad)
    if bad.mean() > 0.5:
        raise FitError("lin: more than half of the pixels did not respond")
    r_map[bad] = np.median(r_map[~bad])
    a_lin = a_c
    b_lin = b_c - 2.0 * a_c * ref  # eq. 1's uncentred b: a·T² + b·T ≡ a_c·Δ² + b_c·Δ + const
    extra: dict[str, np.ndarray] = {}
    if level:
        # each pixel's counts at the reference against the set points' level: c + g·ℓ
        lev_basis = np.stack([np.ones(have.sum()), rad_s[have] - level_c], axis=1)
        cg, *_ = np.linalg.lstsq(lev_basis, sp_level[have], rcond=None)
        gain_map = cg[1].reshape(h, w)
        bad |= ~(gain_map > 0)
        gain_map[bad] = np.median(gain_map[~bad])
        extra = {"a1": a1_c, "b1": b1_c - 2.0 * a1_c * ref, "level_counts": cg[0],
                 "level_gain": gain_map.ravel()}
    used = data.fpa_c[kept]
    info = calibration_info(data.session) | scan.report() | {
        "planck_r_mean": planck_r, "planck_o_mean": planck_o,
        "stable_frames": int((stable & kept).sum()), "unstable_frames": unstable_frames,
        "setpoints_c": [float(v) for v in points],
    } | ({"level_centre_radiance": level_c} if level else {})

    def as_map(v: np.ndarray) -> np.ndarray:
        return v.reshape(h, w).astype(np.float32)

    return LinCalibration(
        a=as_map(a_lin), b=as_map(b_lin), m=as_map(mnp[0]), n=as_map(mnp[1]), p=as_map(mnp[2]),
        r=r_map.astype(np.float32), o=o_map.astype(np.float32), bad=bad,
        lag=(mnp[3:].reshape(-1, h, w).astype(np.float32) if rate_lags_s else None),
        rate_lags_s=tuple(float(v) for v in rate_lags_s),
        planck_b=planck_b, planck_f=planck_f, t_ref_c=ref,
        fpa_range_c=(float(used.min()), float(used.max())), rate_smooth_s=rate_smooth_s,
        max_rate_c_per_min=float(np.abs(rate[kept]).max()), info=info,
        **{k: as_map(v) for k, v in extra.items()},
    )


def lin_level(session: Any, **options: Any) -> LinCalibration:
    """The ``lin-level`` extension of Lin et al.: :func:`lin` with ``level=True``."""
    return lin(session, level=True, **options)


def lin_lag(session: Any, **options: Any) -> LinCalibration:
    """The ``lin-lag`` extension of Lin et al.: ``lin-level`` with the lagged rates of
    :data:`RATE_LAGS_S`."""
    return lin(session, level=True, rate_lags_s=RATE_LAGS_S, **options)


def _lagged_rates(rate: np.ndarray, time_s: np.ndarray, lags_s: tuple[float, ...]) -> np.ndarray:
    """The FPA rate through each lag of ``lags_s``, ``(M, len(lags_s))`` °C/min."""
    if not lags_s:
        return np.zeros((np.size(rate), 0))
    return np.stack([lagged_rate(rate, time_s, tau) for tau in lags_s], axis=1)


class _GroupSums:
    """Running sums of a fixed-effects regression with one intercept per set point: Σ x xᵀ,
    Σ x y over all frames, and per group the frames, Σ x and Σ y."""

    def __init__(self, k: int, n_groups: int, npix: int) -> None:
        self.xx = np.zeros((k, k))
        self.xy = np.zeros((k, npix))
        self.ysum = np.zeros((n_groups, npix))
        self.n = np.zeros(n_groups)
        self.xsum = np.zeros((n_groups, k))

    def add(self, xs: np.ndarray, y: np.ndarray, groups: np.ndarray) -> None:
        """Frames with regressors ``xs`` ``(F, K)``, counts ``y`` ``(F, P)`` and groups ``(F,)``."""
        self.xx += xs.T @ xs
        self.xy += xs.T.astype(np.float32) @ y
        for g in np.unique(groups):
            sel = groups == g
            self.ysum[g] += y[sel].sum(axis=0, dtype=np.float64)
            self.n[g] += sel.sum()
            self.xsum[g] += xs[sel].sum(axis=0)

    def solve(self, xy: np.ndarray | None = None, ysum: np.ndarray | None = None) -> np.ndarray:
        """The shared slopes ``(K, P)`` (``xy``, ``ysum``: the sums to use instead)."""
        have = self.n > 0
        ysum = self.ysum if ysum is None else ysum
        return _within_solve(self.xx, self.xy if xy is None else xy, self.n[have],
                             self.xsum[have] / self.n[have, None],
                             ysum[have] / self.n[have, None])


def _eq1_counts(ab: np.ndarray, dt: np.ndarray, ell: np.ndarray | None) -> np.ndarray:
    """Eq. 1's counts ``(F, P)`` of frames at ``Δ = dt`` (``ell``: their scene levels,
    lin-level) from its centred coefficients ``ab`` (``a_c, b_c[, a1_c, b1_c]``)."""
    d = dt.astype(np.float32)[:, None]
    out = ab[0][None] * d * d + ab[1][None] * d
    if ell is not None:
        out += ell.astype(np.float32)[:, None] * (ab[2][None] * d * d + ab[3][None] * d)
    return out


def _fixed_effects(
    x: np.ndarray, sel: np.ndarray, group: np.ndarray, sums: _GroupSums, shift: np.ndarray,
) -> np.ndarray:
    """Shared slopes of eq. 1 with per-set-point intercepts, counts referred by ``shift``."""
    # Σ x·(y − shift) = Σ x·y − Σ x·shift (shift is per frame, the same for every pixel)
    xy = sums.xy - (x[sel] * shift[sel, None]).sum(axis=0)[:, None]
    ysum = sums.ysum - np.array([shift[sel & (group == g)].sum()
                                 for g in range(len(sums.n))])[:, None]
    return sums.solve(xy, ysum)
