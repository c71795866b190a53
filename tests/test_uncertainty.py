"""The network's σ model (issue 18, item 1): fitted by Gaussian NLL, never below the unit-level
floor, tied to its weights, and written beside every estimate that asks for it."""

from __future__ import annotations

import math

import numpy as np
import pytest
import tifffile
from cli_run import run

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.estimation.pipeline import estimate
from thermocal.io.recording import Recording, write_recording
from thermocal.nn.uncertainty import (
    MAX_CONTRAST_PER_C,
    OUTSIDE_SIGMA_C,
    UNIT_FLOOR_MIN_C,
    SigmaModel,
    features,
    fit_sigma_model,
    sidecar_path,
)

pytest.importorskip("torch")


def test_the_fit_recovers_a_known_sigma():
    """Errors drawn with σ² = floor² + exp(c0 + c·f): the NLL fit finds σ to a few per cent."""
    rng = np.random.default_rng(0)
    f = rng.normal(0, 1, (3, 20000))
    floor, coef = 0.6, np.array([-1.0, 0.5, 0.3, -0.2])
    sigma = np.sqrt(floor**2 + np.exp(coef[0] + coef[1:] @ f))
    model = fit_sigma_model(rng.normal(0, sigma), f, weights_sha256="x")
    fitted = model.sigma_of(f)
    assert np.median(np.abs(fitted / sigma - 1)) < 0.05
    assert model.floor_c == pytest.approx(floor, abs=0.08)


def test_the_two_stage_fit_recovers_a_level_growing_with_the_contrast(tmp_path):
    """Bursts of a population of units: each burst's level one draw of σ² = floor² +
    (k·contrast)², shared by its pixels, plus a pixel part exp(c0 + c·f): the level is fitted on
    the bursts' means (400 draws, not 400 × 200 pixels), the pixel part on the pixels."""
    rng = np.random.default_rng(4)
    n_b, n_p = 400, 200
    floor, k, coef = 0.5, 0.012, np.array([-1.5, 0.4, 0.0, 0.0])
    contrast_b = rng.uniform(-80.0, 20.0, n_b)
    level = rng.normal(0.0, np.sqrt(floor**2 + (k * contrast_b) ** 2))
    f = rng.normal(0.0, 1.0, (3, n_b * n_p))
    labels = np.repeat(np.arange(n_b), n_p)
    contrast = contrast_b[labels] + rng.normal(0.0, 3.0, labels.size)
    errors = level[labels] + rng.normal(0.0, np.sqrt(np.exp(coef[0] + coef[1:] @ f)))
    model = fit_sigma_model(errors, f, weights_sha256="x", bursts=labels, contrast_c=contrast)
    assert model.floor_c == pytest.approx(floor, abs=0.06)
    assert model.contrast_per_c == pytest.approx(k, abs=0.004)
    assert model.coef[1] == pytest.approx(0.4, abs=0.08)
    # σ grows with the contrast; it needs the FPA temperature to say so
    feats = np.zeros((3, 1, 2))
    s = model.sigma_of(feats, temperature_c=np.array([[20.0, -40.0]]), fpa_c=20.0)[0]
    assert s[1] > s[0] and s[0] == pytest.approx(np.hypot(floor, np.exp(coef[0] / 2)), abs=0.08)
    with pytest.raises(InvalidInputError, match="FPA temperature"):
        model.sigma_of(feats, temperature_c=np.zeros((1, 2)))
    # the level alone is the part σ states where the views reveal nothing, by hand
    lev = model.level_sigma(np.array([20.0, -40.0]), 20.0)
    assert lev == pytest.approx(np.hypot(model.floor_c, model.contrast_per_c * np.array([0, 60])))
    assert np.all(s**2 > lev**2) and s[0] ** 2 - lev[0] ** 2 == pytest.approx(
        np.exp(model.coef[0]), rel=1e-4)
    # one stage, as before, where the bursts are not given: no contrast term
    assert fit_sigma_model(errors, f, weights_sha256="x").contrast_per_c is None
    with pytest.raises(InvalidInputError, match="both"):
        fit_sigma_model(errors, f, weights_sha256="x", bursts=labels)
    with pytest.raises(InvalidInputError, match="need >= 10"):
        fit_sigma_model(errors[:900], f[:, :900], weights_sha256="x", bursts=labels[:900],
                        contrast_c=contrast[:900])
    # round trip; a contrast term out of range is refused; a model without one keeps its digest
    path = model.save(tmp_path / "m.sigma.json")
    assert SigmaModel.load(path, weights_sha256="x") == model
    with pytest.raises(InvalidInputError, match="contrast"):
        SigmaModel(0.5, (0.0, 0.0, 0.0, 0.0), contrast_per_c=0.5)
    plain = SigmaModel(0.5, (0.0,) * 4)
    text = plain.save(tmp_path / "p.json").read_text()
    assert "contrast_per_c" not in text and '"version": 1' in text
    # a model without the term needs no FPA temperature (as before it existed)
    assert plain.sigma_of(np.zeros((3, 2, 2))).shape == (2, 2)
    assert plain.level_sigma() == 0.5 and plain.level_sigma(np.zeros(3)).shape == (3,)
    # written as version 2, which a reader of version 1 would refuse rather than misapply
    assert '"version": 2' in path.read_text()
    for old, new in (('"version": 2', '"version": 1'), ('"version": 2', '"version": 3')):
        (tmp_path / "v.json").write_text(path.read_text().replace(old, new))
        with pytest.raises(FileFormatError, match="contrast term|format version 3"):
            SigmaModel.load(tmp_path / "v.json", weights_sha256="x")
    assert SigmaModel(0.5, (0.0,) * 4, contrast_per_c=0).contrast_per_c == 0.0
    with pytest.raises(InvalidInputError, match="contrast"):
        SigmaModel(0.5, (0.0,) * 4, contrast_per_c=True)
    # a contrast beyond the bound is held there, and the floor refitted with it (not left to
    # the pixel term)
    wide = rng.normal(0.0, np.sqrt(floor**2 + (0.3 * contrast_b) ** 2))
    capped = fit_sigma_model(wide[labels] + errors - level[labels], f, weights_sha256="x",
                             bursts=labels, contrast_c=contrast)
    assert capped.contrast_per_c == MAX_CONTRAST_PER_C and capped.floor_c > floor + 0.3


