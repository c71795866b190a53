"""Tests of thermocal.registration: register_burst / register_pair on simulated flights."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from thermocal.camera.model import expected_counts
from thermocal.camera.presets import make_camera
from thermocal.errors import InvalidInputError, RegistrationError, ResolutionMismatchError
from thermocal.registration import (
    BurstRegistration,
    estimate_fixed_pattern,
    register_burst,
    register_pair,
)
from thermocal.registration.fixed_pattern import (
    back_projected_pattern,
    initial_patterns,
    joint_residual,
)
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

SIZE = (128, 96)


def corner_error(h_est: np.ndarray, h_true: np.ndarray, size=SIZE) -> float:
    w, h = size
    c = np.array([[0, 0, 1], [w - 1, 0, 1], [w - 1, h - 1, 1], [0, h - 1, 1]], float).T
    a = h_est @ c
    b = h_true @ c
    return float(np.linalg.norm(a[:2] / a[2] - b[:2] / b[2], axis=0).mean())


@pytest.fixture(scope="module")
def flight():
    cam = make_camera("tau2", unit=3, size=SIZE)
    scene = procedural_scene((512, 512), rng=np.random.default_rng(5), kind="mixed")
    return simulate_flight(scene, cam, n_frames=5, motion="walk", seed=2)


def test_burst_recovers_the_true_homographies_through_fpn(flight):
    frames = flight.frames.copy()
    reg = register_burst(flight.frames, pivot=flight.pivot)
    np.testing.assert_array_equal(frames, flight.frames)  # input untouched
    assert isinstance(reg, BurstRegistration)
    assert reg.homographies.shape == (5, 3, 3) and reg.homographies.dtype == np.float64
    assert reg.pivot == flight.pivot and reg.method == "auto"
    np.testing.assert_array_equal(reg.homographies[reg.pivot], np.eye(3))
    assert reg.inliers.shape == (5,) and reg.inliers[reg.pivot] == 0
    errs = [corner_error(reg.homographies[i], flight.homographies[i])
            for i in range(5) if i != flight.pivot]
    # the true motion is 20-40 px; the fixed pattern alone would give the identity
    assert np.median(errs) < 0.5, errs
    assert max(errs) < 1.0, errs
    assert reg.correlation.shape == (5,) and reg.correlation.min() > 0.9
    assert reg.fixed_pattern.shape == flight.frames.shape[1:]


def test_pivot_chosen_by_overlap_is_the_middle_of_a_walk(flight):
    reg = register_burst(flight.frames)
    assert reg.pivot == flight.pivot
    warped, valid = reg.warp(flight.frames)
    assert warped.shape == (5, *flight.frames.shape[1:]) and valid[reg.pivot].all()
    assert 0.4 < valid.mean() < 1.0


def test_pair_of_clean_frames_with_known_shift():
    rng = np.random.default_rng(0)
    scene = procedural_scene((256, 256), rng=rng, kind="urban")
    fixed = scene[40:136, 50:178]
    moving = scene[47:143, 38:166]  # moving(x, y) = scene(x + 38, y + 47) = fixed(x - 12, y + 7)
    h, support = register_pair(moving, fixed)
    truth = np.array([[1.0, 0, -12.0], [0, 1.0, 7.0], [0, 0, 1.0]])
    assert corner_error(h, truth) < 1.0
    assert support > 0


def test_uniform_burst_is_an_explicit_failure():
    cam = make_camera("tau2", unit=0, size=(64, 48))
    from thermocal.camera.model import render

    frames = render(cam, np.full((4, 48, 64), 20.0, np.float32), np.full(4, 30.0),
                    housing_c=np.full(4, 30.0), rng=np.random.default_rng(0))
    with pytest.raises(RegistrationError, match="frame"):
        register_burst(frames)


def test_constant_frame_is_reported_as_uniform(flight):
    frames = flight.frames.copy()
    frames[1] = 5000
    with pytest.raises(RegistrationError, match="frame 1.*uniform"):
        register_burst(frames)


def test_bad_input():
    good = np.zeros((3, 32, 32), np.float32)
    with pytest.raises(InvalidInputError):
        register_burst(good[0])
    bad = good.copy()
    bad[1, 2, 3] = np.nan
    with pytest.raises(InvalidInputError, match="frame 1"):
        register_burst(bad)
    with pytest.raises(InvalidInputError, match="pivot"):
        register_burst(good, pivot=3)
    with pytest.raises(InvalidInputError, match="method"):
        register_burst(good, method="magic")
    with pytest.raises(ResolutionMismatchError):
        register_pair(good[0], np.zeros((32, 40)))
    one = register_burst(good[:1])
    np.testing.assert_array_equal(one.homographies, np.eye(3)[None])


def test_pattern_and_homographies_explain_the_burst(flight):
    """Physics: with the true homographies the back-projected pattern is the camera's offset
    pattern, and the joint misfit is far lower than with no motion."""
    x = flight.frames.astype(np.float32)
    cam = make_camera("tau2", unit=3, size=SIZE)
    start = initial_patterns(x)
    assert set(start) == {"median", "fine"}
    f = back_projected_pattern(x, flight.homographies, start["fine"], sweeps=4)
    # the camera's fixed output at the burst's mean scene level (offsets and gains times level)
    level = np.full((1, *x.shape[1:]), float(flight.truth_c.mean()), np.float32)
    true = expected_counts(cam, level, flight.fpa_true_c[:1], housing_c=flight.housing_c[:1])[0]
    away = cv2.erode((~cam.defects).astype(np.uint8), np.ones((25, 25), np.uint8)) > 0

    def fine(a: np.ndarray) -> np.ndarray:
        return (a - cv2.GaussianBlur(a, (0, 0), 4.0))[away]

    assert np.corrcoef(fine(f), fine(true))[0, 1] > 0.9
    eye = np.repeat(np.eye(3)[None], 5, axis=0)
    good = joint_residual(x, flight.homographies, f)
    bad = joint_residual(x, eye, back_projected_pattern(x, eye, start["fine"], sweeps=4))
    assert good < 0.5 * bad


def test_threads_do_not_change_the_result(flight):
    one = register_burst(flight.frames, pivot=flight.pivot, workers=1)
    two = register_burst(flight.frames, pivot=flight.pivot, workers=2)
    np.testing.assert_allclose(one.homographies, two.homographies, atol=1e-9)
    with pytest.raises(InvalidInputError, match="workers"):
        register_burst(flight.frames, workers=0)


def test_known_pattern_is_used_and_checked(flight):
    cam = make_camera("tau2", unit=3, size=SIZE)
    scene = procedural_scene((512, 512), rng=np.random.default_rng(5), kind="mixed")
    other = simulate_flight(scene, cam, n_frames=40, motion="uav", seed=9)  # same unit, scene
    fp = estimate_fixed_pattern(other.frames)
    reg = register_burst(flight.frames, pivot=flight.pivot, fixed_pattern=fp)
    errs = [corner_error(reg.homographies[i], flight.homographies[i])
            for i in range(5) if i != flight.pivot]
    assert max(errs) < 1.0, errs
    with pytest.raises(ResolutionMismatchError):
        register_burst(flight.frames, fixed_pattern=np.zeros((10, 10)))
