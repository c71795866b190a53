"""Shared fixtures: small seeded cameras and the shared data folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thermocal.camera.presets import make_camera


@pytest.fixture(scope="session")
def small_camera():
    """Unit 0 of the tau2 preset at 64x48 pixels."""
    return make_camera("tau2", unit=0, size=(64, 48))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` beside the repository; tests that need it skip without it."""
    path = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    if not path.is_dir():
        pytest.skip("shared/data is not beside the repository")
    return path
