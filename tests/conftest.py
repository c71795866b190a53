"""Shared fixtures: small seeded cameras and the shared data folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thermocal.camera.presets import make_camera
from thermocal.scenes.real import find_shared_data


@pytest.fixture(scope="session")
def small_camera():
    """Unit 0 of the tau2 preset at 64x48 pixels."""
    return make_camera("tau2", unit=0, size=(64, 48))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real data: ``../shared/data`` beside the repository, else the package's copy."""
    path = find_shared_data()
    if path is None:
        pytest.skip("no shared/data and no bundled copy")
    return path


@pytest.fixture(scope="session")
def fitted_session(tmp_path_factory):
    """Unit 3 of `tau2` (64×48) and its chamber session (a slow sawtooth), written once:
    ``(camera, path)``."""
    from thermocal.camera.presets import make_camera
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber

    path = tmp_path_factory.mktemp("calsigma") / "c.h5"
    camera = make_camera("tau2", unit=3, size=(64, 48))
    plan = ChamberPlan(setpoints_c=(0.0, 10.0, 20.0, 30.0, 40.0, 50.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.25,
                       interval_s=20.0)
    write_simulated_chamber(path, camera, plan, seed=1)
    return camera, path


@pytest.fixture(scope="session")
def fitted(fitted_session):
    """:func:`fitted_session`'s camera and its `polynomial` calibration with the
    cross-validation report: ``(camera, calibration, report)``."""
    from thermocal.calibration.report import fit_with_report

    camera, path = fitted_session
    cal, report = fit_with_report(path, "polynomial", frames="settled")
    return camera, cal, report
