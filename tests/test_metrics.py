"""Tests for thermocal.metrics against hand-computed answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thermocal.errors import InvalidInputError, ResolutionMismatchError
from thermocal.metrics import (
    best_affine_fit,
    cosine_similarity,
    error_cdf,
    fraction_within,
    mae,
    netd,
    netd_map,
    psnr,
    rmse,
    roughness,
    ssim,
)

TRUTH = np.array([[20.0, 21.0], [22.0, 23.0]])
ESTIMATE = TRUTH + np.array([[1.0, -1.0], [2.0, 0.0]])  # errors 1, -1, 2, 0


# ------------------------------------------------------------------------------ MAE / RMSE


def test_mae_rmse_known():
    assert mae(ESTIMATE, TRUTH) == pytest.approx(1.0)
    assert rmse(ESTIMATE, TRUTH) == pytest.approx(math.sqrt(6 / 4))


def test_mae_rmse_with_valid_mask():
    valid = np.array([[True, True], [False, True]])  # drop the error of 2
    assert mae(ESTIMATE, TRUTH, valid=valid) == pytest.approx(2 / 3)
    assert rmse(ESTIMATE, TRUTH, valid=valid) == pytest.approx(math.sqrt(2 / 3))


def test_2d_mask_broadcasts_over_frames():
    est, tru = np.stack([ESTIMATE, ESTIMATE]), np.stack([TRUTH, TRUTH])
    valid = np.array([[True, True], [False, True]])
    assert mae(est, tru, valid=valid) == pytest.approx(2 / 3)


def test_inputs_not_modified():
    est, tru = ESTIMATE.copy(), TRUTH.copy()
    est.flags.writeable = False
    for f in (mae, rmse, fraction_within, best_affine_fit, cosine_similarity, error_cdf):
        f(est, tru)
    assert np.array_equal(est, ESTIMATE) and np.array_equal(tru, TRUTH)


@pytest.mark.parametrize("metric", [mae, rmse, fraction_within, cosine_similarity, error_cdf])
def test_shape_mismatch(metric):
    with pytest.raises(ResolutionMismatchError, match="shape"):
        metric(np.zeros((3, 4)), np.zeros((4, 3)))


@pytest.mark.parametrize("metric", [mae, rmse, fraction_within, best_affine_fit])
def test_nan_rejected(metric):
    bad = ESTIMATE.copy()
    bad[0, 0] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        metric(bad, TRUTH)


@pytest.mark.parametrize(
    ("valid", "err", "match"),
    [
        (np.ones((2, 2), dtype=int), InvalidInputError, "boolean"),
        (np.zeros((2, 2), dtype=bool), InvalidInputError, "no pixel"),
        (np.ones((3, 3), dtype=bool), ResolutionMismatchError, "valid has shape"),
    ],
)
def test_bad_masks(valid, err, match):
    with pytest.raises(err, match=match):
        mae(ESTIMATE, TRUTH, valid=valid)


# ------------------------------------------------------------------------------ error CDF


def test_error_cdf_known():
    truth = np.zeros((2, 2))
    est = np.array([[0.0, 1.0], [-2.0, 3.0]])  # |errors| 0, 1, 2, 3
    thresholds, fraction = error_cdf(est, truth, max_error=3.0, num=4)
    np.testing.assert_allclose(thresholds, [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(fraction, [0.25, 0.5, 0.75, 1.0])


def test_error_cdf_default_range_and_monotone():
    rng = np.random.default_rng(0)
    truth = rng.normal(20, 5, (32, 32))
    est = truth + rng.normal(0, 1, (32, 32))
    thresholds, fraction = error_cdf(est, truth)
    assert thresholds[0] == 0 and fraction[-1] == 1.0
    assert thresholds[-1] == pytest.approx(np.abs(est - truth).max())
    assert np.all(np.diff(fraction) >= 0)


def test_error_cdf_bad_options():
    with pytest.raises(InvalidInputError, match="max_error"):
        error_cdf(ESTIMATE, TRUTH, max_error=0)
    with pytest.raises(InvalidInputError, match="num"):
        error_cdf(ESTIMATE, TRUTH, num=1)


def test_fraction_within():
    truth = np.zeros((2, 2))
    est = np.array([[0.1, -0.4], [0.6, 1.0]])
    assert fraction_within(est, truth) == 0.5
    assert fraction_within(est, truth, 0.6) == 0.75  # the tolerance is inclusive
    assert fraction_within(est, truth, tol=0.5, valid=np.array([[1, 1], [0, 0]], bool)) == 1.0
    with pytest.raises(InvalidInputError, match="tol"):
        fraction_within(est, truth, -1.0)


# ------------------------------------------------------------------------------ roughness


def test_roughness_constant_is_zero():
    assert roughness(np.full((8, 9), 25.0)) == 0.0
    assert roughness(np.full((8, 9), 25.0), norm=1, circular=False) == 0.0


def test_roughness_checkerboard():
    board = (np.indices((6, 8)).sum(axis=0) % 2).astype(float)  # 0/1, even sides
    # every horizontal and vertical difference is ±1, half the pixels are 1
    assert roughness(board, norm=1) == pytest.approx(4.0)  # (HW + HW) / (HW / 2)
    assert roughness(board) == pytest.approx(2 * math.sqrt(2))  # 2 sqrt(HW) / sqrt(HW / 2)
    a, b = 30.0, 10.0
    board_ab = np.where(board == 1, a, b)
    expected_l2 = 2 * abs(a - b) / math.sqrt((a * a + b * b) / 2)
    assert roughness(board_ab) == pytest.approx(expected_l2)


def test_roughness_ramp_circular_vs_inside():
    ramp = np.tile([1.0, 2.0, 3.0, 4.0], (5, 1))
    # inside the image: |dx| = 1 three times per row; ‖X‖₁ = 10 per row
    assert roughness(ramp, norm=1, circular=False) == pytest.approx(0.3)
    # circular: the wrap-around difference 4 -> 1 adds 3 per row
    assert roughness(ramp, norm=1, circular=True) == pytest.approx(0.6)


def test_roughness_per_frame():
    frames = np.stack([np.full((4, 4), 5.0), (np.indices((4, 4)).sum(axis=0) % 2) * 1.0])
    rho = roughness(frames, norm=1)
    assert rho.shape == (2,)
    np.testing.assert_allclose(rho, [0.0, 4.0])


def test_roughness_rejects():
    with pytest.raises(InvalidInputError, match="all pixels are zero"):
        roughness(np.zeros((4, 4)))
    with pytest.raises(InvalidInputError, match="norm"):
        roughness(np.ones((4, 4)), norm=3)
    with pytest.raises(InvalidInputError, match="2x2"):
        roughness(np.ones((1, 4)))


# ------------------------------------------------------------------------------ similarity


def test_cosine_similarity_known():
    img = np.random.default_rng(1).uniform(10, 30, (16, 16))
    assert cosine_similarity(img, img) == pytest.approx(1.0)
    assert cosine_similarity(img, 3.0 * img) == pytest.approx(1.0)
    assert cosine_similarity(img, -img) == pytest.approx(-1.0)
    a = np.array([[1.0, 0.0], [0.0, 0.0]])
    b = np.array([[0.0, 1.0], [0.0, 0.0]])
    assert cosine_similarity(a, b) == 0.0
    assert cosine_similarity(a, a + b) == pytest.approx(1 / math.sqrt(2))
    assert cosine_similarity(a, b, valid=np.array([[True, True], [True, True]])) == 0.0
    with pytest.raises(InvalidInputError, match="all zeros"):
        cosine_similarity(np.zeros((2, 2)), a)


def test_ssim_psnr():
    rng = np.random.default_rng(2)
    img = rng.uniform(20, 30, (32, 32))
    assert ssim(img, img, data_range=10.0) == pytest.approx(1.0)
    assert psnr(img, img, data_range=10.0) == math.inf
    # a uniform error of 1 with a range of 10: 10 log10(100 / 1) = 20 dB
    assert psnr(img + 1.0, img, data_range=10.0) == pytest.approx(20.0)
    noisy = img + rng.normal(0, 1, img.shape)
    assert 0 < ssim(noisy, img, data_range=10.0) < 1
    stack = np.stack([img, noisy])
    assert ssim(stack, np.stack([img, img]), data_range=10.0) == pytest.approx(
        (1 + ssim(noisy, img, data_range=10.0)) / 2
    )


def test_ssim_psnr_reject():
    img = np.ones((32, 32))
    with pytest.raises(InvalidInputError, match="data_range"):
        psnr(img, img, data_range=0)
    with pytest.raises(InvalidInputError, match="7x7"):
        ssim(np.ones((5, 5)), np.ones((5, 5)), data_range=1.0)
    with pytest.raises(ResolutionMismatchError):
        ssim(img, np.ones((32, 31)), data_range=1.0)


# ------------------------------------------------------------------------------ affine fit


def test_best_affine_fit_recovers_truth():
    truth = np.random.default_rng(3).uniform(10, 40, (3, 8, 8))
    est = 2.0 * truth + 3.0
    np.testing.assert_allclose(best_affine_fit(est, truth), truth, atol=1e-9)


def test_best_affine_fit_uses_only_valid_pixels():
    truth = np.random.default_rng(4).uniform(10, 40, (8, 8))
    est = 0.5 * truth - 4.0
    est_bad = est.copy()
    est_bad[0, 0] = 1e6  # an outlier excluded from the fit
    valid = np.ones_like(truth, dtype=bool)
    valid[0, 0] = False
    mapped = best_affine_fit(est_bad, truth, valid)
    np.testing.assert_allclose(mapped[valid], truth[valid], atol=1e-9)


def test_best_affine_fit_constant_estimate():
    mapped = best_affine_fit(np.full((4, 4), 7.0), TRUTH.repeat(2, 0).repeat(2, 1))
    np.testing.assert_allclose(mapped, TRUTH.mean())


# ------------------------------------------------------------------------------ NETD


def _flat_fields(rng, n, responsivity, sigma, offset, t_c):
    mean = offset + responsivity * t_c
    return mean + rng.normal(0.0, sigma, size=(n, *responsivity.shape))


def test_netd_recovers_known_value():
    rng = np.random.default_rng(5)
    responsivity = rng.uniform(40.0, 60.0, (32, 32))  # counts/K, median 50
    offset = rng.uniform(5000, 6000, (32, 32))
    sigma = 2.0  # counts
    low = _flat_fields(rng, 100, responsivity, sigma, offset, 20.0)
    high = _flat_fields(rng, 100, responsivity, sigma, offset, 40.0)
    expected = sigma / 50.0  # 40 mK
    assert netd(low, high, 20.0, 40.0) == pytest.approx(expected, rel=0.05)
    assert netd(high, low, 40.0, 20.0) == pytest.approx(netd(low, high, 20.0, 40.0))
    per_pixel = netd_map(low, high, 20.0, 40.0)
    assert per_pixel.shape == (32, 32)
    np.testing.assert_allclose(np.median(per_pixel / (sigma / responsivity)), 1.0, rtol=0.05)


def test_netd_accepts_uint16_counts_and_marks_dead_pixels():
    rng = np.random.default_rng(6)
    responsivity = np.full((8, 8), 50.0)
    low = np.round(_flat_fields(rng, 50, responsivity, 3.0, 8000.0, 20.0)).astype(np.uint16)
    high = np.round(_flat_fields(rng, 50, responsivity, 3.0, 8000.0, 30.0)).astype(np.uint16)
    low[:, 0, 0] = high[:, 0, 0] = 1234  # a dead (stuck) pixel: no response, no noise
    per_pixel = netd_map(low, high, 20.0, 30.0)
    assert np.isinf(per_pixel[0, 0])
    assert netd(low, high, 20.0, 30.0) == pytest.approx(3.0 / 50.0, rel=0.1)


def test_netd_rejects():
    stack = np.random.default_rng(7).normal(0, 1, (4, 8, 8))
    with pytest.raises(ResolutionMismatchError):
        netd(stack, stack[:, :4], 20.0, 30.0)
    with pytest.raises(InvalidInputError, match="differ"):
        netd(stack, stack, 20.0, 20.0)
    with pytest.raises(InvalidInputError, match="at least 2 frames"):
        netd(stack[:1], stack, 20.0, 30.0)
    with pytest.raises(InvalidInputError, match="no response"):
        netd(stack, stack, 20.0, 30.0)  # zero responsivity everywhere


def test_sigma_coverage_of_gaussian_errors():
    from thermocal.metrics import sigma_coverage

    rng = np.random.default_rng(0)
    sigma = rng.uniform(0.5, 2.0, 200_000)
    cov = sigma_coverage(rng.normal(0.0, sigma), sigma)
    assert cov["within_1sigma"] == pytest.approx(0.683, abs=0.005)
    assert cov["within_2sigma"] == pytest.approx(0.954, abs=0.003)
    assert cov["pixels"] == 200_000 and 1.0 < cov["median_sigma_c"] < 1.5
    with pytest.raises(InvalidInputError):
        sigma_coverage(np.zeros(3), np.ones(4))



def test_coverage_interval_resamples_whole_groups():
    from thermocal.metrics import coverage_interval

    rng = np.random.default_rng(2)

    def groups(n: int, offset_sd: float) -> list:
        # each group's errors share one offset (a unit's level), σ states the total spread
        sd = np.hypot(offset_sd, 0.2)
        return [(rng.normal(rng.normal(0.0, offset_sd), 0.2, 500), np.full(500, sd))
                for _ in range(n)]

    few, many = coverage_interval(groups(40, 1.0)), coverage_interval(groups(400, 1.0))
    lo, hi = many["within_1sigma"]
    assert lo < 0.683 < hi and many["groups"] == 400  # a well-stated σ: inside the interval
    assert many["within_2sigma"][0] < 0.96 and many["within_2sigma"][1] > 0.95
    # the groups' offsets, not their 200,000 pixels, set the width (a binomial interval of the
    # pixels: 2 × 1.645 × √(0.68 · 0.32 / 200000) = 0.003); 40 groups: about √10 times wider
    assert few["within_1sigma"][1] - few["within_1sigma"][0] > 2 * (hi - lo) > 0.02
    # a σ too small by half: the interval sits well below a Gaussian's share
    short = coverage_interval([(e, s / 2) for e, s in groups(400, 1.0)])
    assert short["within_1sigma"][1] < 0.5
    with pytest.raises(InvalidInputError):
        coverage_interval(groups(1, 1.0))
    with pytest.raises(InvalidInputError, match="must match"):
        coverage_interval([(np.zeros(3), np.ones(1)), (np.zeros(3), np.ones(3))])


def test_rescaled_coverage_finds_the_level_of_a_gaussian_and_not_of_a_rectangle():
    from thermocal.metrics import rescaled_coverage

    rng = np.random.default_rng(1)
    sigma = rng.uniform(0.5, 2.0, 100_000)
    # a Gaussian error stated at a third of its σ: the factor 3 puts it back in band
    cov = rescaled_coverage(rng.normal(0.0, sigma), sigma / 3.0)
    assert cov["in_band"] and cov["factor"] == pytest.approx(3.0, rel=0.03)
    assert cov["within_1sigma"] == pytest.approx(0.683, abs=0.01)
    # a systematic error of nearly constant size (rectangular): no factor meets both bands
    rect = rescaled_coverage(rng.uniform(-1.0, 1.0, 100_000), np.ones(100_000))
    assert not rect["in_band"]
    assert rect["within_2sigma"] > 0.98 or rect["within_1sigma"] < 0.63
    # a σ of 0 covers nothing, at any factor (as in sigma_coverage)
    assert rescaled_coverage(np.ones(2), np.array([1.0, 0.0]))["within_2sigma"] <= 0.5
    with pytest.raises(InvalidInputError):
        rescaled_coverage(np.zeros(3), np.ones(4))


# ------------------------------------------------------------------ the parts of the error


def test_bias_free_mae_removes_each_maps_own_mean():
    from thermocal.metrics import bias_free_mae

    truth = np.zeros((2, 2, 2))
    est = np.stack([np.array([[1.0, 3.0], [1.0, 3.0]]),  # mean 2, deviations ±1
                    np.array([[-5.0, -5.0], [-5.0, -9.0]])])  # mean -6, deviations 1, 1, 1, 3
    assert bias_free_mae(est[0], truth[0]) == pytest.approx(1.0)
    assert bias_free_mae(est[1], truth[1]) == pytest.approx(1.5)
    assert bias_free_mae(est, truth) == pytest.approx(1.25)  # not one mean over both maps
    assert bias_free_mae(est[0] + 7.0, truth[0]) == pytest.approx(1.0)  # a level is free
    # the mask selects the pixels of the mean and of the MAE: errors 1, 3, 1 → mean 5/3
    valid = np.array([[True, True], [True, False]])
    assert bias_free_mae(est[0], truth[0], valid=valid) == pytest.approx(
        (2 / 3 + 4 / 3 + 2 / 3) / 3)


def test_affine_free_mae_is_zero_for_any_gain_and_offset_per_map():
    from thermocal.metrics import affine_free_mae

    rng = np.random.default_rng(1)
    truth = rng.normal(20.0, 3.0, (3, 8, 9))
    est = np.stack([2.0 * truth[0] + 1.0, 0.5 * truth[1] - 4.0, truth[2] + 3.0])
    assert affine_free_mae(est, truth) == pytest.approx(0.0, abs=1e-9)
    # one affine map for the whole stack would not do: the maps have different gains
    assert mae(best_affine_fit(est, truth), truth) > 0.5
    # noise stays: the best affine map of truth + noise is close to the noise's MAE
    noise = rng.choice([-0.2, 0.2], size=truth.shape)
    assert affine_free_mae(truth + noise, truth) == pytest.approx(0.2, abs=0.02)


def test_column_bands_of_known_stripes():
    from thermocal.metrics import column_bands, row_bands

    stripes = np.array([0.3, -0.1, 0.2, -0.4, 0.0, 0.0])  # SD of these column offsets
    truth = np.random.default_rng(2).normal(25.0, 2.0, (10, 6))
    est = truth + stripes[None, :] + 1.5  # a level offset does not count
    assert column_bands(est, truth) == pytest.approx(float(np.std(stripes)))
    assert row_bands(est, truth) == pytest.approx(0.0, abs=1e-12)  # every row mean is the same
    # transposed: the same stripes are row bands
    assert row_bands(est.T, truth.T) == pytest.approx(float(np.std(stripes)))
    # a pattern along the columns (zero mean down each column) is not a column band
    along = np.tile(np.array([[0.5], [-0.5]]), (5, 6))
    assert column_bands(truth + along, truth) == pytest.approx(0.0, abs=1e-12)
    assert row_bands(truth + along, truth) == pytest.approx(0.5)


def test_column_bands_per_map_mean_and_mask():
    from thermocal.metrics import column_bands

    truth = np.zeros((2, 4, 4))
    est = np.zeros((2, 4, 4))
    est[0] += np.array([1.0, -1.0, 1.0, -1.0])  # SD 1
    est[1] += np.array([0.5, -0.5, 0.5, -0.5])  # SD 0.5
    assert column_bands(est, truth) == pytest.approx(0.75)  # the mean of the maps' values
    # a masked pixel leaves its column's mean to the rest; a column with none is left out
    est2 = est[0].copy()
    est2[0, 0] = 99.0
    valid = np.ones((4, 4), bool)
    valid[0, 0] = False
    assert column_bands(est2, truth[0], valid=valid) == pytest.approx(1.0)
    valid[:, 3] = False  # columns 1, -1, 1 left: SD sqrt(8/9)
    assert column_bands(est2, truth[0], valid=valid) == pytest.approx(math.sqrt(8 / 9))


def test_column_bands_detrended_keeps_stripes_drops_ramps():
    from thermocal.metrics import column_bands

    w = 200
    ramp = np.linspace(-1.0, 1.0, w)  # a smooth trend across the frame
    stripes = np.where(np.arange(w) % 2 == 0, 0.1, -0.1)  # alternate columns
    truth = np.zeros((5, w))
    assert column_bands(truth + ramp, truth) == pytest.approx(float(np.std(ramp)))
    assert column_bands(truth + ramp, truth, detrend_px=6.0) < 0.01
    both = column_bands(truth + ramp + stripes, truth, detrend_px=6.0)
    assert both == pytest.approx(0.1, abs=0.01)
    with pytest.raises(InvalidInputError, match="detrend_px"):
        column_bands(truth, truth, detrend_px=0.0)


@pytest.mark.parametrize("name", ["bias_free_mae", "affine_free_mae", "column_bands",
                                  "row_bands"])
def test_error_parts_bad_input(name):
    import thermocal.metrics as m

    metric = getattr(m, name)
    with pytest.raises(ResolutionMismatchError, match="shape"):
        metric(np.zeros((3, 4)), np.zeros((4, 3)))
    bad = ESTIMATE.copy()
    bad[0, 0] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        metric(bad, TRUTH)
    with pytest.raises(InvalidInputError, match="no pixel"):
        metric(ESTIMATE, TRUTH, valid=np.zeros((2, 2), bool))
    # a stack whose second map has no valid pixel
    valid = np.ones((2, 2, 2), bool)
    valid[1] = False
    with pytest.raises(InvalidInputError, match="map 1"):
        metric(np.stack([ESTIMATE, ESTIMATE]), np.stack([TRUTH, TRUTH]), valid=valid)
    est = ESTIMATE.copy()
    est.flags.writeable = False
    metric(est, TRUTH)
    assert np.array_equal(est, ESTIMATE)
