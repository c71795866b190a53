"""Wolf, Pezoa & Figueroa (2016): temperature-dependent NU compensation with HW and LMS estimators.

Per pixel p and frame k (Wolf et al. eq. 6), in band radiance ``X`` (W·m⁻²·sr⁻¹)::

    X̂_p[k] = S0_p · Y_p[k] + S1_p + S2_p · ΔT̂[k] + Ω(ΔT[k])

- ``S0, S1, S2`` per pixel from ≥ 3 (blackbody, ΔT) points, eq. 7–9 (least squares over every
  frame given; ``ΔT`` is the FPA sensor's change from the reference ``fpa_ref_c``);
- ``Ω``: the spatially uniform term (housing radiation, unmodelled nonlinear dynamics), a
  Hammerstein–Wiener estimator driven by the FPA sensor: a static polynomial of order 3 in ΔT
  (input nonlinearity), a first-order linear dynamic block with one extra input lag, and the
  identity as output map (the linear model of eq. 5). It is identified offline from the chamber
  session with Bai's (1998) two-stage algorithm: over-parameterised least squares, then a rank-1
  SVD that separates the linear block from the nonlinearity; then refined on the error of its
  output run open loop, as it runs at apply time (Bai's equation-error fit leaves the static
  gain poorly determined: ±10 °C at the FPA ends of a ``boson`` session; see
  :func:`identify_hammerstein_wiener`);
- ``ΔT̂[k]``: the online LMS estimate of the FPA change from the scene statistics (eq. 10–11),
  a gradient step that makes ``X̂`` locally flat over a ``(2W+1)²`` window. Here the step is
  normalised by the gradient's response to ΔT̂ so that ``eta`` does not depend on the units or
  the frame size (``eta = 1`` jumps to the minimum), and its sign follows eq. 6's
  ``+ S2 · ΔT̂`` (descent on the local squared error).
  It runs every frame for ``warmup_frames`` frames, then every ``update_interval_s`` of
  recording time (the paper: 100 frames, then every 500 ms).

The paper does not say how the HW linear block starts. A block with a lead (``b0 ≈ −b1``: Ω
follows the FPA *rate*, as Bai's stages alone identified it on chamber data) started settled at
the first FPA sample is wrong by the rate term whenever a stream starts while the FPA
temperature is changing, and takes its time constant (minutes) to catch up. A stream therefore
starts on the steady response to a ramp at the FPA rate fitted to its first samples
(``hw_start="ramp"``, as ``lfilter_zi`` starts a filter on a constant); ``hw_start="steady"`` keeps
the settled start. (Refined on the open-loop error, the block identified on the ``tau2``
preset's sessions settles alike from either start on a Wolf Fig. 6 ramp.)

:class:`Wolf2016Stream` does this frame by frame (a
:class:`~thermocal.calibration.base.StreamingCorrector`); :meth:`Wolf2016Calibration.apply` runs
a fresh stream over a stack of frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from thermocal._validate import SATURATED_FRACTION, saturated_fraction
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
    check_response,
    check_scalar,
    damaged,
)
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FileFormatError, FitError, InvalidInputError

METHOD = "wolf2016"
#: The longest time constant the HW linear block is searched over, s.
HW_MAX_TAU_S = 3600.0
#: The largest pole of the HW linear block (its time constant finite).
HW_MAX_POLE = 0.999


@dataclass(frozen=True)
class HammersteinWiener:
    """Hammerstein–Wiener model of the uniform term Ω (W·m⁻²·sr⁻¹) from the FPA change ΔT (°C).

    ``v[k] = Σ_i c_i (ΔT[k]/u_scale)^i`` (i = 1…order), ``z[k] = a·z[k−1] + b0·v[k] + b1·v[k−1]``,
    ``Ω[k] = z[k] + bias``; one step every ``period_s`` seconds of recording time.
    """

    c: tuple[float, ...]
    a: float
    b: tuple[float, float]
    bias: float
    u_scale: float
    period_s: float

    def nonlinearity(self, delta_t_c: Any) -> np.ndarray:
        u = np.asarray(delta_t_c, dtype=np.float64) / self.u_scale
        return sum(ci * u ** (i + 1) for i, ci in enumerate(self.c))

    def initial_state(self, delta_t_c: float, rate_c_per_s: float = 0.0) -> tuple[float, float]:
        """State ``(z, v)`` of the linear block after a steady ramp through ``delta_t_c``.

        The ramp is ``rate_c_per_s`` (°C/s) in ΔT, i.e. ``v[k] − v[k−1] = r`` with
        ``r = v(ΔT) − v(ΔT − rate·period_s)``; its particular solution is ``z = G·v − r·(a·G +
        b1)/(1 − a)`` with the DC gain ``G = (b0 + b1)/(1 − a)``. ``rate_c_per_s = 0`` is the
        steady state of a constant input (what ``scipy.signal.lfilter_zi`` gives).
        """
        v = float(self.nonlinearity(delta_t_c))
        r = v - float(self.nonlinearity(delta_t_c - rate_c_per_s * self.period_s))
        gain = (self.b[0] + self.b[1]) / (1.0 - self.a)
        return gain * v - r * (self.a * gain + self.b[1]) / (1.0 - self.a), v

    def simulate(self, delta_t_c: Any, rate_c_per_s: float = 0.0) -> np.ndarray:
        """Ω for a series sampled every ``period_s``.

        It starts on the steady response to a ramp of ``rate_c_per_s`` (°C/s) through its
        first value: settled at that value for the default 0.
        """
        u = np.asarray(delta_t_c, dtype=np.float64)
        v = self.nonlinearity(u)
        if v.size == 0:
            return v + self.bias
        z0, _ = self.initial_state(float(u[0]), rate_c_per_s)
        # z[0] = z0, then z[k] = a·z[k−1] + b0·v[k] + b1·v[k−1]: the filter's state after the
        # first sample is what makes its first output z0
        z = lfilter(self.b, (1.0, -self.a), v, zi=[z0 - self.b[0] * v[0]])[0]
        return z + self.bias

    def to_list(self) -> list[float]:
        return [*self.c, self.a, *self.b, self.bias, self.u_scale, self.period_s]

    @classmethod
    def from_list(cls, values: Any, order: int) -> HammersteinWiener:
        v = [float(x) for x in values]
        return cls(tuple(v[:order]), v[order], (v[order + 1], v[order + 2]), v[order + 3],
                   v[order + 4], v[order + 5])


def identify_hammerstein_wiener(
    delta_t_c: np.ndarray, omega: np.ndarray, *, period_s: float, order: int = 3,
    segments: np.ndarray | None = None,
) -> HammersteinWiener:
    """Identify the HW model of Ω from a series sampled every ``period_s`` (Bai 1998).

    ``segments`` (int per sample) marks contiguous stretches; the recursion never links samples
    of different segments (e.g. two chamber runs in one file).

    Stage 1 fits the over-parameterised ARX model ``Ω[k] = a·Ω[k−1] + Σ_j Σ_i θ_ji u[k−j]^i +
    β`` by least squares; stage 2 factors ``θ ≈ b·cᵀ`` with the leading singular pair. A third
    stage refines that on the open-loop error (:func:`_output_error_refit`); the model of the
    two with the smaller open-loop error is kept.
    """
    u_all = np.asarray(delta_t_c, dtype=np.float64)
    y_all = np.asarray(omega, dtype=np.float64)
    seg = np.zeros(u_all.size, dtype=np.int64) if segments is None else np.asarray(segments)
    u_scale = float(np.abs(u_all).max()) or 1.0
    if y_all.size < 4 * (order + 2):
        raise FitError(
            f"the Hammerstein–Wiener estimator needs >= {4 * (order + 2)} frames in time "
            f"order, got {y_all.size}"
        )
    powers = np.stack([(u_all / u_scale) ** (i + 1) for i in range(order)], axis=1)  # (K, n)
    same = seg[1:] == seg[:-1]  # regress only within contiguous segments
    reg = np.concatenate(
        [y_all[:-1, None], powers[1:], powers[:-1], np.ones((y_all.size - 1, 1))], axis=1
    )[same]
    theta, *_ = np.linalg.lstsq(reg, y_all[1:][same], rcond=None)
    a = float(np.clip(theta[0], 0.0, HW_MAX_POLE))
    big = np.stack([theta[1 : 1 + order], theta[1 + order : 1 + 2 * order]])  # (2, n)
    uu, ss, vt = np.linalg.svd(big)
    b = uu[:, 0] * ss[0]
    c = vt[0]
    if abs(c).max() > 0:
        sign = np.sign(c[0]) if c[0] != 0 else 1.0
        b, c = b * sign, c * sign
    beta = float(theta[-1])
    bai = HammersteinWiener(tuple(float(x) for x in c), a, (float(b[0]), float(b[1])), 0.0,
                            u_scale, float(period_s))
    # The constant term of the ARX model becomes the output bias, refitted on the simulated
    # output (the recursion is run open loop at apply time), segment by segment.
    y_sorted = np.concatenate([y_all[seg == s] for s in np.unique(seg)])
    bias = (float(np.mean(y_sorted - _simulate_segments(bai, u_all, seg))) if np.isfinite(beta)
            else 0.0)
    bai = HammersteinWiener(bai.c, a, bai.b, bias, u_scale, float(period_s))
    refined = _output_error_refit(bai, u_all, y_sorted, seg)
    return min((bai, refined),
               key=lambda m: float(np.mean((_simulate_segments(m, u_all, seg) - y_sorted) ** 2)))


def _simulate_segments(model: HammersteinWiener, u: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """``model`` run open loop over each segment of ``u`` on its own (settled at its first
    sample), concatenated segment by segment (``seg``: int per sample)."""
    return np.concatenate([model.simulate(u[seg == s]) for s in np.unique(seg)])


def _output_error_refit(start: HammersteinWiener, u: np.ndarray, y_sorted: np.ndarray,
                        seg: np.ndarray) -> HammersteinWiener:
    """The HW model of least open-loop error, from Bai's estimate ``start``.

    Bai's stage 1 is an equation-error fit: it weights the one-step prediction, which on a
    slowly varying Ω puts the pole near 1 and leaves the static gain, the small difference of
    two nearly equal lead coefficients, poorly determined: identified on the ``boson`` preset's
    chamber session it erred by ±10 °C at the session's FPA ends (the output runs open loop at
    apply time). For a given pole ``a`` the open-loop output is linear in ``b·cᵀ`` and the bias,
    so they are solved by least squares; ``a`` is searched (time constants from one sample to
    :data:`HW_MAX_TAU_S`, Bai's among them, then refined), and ``b·cᵀ`` factored by its
    leading singular pair as in Bai's stage 2; ``c`` and the bias are then refitted for that
    ``b``. Hand-written: the structure (a rank-1 bilinear term inside a linear filter) is not a
    problem a general optimiser exploits. ``y_sorted``: the output, segment by segment.
    """
    order = len(start.c)

    def columns(a: float, b: tuple[float, float] | None) -> np.ndarray:
        cols = []
        for bb in ([(1.0, 0.0), (0.0, 1.0)] if b is None else [b]):
            for i in range(order):
                unit = HammersteinWiener(tuple(float(k == i) for k in range(order)), a, bb, 0.0,
                                         start.u_scale, start.period_s)
                cols.append(_simulate_segments(unit, u, seg))
        return np.column_stack([*cols, np.ones(y_sorted.size)])

    def solve(a: float, b: tuple[float, float] | None = None) -> tuple[np.ndarray, float]:
        design = columns(a, b)
        sol, *_ = np.linalg.lstsq(design, y_sorted, rcond=None)
        return sol, float(np.mean((design @ sol - y_sorted) ** 2))

    taus = np.geomspace(start.period_s, max(HW_MAX_TAU_S, 2.0 * start.period_s), 25)
    grid = np.unique(np.r_[np.exp(-start.period_s / taus), start.a].clip(0.0, HW_MAX_POLE))
    costs = [solve(float(a))[1] for a in grid]
    best = int(np.argmin(costs))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    a = float(grid[best])
    if hi > lo:
        found = minimize_scalar(lambda x: solve(float(x))[1], bounds=(lo, hi), method="bounded",
                                options={"xatol": 1e-5})
        a = float(found.x) if found.fun < costs[best] else a
    sol, _ = solve(a)
    uu, ss, _ = np.linalg.svd(sol[: 2 * order].reshape(2, order))
    b = uu[:, 0] * ss[0]
    if not np.all(np.isfinite(b)):
        return start
    b_pair = (float(b[0]), float(b[1]))
    sol, _ = solve(a, b_pair)  # c and the bias for the factored b
    return HammersteinWiener(tuple(float(x) for x in sol[:order]), a, b_pair, float(sol[-1]),
                             start.u_scale, start.period_s)


@dataclass(frozen=True, eq=False)
class Wolf2016Calibration(StoredCalibrationMixin):
    """Fitted Wolf et al. (2016) model: ``S0`` (W·m⁻²·sr⁻¹ per count), ``S1``, ``S2`` (per °C)."""

    s0: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    bad: np.ndarray
    fpa_ref_c: float
    hw: HammersteinWiener
    fpa_range_c: tuple[float, float]
    hw_order: int = 3
    window: int = 1
    eta: float = 0.05
    warmup_frames: int = 100
    update_interval_s: float = 0.5
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6)
    info: dict[str, Any] = field(default_factory=dict)

    method = METHOD
    _layout = FileLayout(
        methods=(METHOD,),
        arrays={"s0": np.float32, "s1": np.float32, "s2": np.float32, "bad": bool},
        metadata={"fpa_ref_c": float, "hw": list, "hw_order": int, "window": int, "eta": float,
                  "warmup_frames": int, "update_interval_s": float, "band_m": tuple},
    )

    @property
    def shape(self) -> tuple[int, int]:
        return self.bad.shape  # type: ignore[return-value]

    def stream(self, **options: Any) -> Wolf2016Stream:
        """A fresh per-frame corrector (see :class:`Wolf2016Stream` for the options)."""
        return Wolf2016Stream(self, **options)

    def apply(self, frames: Any, *, fpa_c: Any = None, time_s: Any = None,
              frame_rate_hz: float = 30.0, **options: Any) -> np.ndarray:
        """Correct a recording from a cold start: scene temperature, °C, float32 ``(N, H, W)``.

        ``fpa_c`` (the FPA sensor, °C) is required; ``time_s`` defaults to frames at
        ``frame_rate_hz``. ``options`` go to :class:`Wolf2016Stream` (e.g. ``hw_start``: by
        default the HW block starts on the FPA ramp fitted to the first samples).
        """
        return self.stream(**options).correct(frames, fpa_c=fpa_c, time_s=time_s,
                                              frame_rate_hz=frame_rate_hz)

    def _metadata(self) -> dict[str, Any]:
        return super()._metadata() | {"hw": self.hw.to_list()}  # same place in the JSON

    @classmethod
    def _fields(cls, stored: StoredCalibration, path: str | Path) -> dict[str, Any]:
        kw = super()._fields(stored, path)
        order, values = kw["hw_order"], kw["hw"]
        try:
            if int(order) < 1 or len(values) != int(order) + 6:
                raise ValueError(f"{len(values)} values for order {order}")
            hw = HammersteinWiener.from_list(values, int(order))
        except (IndexError, TypeError, ValueError) as exc:
            raise FileFormatError(
                f"{path}: damaged wolf2016 calibration (Hammerstein-Wiener model: {exc})"
            ) from None
        return kw | {"hw": hw}

    @classmethod
    def _check_fields(cls, kw: dict[str, Any], stored: StoredCalibration,
                      path: str | Path) -> None:
        """Beyond finiteness: the band within :data:`~thermocal.calibration.store.BAND_LIMITS_M`,
        ``fpa_ref_c`` within :data:`~thermocal.calibration.store.FPA_LIMITS_C`; ``S0 > 0`` on
        every pixel (the fit marks the others bad and gives them the median) with a
        0 → 100 °C response ``ΔL / S0`` of
        :data:`~thermocal.calibration.store.RESPONSE_LIMITS_COUNTS`; the LMS options as
        :class:`Wolf2016Stream` accepts them (``0 < eta <= 1``, ``1 <= window <= 1024``,
        ``warmup_frames >= 0``, ``update_interval_s >= 0``); the HW model: order 1…10, every
        value finite, ``0 <= a <= 0.999`` (what the identification clips it to: a stable
        recursion), ``u_scale > 0`` (it divides), ``period_s`` in (0, 1 day] s."""
        super()._check_fields(kw, stored, path)
        m = METHOD
        check_band(kw["band_m"], path, m)
        check_scalar(kw["fpa_ref_c"], "fpa_ref_c", *FPA_LIMITS_C, path, m, unit="°C")
        s0 = kw["s0"].astype(np.float64)
        if not np.all(s0 > 0):
            raise damaged(path, m, "an S0 is not positive")
        band = band_for(tuple(kw["band_m"]))
        span = float(band.radiance(np.float64(100.0 + ZERO_CELSIUS_K))
                     - band.radiance(np.float64(ZERO_CELSIUS_K)))
        check_response(span / s0, path, m, "(S0)")
        check_scalar(kw["eta"], "eta", 0.0, 1.0, path, m, low_open=True)
        check_scalar(kw["window"], "window", 1, 1024, path, m, integer=True)
        check_scalar(kw["warmup_frames"], "warmup_frames", 0, 2**31, path, m, integer=True)
        check_scalar(kw["update_interval_s"], "update_interval_s", 0.0, 86400.0, path, m)
        check_scalar(kw["hw_order"], "hw_order", 1, 10, path, m, integer=True)
        hw = kw["hw"]
        if not all(np.isfinite(v) for v in hw.to_list()):
            raise damaged(path, m, "a Hammerstein-Wiener value is not finite")
        check_scalar(hw.a, "the HW pole a", 0.0, 0.999, path, m)
        check_scalar(hw.u_scale, "the HW u_scale", 0.0, np.inf, path, m, low_open=True)
        check_scalar(hw.period_s, "the HW period_s", 0.0, 86400.0, path, m, unit="s",
                     low_open=True)


class Wolf2016Stream:
    """Frame-by-frame Wolf et al. correction (a
    :class:`~thermocal.calibration.base.StreamingCorrector`): :meth:`correct_frame` corrects a
    frame with the current ΔT̂, :meth:`update` takes the LMS step from it, :meth:`process` does
    both and :meth:`correct` processes a stack.

    Parameters
    ----------
    calibration : Wolf2016Calibration
    eta : float, optional
        Normalised LMS rate (0 < eta ≤ 1); default the calibration's.
    window : int, optional
        ``W`` of the ``(2W+1)²`` local mean (eq. 11); default the calibration's (1).
    warmup_frames : int, optional
        Frames updated every frame at start (default 100).
    update_interval_s : float, optional
        Recording time between LMS updates after the warm-up, s (default 0.5).
    delta_t0_c : float
        Initial ΔT̂, °C (a cold start: 0).
    hw_start : {"ramp", "steady"}
        Initial state of the HW linear block (the paper does not specify one). ``"ramp"``
        (default): for the first ``hw_rate_window_s`` of recording time the state is held at the
        steady response to a ramp through the current FPA sample, at the rate fitted by least
        squares to the FPA samples seen so far (0 until they span ``hw_rate_min_s``); then the
        recursion runs from there. ``"steady"``: settled at the first sample (rate 0), which
        leaves the block's own lag (its time constant, minutes) to catch up when the stream
        starts while the FPA temperature is changing.
    hw_rate_window_s, hw_rate_min_s : float
        See ``hw_start`` (s; default 60 and 10).
    """

    def __init__(self, calibration: Wolf2016Calibration, *, eta: float | None = None,
                 window: int | None = None, warmup_frames: int | None = None,
                 update_interval_s: float | None = None, delta_t0_c: float = 0.0,
                 hw_start: str = "ramp", hw_rate_window_s: float = 60.0,
                 hw_rate_min_s: float = 10.0) -> None:
        cal = calibration
        self.calibration = cal
        self.eta = float(cal.eta if eta is None else eta)
        if not 0.0 < self.eta <= 1.0:
            raise InvalidInputError(f"eta must be in (0, 1], got {self.eta}")
        self.window = int(cal.window if window is None else window)
        if self.window < 1:
            raise InvalidInputError(f"window W must be >= 1, got {self.window}")
        self.warmup_frames = int(cal.warmup_frames if warmup_frames is None else warmup_frames)
        self.update_interval_s = float(
            cal.update_interval_s if update_interval_s is None else update_interval_s
        )
        self.delta_t_c = float(delta_t0_c)
        self.band = band_for(tuple(cal.band_m))
        self._s2_hp, self._norm = _s2_highpass(cal.s2, cal.bad, self.window)
        self._last_x: np.ndarray | None = None
        self._frames = 0
        self._last_update_s: float | None = None
        if hw_start not in ("ramp", "steady"):
            raise InvalidInputError(f"hw_start must be 'ramp' or 'steady', got {hw_start!r}")
        if not 0.0 <= hw_rate_min_s <= hw_rate_window_s:
            raise InvalidInputError("need 0 <= hw_rate_min_s <= hw_rate_window_s")
        self.hw_start = hw_start
        self.hw_rate_window_s = float(hw_rate_window_s) if hw_start == "ramp" else 0.0
        self.hw_rate_min_s = float(hw_rate_min_s)
        self._hw_time: float | None = None
        self._hw_t0 = 0.0
        self._hw_z = 0.0
        self._hw_v = 0.0
        self._fpa_sums = np.zeros(5)  # n, Σt, Σt², Σf, Σt·f of the FPA samples in the window
        self.history: list[float] = []

    def _fpa_rate(self, delta_t_c: float, time_s: float) -> float:
        """Least-squares FPA rate (°C/s) of the samples so far; 0 until they span the minimum."""
        t = time_s - self._hw_t0
        self._fpa_sums += (1.0, t, t * t, delta_t_c, t * delta_t_c)
        n, st, stt, sf, stf = self._fpa_sums
        var = stt - st * st / n
        if t < self.hw_rate_min_s or var <= 0:
            return 0.0
        return float((stf - st * sf / n) / var)

    def _omega(self, fpa_c: float, time_s: float) -> float:
        hw = self.calibration.hw
        d = fpa_c - self.calibration.fpa_ref_c
        if self._hw_time is None:
            self._hw_time = self._hw_t0 = time_s
        steps = int((time_s - self._hw_time) // hw.period_s) if hw.period_s > 0 else 0
        if steps > 0:
            self._hw_time += steps * hw.period_s
        if time_s - self._hw_t0 <= self.hw_rate_window_s:  # the start: no history to recurse on
            rate = self._fpa_rate(d, time_s) if self.hw_start == "ramp" else 0.0
            self._hw_z, self._hw_v = hw.initial_state(d, rate)
            return self._hw_z + hw.bias
        v = float(hw.nonlinearity(d))
        for _ in range(min(max(steps, 0), 10_000)):  # HW runs once per period of recording time
            self._hw_z = hw.a * self._hw_z + hw.b[0] * v + hw.b[1] * self._hw_v
            self._hw_v = v
        return self._hw_z + hw.bias

    def correct_frame(self, frame: Any, *, fpa_c: float, time_s: float) -> np.ndarray:
        """Scene temperature of one frame ``(H, W)`` (raw counts), °C, float32 ``(H, W)``, with
        the current ΔT̂ (the HW block advanced to ``time_s``, s; ``fpa_c``: the FPA sensor, °C).
        """
        return self._correct(check_frames(frame, self.calibration.shape)[0], fpa_c, time_s)

    def _correct(self, counts: np.ndarray, fpa_c: float, time_s: float) -> np.ndarray:
        """:meth:`correct_frame` of checked counts ``(H, W)``."""
        cal = self.calibration
        x = counts.astype(np.float32) * cal.s0
        x += cal.s1
        x += cal.s2 * np.float32(self.delta_t_c)
        x += np.float32(self._omega(float(fpa_c), float(time_s)))
        self._last_x = x
        self._last_time = float(time_s)
        lo, hi = self.band.radiance_range
        temp = self.band.temperature(np.clip(x, lo, hi)) - np.float32(ZERO_CELSIUS_K)
        return fill_bad_pixels(temp[None], cal.bad)[0]

    def update(self) -> bool:
        """Learn: one LMS step (eq. 10–11) from the last corrected frame, if one is due; True if
        done."""
        if self._last_x is None:
            raise InvalidInputError("Wolf2016Stream.update: correct a frame first")
        self._frames += 1
        due = (
            self._frames <= self.warmup_frames
            or self._last_update_s is None
            or self._last_time - self._last_update_s >= self.update_interval_s
        )
        if due:
            grad = float(np.sum(self._s2_hp * self._last_x, dtype=np.float64))
            self.delta_t_c -= self.eta * grad / self._norm
            self._last_update_s = self._last_time
        self.history.append(self.delta_t_c)
        return due

    def process(self, frame: Any, *, fpa_c: float, time_s: float) -> np.ndarray:
        """:meth:`correct_frame` then :meth:`update`: the temperature of this frame, °C
        ``(H, W)``."""
        temp = self.correct_frame(frame, fpa_c=fpa_c, time_s=time_s)
        self.update()
        return temp

    def correct(self, frames: Any, *, fpa_c: Any, time_s: Any = None,
                frame_rate_hz: float = 30.0) -> np.ndarray:
        """:meth:`process` every frame of raw counts ``(N, H, W)`` in order: °C, float32
        ``(N, H, W)``.

        ``fpa_c`` (the FPA sensor, °C: one value or one per frame) is required and checked
        against the calibrated range (a warning); ``time_s`` (s, one per frame) defaults to
        frames at ``frame_rate_hz``.
        """
        counts = check_frames(frames, self.calibration.shape)
        n = len(counts)
        fpa = require_fpa(fpa_c, n, METHOD)
        warn_outside_range(fpa, self.calibration.fpa_range_c, METHOD)
        t = (np.arange(n) / frame_rate_hz if time_s is None
             else per_frame_series(time_s, n, "time_s", temperature=False))
        out = np.empty(counts.shape, dtype=np.float32)
        for k in range(n):
            out[k] = self._correct(counts[k], float(fpa[k]), float(t[k]))
            self.update()
        return out


def _s2_highpass(s2: np.ndarray, bad: np.ndarray, window: int) -> tuple[np.ndarray, float]:
    """The LMS kernel and its normalisation.

    With ``hp(x) = x − E[x]`` (eq. 11, a symmetric box filter), the gradient of eq. 10,
    ``Σ hp(S2)·hp(X̂)``, equals ``Σ K·X̂`` with ``K = hp(hp(S2))`` (the adjoint; exact away from
    the border): one dot product per update instead of a filter. Returns ``K`` (zero on bad
    pixels) and ``Σ K·S2`` (the gradient's response to ΔT̂, for the normalised step).
    """
    good = ~bad
    filled = np.where(good, s2, np.median(s2[good])).astype(np.float32)
    size = 2 * window + 1
    hp = filled - uniform_filter(filled, size=size, mode="mirror")
    kernel = hp - uniform_filter(hp, size=size, mode="mirror")
    kernel = (kernel - kernel[good].mean()) * good  # blind to a uniform X̂, as hp(X̂) is
    norm = float(np.sum(kernel.astype(np.float64) * filled))
    return kernel.astype(np.float32), norm if norm > 0 else 1.0


def _lms_fixed_point(x0: np.ndarray, kernel: np.ndarray, norm: float) -> float:
    """The ΔT̂ at which the LMS of eq. 10 stops on a frame with ``S0·Y + S1 = x0``."""
    return -float(np.sum(kernel * x0, dtype=np.float64)) / norm


def wolf2016(
    session: Any,
    *,
    fpa_ref_c: float | None = None,
    fpa_window_c: float = 3.0,
    hw_order: int = 3,
    hw_setpoints_c: Any = None,
    frames: str = "settled",
    window: int = 1,
    eta: float = 0.05,
    warmup_frames: int = 100,
    update_interval_s: float = 0.5,
    outlier_mads: float = 10.0,
    band_m: tuple[float, float] = (7.5e-6, 13.5e-6),
    chunk: int = 64,
) -> Wolf2016Calibration:
    """Fit Wolf et al. (2016) to a chamber session.

    Parameters
    ----------
    session : ChamberSession, ChamberData or path
    fpa_ref_c : float, optional
        Reference FPA temperature (ΔT = 0), °C; default the first frame's.
    fpa_window_c : float
        ``S0, S1, S2`` are fitted on the frames within ``± fpa_window_c`` of the reference (the
        paper: ΔT of 0 and 4 °C); the HW estimator on the whole session.
    hw_order : int
        Order of the HW input polynomial (3 in the paper).
    hw_setpoints_c : sequence of float, optional
        Identify Ω only on frames at these blackbody set points (default: every frame). Ω is
        one uniform term for every scene: identify it on the scenes you will measure.
    frames : {"stable", "settled", "all"}
        Frames used for ``S0, S1, S2`` by FPA stability.
    window, eta, warmup_frames, update_interval_s
        Defaults of the online LMS (see :class:`Wolf2016Stream`).

    Raises
    ------
    FitError
        Fewer than 2 set points or an FPA span under 1 °C near the reference (3 points with 2
        temperatures and 2 ΔT are the minimum of eq. 7–9), or too few frames for the HW model.
    """
    data = prepare_chamber(session)
    band = band_for(tuple(band_m))
    first = int(np.flatnonzero(data.usable)[0])
    ref = float(data.fpa_c[first]) if fpa_ref_c is None else float(fpa_ref_c)
    near = data.usable & stability_mask(data, frames) & (np.abs(data.fpa_c - ref) <= fpa_window_c)
    what = (f"{describe_frames(data, frames)} within ±{fpa_window_c:g} °C of the reference FPA "
            f"{ref:.2f} °C")
    require_setpoints(data, 2, "wolf2016 (S0, S1, S2 of eq. 7-9)", near, frames=what,
                      record="record >= 2 set points with the FPA near the reference, or choose "
                      "another fpa_ref_c")
    require_fpa_span(data, 1.0, "wolf2016 (S2 of eq. 7-9)", near, frames=what,
                     record="record the FPA at two temperatures >= 1 °C apart near the "
                     "reference, or widen fpa_window_c")
    x_all = np.asarray(band.radiance(data.scene_c + ZERO_CELSIUS_K), dtype=np.float64)
    dt_all = data.fpa_c - ref
    h, w = data.frame_shape
    scan = FrameScan((h, w), data.session.bit_depth)
    # Per-pixel normal equations of X = S0·Y + S1 + S2·ΔT (eq. 7–9 in least squares).
    sy = np.zeros((h, w))
    syy = np.zeros((h, w))
    syd = np.zeros((h, w))
    syx = np.zeros((h, w))
    n = sd = sdd = sx = sxd = 0.0
    ref_counts: np.ndarray | None = None
    for idx, block in iter_frames(data.session, np.flatnonzero(near), chunk=chunk):
        keep = scan.check(idx, block)
        if not keep.any():
            continue
        y = block[keep].astype(np.float64)
        if ref_counts is None:
            ref_counts = y[0].copy()
        y -= ref_counts
        d = dt_all[idx[keep]]
        x = x_all[idx[keep]]
        sy += y.sum(0)
        syy += np.einsum("kij,kij->ij", y, y)
        syd += np.tensordot(d, y, axes=1)
        syx += np.tensordot(x, y, axes=1)
        n += d.size
        sd += d.sum()
        sdd += d @ d
        sx += x.sum()
        sxd += x @ d
    if ref_counts is None:
        raise FitError("wolf2016: every calibration frame is saturated")
    mat = np.empty((h, w, 3, 3))
    mat[..., 0, 0], mat[..., 0, 1], mat[..., 0, 2] = syy, sy, syd
    mat[..., 1, 0], mat[..., 1, 1], mat[..., 1, 2] = sy, n, sd
    mat[..., 2, 0], mat[..., 2, 1], mat[..., 2, 2] = syd, sd, sdd
    rhs = np.stack([syx, np.full((h, w), sx), np.full((h, w), sxd)], axis=-1)
    bad = scan.saturated_pixels()
    det = np.linalg.det(mat)
    bad |= ~(np.abs(det) > 1e-12 * np.abs(mat[..., 0, 0] * n * sdd).clip(1e-300))
    mat[bad] = np.eye(3)
    sol = np.linalg.solve(mat, rhs[..., None])[..., 0]
    s0, s1, s2 = sol[..., 0], sol[..., 1] - sol[..., 0] * ref_counts, sol[..., 2]
    bad |= (s0 <= 0) | robust_outliers(s0, mads=outlier_mads, valid=~bad)
    if bad.mean() > 0.5:
        raise FitError("wolf2016: more than half of the pixels did not respond")
    for arr in (s0, s1, s2):
        arr[bad] = np.median(arr[~bad])
    s0, s1, s2 = (a.astype(np.float32) for a in (s0, s1, s2))

    # Ω: per-frame spatial mean residual over the session, in time order, sampled on the
    # session's frame interval; identified by Bai's two-stage method. The residual is taken with
    # the ΔT̂ the online LMS converges to on each frame (its fixed point: X̂ locally flattest),
    # so that Ω completes what S2·ΔT̂ leaves at apply time.
    hw_sel = data.usable.copy()
    if hw_setpoints_c is not None:
        wanted = np.asarray(hw_setpoints_c, dtype=np.float64)
        hw_sel &= np.isin(np.round(data.session.blackbody_c, 6), np.round(wanted, 6))
        if not hw_sel.any():
            raise FitError(f"wolf2016: no frame at the HW set points {list(wanted)} °C")
    hw_idx = np.flatnonzero(hw_sel)
    mean_model = np.full(data.n_frames, np.nan)
    lms_dt = np.full(data.n_frames, np.nan)
    good = ~bad
    s2_hp, norm = _s2_highpass(s2, bad, window)
    s2_mean = float(s2[good].mean())
    hw_saturated: list[int] = []
    for idx, block in iter_frames(data.session, hw_idx, chunk=chunk):
        over = saturated_fraction(block, data.session.bit_depth) > SATURATED_FRACTION
        hw_saturated.extend(int(i) for i in idx[over])
        for i, frame in zip(idx[~over], block[~over], strict=True):
            x0 = frame.astype(np.float32) * s0 + s1
            d_hat = _lms_fixed_point(x0, s2_hp, norm)
            lms_dt[i] = d_hat
            mean_model[i] = float(x0[good].mean()) + s2_mean * d_hat
    excluded = np.zeros(data.n_frames, dtype=bool)
    excluded[scan.excluded] = True
    excluded[hw_saturated] = True
    valid = hw_sel & np.isfinite(mean_model) & ~excluded
    # Resample on a uniform grid of the session's frame interval (the ARX model needs equal
    # steps), run by run: a gap of more than 5 frame intervals in the session (another chamber
    # run, a pause) starts a new segment.
    session_steps = np.diff(data.time_s)
    period = float(np.median(session_steps)) if session_steps.size else 1.0
    run = np.r_[0, np.cumsum(session_steps > 5 * period)]
    resid = x_all - mean_model
    omegas, dgrids, segs = [], [], []
    for i in np.unique(run[valid]):
        sel = valid & (run == i)
        t = data.time_s[sel]
        if t.size < 2:
            continue
        grid = np.arange(t[0], t[-1] + 0.5 * period, period)
        omegas.append(np.interp(grid, t, resid[sel]))
        dgrids.append(np.interp(grid, t, dt_all[sel]))
        segs.append(np.full(grid.size, len(segs)))
    if not omegas:
        raise FitError("wolf2016: no run of consecutive frames to identify the HW estimator")
    omega, dgrid, seg = np.concatenate(omegas), np.concatenate(dgrids), np.concatenate(segs)
    hw = identify_hammerstein_wiener(dgrid, omega, period_s=period, order=hw_order, segments=seg)
    sim = _simulate_segments(hw, dgrid, seg)
    used = data.fpa_c[valid]
    info = calibration_info(data.session) | scan.report() | {
        "excluded_frames": int(excluded.sum()),
        "excluded_frame_indices": [int(i) for i in np.flatnonzero(excluded)[:50]],
        "frames_used_s": scan.n_seen,
        "frames_used_hw": int(valid.sum()),
        "lms_fixed_point_rms_c": float(np.sqrt(np.nanmean((lms_dt - dt_all)[valid] ** 2))),
        "hw_rms_residual": float(np.sqrt(np.mean((sim - omega) ** 2))),
        "hw_segments": int(seg.max() + 1),
    }
    return Wolf2016Calibration(
        s0=s0, s1=s1, s2=s2, bad=bad, fpa_ref_c=ref, hw=hw,
        fpa_range_c=(float(used.min()), float(used.max())), hw_order=hw_order, window=window,
        eta=eta, warmup_frames=warmup_frames, update_interval_s=update_interval_s,
        band_m=tuple(band_m), info=info,
    )
