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
