"""A network refuses a burst outside what it was trained on (issue 18, item 2): FPA and scene
range, and a camera of another family; ``--force`` estimates it with a warning."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from cli_run import run

from thermocal.camera.presets import make_camera
from thermocal.errors import OutsideDomainError
from thermocal.estimation.pipeline import estimate
from thermocal.metrics import line_patterns
from thermocal.nn.infer import NetworkEstimator
from thermocal.nn.validity import LINE_CHECK_MIN_PX, LINE_RATIO_MAX, Domain, outside_domain
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

pytest.importorskip("torch")

SIZE = (336, 256)


@pytest.fixture(scope="module")
def network():
    return NetworkEstimator.from_file("kpn")


def _burst(preset, unit, *, fpa_c=30.0, seed=4, offset_c=0.0):
    rng = np.random.default_rng(seed)
    scene = procedural_scene((384, 384), rng=rng, kind="mixed") + offset_c
    cam = make_camera(preset, unit=unit, size=SIZE)
    return simulate_flight(scene, cam, n_frames=7, motion="walk", fpa_c=fpa_c, seed=seed)


def test_the_shipped_network_records_its_domain(network):
    d = network.domain
    assert d.family == "tau2" and d.line_fpn == "column"
    assert d.fpa_range_c == (10.0, 50.0)
    assert d.scene_level_c == (-15.0, 60.0)


def test_line_patterns_see_lines_not_scenes():
    rng = np.random.default_rng(0)
    scene = procedural_scene((256, 336), rng=rng, kind="mixed")[None].repeat(3, axis=0)
    columns = scene + rng.normal(0, 1.0, 336).astype(np.float32)[None, None, :]
    rows, cols = line_patterns(columns)
    assert cols > 0.8 and rows < LINE_RATIO_MAX * cols
    rows_t, cols_t = line_patterns(np.swapaxes(columns, 1, 2))
    assert rows_t == pytest.approx(cols) and cols_t == pytest.approx(rows)


def test_domain_checks_name_each_reason():
    d = Domain((10.0, 50.0), (-15.0, 60.0), (-40.0, 100.0), "tau2", "column")
    rng = np.random.default_rng(1)
    stripes = rng.normal(0, 1.0, 160).astype(np.float32)
    frames = 20.0 + np.zeros((2, 120, 160), np.float32) + stripes
    assert outside_domain(d, frames, 30.0) == ()
    assert "FPA temperature 55.0 °C" in outside_domain(d, frames, 55.0)[0]
    assert "median 89.9 °C" in outside_domain(d, frames + 70.0, 30.0)[0]  # stripes: −0.1
    hot = frames.copy()
    hot[:, :10] = 400.0
    assert any("spans" in r for r in outside_domain(d, hot, 30.0))
    (why,) = outside_domain(d, np.swapaxes(frames, 1, 2).copy(), 30.0)
    assert "runs along rows" in why and "tau2 family" in why
    assert outside_domain(d, None, 30.0) == ()


def test_frames_too_small_to_check_the_family_are_refused():
    """Below LINE_CHECK_MIN_PX a side no line statistic tells the families apart (RESULTS.md):
    refused whichever way the lines run, with the size; a network without a line pattern to
    check (none recorded) takes them."""
    d = Domain((10.0, 50.0), (-15.0, 60.0), (-40.0, 100.0), "tau2", "column")
    stripes = np.random.default_rng(2).normal(0, 1.0, 160).astype(np.float32)
    small = 20.0 + np.zeros((2, LINE_CHECK_MIN_PX - 1, 160), np.float32) + stripes
    (why,) = outside_domain(d, small, 30.0)
    assert f"160×{LINE_CHECK_MIN_PX - 1}" in why and "too small" in why and "tau2" in why
    rows = np.swapaxes(small, 1, 2).copy()  # lines along rows: refused for its size all the same
    (why,) = outside_domain(d, rows, 30.0)
    assert f"{LINE_CHECK_MIN_PX - 1}×160" in why and "too small" in why
    fit = 20.0 + np.zeros((2, LINE_CHECK_MIN_PX, 160), np.float32) + stripes
    assert outside_domain(d, fit, 30.0) == ()
    assert outside_domain(replace(d, line_fpn=None), small, 30.0) == ()


def test_boson_burst_refused_tau2_burst_accepted(network):
    tau2 = _burst("tau2", 101)
    est = estimate(tau2.frames, network, fpa_c=tau2.fpa_c)
    assert est.outside == ()
    boson = _burst("boson", 101)
    with pytest.raises(OutsideDomainError, match="runs along rows"):
        estimate(boson.frames, network, fpa_c=boson.fpa_c)
    forced = estimate(boson.frames, network, fpa_c=boson.fpa_c, force=True)
    assert forced.outside and np.all(np.isfinite(forced.temperature_c))


def test_estimate_command_refuses_and_forces(tmp_path, network, capsys):
    from thermocal.io.recording import Recording, write_recording

    boson = _burst("boson", 102, seed=6)
    path, _ = write_recording(tmp_path / "b.tiff", Recording(boson.frames, fpa_c=boson.fpa_c))
    out = tmp_path / "t.tiff"
    code, text, err = run(["estimate", path, "--out", out], capsys)
    text += err
    assert code == 2, text
    assert "runs along rows" in text and "thermocal train --chamber" in text
    assert len(text.strip().splitlines()) == 1 and "Traceback" not in text
    assert not out.exists()
    code, text, err = run(["estimate", path, "--out", out, "--force"], capsys)
    text += err
    assert code == 0, text
    assert "warning" in text and out.exists()
    hot = _burst("tau2", 103, fpa_c=30.0, seed=7)
    path, _ = write_recording(tmp_path / "h.tiff", Recording(hot.frames, fpa_c=np.full(7, 58.0)))
    code, text, err = run(["estimate", path, "--out", tmp_path / "h_t.tiff"], capsys)
    text += err
    assert code == 2 and "FPA temperature 58.0 °C" in text


def test_line_medians_are_numpys_medians():
    from thermocal.metrics import _line_medians

    rng = np.random.default_rng(3)
    for _ in range(100):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        a = (rng.standard_normal((h, w)) * 100).astype(np.float32)
        if rng.random() < 0.3:
            a = np.round(a)  # ties
        if rng.random() < 0.2:
            a[int(rng.integers(h)), int(rng.integers(w))] = np.nan
        assert np.array_equal(_line_medians(a), np.median(a, axis=1), equal_nan=True)
