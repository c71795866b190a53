"""Tests of thermocal.scenes.procedural: fractal noise and procedural aerial scenes."""

from __future__ import annotations

import time

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.scenes.procedural import KINDS, fractal_noise, procedural_scene


def _spectral_slope(field: np.ndarray) -> float:
    """Slope of the radially averaged power spectrum in log-log over mid frequencies."""
    h, w = field.shape
    p = np.abs(np.fft.fft2(field)) ** 2
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.fftfreq(w)[None, :]
    f = np.hypot(fy, fx).ravel()
    bins = np.logspace(np.log10(4.0 / min(h, w)), np.log10(0.25), 15)
    idx = np.digitize(f, bins)
    centres, power = [], []
    for k in range(1, len(bins)):
        sel = idx == k
        if sel.any():
            centres.append(f[sel].mean())
            power.append(p.ravel()[sel].mean())
    return float(np.polyfit(np.log(centres), np.log(power), 1)[0])


# --------------------------------------------------------------------------------------------
# fractal noise
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(64, 64), (97, 131), (1, 40), (256, 128)])
def test_fractal_noise_shape_dtype_moments(shape):
    n = fractal_noise(shape, beta=2.0, rng=np.random.default_rng(0))
    assert n.shape == shape
    assert n.dtype == np.float32
    assert np.all(np.isfinite(n))
    assert abs(float(n.mean())) < 1e-4
    assert float(n.std()) == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("beta", [1.0, 2.0, 3.0])
def test_fractal_noise_spectral_slope(beta):
    n = fractal_noise((512, 512), beta=beta, rng=np.random.default_rng(1))
    assert _spectral_slope(n) == pytest.approx(-beta, abs=0.25)


def test_fractal_noise_white_is_uncorrelated_and_smooth_is_correlated():
    white = fractal_noise((256, 256), beta=0.0, rng=np.random.default_rng(2))
    smooth = fractal_noise((256, 256), beta=4.0, rng=np.random.default_rng(2))

    def lag1(x):
        return float(np.corrcoef(x[:, :-1].ravel(), x[:, 1:].ravel())[0, 1])

    assert abs(lag1(white)) < 0.05
    assert lag1(smooth) > 0.99


def test_fractal_noise_seeded():
    a = fractal_noise((64, 80), beta=2.0, rng=np.random.default_rng(5))
    b = fractal_noise((64, 80), beta=2.0, rng=np.random.default_rng(5))
    c = fractal_noise((64, 80), beta=2.0, rng=np.random.default_rng(6))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("beta", [-1.0, 9.0, float("nan"), "two"])
def test_fractal_noise_bad_beta(beta):
    with pytest.raises(InvalidInputError):
        fractal_noise((16, 16), beta=beta, rng=np.random.default_rng(0))


@pytest.mark.parametrize("shape", [(0, 16), (16,), (16.5, 16), (-3, 4), "big"])
def test_fractal_noise_bad_shape(shape):
    with pytest.raises(InvalidInputError):
        fractal_noise(shape, beta=2.0, rng=np.random.default_rng(0))


def test_fractal_noise_needs_generator():
    with pytest.raises(InvalidInputError):
        fractal_noise((16, 16), beta=2.0, rng=42)


# --------------------------------------------------------------------------------------------
# scenes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scene_shape_dtype_range(kind, seed):
    m = procedural_scene((256, 320), rng=np.random.default_rng(seed), kind=kind)
    assert m.shape == (256, 320)
    assert m.dtype == np.float32
    assert np.all(np.isfinite(m))
    # daytime surface temperatures: water ~15 °C ... hot roofs ~65 °C (texture adds a little)
    assert float(m.min()) > 10.0
    assert float(m.max()) < 72.0
    assert 18.0 < float(np.median(m)) < 50.0


def test_scene_is_seeded():
    a = procedural_scene((128, 160), rng=np.random.default_rng(3), kind="mixed")
    b = procedural_scene((128, 160), rng=np.random.default_rng(3), kind="mixed")
    c = procedural_scene((128, 160), rng=np.random.default_rng(4), kind="mixed")
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_farmland_has_cool_vegetation_and_warm_soil():
    cool, warm = [], []
    for seed in range(4):
        m = procedural_scene((512, 512), rng=np.random.default_rng(seed), kind="farmland")
        cool.append(np.percentile(m, 5))
        warm.append(np.percentile(m, 95))
    assert np.median(cool) < 27.0  # crops, trees, wet soil
    assert np.median(warm) > 34.0  # dry soil, roads


def test_urban_has_hot_surfaces_and_water():
    for seed in range(3):
        m = procedural_scene((512, 512), rng=np.random.default_rng(seed), kind="urban")
        assert np.mean(m > 45.0) > 0.05  # asphalt and dark roofs
        assert np.mean(m < 23.0) > 0.005  # the water body, trees
        assert float(m.max()) <= 70.0


@pytest.mark.parametrize("kind", KINDS)
def test_scene_has_sharp_edges_and_texture(kind):
    m = procedural_scene((256, 256), rng=np.random.default_rng(7), kind=kind).astype(np.float64)
    dx = np.abs(np.diff(m, axis=1))
    # objects have sharp borders (blur of 0.7 px keeps most of a step) ...
    assert np.percentile(dx, 99.9) > 3.0
    # ... and texture everywhere: almost no pixel is exactly flat
    assert np.mean(dx < 1e-4) < 0.05


def test_scene_multiscale_spectrum():
    """Power falls with frequency, as in natural images (a negative log-log slope)."""
    m = procedural_scene((512, 512), rng=np.random.default_rng(8), kind="farmland")
    slope = _spectral_slope(m - m.mean())
    assert -4.0 < slope < -1.0


def test_scene_scale_changes_object_size():
    small = procedural_scene((256, 256), rng=np.random.default_rng(9), kind="urban", scale=0.5)
    big = procedural_scene((256, 256), rng=np.random.default_rng(9), kind="urban", scale=3.0)

    def edge_density(m):
        return float(np.mean(np.abs(np.diff(m, axis=1)) > 2.0))

    assert edge_density(small) > edge_density(big)


def test_scene_bad_inputs():
    rng = np.random.default_rng(0)
    with pytest.raises(InvalidInputError):
        procedural_scene((64, 64), rng=rng, kind="desert")
    with pytest.raises(InvalidInputError):
        procedural_scene((0, 64), rng=rng)
    with pytest.raises(InvalidInputError):
        procedural_scene((64, 64), rng=0)
    with pytest.raises(InvalidInputError):
        procedural_scene((64, 64), rng=rng, scale=0.0)


def test_scene_tiny_shapes():
    for shape in [(1, 1), (3, 50), (50, 3)]:
        m = procedural_scene(shape, rng=np.random.default_rng(0), kind="mixed")
        assert m.shape == shape
        assert np.all(np.isfinite(m))


@pytest.mark.parametrize("kind", KINDS)
def test_scene_speed_1024(kind):
    rng = np.random.default_rng(11)
    procedural_scene((256, 256), rng=rng, kind=kind)  # warm up
    best = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        procedural_scene((1024, 1024), rng=rng, kind=kind)
        best = min(best, time.perf_counter() - t0)
    assert best < 1.0
