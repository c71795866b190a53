"""Thermal state: ambient profiles, lags, self-heating and the FPA sensor."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal.camera.thermal import (
    ThermalParams,
    ambient_profile,
    fpa_sensor,
    profile_duration_s,
    thermal_response,
)
from thermocal.errors import InvalidInputError


def test_constant_ambient_settles_with_self_heating():
    p = ThermalParams()
    t = np.arange(0.0, 600.0, 2.0)
    state = thermal_response(t, np.full(t.shape, 20.0), p)
    np.testing.assert_allclose(state.housing_c, 20.0 + p.housing_self_heating_c)
    np.testing.assert_allclose(state.fpa_c, p.steady_fpa_c(20.0))
    np.testing.assert_allclose(state.fpa_rate_c_per_min, 0.0, atol=1e-12)
    assert p.ambient_for_fpa_c(p.steady_fpa_c(20.0)) == pytest.approx(20.0)


def test_housing_lag_reaches_63_percent_after_one_time_constant():
    p = ThermalParams(tau_housing_s=300.0)
    t = np.arange(0.0, 2000.0, 1.0)
    ambient = np.where(t > 0, 30.0, 20.0)
    state = thermal_response(t, ambient, p)
    rise = (state.housing_c - state.housing_c[0]) / 10.0
    assert rise[300] == pytest.approx(1 - np.exp(-1), abs=0.01)
    # the FPA lags the housing: it is behind it during the step
    assert np.all(state.fpa_c[1:400] - p.fpa_self_heating_c <= state.housing_c[1:400] + 1e-9)


def test_fpa_rate_matches_the_numerical_derivative():
    t = np.arange(0.0, 3600.0, 1.0)
    amb = ambient_profile("sawtooth", t, low_c=10.0, high_c=35.0, rate_c_per_min=2.0)
    state = thermal_response(t, amb)
    numeric = np.gradient(state.fpa_c, t) * 60.0
    np.testing.assert_allclose(state.fpa_rate_c_per_min[5:-5], numeric[5:-5], atol=0.02)


@pytest.mark.parametrize("kind", ["constant", "steps", "ramp", "sawtooth"])
def test_profiles_stay_in_range_and_have_a_duration(kind):
    dur = profile_duration_s(kind, low_c=10.0, high_c=30.0, rate_c_per_min=1.0)
    t = np.linspace(0.0, dur, 500)
    amb = ambient_profile(kind, t, low_c=10.0, high_c=30.0, rate_c_per_min=1.0)
    assert amb.min() >= 10.0 - 1e-9 and amb.max() <= 30.0 + 1e-9
    if kind != "constant":
        assert amb.max() == pytest.approx(30.0, abs=0.1)


def test_sawtooth_goes_up_and_back_at_the_rate():
    t = np.arange(0.0, 3000.0, 10.0)
    amb = ambient_profile("sawtooth", t, low_c=10.0, high_c=30.0, rate_c_per_min=1.0)
    slope = np.abs(np.diff(amb)) / 10.0 * 60.0
    assert np.median(slope) == pytest.approx(1.0)
    assert amb[np.searchsorted(t, 1200.0)] == pytest.approx(30.0)


def test_fpa_sensor_is_quantised_and_noisy():
    p = ThermalParams(sensor_quantum_c=0.01, sensor_noise_c=0.02)
    true = np.full(10000, 30.004)
    reading = fpa_sensor(true, p, rng=np.random.default_rng(0))
    np.testing.assert_allclose(reading * 100, np.round(reading * 100), atol=1e-6)
    assert reading.std() == pytest.approx(0.02, rel=0.1)
    assert reading.mean() == pytest.approx(30.004, abs=0.002)


def test_bad_profiles_and_times():
    t = np.arange(10.0)
    with pytest.raises(InvalidInputError, match="unknown ambient profile"):
        ambient_profile("wiggle", t, low_c=0.0, high_c=1.0)
    with pytest.raises(InvalidInputError, match="rate"):
        ambient_profile("ramp", t, low_c=0.0, high_c=1.0, rate_c_per_min=0.0)
    with pytest.raises(InvalidInputError, match="evenly spaced"):
        thermal_response(np.array([0.0, 1.0, 5.0]), np.zeros(3))
    with pytest.raises(InvalidInputError, match="absolute zero"):
        thermal_response(t, np.full(10, -300.0))
