"""Tests of thermocal.nuc.deepir: DeepIR against bursts with a known scene, pattern and motion."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from thermocal.camera.presets import make_camera
from thermocal.errors import InvalidInputError
from thermocal.metrics import best_affine_fit, rmse
from thermocal.nuc.deepir import deepir
from thermocal.registration.warp import translation
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

torch = pytest.importorskip("torch")

H, W, N = 48, 64, 9
FAST = {"iterations": 150, "channels": 16, "scales": 3}


def _affine_rmse(frames, truth, valid=None):
    return float(np.mean([rmse(best_affine_fit(f, t, valid), t, valid=valid)
                          for f, t in zip(frames, truth, strict=True)]))


@pytest.fixture(scope="module")
def burst():
    """Integer shifts of a procedural scene (°C) seen through a known gain and offset pattern:
    y = 40 counts/°C · (g ⊙ x + o) + 6000, with per-pixel and column components."""
    rng = np.random.default_rng(5)
    scene = procedural_scene((160, 160), rng=rng, kind="mixed").astype(np.float64)
    shifts = rng.integers(-6, 7, size=(N, 2))
    shifts[N // 2] = 0
    y0, x0 = 40, 40
    truth = np.stack([scene[y0 + dy:y0 + dy + H, x0 + dx:x0 + dx + W] for dy, dx in shifts])
    contrast = float(truth.std())
    gain = 1.0 + 0.04 * rng.standard_normal((H, W)) + 0.03 * rng.standard_normal((1, W))
    offset = contrast * (0.5 * rng.standard_normal((H, W)) + 0.4 * rng.standard_normal((1, W)))
    frames = 40.0 * (gain * truth + offset) + 6000.0 + rng.normal(0.0, 1.0, truth.shape)
    # homography frame k → pivot: pixel (c, r) of frame k is scene (c + dx_k, r + dy_k)
    hs = np.stack([translation(dx, dy) for dy, dx in shifts])
    return np.round(frames).astype(np.uint16), truth, hs


@pytest.fixture(scope="module")
def corrected(burst):
    frames, _, hs = burst
    before = frames.copy()
    out = deepir(frames, homographies=hs, **FAST)
    np.testing.assert_array_equal(frames, before)  # the input is never modified
    return out


def test_recovers_the_scene_behind_a_known_pattern(burst, corrected):
    frames, truth, _ = burst
    out = corrected
    assert out.shape == frames.shape and out.dtype == np.float32
    assert np.all(np.isfinite(out))
    raw_err = _affine_rmse(frames.astype(np.float64), truth)
    out_err = _affine_rmse(out, truth)
    assert out_err < 0.3 * raw_err, (out_err, raw_err)
    # counts-like: the input's level and scale, not normalised units
    assert abs(float(np.median(out)) - float(np.median(frames))) < 0.2 * float(np.ptp(frames))


@pytest.fixture(scope="module")
def walk():
    cam = make_camera("tau2", unit=4, size=(W, H))
    scene = procedural_scene((256, 256), rng=np.random.default_rng(1), kind="mixed")
    return cam, simulate_flight(scene, cam, n_frames=N, motion="walk", seed=7)


@pytest.mark.parametrize(("known_motion", "factor"), [(True, 0.5), (False, 0.75)])
def test_improves_a_simulated_tau2_walk(walk, known_motion, factor):
    """A camera-model burst (vignetting, per-pixel gain and offset, dead pixels, noise) over a
    procedural scene, with the true homographies or registered by thermocal.registration;
    dead pixels are kept out of the score."""
    cam, fl = walk
    ok = ~cam.defects
    hs = fl.homographies if known_motion else None
    out = deepir(fl.frames, homographies=hs, **FAST)
    raw_err = _affine_rmse(fl.frames.astype(np.float64), fl.truth_c, ok)
    out_err = _affine_rmse(out, fl.truth_c, ok)
    assert out_err < factor * raw_err, (out_err, raw_err)
    assert np.all(np.isfinite(out))


def test_deterministic_and_seeded_without_touching_the_global_rng(burst):
    frames, _, hs = burst
    opts = {"iterations": 20, "channels": 8, "scales": 2}
    state = torch.random.get_rng_state()
    a = deepir(frames[:4], homographies=hs[:4], seed=3, **opts)
    b = deepir(frames[:4], homographies=hs[:4], seed=3, **opts)
    c = deepir(frames[:4], homographies=hs[:4], seed=4, **opts)
    assert torch.equal(state, torch.random.get_rng_state())
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_more_iterations_fit_better(burst, corrected):
    frames, truth, hs = burst
    few = deepir(frames, homographies=hs, **{**FAST, "iterations": 5})
    assert _affine_rmse(corrected, truth) < 0.3 * _affine_rmse(few, truth)


@pytest.mark.parametrize(
    ("frames", "options", "match"),
    [
        (np.zeros((1, 16, 16)), {}, "at least 2 frames"),
        (np.zeros((16, 16)) + 5.0, {}, "at least 2 frames"),
        (np.full((3, 16, 16), np.nan), {}, "NaN"),
        (np.zeros((2, 3, 16, 16)), {}, "frames"),
        (np.ones((3, 16, 16)), {"iterations": 0}, "iterations"),
        (np.ones((3, 16, 16)), {"seed": -1}, "seed"),
        (np.ones((3, 16, 16)), {"channels": 2.5}, "channels"),
        (np.ones((3, 16, 16)), {"learning_rate": 0.0}, "learning_rate"),
        (np.ones((3, 16, 16)), {"offset_smoothness": -1.0}, "offset_smoothness"),
        (np.ones((3, 16, 16)), {"scene_tv": float("nan")}, "scene_tv"),
        (np.ones((3, 16, 16)), {"homographies": np.stack([np.eye(3)] * 2)}, "homographies"),
        (np.ones((3, 16, 16)), {"homographies": np.full((3, 3, 3), np.nan)}, "homographies"),
        (np.ones((3, 16, 16)), {"device": "tpu"}, "device must be auto, cpu or cuda"),
    ],
)
def test_bad_input_raises_one_line_errors(frames, options, match):
    if "homographies" not in options:
        options = {**options, "homographies": np.stack([np.eye(3)] * max(len(frames), 1))}
    with pytest.raises(InvalidInputError, match=match) as info:
        deepir(frames, **options)
    assert "\n" not in str(info.value)


@pytest.mark.skipif(torch.cuda.is_available(), reason="a CUDA GPU is here")
def test_asking_for_a_gpu_that_is_not_there_is_refused():
    with pytest.raises(InvalidInputError, match="sees no CUDA GPU"):
        deepir(np.ones((3, 16, 16)), homographies=np.stack([np.eye(3)] * 3), device="cuda")


def test_constant_frames_stay_finite():
    out = deepir(np.full((3, 16, 16), 7000, np.uint16), homographies=np.stack([np.eye(3)] * 3),
                 iterations=5, channels=8, scales=2)
    assert np.all(np.isfinite(out))


def test_imports_without_torch_and_says_what_is_missing():
    code = (
        "import sys; sys.modules['torch'] = None\n"
        "import numpy as np\n"
        "from thermocal.errors import InvalidInputError\n"
        "from thermocal.nuc.deepir import deepir\n"
        "try:\n"
        "    deepir(np.ones((2, 16, 16)), homographies=np.stack([np.eye(3)] * 2))\n"
        "except InvalidInputError as exc:\n"
        "    assert 'torch' in str(exc), exc\n"
        "else:\n"
        "    raise SystemExit('no error')\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr
