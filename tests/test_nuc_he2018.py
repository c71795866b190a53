"""he2018: the single-image CNN NUC after He et al. 2018 (shipped weights, checks, accuracy)."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from thermocal.camera.presets import make_camera
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.metrics import best_affine_fit, column_bands, rmse
from thermocal.nuc import he2018 as mod
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.flight import simulate_flight

torch = pytest.importorskip("torch")

WEIGHTS = Path(mod.__file__).parent / "weights" / "he2018.pt"


@pytest.fixture(scope="module")
def held_out():
    """Two frames of held-out unit 100 over the held-out aerial scene, FPA 20 and 40 °C.

    The scene's contrast is tripled (its SD becomes ~2.7 °C instead of 0.9 °C over the view):
    at its own contrast, the frame's one hot pixel, not the scene, sets the raw frame's affine
    fit, which then hides the stripes."""
    cam = make_camera("tau2", unit=100, size=(96, 72))
    aerial = load_builtin_scene("aerial")
    scene = (aerial - aerial.mean()) * 3.0 + aerial.mean()
    flights = [simulate_flight(scene, cam, n_frames=1, fpa_c=fpa, seed=7 + i)
               for i, fpa in enumerate((20.0, 40.0))]
    frames = np.concatenate([f.frames for f in flights])
    truth = np.concatenate([f.truth_c for f in flights])
    return frames, truth


def _scores(out: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Mean over frames of the RMSE after the best affine fit and of the column-band level
    (SD of the error's column means less their 8-column Gaussian trend: the stripes, not the
    smooth radial shading, which a single-frame method leaves by design), °C."""
    r, c = [], []
    for o, t in zip(out, truth, strict=True):
        fit = best_affine_fit(o, t)
        r.append(rmse(fit, t))
        c.append(column_bands(fit, t, detrend_px=8.0))
    return float(np.mean(r)), float(np.mean(c))


def _zero_weights(path: Path) -> Path:
    """A well-formed weights file whose network predicts no pattern (all weights 0)."""
    payload = torch.load(WEIGHTS, map_location="cpu", weights_only=True)
    state = {k: torch.zeros_like(v) for k, v in payload["state_dict"].items()}
    payload.update(state_dict=state, sha256=mod.tensor_sha256(state))
    torch.save(payload, path)
    return path


def test_shipped_weights_load_and_checksum_verifies():
    net, header = mod.load_weights()
    payload = torch.load(WEIGHTS, map_location="cpu", weights_only=True)
    side = json.loads(WEIGHTS.with_suffix(".json").read_text())
    assert header["sha256"] == payload["sha256"] == mod.tensor_sha256(payload["state_dict"])
    assert side["sha256"] == header["sha256"]
    assert header["config"] == mod.CONFIG
    assert WEIGHTS.stat().st_size < 2_000_000
    # trained by the documented command, with its defaults
    assert side["command"] == ("python -m thermocal.nuc.he2018 --train --out "
                               "src/thermocal/nuc/weights/he2018.pt")
    assert (side["steps"], side["seed"]) == (mod.TRAIN_STEPS, mod.TRAIN_SEED)
    assert side["data"]["units"] == list(range(24))  # the training units only
    assert not {100, 101, 102, 103, 104} & set(side["data"]["units"])
    assert not {"builtin:aerial", "02_irwatercooler", "14_kujawy_wiatrak"} & set(
        side["data"]["scenes"])
    assert side["val_loss"] < 0.5 * side["val_loss_no_correction"]


def test_corrects_a_held_out_unit_and_scene(held_out):
    frames, truth = held_out
    raw_rmse, raw_cols = _scores(frames.astype(np.float32), truth)
    out = mod.he2018(frames)
    he_rmse, he_cols = _scores(out, truth)
    assert out.shape == frames.shape and out.dtype == np.float32
    assert he_rmse < 0.6 * raw_rmse, (he_rmse, raw_rmse)  # measured 0.85 vs 1.79 °C
    assert he_cols < 0.5 * raw_cols, (he_cols, raw_cols)  # measured 0.21 vs 0.61 °C
    # the level is kept: counts-like around the raw mean, not rescaled
    assert abs(float(out.mean()) - float(frames.mean())) < 50.0


