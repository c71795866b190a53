"""The second camera family (``boson``): each part whose form differs from ``tau2`` is there and
recovers its known answer, and ``tau2`` is unchanged by the forms' existence."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from thermocal.camera.model import expected_counts, fpa_basis, invert, render
from thermocal.camera.presets import BOSON, PRESETS, CameraPreset, make_camera
from thermocal.camera.thermal import ThermalParams, thermal_response
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError
from thermocal.radiometry import BandRadiance, band_radiance
from thermocal.simulate.chamber import ChamberPlan, simulate_chamber

SIZE = (64, 48)


@pytest.fixture(scope="module")
def boson():
    return make_camera("boson", unit=5, size=SIZE)


@pytest.fixture(scope="module")
def tau2():
    return make_camera("tau2", unit=5, size=SIZE)


def test_registry_has_both_families():
    assert set(PRESETS) == {"tau2", "boson"}
    assert PRESETS["boson"] is BOSON


def test_response_to_fpa_is_exponential(boson, tau2):
    """boson: G(t) = G0 · (1 + s·expm1(−Δt/120 °C)), s the unit's own tempco scale;
    tau2: a cubic."""
    x = np.array([-20.0, -5.0, 0.0, 10.0, 30.0])
    g = np.array([boson.gain_at(25.0 + d)[10, 10] for d in x], dtype=np.float64)
    s = (g / g[2] - 1.0)[x != 0] / np.expm1(-x[x != 0] / 120.0)
    np.testing.assert_allclose(s, s[0], rtol=1e-3)
    assert 0.8 < s[0] < 1.2
    g2 = np.array([tau2.gain_at(25.0 + d)[10, 10] for d in x], dtype=np.float64)
    cubic = np.polyval(np.polyfit(x, g2, 3), x)
    np.testing.assert_allclose(cubic, g2, rtol=1e-5)
    np.testing.assert_allclose(fpa_basis(2.0), [1, 2, 4, 8])
    np.testing.assert_allclose(fpa_basis(2.0, (10.0, -5.0)),
                               [1, 2, 10 * np.expm1(0.2), -5 * np.expm1(-0.4)])


def test_spectral_response_weights_the_band(boson):
    """The boson band is ∫ s(λ) B dλ with its sloped response, not the flat 8–14 µm band."""
    flat = BandRadiance(band_m=(8e-6, 14e-6))
    t = np.array([273.15, 300.0, 350.0])
    weighted = boson.band.radiance(t)
    assert np.all(weighted < 0.95 * flat.radiance(t))
    # by hand: a trapezoid rule over a fine grid of the linear response
    lam = np.linspace(8e-6, 14e-6, 4001)
    s = np.interp(lam, *zip(*BOSON.spectral_response, strict=True))
    c1l, c2 = 1.191042972e-16, 1.438776877e-2
    planck = c1l / lam[:, None] ** 5 / np.expm1(c2 / (lam[:, None] * t))
    by_hand = np.trapezoid(s[:, None] * planck, lam, axis=0)
    np.testing.assert_allclose(weighted, by_hand, rtol=1e-4)
    np.testing.assert_allclose(boson.band.temperature(weighted), t, atol=1e-3)
    # a flat response is the plain band integral
    np.testing.assert_allclose(flat.radiance(t), band_radiance(t, (8e-6, 14e-6)), rtol=1e-5)
    with pytest.raises(InvalidInputError, match="spectral response"):
        BandRadiance(band_m=(8e-6, 14e-6), response=((9e-6, 0.5), (8.5e-6, 1.0)))


def test_line_fpn_runs_along_rows(boson, tau2):
    def line_spread(offset, axis):
        high = offset - gaussian_filter(offset, 4.0, mode="nearest")
        return float(np.std(np.median(high, axis=axis)))

    b, t = boson.gain[0], tau2.gain[0]  # the line factor on the responsivity
    assert line_spread(b, 1) > 2 * line_spread(b, 0)  # row medians vary: rows
    assert line_spread(t, 0) > 2 * line_spread(t, 1)  # column medians vary: columns
    assert "row_gain" in boson.info and "column_gain" not in boson.info


def test_housing_emission_is_a_one_sided_ramp(boson, tau2):
    """boson: H is linear across the frame (a warm side); tau2: radial (floor + R²)."""
    h = boson.housing.astype(np.float64)
    rows, cols = np.mgrid[0 : h.shape[0], 0 : h.shape[1]]
    design = np.stack([np.ones(h.size), rows.ravel(), cols.ravel()], axis=1)
    coef, res, *_ = np.linalg.lstsq(design, h.ravel(), rcond=None)
    assert np.sqrt(res[0] / h.size) < 1e-3 * h.mean()
    t = tau2.housing
    assert t[t.shape[0] // 2, t.shape[1] // 2] < t[0, 0]  # radial: the corners above the centre


def test_optics_lag_is_second_order_and_transient_lags():
    """After an ambient step the optics start with zero slope (two lags in series); the
    transient term's rate rises later than the FPA rate itself."""
    params = BOSON.thermal
    t = np.arange(0, 1200.0, 1.0)
    ambient = np.where(t < 10, 20.0, 30.0)
    state = thermal_response(t, ambient, params)
    first = ThermalParams(tau_housing_s=params.tau_housing_s)
    single = thermal_response(t, ambient, first)
    k = 20  # 10 s after the step
    assert state.housing_c[k] - 23.0 < 0.2 * (single.housing_c[k] - 24.0)
    assert state.housing_c[-1] == pytest.approx(single.housing_c[-1] - 1.0, abs=0.5)
    peak_rate = int(np.argmax(state.fpa_rate_c_per_min))
    peak_seen = int(np.argmax(state.transient_rate_c_per_min))
    assert peak_seen > peak_rate + 10
    tau2_state = thermal_response(t, ambient)
    np.testing.assert_array_equal(tau2_state.transient_rate_c_per_min,
                                  tau2_state.fpa_rate_c_per_min)