def test_the_shipped_fit_of_sigma_takes_its_units_one_per_burst():
    """fit_network_sigma on the preset's units (one scene-pass each, 11 bursts): the level's
    contrast term fitted on the bursts, each of its own unit."""
    from thermocal.evaluation.sigma_fit import fit_network_sigma
    from thermocal.nn.infer import shipped_model_path

    sigma = fit_network_sigma(shipped_model_path("kpn"), per_scene=1)
    assert sigma.fitted_on["bursts"] == len(sigma.fitted_on["units"]) >= 10
    assert sigma.contrast_per_c is not None and 0.0 <= sigma.contrast_per_c <= 0.2
    assert sigma.floor_c >= UNIT_FLOOR_MIN_C - 1e-9


def test_the_floor_is_never_below_the_unit_spread():
    rng = np.random.default_rng(1)
    f = rng.normal(0, 1, (3, 5000))
    model = fit_sigma_model(rng.normal(0, 0.01, 5000), f, weights_sha256=None)
    assert model.floor_c >= UNIT_FLOOR_MIN_C - 1e-9
    assert np.all(model.sigma_of(f) >= UNIT_FLOOR_MIN_C - 1e-6)
    assert UNIT_FLOOR_MIN_C == pytest.approx(0.34 * math.sqrt(math.pi / 2))
    with pytest.raises(InvalidInputError, match="floor"):
        SigmaModel(0.1, (0.0, 0.0, 0.0, 0.0))


def test_features_see_views_gradient_and_disagreement():
    warped = np.zeros((4, 8, 8), np.float32)
    valid = np.ones((4, 8, 8), bool)
    valid[2:, :, :4] = False
    warped[0, :, 6:] = 1.0
    temp = np.zeros((8, 8), np.float32)
    temp[:, 4:] = 5.0
    spread, grad, inv_n = features(warped, valid, temp)
    assert np.allclose(inv_n[:, :4], -np.log(2)) and np.allclose(inv_n[:, 4:], -np.log(4))
    assert spread[0, 7] > spread[0, 4] and grad[0, 4] > grad[0, 0]


