"""The camera model: known answers, and the properties DESIGN.md asks of the tau2 preset."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from thermocal import metrics
from thermocal.calibration.two_point import fit_two_point
from thermocal.camera import (
    ThermalParams,
    ambient_profile,
    expected_counts,
    invert,
    make_camera,
    radial_map,
    render,
    thermal_response,
)
from thermocal.errors import InvalidInputError, ResolutionMismatchError

THERMAL = ThermalParams()


def steady_housing(fpa_c: float) -> float:
    """Housing temperature of a camera settled with its FPA at ``fpa_c``."""
    return fpa_c - THERMAL.fpa_self_heating_c


def test_responsivity_is_tens_of_counts_per_degree_near_25c(small_camera):
    counts = expected_counts(small_camera, np.array([24.0, 26.0]), 25.0)
    responsivity = (counts[1] - counts[0]) / 2.0
    median = float(np.median(responsivity))
    assert 20.0 <= median <= 100.0
    assert np.all(responsivity[~small_camera.defects] > 0)


def test_netd_from_flat_fields_is_30_to_80_mk(rng):
    camera = make_camera("tau2", unit=0, size=(96, 64))
    low = render(camera, np.full(24, 20.0), 25.0, rng=rng)
    high = render(camera, np.full(24, 30.0), 25.0, rng=rng)
    good = ~camera.defects
    netd_k = metrics.netd(low[:, good][..., None], high[:, good][..., None], 20.0, 30.0)
    assert 0.030 <= netd_k <= 0.080


def test_two_point_at_one_fpa_is_off_by_several_degrees_10c_away(rng):
    camera = make_camera("tau2", unit=1, size=(64, 48))
    fpa_cal = 25.0
    housing = steady_housing(fpa_cal)
    low = render(camera, np.full(8, 15.0), fpa_cal, housing_c=housing, rng=rng)
    high = render(camera, np.full(8, 45.0), fpa_cal, housing_c=housing, rng=rng)
    cal = fit_two_point(low, high, 15.0, 45.0, fpa_ref_c=fpa_cal)

    scene = np.full(4, 30.0)
    same = render(camera, scene, fpa_cal, housing_c=housing, rng=rng)
    away = render(camera, scene, fpa_cal + 10.0, housing_c=steady_housing(fpa_cal + 10.0), rng=rng)
    good = ~camera.defects
    err_same = np.abs(cal.apply(same) - 30.0)[:, good].mean()
    err_away = np.abs(cal.apply(away) - 30.0)[:, good].mean()
    assert err_same < 0.2
    assert 2.0 <= err_away <= 20.0


def test_uniform_blackbody_shows_a_radial_pattern():
    camera = make_camera("tau2", unit=2, size=(160, 128))
    frame = expected_counts(camera, 30.0, 30.0, housing_c=steady_housing(30.0))[0]
    smooth = gaussian_filter(frame, 8.0, mode="nearest")
    r2 = radial_map(camera.shape, tuple(camera.info["optical_centre"])) ** 2
    inner = r2 < 0.02
    corr = np.corrcoef(smooth[~inner].ravel(), r2[~inner].ravel())[0, 1]
    assert abs(corr) > 0.9
    # centre to corner: tens of counts at least (a visible pattern, well above the noise)
    assert abs(smooth[r2 < 0.01].mean() - smooth[r2 > 0.4].mean()) > 40.0


def test_ignoring_the_transient_term_costs_over_1c_at_1c_per_min():
    camera = make_camera("tau2", unit=3, size=(48, 32))
    rate = 1.0
    counts = expected_counts(
        camera, 30.0, 30.0, housing_c=steady_housing(30.0), fpa_rate_c_per_min=rate
    )
    kw = {"housing_c": steady_housing(30.0), "fpa_rate_c_per_min": rate}
    exact = invert(camera, counts, 30.0, **kw)
    ignored = invert(camera.without_transient(), counts, 30.0, **kw)
    good = ~camera.defects
    assert np.abs(exact - 30.0)[:, good].max() < 1e-2
    assert np.abs(ignored - 30.0)[:, good].mean() >= 1.0


def test_a_1c_per_min_ambient_ramp_drives_the_fpa_at_about_1c_per_min():
    t = np.arange(0.0, 3600.0, 1.0)
    ramp = ambient_profile("ramp", t, low_c=0.0, high_c=80.0, rate_c_per_min=1.0)
    state = thermal_response(t, ramp)
    assert 0.9 <= state.fpa_rate_c_per_min[-1] <= 1.02


def test_invert_recovers_the_scene_noise_free(small_camera, rng):
    scene = 20.0 + 15.0 * rng.random((2, *small_camera.shape))
    counts = expected_counts(small_camera, scene, [22.0, 31.0], housing_c=[20.0, 29.0])
    est = invert(small_camera, counts, [22.0, 31.0], housing_c=[20.0, 29.0])
    good = ~small_camera.defects
    np.testing.assert_allclose(est[:, good], scene[:, good], atol=2e-3)


def test_render_is_14_bit_seeded_and_defects_stick(small_camera):
    a = render(small_camera, 25.0, 25.0, rng=np.random.default_rng(5))
    b = render(small_camera, 25.0, 25.0, rng=np.random.default_rng(5))
    assert a.dtype == np.uint16 and a.shape == (1, *small_camera.shape)
    np.testing.assert_array_equal(a, b)
    hot = render(small_camera, 600.0, 25.0, rng=np.random.default_rng(5))
    assert hot.max() == 16383  # saturates, clipped at 14 bits
    d = small_camera.defects
    np.testing.assert_array_equal(a[0][d], small_camera.defect_counts[d])


def test_temporal_noise_has_variance_about_5_counts2(small_camera):
    frames = render(small_camera, np.full(64, 25.0), 25.0, rng=np.random.default_rng(0))
    var = frames.astype(np.float64).var(axis=0, ddof=1)[~small_camera.defects]
    # rounding adds 1/12 count²
    assert 4.5 <= float(np.median(var)) <= 5.8


def test_units_differ_and_are_reproducible():
    a = make_camera("tau2", unit=0, size=(64, 48))
    b = make_camera("tau2", unit=1, size=(64, 48))
    a2 = make_camera("tau2", unit=0, size=(64, 48))
    np.testing.assert_array_equal(a.gain, a2.gain)
    assert not np.allclose(a.gain, b.gain)
    assert a.info["radial_strength"] != b.info["radial_strength"]
    big = make_camera("tau2", unit=0, size=(640, 512))
    assert big.shape == (512, 640)
    assert big.info["optical_centre"] == a.info["optical_centre"]


def test_column_fpn_follows_oz_eq19(small_camera):
    col = small_camera.info["column_gain"]
    assert col.min() >= 0.9 and col.max() <= 1.01


@pytest.mark.parametrize(
    "kwargs",
    [
        {"scene_c": -300.0},
        {"scene_c": np.full((10, 10), 20.0)},
        {"fpa_c": np.nan},
        {"scene_c": np.full((3, 48, 64), 20.0), "fpa_c": [20.0, 21.0]},
    ],
)
def test_bad_input_raises(small_camera, kwargs):
    args = {"scene_c": 20.0, "fpa_c": 25.0} | kwargs
    with pytest.raises(InvalidInputError):
        expected_counts(small_camera, args["scene_c"], args["fpa_c"])


def test_mismatched_resolution_is_named(small_camera):
    with pytest.raises(ResolutionMismatchError, match="64x48"):
        expected_counts(small_camera, np.full((10, 12), 20.0), 25.0)


def test_render_without_rng_is_refused(small_camera):
    with pytest.raises(InvalidInputError, match="rng"):
        render(small_camera, 20.0, 25.0)


def test_unknown_preset_and_bad_sizes():
    with pytest.raises(InvalidInputError, match="unknown camera preset"):
        make_camera("lepton")
    with pytest.raises(InvalidInputError):
        make_camera("tau2", size=(4, 100000))
    with pytest.raises(InvalidInputError):
        make_camera("tau2", unit=-1)
