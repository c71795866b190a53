"""Simulated chamber sessions: schedules, thermal metadata and the HDF5 file."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal.camera import make_camera
from thermocal.errors import InvalidInputError
from thermocal.io.chamber import read_chamber
from thermocal.simulate.chamber import (
    ChamberPlan,
    blackbody_schedule,
    radiance_temperature_c,
    simulate_chamber,
    write_simulated_chamber,
)


def test_schedules_visit_every_set_point():
    rng = np.random.default_rng(0)
    for order in ("sweep", "sawtooth", "random"):
        plan = ChamberPlan(setpoints_c=(10.0, 20.0, 30.0), frames_per_point=2, order=order,
                           duration_s=60.0, interval_s=1.0)
        bb = blackbody_schedule(plan, rng=rng)
        assert bb.shape == (60,)
        assert set(bb) == {10.0, 20.0, 30.0}
        assert np.all(bb[0::2] == bb[1::2])  # blocks of frames_per_point
    sweep = blackbody_schedule(ChamberPlan(setpoints_c=(1.0, 2.0, 3.0), frames_per_point=1,
                                           duration_s=6, interval_s=1.0), rng=rng)
    np.testing.assert_array_equal(sweep, [1, 2, 3, 1, 2, 3])
    saw = blackbody_schedule(ChamberPlan(setpoints_c=(1.0, 2.0, 3.0), frames_per_point=1,
                                         order="sawtooth", duration_s=6, interval_s=1.0), rng=rng)
    np.testing.assert_array_equal(saw, [1, 2, 3, 2, 1, 2])


def test_grey_body_reflecting_a_cooler_surround_looks_slightly_cooler():
    from thermocal.radiometry import TAU2

    eff = radiance_temperature_c(np.array([50.0]), np.array([20.0]), 0.98, TAU2)
    assert 49.0 < eff[0] < 50.0
    same = radiance_temperature_c(np.array([20.0]), np.array([20.0]), 0.98, TAU2)
    assert same[0] == pytest.approx(20.0, abs=1e-4)


def test_session_metadata_follows_the_ambient():
    camera = make_camera("tau2", unit=0, size=(32, 24))
    plan = ChamberPlan(setpoints_c=(20.0, 40.0), profile="ramp", ambient_c=(10.0, 30.0),
                       rate_c_per_min=1.0, interval_s=10.0, duration_s=2400.0)
    parts = list(simulate_chamber(camera, plan, seed=1, chunk=50))
    fpa = np.concatenate([p.fpa_true_c for p in parts])
    amb = np.concatenate([p.ambient_c for p in parts])
    frames = np.concatenate([p.frames for p in parts])
    assert frames.shape == (240, 24, 32) and frames.dtype == np.uint16
    assert amb[0] == pytest.approx(10.0) and amb[-1] == pytest.approx(30.0)
    assert np.all(np.diff(fpa) >= -1e-9)
    bb = np.concatenate([p.blackbody_c for p in parts])
    good = ~camera.defects
    assert frames[bb == 40.0][:, good].mean() > frames[bb == 20.0][:, good].mean() + 500


def test_written_session_reads_back(tmp_path):
    camera = make_camera("tau2", unit=4, size=(32, 24))
    plan = ChamberPlan(setpoints_c=(10.0, 30.0, 50.0), frames_per_point=2, interval_s=5.0,
                       duration_s=300.0)
    path = tmp_path / "c.h5"
    n = write_simulated_chamber(path, camera, plan, seed=3)
    session = read_chamber(path)
    assert n == 60 == session.frames.shape[0]
    assert session.attrs["unit"] == 4
    assert set(np.unique(session.blackbody_c)) == {10.0, 30.0, 50.0}


def test_bad_plans():
    with pytest.raises(InvalidInputError):
        ChamberPlan(setpoints_c=())
    with pytest.raises(InvalidInputError):
        ChamberPlan(order="zigzag")
    with pytest.raises(InvalidInputError):
        ChamberPlan(setpoints_c=(-300.0,))
    with pytest.raises(InvalidInputError):
        ChamberPlan(frames_per_point=0)


def test_set_points_beyond_the_radiance_tables_are_refused_before_any_work(tmp_path):
    cam = make_camera("tau2", unit=0, size=(16, 12))
    plan = ChamberPlan(setpoints_c=(10.0, 700.0), frames_per_point=1, duration_s=4,
                       interval_s=1.0)
    with pytest.raises(InvalidInputError, match=r"set points: 10…700 °C go beyond the "
                       r"-123.15…626.85 °C"):
        write_simulated_chamber(tmp_path / "c.h5", cam, plan, seed=0)
    assert not list(tmp_path.iterdir())