def test_sidecar_round_trip_and_refusals(tmp_path):
    model = SigmaModel(0.5, (-1.0, 0.1, 0.2, 0.3), "abc", fitted_on={"bursts": 3})
    path = model.save(tmp_path / "m.sigma.json")
    assert SigmaModel.load(path, weights_sha256="abc") == model
    with pytest.raises(FileFormatError, match="other weights"):
        SigmaModel.load(path, weights_sha256="def")
    path.write_text(path.read_text().replace('"floor_c": 0.5', '"floor_c": -3'))
    with pytest.raises(FileFormatError, match="not a usable σ model"):
        SigmaModel.load(path, weights_sha256="abc")
    assert sidecar_path(tmp_path / "kpn_n7.pt").name == "kpn_n7.sigma.json"


def test_a_chamber_models_misfit_grows_beyond_its_set_points_and_round_trips(tmp_path):
    """A network trained on a chamber file's camera model: σ takes that model's level misfit
    at the estimate's temperature, linear between the set points, growing beyond them along
    the end segments (never below the end's value)."""
    model = SigmaModel(0.5, (-30.0, 0.0, 0.0, 0.0), "abc",
                       misfit_c=((10.0, 20.0, 30.0), (1.0, 0.8, 0.9)))
    t = np.array([0.0, 10.0, 15.0, 30.0, 40.0])
    np.testing.assert_allclose(model.misfit_at(t), [1.2, 1.0, 0.9, 0.9, 1.0])
    feats = np.zeros((3, 1, 5))
    np.testing.assert_allclose(model.sigma_of(feats, temperature_c=t[None])[0],
                               np.hypot(0.5, [1.2, 1.0, 0.9, 0.9, 1.0]), rtol=1e-6)
    with pytest.raises(InvalidInputError, match="needs the estimate's temperature"):
        model.sigma_of(feats)
    path = model.save(tmp_path / "m.sigma.json")
    assert SigmaModel.load(path, weights_sha256="abc") == model
    # falling towards the ends: held there, not shrunk to 0
    flat = SigmaModel(0.5, (-30.0, 0.0, 0.0, 0.0), misfit_c=((10.0, 20.0), (0.5, 1.0)))
    assert flat.misfit_at(np.array([-20.0]))[0] == pytest.approx(0.5)
    for bad in (((10.0,), (1.0,)), ((20.0, 10.0), (1.0, 1.0)), ((10.0, 20.0), (1.0, -1.0)),
                ((10.0, 20.0), (1.0, float("nan")))):
        with pytest.raises(InvalidInputError, match="misfit"):
            SigmaModel(0.5, (0.0, 0.0, 0.0, 0.0), misfit_c=bad)
    # given as arrays, stored as floats (JSON, the digest); a NaN estimate has a NaN misfit
    arr = SigmaModel(0.5, (0.0, 0.0, 0.0, 0.0),
                     misfit_c=(np.array([10.0, 20.0], np.float32), np.array([1.0, 0.5])))
    assert arr.misfit_c == ((10.0, 20.0), (1.0, 0.5)) and len(arr.digest()) == 64
    assert np.isnan(arr.misfit_at(np.array([np.nan]))[0])
    with pytest.raises(InvalidInputError, match="misfit"):
        SigmaModel(0.5, (0.0, 0.0, 0.0, 0.0), misfit_c=((10.0, 20.0),))
    # a model without one keeps the SHA-256 it was saved with before the field existed
    plain = SigmaModel(0.5, (-1.0, 0.1, 0.2, 0.3), "abc")
    assert "misfit_c" not in plain.save(tmp_path / "p.sigma.json").read_text()


def test_the_shipped_network_has_its_sigma_model():
    from thermocal.nn.infer import NetworkEstimator

    net = NetworkEstimator.from_file("kpn")
    assert net.sigma_model is not None
    assert net.sigma_model.floor_c >= UNIT_FLOOR_MIN_C - 1e-9
    assert net.sigma_model.fitted_on["bursts"] >= 20
    assert not set(net.sigma_model.fitted_on["units"]) & {*range(0, 24), *range(100, 105)}