def test_the_network_does_the_work(held_out, tmp_path):
    """Stuck-pixel replacement alone (a network that predicts nothing) does not pass."""
    frames, truth = held_out
    zero = _zero_weights(tmp_path / "zero.pt")
    z_rmse, z_cols = _scores(mod.he2018(frames, weights=zero), truth)
    he_rmse, he_cols = _scores(mod.he2018(frames), truth)
    assert he_rmse < 0.7 * z_rmse, (he_rmse, z_rmse)  # measured 0.85 vs 1.50 °C
    assert he_cols < 0.4 * z_cols, (he_cols, z_cols)  # measured 0.21 vs 0.88 °C


def test_input_unchanged_deterministic_any_size(held_out):
    frames, _ = held_out
    before = frames.copy()
    a = mod.he2018(frames)
    b = mod.he2018(frames)
    assert np.array_equal(frames, before)
    assert np.array_equal(a, b)
    # each frame on its own: the same result alone as in the stack
    assert np.array_equal(mod.he2018(frames[1]), a[1:2])
    for h, w in ((4, 4), (37, 50), (65, 31)):
        f = frames[0, :h, :w].astype(np.float64)
        keep = f.copy()
        out = mod.he2018(f)
        assert out.shape == (1, h, w) and out.dtype == np.float32
        assert np.all(np.isfinite(out))
        assert np.array_equal(f, keep)


@pytest.mark.parametrize("bad", [
    np.zeros(10), np.zeros((3, 3)), np.zeros((0, 8, 8)), np.zeros((2, 2, 8, 8)),
    np.full((8, 8), np.nan), np.full((8, 8), np.inf), "frame", None,
])
def test_bad_input_is_refused_in_one_line(bad):
    with pytest.raises(InvalidInputError) as exc:
        mod.he2018(bad)
    assert "\n" not in str(exc.value)


def test_damaged_weights_are_refused(tmp_path):
    data = WEIGHTS.read_bytes()
    cases = {
        "truncated.pt": data[: len(data) // 2],
        "text.pt": b"not a weights file\n",
        "empty.pt": b"",
    }
    # bytes flipped in the middle of the largest tensor's data
    with zipfile.ZipFile(WEIGHTS) as z:
        big = max(z.infolist(), key=lambda i: i.file_size)
    flipped = bytearray(data)
    start = big.header_offset + big.file_size // 2
    flipped[start : start + 64] = bytes(b ^ 0xFF for b in flipped[start : start + 64])
    cases["flipped.pt"] = bytes(flipped)
    for name, content in cases.items():
        p = tmp_path / name
        p.write_bytes(content)
        with pytest.raises(FileFormatError) as exc:
            mod.he2018(np.zeros((8, 8)), weights=p)
        assert "\n" not in str(exc.value), name
    # a readable file whose tensors were changed after the checksum was taken
    payload = torch.load(WEIGHTS, map_location="cpu", weights_only=True)
    name = sorted(payload["state_dict"])[0]
    payload["state_dict"][name] = payload["state_dict"][name] + 1e-3
    torch.save(payload, tmp_path / "edited.pt")
    with pytest.raises(FileFormatError, match="checksum"):
        mod.load_weights(tmp_path / "edited.pt")
    with pytest.raises(FileFormatError):
        mod.load_weights(tmp_path / "missing.pt")


def test_training_is_deterministic(tmp_path):
    """Two short runs of the training with the same seed give the same tensors."""
    kw = {"steps": 2, "batch": 2, "patch": 24, "seed": 5, "log": lambda s: None}
    a = mod.train(tmp_path / "a.pt", **kw)
    b = mod.train(tmp_path / "b.pt", **kw)
    assert a["sha256"] == b["sha256"]
    c = mod.train(tmp_path / "c.pt", **{**kw, "seed": 6})
    assert c["sha256"] != a["sha256"]
    out = mod.he2018(np.random.default_rng(0).normal(5000, 50, (12, 12)), weights=tmp_path / "a.pt")
    assert out.shape == (1, 12, 12)


def test_package_imports_without_torch():
    code = ("import sys; import thermocal.nuc.he2018; "
            "assert 'torch' not in sys.modules, 'torch imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_training_command_runs_the_module_once():
    """``python -m thermocal.nuc.he2018`` without runpy's warning that the package had
    already loaded the module (the registry imports it when first called, not at import)."""
    run = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-m",
                          "thermocal.nuc.he2018", "--help"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "RuntimeWarning" not in run.stderr
