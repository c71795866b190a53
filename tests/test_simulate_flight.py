"""Simulated flights: ground truth in every view, true homographies, the camera's thermal state."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal.camera import invert, make_camera
from thermocal.errors import InvalidInputError
from thermocal.registration.warp import warp_to_pivot
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.flight import simulate_flight, write_flight


@pytest.fixture(scope="module")
def scene():
    return load_builtin_scene("aerial")


@pytest.mark.parametrize("motion", ["walk", "hover", "uav"])
def test_truth_warps_onto_the_pivot_with_the_true_homographies(scene, motion):
    camera = make_camera("tau2", unit=0, size=(96, 64))
    flight = simulate_flight(scene, camera, n_frames=5, motion=motion, seed=2)
    warped, valid = warp_to_pivot(flight.truth_c, flight.homographies)
    pivot = flight.truth_c[flight.pivot]
    assert valid.mean() > 0.5
    for k in range(5):
        err = np.abs(warped[k] - pivot)[valid[k]]
        assert np.median(err) < 0.05  # only interpolation of an (upsampled) real scene


def test_frames_are_the_camera_model_of_the_truth(scene):
    camera = make_camera("tau2", unit=5, size=(64, 48))
    flight = simulate_flight(scene, camera, n_frames=3, motion="uav", fpa_c=36.0, seed=4)
    assert flight.frames.dtype == np.uint16 and flight.frames.shape == (3, 48, 64)
    np.testing.assert_allclose(flight.fpa_true_c, 36.0, atol=1e-9)
    assert np.all(np.abs(flight.fpa_c - 36.0) < 0.1)  # the sensor reading: noisy, quantised
    est = invert(camera, flight.frames, flight.fpa_true_c, housing_c=flight.housing_c)
    good = ~camera.defects
    assert np.abs(est - flight.truth_c)[:, good].mean() < 0.1  # NETD-level noise only


def test_uav_motion_is_about_3_8_px_per_frame(scene):
    camera = make_camera("tau2", unit=0, size=(64, 48))
    flight = simulate_flight(scene, camera, n_frames=6, motion="uav", seed=0)
    steps = np.diff(flight.to_map[:, :2, 2], axis=0)
    assert np.median(np.hypot(*steps.T)) == pytest.approx(3.8, abs=0.3)


def test_write_flight_refuses_a_file_as_folder(tmp_path, scene):
    camera = make_camera("tau2", unit=0, size=(32, 24))
    flight = simulate_flight(scene, camera, n_frames=2, seed=0)
    (tmp_path / "x").write_text("")
    with pytest.raises(InvalidInputError):
        write_flight(tmp_path / "x", flight)


def test_bad_flights(scene):
    camera = make_camera("tau2", unit=0, size=(32, 24))
    with pytest.raises(InvalidInputError):
        simulate_flight(scene, camera, n_frames=0)
    with pytest.raises(InvalidInputError):
        simulate_flight(scene, camera, motion="teleport")
    with pytest.raises(InvalidInputError):
        simulate_flight(np.full((10, 10), np.nan), camera)