def test_drift_and_noise(boson):
    """1/f drift: deterministic in time, of the stated RMS, with more power at low frequency;
    the warm-up decays; row noise makes whole rows move together."""
    t = np.arange(0, 20000.0, 0.5)
    d = boson.drift_at(t + 1e5) - boson.warmup_counts * np.exp(-(t + 1e5) / boson.warmup_tau_s)
    assert np.std(d) == pytest.approx(boson.flicker_counts, rel=0.35)
    np.testing.assert_array_equal(boson.drift_at(t[:100]), boson.drift_at(t[:100]))
    spectrum = np.abs(np.fft.rfft(d)) ** 2
    freq = np.fft.rfftfreq(d.size, 0.5)
    low = spectrum[(freq > 1e-3) & (freq < 1e-2)].mean()
    high = spectrum[(freq > 1e-1) & (freq < 1.0)].mean()
    assert low > 5 * high
    assert boson.drift_at([0.0])[0] > boson.drift_at([3600.0])[0] + 0.5 * boson.warmup_counts
    rng = np.random.default_rng(0)
    frames = render(boson, np.full((40, *boson.shape), 20.0), 30.0, rng=rng, time_s=None)
    resid = frames.astype(np.float64) - frames.mean(axis=0)
    row_means = resid.mean(axis=2)
    assert np.std(row_means) == pytest.approx(boson.row_noise_counts, rel=0.3)


def test_render_inverts_with_drift_and_chunks(boson):
    """The oracle inversion recovers the scene from boson frames with their drift; a chamber
    session's frames do not depend on the chunk size (the drift is a function of time)."""
    rng = np.random.default_rng(1)
    scene = np.full((3, *boson.shape), 35.0, np.float32)
    times = [1800.0, 1800.1, 1800.2]
    frames = render(boson, scene, 32.0, rng=rng, time_s=times)
    temps = invert(boson, frames, 32.0, time_s=times)
    assert abs(float(np.median(temps)) - 35.0) < 0.05
    plan = ChamberPlan(setpoints_c=(20.0, 40.0), frames_per_point=2, profile="ramp",
                       ambient_c=(15.0, 25.0), duration_s=200.0, interval_s=10.0)
    one = np.concatenate([c.frames for c in simulate_chamber(boson, plan, seed=3, chunk=100)])
    many = np.concatenate([c.frames for c in simulate_chamber(boson, plan, seed=3, chunk=3)])
    np.testing.assert_array_equal(one, many)


def test_counts_of_the_two_families_overlap(boson, tau2):
    """Plausible counts: the families are not told apart by their count levels alone."""
    for scene in (0.0, 30.0, 60.0):
        b = expected_counts(boson, np.array([scene]), 30.0, time_s=[1800.0]).mean()
        t = expected_counts(tau2, np.array([scene]), 30.0).mean()
        assert abs(b - t) < 0.15 * t


def test_tau2_preset_parameters_are_stored_as_before():
    """The new form fields are left out of tau2's stored parameters (files made before them
    stay valid and their checksums unchanged) and read back to the same preset."""
    d = CameraPreset().as_dict()
    assert "thermal" not in d and "fpn" not in d
    assert CameraPreset.from_dict(d) == CameraPreset()
    b = json.loads(json.dumps(BOSON.as_dict()))
    assert CameraPreset.from_dict(b) == BOSON
    assert set(asdict(BOSON)) == set(b)
    with pytest.raises(InvalidInputError, match="fpn"):
        CameraPreset(fpn="diagonal")


def test_simulators_use_the_family_thermal_params(boson):
    plan = ChamberPlan(setpoints_c=(20.0,), frames_per_point=1, profile="constant",
                       ambient_c=(20.0, 20.0), duration_s=30.0, interval_s=10.0)
    chunk = next(simulate_chamber(boson, plan, seed=0))
    expected = BOSON.thermal.steady_fpa_c(20.0)
    assert np.allclose(chunk.fpa_true_c, expected, atol=0.01)
    assert expected != ThermalParams().steady_fpa_c(20.0)
    assert float(ZERO_CELSIUS_K) == 273.15