def test_estimate_writes_sigma_and_inflates_it_outside(tmp_path, capsys):
    from thermocal.camera.presets import make_camera
    from thermocal.io.recording import Recording, write_recording
    from thermocal.scenes.procedural import procedural_scene
    from thermocal.simulate.flight import simulate_flight

    scene = procedural_scene((384, 384), rng=np.random.default_rng(3), kind="mixed")
    for preset in ("tau2", "boson"):
        fl = simulate_flight(scene, make_camera(preset, unit=104, size=(336, 256)), n_frames=7,
                             motion="walk", fpa_c=25.0, seed=3)
        path, _ = write_recording(tmp_path / f"{preset}.tiff",
                                  Recording(fl.frames, fpa_c=fl.fpa_c))
        out, sig = tmp_path / f"{preset}_t.tiff", tmp_path / f"{preset}_s.tiff"
        code, _, err = run(["estimate", path, "--out", out, "--sigma-out", sig, "--force"],
                           capsys)
        assert code == 0, err
        assert f"and its σ to {sig}" in err  # the console names both files
        sigma = tifffile.imread(sig)
        assert sigma.shape == (256, 336) and sigma.dtype == np.float32
        if preset == "tau2":
            assert UNIT_FLOOR_MIN_C - 1e-6 <= sigma.min() and np.median(sigma) < 1.5
            error = np.abs(tifffile.imread(out) - fl.truth_c[fl.pivot])
            assert 0.5 < np.mean(error <= 2 * sigma)  # a sanity check; coverage: benchmarks
        else:
            assert sigma.min() >= OUTSIDE_SIGMA_C and "warning" in err
    code, _, err = run(["estimate", tmp_path / "tau2.tiff", "--out", tmp_path / "x.tiff",
                        "--sigma-out", tmp_path / "tau2.tiff"], capsys)
    assert code == 2 and "input" in err and not (tmp_path / "x.tiff").exists()


def test_a_typed_fpa_temperatures_uncertainty_enters_sigma(tmp_path, capsys):
    """An FPA temperature typed 15 °C off (a FLIR file carries none) moved the shipped
    network's temperatures 7.7 °C where σ said 0.84, silent (a helper's audit): σ takes it as
    exact unless --fpa-sigma-c says how well it is known, and says so; given, σ takes in how
    far a °C of it moves each pixel (0.48-0.58 °C per °C on this unit), and covers the error;
    --fpa-sigma-c without --fpa-c, or out of range, is refused."""
    from thermocal._validate import FPA_RANGE_C
    from thermocal.camera.presets import make_camera
    from thermocal.estimation.pipeline import fpa_sensitivity, fpa_step
    from thermocal.estimation.registry import make_estimator
    from thermocal.scenes.procedural import procedural_scene
    from thermocal.simulate.flight import simulate_flight

    scene = procedural_scene((256, 256), rng=np.random.default_rng(2), kind="mixed")
    fl = simulate_flight(scene, make_camera("tau2", unit=31, size=(160, 120)), n_frames=7,
                         motion="walk", fpa_c=45.0, seed=2)
    path, _ = write_recording(tmp_path / "r.tiff", Recording(fl.frames, fpa_c=fl.fpa_c))
    truth = fl.truth_c[fl.pivot]
    base = ["estimate", path, "--fpa-c", "30", "--force", "--out", tmp_path / "t.tiff",
            "--sigma-out", tmp_path / "s.tiff"]
    code, _, err = run(base, capsys)
    assert code == 0 and "σ takes --fpa-c 30 as exact" in err, err
    temps = tifffile.imread(tmp_path / "t.tiff")
    error, exact = np.abs(temps - truth), tifffile.imread(tmp_path / "s.tiff")
    assert np.median(error) > 5.0 and np.mean(error <= 2 * exact) < 0.2  # the audit's silence
    code, _, err = run([*base, "--fpa-sigma-c", "15"], capsys)
    assert code == 0 and "as exact" not in err, err
    sigma = tifffile.imread(tmp_path / "s.tiff")
    np.testing.assert_array_equal(tifffile.imread(tmp_path / "t.tiff"), temps)  # σ alone
    assert np.mean(error <= 2 * sigma) > 0.95 and np.median(sigma) < 12.0
    est = make_estimator("kpn")
    result = estimate(fl.frames, est, fpa_c=30.0, force=True)
    moved = fpa_sensitivity(fl.frames, est, result, fpa_c=30.0)
    assert 0.4 < float(np.median(moved)) < 0.7
    assert fpa_step(30.0) == 1.0 and fpa_step(FPA_RANGE_C[1] - 0.5) == -1.0  # stays inside
    np.testing.assert_allclose(sigma, np.hypot(result.sigma_c, 15.0 * moved), rtol=1e-4)
    for extra, message in ((["--fpa-sigma-c", "-1"], "--fpa-sigma-c must be 0-20 °C"),
                           (["--fpa-sigma-c", "nan"], "--fpa-sigma-c must be 0-20 °C")):
        code, _, err = run([*base, *extra], capsys)
        assert code == 2 and message in err, err
    code, _, err = run(["estimate", path, "--fpa-sigma-c", "2", "--out", tmp_path / "u.tiff",
                        "--sigma-out", tmp_path / "us.tiff"], capsys)
    assert code == 2 and "give --fpa-c too" in err and not (tmp_path / "u.tiff").exists()


