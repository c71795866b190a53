"""Thermal state of the camera: ambient profiles, housing and FPA lags, the FPA sensor.

The ambient temperature drives the housing through a first-order lag of minutes; the housing drives
the FPA through a faster lag; the electronics heat both (self-heating offsets). The camera reports
the FPA temperature through a quantised, noisy sensor. All temperatures °C, times s, rates °C/min.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thermocal._validate import as_float_array, as_temperature_c
from thermocal.errors import InvalidInputError

PROFILES = ("constant", "steps", "ramp", "sawtooth")

#: Time after switch-on at which the simulators start a session or a flight, s (the camera has
#: warmed up for half an hour, as a careful operator does; what drift remains shows).
WARMED_UP_S = 1800.0


@dataclass(frozen=True)
class ThermalParams:
    """Time constants (s), self-heating offsets (°C) and the FPA sensor of a camera.

    ``tau_optics_s``: when > 0, what radiates onto the FPA (lens and inner housing) follows the
    housing through one more first-order lag, so that the optics lag the ambient with a
    second-order response; 0 (``tau2``): they are at the housing temperature. ``transient_lag_s``:
    when > 0, the transient term of the camera model sees the FPA rate through a first-order lag
    (a term that builds up and dies away after the FPA changes pace); 0: the rate itself.
    """

    tau_housing_s: float = 300.0
    tau_fpa_s: float = 60.0
    housing_self_heating_c: float = 4.0
    fpa_self_heating_c: float = 1.5
    sensor_quantum_c: float = 0.01
    sensor_noise_c: float = 0.01
    tau_optics_s: float = 0.0
    transient_lag_s: float = 0.0

    def steady_fpa_c(self, ambient_c: float) -> float:
        """FPA temperature once the camera has settled at a constant ambient, °C."""
        return ambient_c + self.housing_self_heating_c + self.fpa_self_heating_c

    def ambient_for_fpa_c(self, fpa_c: float) -> float:
        """The constant ambient that settles the FPA at ``fpa_c``, °C."""
        return fpa_c - self.housing_self_heating_c - self.fpa_self_heating_c


@dataclass(frozen=True)
class ThermalState:
    """The camera's temperatures at each sample time, all ``(N,)``.

    ``housing_c`` is the temperature of what radiates onto the FPA (the optics, with
    :attr:`ThermalParams.tau_optics_s`); ``transient_rate_c_per_min`` the FPA rate as the
    camera's transient term sees it (the rate itself unless ``transient_lag_s`` > 0): pass it as
    ``fpa_rate_c_per_min`` to :func:`thermocal.camera.model.render`.
    """

    time_s: np.ndarray
    ambient_c: np.ndarray
    housing_c: np.ndarray
    fpa_c: np.ndarray
    fpa_rate_c_per_min: np.ndarray
    transient_rate_c_per_min: np.ndarray


def profile_duration_s(
    kind: str, *, low_c: float, high_c: float, rate_c_per_min: float, step_c: float = 5.0,
    hold_s: float = 1200.0,
) -> float:
    """The natural length of an ambient profile, s (one full cycle; ``constant``: ``hold_s``)."""
    span = abs(high_c - low_c)
    if kind == "constant":
        return hold_s
    if kind == "ramp":
        return 60.0 * span / rate_c_per_min + hold_s / 2
    if kind == "sawtooth":
        return 2 * 60.0 * span / rate_c_per_min
    if kind == "steps":
        return (int(np.floor(span / step_c + 1e-9)) + 1) * hold_s
    raise InvalidInputError(f"unknown ambient profile {kind!r}; choose from {', '.join(PROFILES)}")


def ambient_profile(
    kind: str,
    time_s: np.ndarray,
    *,
    low_c: float,
    high_c: float,
    rate_c_per_min: float = 1.0,
    step_c: float = 5.0,
    hold_s: float = 1200.0,
) -> np.ndarray:
    """Ambient temperature at each time, °C, ``(N,)``.

    ``constant`` stays at ``low_c``; ``ramp`` goes from ``low_c`` to ``high_c`` at
    ``rate_c_per_min`` and holds; ``sawtooth`` goes up and down between them at that rate,
    repeatedly; ``steps`` climbs by ``step_c`` every ``hold_s`` seconds (instant steps; the
    camera's lags smooth them).
    """
    t = as_float_array(time_s, "time_s", ndim=1)
    as_temperature_c([low_c, high_c], "ambient range")
    if rate_c_per_min <= 0:
        raise InvalidInputError(f"rate must be > 0 °C/min, got {rate_c_per_min}")
    span = high_c - low_c
    if kind == "constant":
        return np.full(t.shape, float(low_c))
    if kind == "ramp":
        return low_c + np.sign(span) * np.minimum(rate_c_per_min * t / 60.0, abs(span))
    if kind == "sawtooth":
        if span == 0:
            return np.full(t.shape, float(low_c))
        period = 2 * 60.0 * abs(span) / rate_c_per_min
        phase = np.mod(t, period) / period
        return low_c + span * (1.0 - np.abs(2.0 * phase - 1.0))
    if kind == "steps":
        if step_c <= 0 or hold_s <= 0:
            raise InvalidInputError("steps need step_c > 0 and hold_s > 0")
        n_steps = int(np.floor(abs(span) / step_c + 1e-9))
        k = np.minimum(np.floor(t / hold_s), n_steps)
        return low_c + np.sign(span) * step_c * k
    raise InvalidInputError(f"unknown ambient profile {kind!r}; choose from {', '.join(PROFILES)}")


def _lag(u: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """First-order lag ``τ dy/dt = u − y`` sampled every ``dt``, starting settled at ``u[0]``.

    Exact for an input held constant between samples (zero-order hold), as an IIR filter.
    """
    # imported here: scipy.signal takes 0.7 s to import, which every command would pay
    from scipy.signal import lfilter, lfilter_zi

    a = np.exp(-dt / tau)
    b, den = [0.0, 1.0 - a], [1.0, -a]
    y, _ = lfilter(b, den, u, zi=lfilter_zi(b, den) * u[0])
    return y


def thermal_response(
    time_s: np.ndarray, ambient_c: np.ndarray, params: ThermalParams = ThermalParams()
) -> ThermalState:
    """Housing and FPA temperatures (°C) and the FPA rate (°C/min) for an ambient series.

    ``time_s`` must be evenly spaced; the camera starts settled at the first ambient value.
    """
    t = as_float_array(time_s, "time_s", ndim=1)
    amb = as_temperature_c(ambient_c, "ambient_c", ndim=1)
    if t.shape != amb.shape or t.size == 0:
        raise InvalidInputError(f"time_s {t.shape} and ambient_c {amb.shape} must match, non-empty")
    dt = float(t[1] - t[0]) if t.size > 1 else 1.0
    if t.size > 1 and (dt <= 0 or not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-9)):
        raise InvalidInputError("time_s must be evenly spaced and increasing")
    housing = _lag(amb + params.housing_self_heating_c, dt, params.tau_housing_s)
    target = housing + params.fpa_self_heating_c
    fpa = _lag(target, dt, params.tau_fpa_s)
    rate = 60.0 * (target - fpa) / params.tau_fpa_s
    optics = _lag(housing, dt, params.tau_optics_s) if params.tau_optics_s > 0 else housing
    seen = _lag(rate, dt, params.transient_lag_s) if params.transient_lag_s > 0 else rate
    return ThermalState(t, amb, optics, fpa, rate, seen)


def fpa_sensor(
    fpa_c: np.ndarray, params: ThermalParams = ThermalParams(), *, rng: np.random.Generator
) -> np.ndarray:
    """What the camera reports as its FPA temperature: true value + noise, quantised, °C."""
    fpa = as_temperature_c(fpa_c, "fpa_c")
    reading = fpa + params.sensor_noise_c * rng.standard_normal(fpa.shape)
    if params.sensor_quantum_c > 0:
        reading = np.round(reading / params.sensor_quantum_c) * params.sensor_quantum_c
    return reading
