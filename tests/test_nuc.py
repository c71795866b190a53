"""Tests of thermocal.nuc: every method against a simulated flight with known truth."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from scipy.ndimage import gaussian_filter1d

from thermocal.calibration import StreamingCorrector
from thermocal.camera.presets import make_camera
from thermocal.cli import main
from thermocal.errors import InvalidInputError, ResolutionMismatchError
from thermocal.io.recording import Recording, write_recording
from thermocal.metrics import best_affine_fit, rmse, roughness
from thermocal.nuc import (
    NUC_METHODS,
    Scribner,
    correct_nonuniformity,
)
from thermocal.nuc.batch import column_midway, dct_denoise
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

N = 60


@pytest.fixture(scope="module")
def flight():
    cam = make_camera("tau2", unit=4, size=(96, 64))
    scene = procedural_scene((384, 384), rng=np.random.default_rng(1), kind="mixed")
    return simulate_flight(scene, cam, n_frames=N, motion="walk", seed=7)


def _affine_rmse(frames, truth):
    return float(np.mean([rmse(best_affine_fit(f, t), t) for f, t in zip(frames, truth,
                                                                         strict=True)]))


@pytest.mark.parametrize("method", sorted(NUC_METHODS))
def test_every_method_reduces_roughness_and_error(flight, method):
    opts = {"homographies": flight.homographies} if method in ("hardie2000", "zuo2011") else {}
    if method == "deepir":  # a per-burst optimisation: a short one on the first 11 frames
        opts = {"iterations": 150}  # registered by itself
    raw = flight.frames[:11] if method == "deepir" else flight.frames
    before = raw.copy()
    out = correct_nonuniformity(raw, method=method, **opts)
    np.testing.assert_array_equal(raw, before)
    assert out.shape == raw.shape and out.dtype == np.float32
    assert np.all(np.isfinite(out))
    last = slice(len(raw) - 10, len(raw))
    assert np.mean(roughness(out[last])) < np.mean(roughness(raw[last].astype(np.float32)))
    if method not in ("scribner", "hardie2000", "zuo2011", "deepir"):
        return  # constant-statistics methods need more varied motion (next test)
    # structure against the true scene (after the best affine map: not radiometric)
    assert _affine_rmse(out[last], flight.truth_c[last]) < _affine_rmse(
        raw[last].astype(np.float32), flight.truth_c[last]
    )


@pytest.mark.parametrize("method", ["harris1999", "ecr", "torres-kalman", "scribner"])
def test_statistical_methods_recover_the_scene_under_varied_motion(method):
    """Each pixel sees many unrelated scene points: the constant-statistics assumption holds."""
    rng = np.random.default_rng(11)
    scene = procedural_scene((256, 256), rng=rng, kind="urban")
    gain = rng.normal(1.0, 0.05, (32, 48)).astype(np.float32)
    offset = rng.normal(0.0, 1.5, (32, 48)).astype(np.float32)
    pos = rng.integers(0, 200, size=(300, 2))
    truth = np.stack([scene[y:y + 32, x:x + 48] for y, x in pos])
    frames = (truth * gain + offset) * 30.0 + 5000.0
    out = correct_nonuniformity(frames, method=method)
    last = slice(280, 300)
    assert _affine_rmse(out[last], truth[last]) < 0.6 * _affine_rmse(frames[last], truth[last])


def test_scribner_flattens_pure_offset_fpn_on_a_moving_scene():
    rng = np.random.default_rng(3)
    scene = procedural_scene((200, 200), rng=rng, kind="mixed") * 30.0
    fpn = rng.normal(0.0, 40.0, (48, 64)).astype(np.float32)
    shifts = rng.integers(0, 100, size=(150, 2))
    frames = np.stack([scene[y:y + 48, x:x + 64] + fpn for y, x in shifts]) + 5000.0
    nuc = Scribner(learning_rate=0.1, gain_rate=0.0)
    for f in frames:
        nuc.update(f)
    # the learned offset is minus the FPN up to a constant and the scene's local structure
    resid = nuc.offset + fpn
    assert np.std(resid - resid.mean()) < 0.35 * np.std(fpn)


STREAMING = {name: m.streaming for name, m in NUC_METHODS.items() if m.streaming is not None}


def test_streaming_objects_match_the_batch_functions(flight):
    assert set(STREAMING) == {"harris1999", "scribner", "ecr", "torres-kalman", "zuo2011"}
    for name, cls in STREAMING.items():
        obj = cls()
        assert isinstance(obj, StreamingCorrector), name
        manual = np.stack([obj.process(f) for f in flight.frames[:12]])
        np.testing.assert_allclose(
            manual, correct_nonuniformity(flight.frames[:12], method=name), rtol=1e-5, atol=1e-3
        )
        # correct_frame: the current parameters, learning nothing
        seen = obj.n_seen
        np.testing.assert_array_equal(obj.correct_frame(flight.frames[11]), manual[-1])
        assert obj.n_seen == seen and not hasattr(obj, "apply")
    obj = STREAMING["ecr"]()
    obj.update(flight.frames[0])
    with pytest.raises(ResolutionMismatchError):
        obj.update(flight.frames[0][:, :50])


def test_every_nuc_method_has_a_source_and_summary():
    for name, m in NUC_METHODS.items():
        assert m.name == name and m.source and m.summary and "\n" not in m.summary
        assert callable(m.correct)


def test_column_midway_removes_column_offsets():
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:64, 0:80].astype(np.float32)
    scene = 100.0 * np.sin(xx / 13.0) + 80.0 * np.cos(yy / 9.0)
    cols = rng.normal(0.0, 20.0, 80).astype(np.float32)
    out = column_midway(scene + cols[None, :], sigma=4.0)
    col_err = (out - scene).mean(axis=0)
    high = col_err - gaussian_filter1d(col_err, 3.0)  # column-to-column part: the FPN
    assert np.std(high) < 0.2 * np.std(cols)


def test_dct_denoise_reduces_white_noise():
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:64, 0:64].astype(np.float32)
    clean = 50.0 * np.sin(xx / 10.0) * np.cos(yy / 12.0)
    noisy = clean + rng.normal(0, 5.0, clean.shape).astype(np.float32)
    out = dct_denoise(noisy, sigma=5.0)
    assert np.std(out - clean) < 0.6 * np.std(noisy - clean)


def test_bad_input(flight):
    with pytest.raises(InvalidInputError, match="at least 2 frames"):
        correct_nonuniformity(flight.frames[:1], method="scribner")
    assert correct_nonuniformity(flight.frames[0], method="admire").shape == (1, 64, 96)
    bad = flight.frames[:4].astype(np.float32)
    bad[2, 3, 4] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        correct_nonuniformity(bad, method="ecr")
    with pytest.raises(InvalidInputError, match="mixed sizes"):
        correct_nonuniformity([flight.frames[0], flight.frames[1][:, :50]], method="ecr")
    with pytest.raises(InvalidInputError, match="unknown NUC method"):
        correct_nonuniformity(flight.frames, method="magic")
    with pytest.raises(InvalidInputError, match="scribner"):
        correct_nonuniformity(flight.frames, method="scribner", speed=3)


def _run(args, capsys):
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr()


def test_cli_nuc_writes_float32_and_rejects_bad_input(flight, tmp_path, capsys):
    src = tmp_path / "frames.tiff"
    write_recording(src, Recording(frames=flight.frames[:20]))
    out = tmp_path / "corrected.tiff"
    code, io = _run(["nuc", str(src), "--method", "scribner", "--out", str(out)], capsys)
    assert code == 0, io.err
    data = tifffile.imread(out)
    assert data.shape == (20, 64, 96) and data.dtype == np.float32
    one = tmp_path / "one.tiff"
    write_recording(one, Recording(frames=flight.frames[:1]))
    bad_out = tmp_path / "bad.tiff"
    code, io = _run(["nuc", str(one), "--method", "ecr", "--out", str(bad_out)], capsys)
    assert code == 2 and "at least 2 frames" in io.err and len(io.err.strip().splitlines()) == 1
    assert not bad_out.exists()


def test_hardie2000_registers_a_pass_whose_ends_do_not_overlap_its_pivot():
    """Registered by itself, a UAV pass whose first frames share no scene with the middle one
    (onto which a burst is registered) is registered frame to frame and chained, as `thermocal
    flight` registers it; the correction then halves the error left after an affine map."""
    from thermocal.errors import RegistrationError
    from thermocal.nuc.batch import hardie2000
    from thermocal.registration import register_burst

    cam = make_camera("tau2", unit=4, size=(160, 128))
    scene = procedural_scene((512, 512), rng=np.random.default_rng(2), kind="mixed")
    fl = simulate_flight(scene, cam, n_frames=60, motion="uav", seed=0)
    with pytest.raises(RegistrationError):
        register_burst(fl.frames)  # onto one pivot: the pass's ends do not overlap it
    out = hardie2000(fl.frames)
    mid = slice(20, 40)
    assert _affine_rmse(out[mid], fl.truth_c[mid]) < 0.5 * _affine_rmse(
        fl.frames[mid].astype(np.float32), fl.truth_c[mid])