def test_forced_beyond_the_training_scenes_sigma_grows_by_the_distance(tmp_path, capsys):
    """A scene 40 °C hotter than any training scene level, forced: σ grows by at least how far
    beyond it lies (no training burst measured the error there: a FLIR T1030sc CSQ forced
    through the tau2 network read 101 °C where the camera reads 19 °C); inside, no growth."""
    from thermocal.camera.presets import make_camera
    from thermocal.io.recording import Recording, write_recording
    from thermocal.nn.infer import NetworkEstimator
    from thermocal.nn.validity import beyond_training_c
    from thermocal.scenes.procedural import procedural_scene
    from thermocal.simulate.flight import simulate_flight

    domain = NetworkEstimator.from_file("kpn").domain
    lo, hi = domain.scene_level_c
    clip_lo, clip_hi = domain.scene_clip_c
    inside = np.full((4, 5), (lo + hi) / 2, np.float32)
    assert not beyond_training_c(domain, inside, inside).any()
    hot = inside + (hi - inside[0, 0]) + 30.0  # the level 30 °C above the training levels
    t = np.full_like(inside, clip_hi + 5.0)
    assert np.allclose(beyond_training_c(domain, hot, t), 35.0, atol=0.01)
    assert np.allclose(beyond_training_c(domain, None, inside - (inside[0, 0] - clip_lo) - 2), 2)

    scene = procedural_scene((256, 256), rng=np.random.default_rng(3), kind="mixed")
    scene = scene - np.median(scene) + hi + 40.0
    fl = simulate_flight(scene, make_camera("tau2", unit=104, size=(160, 128)), n_frames=7,
                         motion="walk", fpa_c=25.0, seed=3)
    path, _ = write_recording(tmp_path / "hot.tiff", Recording(fl.frames, fpa_c=fl.fpa_c))
    out, sig = tmp_path / "t.tiff", tmp_path / "s.tiff"
    code, _, err = run(["estimate", path, "--out", out, "--sigma-out", sig], capsys)
    assert code == 2 and "training scenes" in err
    code, _, err = run(["estimate", path, "--out", out, "--sigma-out", sig, "--force"], capsys)
    assert code == 0 and "warning" in err, err
    assert np.median(tifffile.imread(sig)) >= 35.0


def test_fuzzed_sigma_models_are_refused_or_sane(tmp_path):
    """200 byte-level mutants of the shipped σ model: each is refused with FileFormatError or
    reads as the very same model (its SHA-256: a changed number cannot pass); nothing else."""
    from mutants import flip_bytes

    from thermocal.nn.infer import shipped_model_path

    original = sidecar_path(shipped_model_path("kpn"))
    data = original.read_bytes()
    same = SigmaModel.load(original, weights_sha256=None)
    rng = np.random.default_rng(18)
    feats = np.zeros((3, 4, 4))
    outcomes = {"refused": 0, "read": 0}
    for i in range(200):
        path = tmp_path / f"m{i}.sigma.json"
        path.write_bytes(flip_bytes(data, rng))
        try:
            model = SigmaModel.load(path, weights_sha256=None)
        except FileFormatError as exc:
            assert len(str(exc).splitlines()) == 1
            outcomes["refused"] += 1
            continue
        sigma = model.sigma_of(feats, temperature_c=np.zeros((4, 4)), fpa_c=20.0)
        assert model == same and np.all(np.isfinite(sigma))
        outcomes["read"] += 1
    assert outcomes["refused"] > 150
