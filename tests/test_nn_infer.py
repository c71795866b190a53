"""`thermocal estimate` / `thermocal train` and the inference path: contract and bad input."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
import tifffile

torch = pytest.importorskip("torch")

from thermocal.calibration.two_point import fit_two_point  # noqa: E402
from thermocal.camera.model import render  # noqa: E402
from thermocal.camera.presets import make_camera  # noqa: E402
from thermocal.cli import main  # noqa: E402
from thermocal.errors import InvalidInputError, RegistrationError, ThermocalError  # noqa: E402
from thermocal.estimation.calibrated import naive_mean  # noqa: E402
from thermocal.io.recording import Recording, write_recording  # noqa: E402
from thermocal.nn import infer  # noqa: E402
from thermocal.nn.data import BurstConfig, ScenePool  # noqa: E402
from thermocal.nn.infer import (  # noqa: E402
    estimate_burst,
    inference_tiling,
    run_network,
)
from thermocal.nn.inputs import Normalisation, frame_r2, sensor_r2  # noqa: E402
from thermocal.nn.model import KPN, ModelConfig  # noqa: E402
from thermocal.nn.store import load_model, save_model  # noqa: E402
from thermocal.nn.train import TrainConfig, step_lr  # noqa: E402
from thermocal.registration.warp import warp_to_pivot  # noqa: E402
from thermocal.scenes.procedural import procedural_scene  # noqa: E402
from thermocal.simulate.flight import simulate_flight, write_flight  # noqa: E402


def run(args: list[str], capsys) -> tuple[int, str]:
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    return code, capsys.readouterr().err


@pytest.fixture(scope="module")
def camera():
    return make_camera("tau2", unit=101, size=(64, 48))


@pytest.fixture(scope="module")
def flight(camera):
    scene = procedural_scene((200, 200), rng=np.random.default_rng(2), kind="urban")
    return simulate_flight(scene, camera, n_frames=3, motion="walk", fpa_c=30.0, seed=4)


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    torch.manual_seed(0)
    model = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3))
    path = tmp_path_factory.mktemp("m") / "tiny.pt"
    save_model(path, model, Normalisation(), BurstConfig(n_frames=3, crop=32))
    return path


@pytest.fixture
def true_registration(monkeypatch, flight):
    """register_burst replaced by the flight's true homographies (registration is tested
    elsewhere)."""
    import thermocal.registration as reg

    def fake(frames, *, pivot=None, method="auto"):
        return reg.BurstRegistration(
            flight.homographies, flight.pivot, np.zeros(len(frames), dtype=int), "true"
        )

    monkeypatch.setattr(reg, "register_burst", fake)


def test_estimate_writes_the_pivot_temperature(
    tmp_path, flight, tiny_model, true_registration, capsys
):
    write_flight(tmp_path / "f", flight)
    out = tmp_path / "t.tiff"
    code, err = run(
        [
            "estimate",
            str(tmp_path / "f" / "frames.tiff"),
            "--model",
            str(tiny_model),
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    t = tifffile.imread(out)
    assert t.shape == (48, 64) and t.dtype == np.float32 and np.all(np.isfinite(t))


def test_estimate_registered_and_pivot(tmp_path, flight, tiny_model, capsys):
    rec = Recording(frames=flight.frames, fpa_c=flight.fpa_c)
    write_recording(tmp_path / "r.tiff", rec)
    out = tmp_path / "t.tiff"
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(tiny_model),
            "--registered",
            "--pivot",
            "0",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    assert tifffile.imread(out).shape == (48, 64)


def test_a_longer_recording_gives_the_network_the_frames_around_the_pivot(
        tmp_path, flight, tiny_model, capsys):
    """A recording of more frames than the network takes: the N frames around --pivot (moved
    inside at the ends), as if they had been the recording, the pivot among them."""
    frames = np.concatenate([flight.frames, flight.frames[::-1]])  # 6 frames, N = 3
    fpa = 30.0 + 0.01 * np.arange(6)
    write_recording(tmp_path / "long.tiff", Recording(frames=frames, fpa_c=fpa))
    for pivot, start, inner in ((None, 2, 1), (0, 0, 0), (5, 3, 2), (3, 2, 1)):
        window = slice(start, start + 3)
        write_recording(tmp_path / "w.tiff", Recording(frames=frames[window], fpa_c=fpa[window]))
        maps = []
        for name, p in (("long", pivot), ("w", inner)):
            out = tmp_path / f"{name}_out.tiff"
            args = ["estimate", str(tmp_path / f"{name}.tiff"), "--model", str(tiny_model),
                    "--registered", "--out", str(out), "--pivot", str(p)]
            code, err = run(args if p is not None else args[:-2], capsys)
            assert code == 0, err
            maps.append(tifffile.imread(out))
        assert np.array_equal(*maps), pivot
    code, err = run(["estimate", str(tmp_path / "long.tiff"), "--model", str(tiny_model),
                     "--registered", "--pivot", "6", "--out", str(tmp_path / "x.tiff")], capsys)
    assert code == 2 and "6" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("frames_fn", "extra", "message"),
    [
        (lambda f: f[:2], [], "trained for N = 3 frames, got 2"),
        (lambda f: np.concatenate([f[:2], np.full_like(f[:1], 16383)]), [], "saturated"),
    ],
)
def test_estimate_bad_bursts(tmp_path, flight, tiny_model, capsys, frames_fn, extra, message):
    rec = Recording(frames=frames_fn(flight.frames), fpa_c=None)
    write_recording(tmp_path / "r.tiff", rec)
    out = tmp_path / "t.tiff"
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(tiny_model),
            "--registered",
            "--fpa-c",
            "30",
            "--out",
            str(out),
            *extra,
        ],
        capsys,
    )
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_estimate_needs_an_fpa_temperature(tmp_path, flight, tiny_model, capsys):
    write_recording(tmp_path / "r.tiff", Recording(frames=flight.frames))
    out = tmp_path / "t.tiff"
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(tiny_model),
            "--registered",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 2 and "no FPA temperature" in err and not out.exists()


def test_estimate_rejects_a_file_that_is_not_weights(tmp_path, flight, capsys):
    write_recording(tmp_path / "r.tiff", Recording(frames=flight.frames, fpa_c=flight.fpa_c))
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a model at all")
    out = tmp_path / "t.tiff"
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(bad),
            "--registered",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 2 and "not a thermocal weights file" in err and not out.exists()
    other = tmp_path / "other.pt"
    torch.save({"hello": 1}, other)
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(other),
            "--registered",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 2 and "not a thermocal weights file" in err


def test_estimate_frames_of_different_sizes(tmp_path, tiny_model, capsys):
    path = tmp_path / "mixed.tiff"
    with tifffile.TiffWriter(path) as tw:
        tw.write(np.full((48, 64), 5000, np.uint16))
        tw.write(np.full((40, 64), 5000, np.uint16))
        tw.write(np.full((48, 64), 5000, np.uint16))
    code, err = run(
        [
            "estimate",
            str(path),
            "--model",
            str(tiny_model),
            "--fpa-c",
            "30",
            "--registered",
            "--out",
            str(tmp_path / "t.tiff"),
        ],
        capsys,
    )
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_estimate_burst_that_does_not_overlap(flight, tiny_model):
    model, norm, _ = load_model(tiny_model)
    far = flight.homographies.copy()
    far[0] = np.array([[1.0, 0, 500.0], [0, 1.0, 0], [0, 0, 1.0]])
    with pytest.raises(RegistrationError, match="overlaps the pivot"):
        estimate_burst(flight.frames, 30.0, model=model, norm=norm, homographies=far)


def test_estimate_mean_needs_a_calibration(tmp_path, flight, capsys):
    write_recording(tmp_path / "r.tiff", Recording(frames=flight.frames, fpa_c=flight.fpa_c))
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--method",
            "mean",
            "--out",
            str(tmp_path / "t.tiff"),
        ],
        capsys,
    )
    assert code == 2 and "--calibration" in err


def test_estimate_method_must_match_the_model(tmp_path, flight, tiny_model, capsys):
    write_recording(tmp_path / "r.tiff", Recording(frames=flight.frames, fpa_c=flight.fpa_c))
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(tiny_model),
            "--method",
            "e2e",
            "--registered",
            "--out",
            str(tmp_path / "t.tiff"),
        ],
        capsys,
    )
    assert code == 2 and "not e2e" in err


def test_naive_mean_with_the_units_own_calibration(tmp_path, camera, flight):
    """Eq. 9 through a two-point calibration of the same unit at the burst's FPA temperature:
    the registered average is close to the truth (the known answer of a perfect calibration)."""
    rng = np.random.default_rng(0)
    fpa = float(flight.fpa_true_c.mean())
    housing = float(flight.housing_c.mean())
    lo = render(camera, np.full(8, 10.0), fpa, housing_c=housing, rng=rng)
    hi = render(camera, np.full(8, 50.0), fpa, housing_c=housing, rng=rng)
    cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=fpa)
    est = naive_mean(flight.frames, cal, fpa_c=flight.fpa_c, homographies=flight.homographies)
    truth = flight.truth_c[flight.pivot]
    inner = est.coverage == 3
    err = np.abs(est.temperature_c - truth)[inner]
    assert np.median(err) < 0.3
    # through the CLI too
    cal.save(tmp_path / "cal.h5")
    from thermocal.calibration import load_any_calibration

    assert load_any_calibration(tmp_path / "cal.h5").shape == (48, 64)


@pytest.mark.parametrize("radial", [0, 2])
def test_tiled_inference_matches_one_pass(flight, tiny_model, radial):
    model, norm, _ = load_model(tiny_model)
    if radial:  # a model that also sees where each tile lies on the sensor
        torch.manual_seed(1)
        model = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, radial=radial)).eval()
        with torch.no_grad():
            model.offset.delta_radial.normal_(0.0, 0.1)
    warped = flight.frames.astype(np.float32)[:, :47, :63]  # odd sides: tiles are padded
    valid = np.ones(warped.shape, dtype=bool)
    one = run_network(model, norm, warped, valid, 30.0, tile=512)
    tiled = run_network(model, norm, warped, valid, 30.0, tile=24, margin=8)
    assert one.shape == tiled.shape == (47, 63)
    assert np.allclose(one, tiled, atol=1e-3)


def test_radiance_model_weights_keep_their_temperature_range_and_band(tmp_path):
    cfg = ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, radiance=True, radial=1,
                      band_m=(8e-6, 14e-6))
    norm = Normalisation(temp_min_c=-20.0, temp_max_c=60.0)
    torch.manual_seed(0)
    model = KPN(cfg, temp_range_c=(-20.0, 60.0)).eval()
    path = save_model(tmp_path / "r.pt", model, norm, BurstConfig(n_frames=3, crop=32))
    back, norm_back, _ = load_model(path)
    assert back.config == cfg and norm_back == norm
    assert back.to_temperature.temp_range_c == (-20.0, 60.0)
    x, fpa, r2 = torch.rand(1, 3, 8, 8), torch.rand(1), torch.rand(1, 1, 8, 8)
    with torch.no_grad():
        assert torch.allclose(back(x, fpa, r2=r2), model(x, fpa, r2=r2), atol=1e-6)
        default = KPN(cfg)  # another range or band: another mapping
        default.load_state_dict(model.state_dict())
        assert not torch.allclose(default.eval()(x, fpa, r2=r2), model(x, fpa, r2=r2))


def test_train_command_smoke(tmp_path, capsys):
    out = tmp_path / "m.pt"
    code, err = run(
        [
            "train",
            "--out",
            str(out),
            "--frames",
            "3",
            "--mu",
            "4",
            "--levels",
            "1",
            "--kernel",
            "3",
            "--crop",
            "32",
            "--batch",
            "2",
            "--steps-per-epoch",
            "2",
            "--max-epochs",
            "1",
            "--val-bursts",
            "2",
            "--units",
            "0-1",
            "--workers",
            "0",
            "--threads",
            "1",
            "--scenes",
            "3",
            "--redraw-pixel-fpn",
            "--walk-frames",
            "5",
        ],
        capsys,
    )
    assert code == 0, err
    model, norm, info = load_model(out)
    assert model.config.n_frames == 3 and norm.counts_max > norm.counts_min
    assert model.config.radiance and model.config.radial == 2  # the defaults
    assert info["data"]["redraw_pixel_fpn"] is True and info["data"]["walk_frames"] == 5
    assert info["meta"]["val_mae_c"] is not None
    assert out.with_suffix(".ckpt").is_file()
    # --resume continues from the checkpoint
    code, err = run(
        [
            "train",
            "--out",
            str(out),
            "--resume",
            "--max-epochs",
            "2",
            "--workers",
            "0",
            "--scenes",
            "3",
        ],
        capsys,
    )
    assert code == 0, err
    assert json.loads(json.dumps(info["data"]))["n_frames"] == 3


def test_step_lr_halves_at_half_and_three_quarters_of_the_first_budget_to_run_out():
    cfg = TrainConfig(lr=1e-3, steps_per_epoch=10, max_epochs=100, max_steps=400)
    assert [step_lr(cfg, s, 0.0) for s in (0, 199, 200, 299, 300, 399)] == [
        1e-3, 1e-3, 5e-4, 5e-4, 2.5e-4, 2.5e-4]
    # epochs run out first (100 steps), then minutes (30 s of 1 min)
    assert step_lr(TrainConfig(lr=1.0, steps_per_epoch=10, max_epochs=10), 50, 0.0) == 0.5
    assert step_lr(TrainConfig(lr=1.0, max_epochs=10**6, max_minutes=1.0), 0, 30.0) == 0.5
    assert step_lr(TrainConfig(lr=1.0, max_epochs=10**6, max_minutes=1.0), 0, 45.0) == 0.25


def test_step_schedule_follows_its_budget_not_the_validation(tmp_path, monkeypatch):
    from dataclasses import replace

    from thermocal.nn import train as train_module

    # a validation loss that never improves: the plateau schedule would halve and stop at once
    monkeypatch.setattr(train_module, "validate", lambda *args: (1.0, 1.0, 1.0))
    model_cfg = ModelConfig(n_frames=3, mu=4, levels=1, kernel=3)
    burst_cfg = BurstConfig(n_frames=3, crop=32, units=(0, 1))
    cfg = TrainConfig(batch=2, steps_per_epoch=1, max_steps=4, lr=1e-3, lr_schedule="step",
                      lr_patience=0, stop_patience=1, val_bursts=2, workers=0, threads=1)

    def fit(name, cfg, **kw):
        return train_module.train(
            tmp_path / name, model_cfg, burst_cfg, cfg, log=lambda line: None, progress=False,
            pool_fn=lambda: ScenePool.training(seed=1, n_procedural=2),
            val_pool_fn=lambda: ScenePool.training(seed=2, n_procedural=2), **kw)

    res = fit("s.pt", cfg)
    assert res.stopped == "max_steps" and res.steps == 4
    # each (one-step) epoch's rate: steps 0, 1 at lr, 2 at lr/2, 3 at lr/4
    assert [h["lr"] for h in res.history] == [1e-3, 1e-3, 5e-4, 2.5e-4]
    # resumed with a longer budget, the rate goes on along the first call's schedule
    res = fit("s.pt", replace(cfg, max_steps=6), resume=True)
    assert res.steps == 6 and [h["lr"] for h in res.history] == [1e-3, 1e-3, 5e-4] + [2.5e-4] * 3
    res = fit("p.pt", replace(cfg, lr_schedule="plateau"))
    assert res.stopped == "early_stop" and res.steps == 2
    assert [h["lr"] for h in res.history] == [1e-3, 5e-4]


def test_train_bad_options(tmp_path, capsys):
    code, err = run(["train", "--out", str(tmp_path / "m.pt"), "--crop", "30"], capsys)
    assert code == 2 and "multiple" in err
    code, err = run(["train", "--out", str(tmp_path / "m.pt"), "--units", "x"], capsys)
    assert code == 2 and "units" in err
    code, err = run(["train", "--out", str(tmp_path / "m.pt"), "--lr-schedule", "cosine"], capsys)
    assert code == 2 and "lr-schedule" in err
    code, err = run(["train", "--out", str(tmp_path / "m.pt"), "--walk-frames", "4"], capsys)
    assert code == 2 and "walk_frames" in err
    with pytest.raises(InvalidInputError):
        infer.shipped_model_path("mean")


def test_train_from_a_chamber_file(tmp_path, capsys):
    """The real-camera path: the camera model fitted on a chamber file replaces the preset."""
    chamber = tmp_path / "c.h5"
    code, err = run(
        [
            "simulate",
            "chamber",
            str(chamber),
            "--size",
            "32x24",
            "--seed",
            "1",
            "--unit",
            "3",
            "--ambient-profile",
            "steps",
            "--ambient-c",
            "10:40",
            "--interval-s",
            "30",
        ],
        capsys,
    )
    assert code == 0, err
    out = tmp_path / "m.pt"
    code, err = run(
        [
            "train",
            "--out",
            str(out),
            "--chamber",
            str(chamber),
            "--frames",
            "3",
            "--mu",
            "4",
            "--levels",
            "1",
            "--kernel",
            "3",
            "--crop",
            "16",
            "--batch",
            "2",
            "--steps-per-epoch",
            "2",
            "--max-epochs",
            "1",
            "--val-bursts",
            "2",
            "--workers",
            "0",
            "--threads",
            "1",
            "--scenes",
            "3",
        ],
        capsys,
    )
    assert code == 0, err
    model, norm, info = load_model(out)
    assert info["meta"]["chamber"] == str(chamber)
    assert info["data"]["sensor_size"] == [32, 24]
    # --calibrated (the default): the fitted model is stored with the weights, at its size
    assert model.config.calibrated and model.nominal.shape == (24, 32)
    # exported only at its camera's size (at 640x512, the default, it wrote a graph whose
    # inputs no camera model could make)
    code, err = run(["export", str(out), "--out", str(tmp_path / "m.onnx")], capsys)
    assert code == 2 and "export it at --size 32x24" in err and not (tmp_path / "m.onnx").exists()
    if importlib.util.find_spec("onnx") is not None:
        code, err = run(["export", str(out), "--out", str(tmp_path / "m.onnx"), "--size",
                         "32x24"], capsys)
        assert code == 0, err
    assert model.nominal.info["preset"] is None and model.nominal.offset.std() > 0
    assert np.all(model.nominal.gain[0] > 0)  # the fit's dead pixels filled from neighbours
    code, err = run(["train", "--out", str(out), "--resume", "--steps", "1"], capsys)
    assert code == 2 and "resume it with --chamber" in err
    lo, hi = info["data"]["fpa_range_c"]
    assert 14.0 < lo < hi < 48.0  # the FPA range the chamber covered (not the preset 10-50)
    # its σ model: fitted on bursts of the camera model fitted on that chamber file
    from thermocal.evaluation.sigma_fit import fit_network_sigma
    from thermocal.nn.uncertainty import SigmaModel, sidecar_path

    sigma = SigmaModel.load(sidecar_path(out), weights_sha256=info["sha256"])
    assert sigma.fitted_on["chamber"] == str(chamber) and "units" not in sigma.fitted_on
    assert sigma.fitted_on["variant"] == "kpn"
    assert sigma.fitted_on["bursts"] == 44  # 4 per validation scene
    # what the fitted model misses of the camera's level, by the file's blackbody set points
    points, misfit = sigma.misfit_c
    assert len(points) >= 2 and all(m > 0 for m in misfit)
    assert sigma.fitted_on["model_level_misfit_c"] > 0
    with pytest.raises(InvalidInputError, match="give --chamber"):
        fit_network_sigma(out)  # the preset's units are not that camera
    from thermocal.nn.infer import shipped_model_path

    with pytest.raises(InvalidInputError, match="leave --chamber out"):
        fit_network_sigma(shipped_model_path("kpn"), chamber=chamber)  # not its camera
    # the misfit is measured against the scene temperature the model was fitted to (the
    # blackbody's, its emissivity and reflected ambient taken in), set points increasing
    from thermocal.calibration.dataset import prepare_chamber
    from thermocal.evaluation.sigma_fit import model_misfit

    m = model_misfit(chamber)
    assert np.all(np.diff(m["setpoints_c"]) > 0) and len(m["setpoints_c"]) == len(points)
    scene = prepare_chamber(chamber).scene_c
    assert scene.min() - 1e-6 <= m["setpoints_c"][0] and m["setpoints_c"][-1] <= scene.max() + 1e-6


def test_estimate_registered_frames_with_uncovered_borders(tmp_path, flight, tiny_model, capsys):
    """Frames registered elsewhere hold 0 where they do not cover the pivot: not saturation."""
    from thermocal.registration.warp import warp_to_pivot

    warped, valid = warp_to_pivot(flight.frames, flight.homographies)
    assert (~valid).mean() > 0.05
    frames = np.where(valid, np.rint(warped), 0).astype(np.uint16)
    write_recording(tmp_path / "r.tiff", Recording(frames=frames, fpa_c=flight.fpa_c))
    out = tmp_path / "t.tiff"
    code, err = run(
        [
            "estimate",
            str(tmp_path / "r.tiff"),
            "--model",
            str(tiny_model),
            "--registered",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    assert np.all(np.isfinite(tifffile.imread(out)))


def test_training_stream_is_the_same_with_any_number_of_workers():
    """Workers take turns (batch start + w, start + w + W, …): the same batches in order."""
    import torch

    from thermocal.nn.data import ScenePool
    from thermocal.nn.train import BurstStream

    cfg = BurstConfig(n_frames=3, crop=16, units=(0,), sensor_size=(32, 24))
    stream = BurstStream(
        lambda: ScenePool.training(seed=1, n_procedural=2),
        cfg,
        Normalisation(),
        seed=5,
        batch=2,
        start_batch=3,
        cameras=None,
    )

    def first(workers: int, n: int = 4) -> list:
        loader = torch.utils.data.DataLoader(stream, batch_size=None, num_workers=workers)
        it = iter(loader)
        return [next(it)[0] for _ in range(n)]

    alone, shared = first(0), first(2)
    assert all(torch.equal(a, b) for a, b in zip(alone, shared, strict=True))
    assert not torch.equal(alone[0], alone[1])


def test_train_device_option(tmp_path, capsys):
    import torch

    from thermocal.nn.train import resolve_device

    assert resolve_device("cpu").type == "cpu"
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    if not torch.cuda.is_available():
        code, err = run(["train", "--out", str(tmp_path / "m.pt"), "--device", "cuda"], capsys)
        assert code == 2 and "no GPU" in err


def test_train_init_starts_from_a_weights_file(tmp_path, capsys):
    """--init: fine-tuning starts from the given weights and keeps their normalisation."""
    first = tmp_path / "a.pt"
    small = ["--frames", "3", "--mu", "4", "--levels", "1", "--kernel", "3", "--crop", "32",
             "--batch", "2", "--steps-per-epoch", "1", "--max-epochs", "1", "--val-bursts", "2",
             "--units", "0-1", "--workers", "0", "--threads", "1", "--scenes", "3"]
    code, err = run(["train", "--out", str(first), *small], capsys)
    assert code == 0, err
    second = tmp_path / "b.pt"
    code, err = run(["train", "--out", str(second), "--init", str(first),
                     "--temp-mean-range-c", "-35:60", "--lr", "1e-12", *small], capsys)
    assert code == 0, err
    a, norm_a, _ = load_model(first)
    b, norm_b, info = load_model(second)
    assert norm_a == norm_b
    assert info["data"]["temp_mean_range_c"] == [-35.0, 60.0]
    # a learning rate of 1e-12: the weights are (almost) those it started from
    wa, wb = a.state_dict(), b.state_dict()
    assert all(np.allclose(wa[k].numpy(), wb[k].numpy(), atol=1e-6) for k in wa
               if wa[k].dtype.is_floating_point and "running" not in k)
    code, err = run(["train", "--out", str(tmp_path / "s.pt"), "--init", "shipped", "--steps",
                     "1", "--max-epochs", "1", "--val-bursts", "2", "--batch", "2", "--workers",
                     "0", "--threads", "1", "--scenes", "3", "--units", "0"], capsys)
    assert code == 0, err
    shipped = load_model(infer.shipped_model_path("kpn"))[0]
    assert load_model(tmp_path / "s.pt")[0].config == shipped.config
    code, err = run(["train", "--out", str(tmp_path / "c.pt"), "--init", str(first),
                     *[x if x != "4" else "8" for x in small]], capsys)
    assert code == 2 and "differs from the one to train in mu (4 there)" in err
    code, err = run(["train", "--out", str(second), "--init", str(first), "--resume"], capsys)
    assert code == 2 and "give one" in err
    code, err = run(["train", "--out", str(tmp_path / "d.pt"), "--temp-mean-range-c", "-80:60",
                     *small], capsys)
    assert code == 2 and "clip range" in err


def test_burst_module_and_mean_need_no_torch():
    """Eq. 9 (``--method mean``) and the burst checks run without importing torch."""
    import subprocess
    import sys

    code = (
        "import sys, numpy as np\n"
        "from thermocal.estimation.calibrated import naive_mean\n"
        "from thermocal.calibration.two_point import fit_two_point\n"
        "from thermocal.camera.presets import make_camera\n"
        "from thermocal.camera.model import render\n"
        "from thermocal.scenes.procedural import procedural_scene\n"
        "from thermocal.simulate.flight import simulate_flight\n"
        "cam = make_camera('tau2', unit=2, size=(64, 48))\n"
        "rng = np.random.default_rng(0)\n"
        "lo = render(cam, np.full(4, 10.0), 30.0, housing_c=28.5, rng=rng)\n"
        "hi = render(cam, np.full(4, 50.0), 30.0, housing_c=28.5, rng=rng)\n"
        "cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=30.0)\n"
        "fl = simulate_flight(procedural_scene((160, 200), rng=rng), cam, n_frames=3,\n"
        "                     motion='walk', fpa_c=30.0, seed=1)\n"
        "est = naive_mean(fl.frames, cal, homographies=fl.homographies)\n"
        "assert np.isfinite(est.temperature_c).all()\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_e2e_runs_in_tiles_of_its_training_crop(tmp_path):
    norm = Normalisation()
    torch.manual_seed(0)
    e2e = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, variant="e2e")).eval()
    kpn = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3)).eval()
    e2e_path = save_model(tmp_path / "e.pt", e2e, norm, BurstConfig(n_frames=3, crop=32))
    kpn_path = save_model(tmp_path / "k.pt", kpn, norm, BurstConfig(n_frames=3, crop=32))
    e2e_back, _, _ = load_model(e2e_path)
    kpn_back, _, _ = load_model(kpn_path)
    assert e2e_back.train_crop == kpn_back.train_crop == 32
    assert inference_tiling(e2e_back) == (32, 8)
    assert inference_tiling(kpn_back) == (512, 32)  # whole frames: the same error, faster
    assert inference_tiling(e2e) == (512, 32)  # no training crop known
    seen = []
    for m in (e2e_back, kpn_back):
        m.register_forward_pre_hook(lambda _m, args: seen.append(tuple(args[0].shape[-2:])))
    warped = np.random.default_rng(0).uniform(6000, 9000, (3, 48, 72)).astype(np.float32)
    valid = np.ones(warped.shape, dtype=bool)
    run_network(e2e_back, norm, warped, valid, 30.0)
    assert len(seen) > 1 and set(seen) == {(32, 32)}  # whole crops, also at the borders
    seen.clear()
    run_network(kpn_back, norm, warped, valid, 30.0)
    run_network(e2e_back, norm, warped, valid, 30.0, tile=512)
    assert seen == [(48, 72), (48, 72)]  # the KPN variants run whole frames
    # its σ is known not to carry over to scenes unlike its training ones: said where it is
    # used (a kpn's σ has no such caveat)
    import warnings

    from thermocal.calibration.base import ThermocalWarning
    from thermocal.nn.uncertainty import SigmaModel, sidecar_path

    for path in (e2e_path, kpn_path):
        sha = load_model(path)[2]["sha256"]
        SigmaModel(0.6, (0.0,) * 4, weights_sha256=sha).save(sidecar_path(path))
    with pytest.warns(ThermocalWarning, match="e2e: its σ is fitted on bursts of the scenes "
                      "it was trained on.*use kpn"):
        assert infer.NetworkEstimator.from_file("e2e", e2e_path).sigma_model is not None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        infer.NetworkEstimator.from_file("kpn", kpn_path)
        sidecar_path(e2e_path).unlink()  # no σ: nothing to warn of
        assert infer.NetworkEstimator.from_file("e2e", e2e_path).sigma_model is None


@pytest.mark.parametrize("variant", ["e2e", "kpn"])
def test_train_says_the_caveat_of_the_variant_its_sigma_was_fitted_for(tmp_path, capsys,
                                                                      monkeypatch, variant):
    """`thermocal train` names the caveat of the variant the σ was fitted on, the weights'
    own (a resumed run's is its checkpoint's, whatever --variant says)."""
    from thermocal.evaluation import sigma_fit
    from thermocal.nn.commands import _fit_sigma
    from thermocal.nn.uncertainty import SigmaModel

    fitted = SigmaModel(0.6, (0.0,) * 4, fitted_on={"variant": variant, "bursts": 3})
    monkeypatch.setattr(sigma_fit, "fit_network_sigma", lambda weights, chamber: fitted)
    _fit_sigma(tmp_path / "m.pt", chamber=None)
    err = capsys.readouterr().err
    assert "σ model (floor 0.60 °C" in err and (tmp_path / "m.sigma.json").is_file()
    assert ("warning: e2e: its σ is fitted on bursts of the scenes" in err) == (variant == "e2e")


def test_train_and_estimate_with_each_frames_sensor_position(tmp_path, capsys, flight):
    """--sensor-motion --radial-frames: trained, saved, and run by estimate_burst with each
    frame's R² found from the burst's homographies."""
    out = tmp_path / "rf.pt"
    small = ["--frames", "3", "--mu", "4", "--levels", "1", "--kernel", "3", "--crop", "32",
             "--batch", "2", "--steps-per-epoch", "2", "--max-epochs", "1", "--val-bursts", "2",
             "--units", "0-1", "--workers", "0", "--threads", "1", "--scenes", "3"]
    code, err = run(["train", "--out", str(out), *small, "--sensor-motion", "--radial-frames",
                     "--no-calibrated"], capsys)  # run_network by hand on raw counts below
    assert code == 0, err
    model, norm, info = load_model(out)
    assert model.config.radial_frames and info["data"]["sensor_motion"] is True
    with torch.no_grad():
        model.offset.delta_radial.normal_(0.0, 0.5)  # make the positions matter
    est = estimate_burst(flight.frames, 30.0, model=model, norm=norm,
                         homographies=flight.homographies, fill_defects=False)
    warped, valid = warp_to_pivot(flight.frames, flight.homographies)
    h, w = valid.shape[1:]
    r2f = frame_r2(sensor_r2((h, w)), flight.homographies, valid)
    by_hand = run_network(model, norm, warped, valid, 30.0, r2_frames=r2f)
    assert np.allclose(est.temperature_c, by_hand, atol=1e-3)
    pivot_only = run_network(model, norm, warped, valid, 30.0,
                             r2_frames=np.repeat(sensor_r2((h, w))[None], 3, 0))
    assert np.abs(pivot_only - by_hand).max() > 1e-3  # the walk's frames saw it elsewhere
    with pytest.raises(InvalidInputError, match="each frame's sensor position"):
        run_network(model, norm, warped, valid, 30.0)
    # another pivot: the frames, masks and positions all go into the model's order
    hs0 = np.linalg.inv(flight.homographies[0]) @ flight.homographies
    est0 = estimate_burst(flight.frames, 30.0, model=model, norm=norm, pivot=0,
                          homographies=hs0, fill_defects=False)
    w0, v0 = warp_to_pivot(flight.frames, hs0)
    order = [1, 0, 2]  # the pivot into the middle
    r0 = frame_r2(sensor_r2((h, w)), hs0, v0)
    hand0 = run_network(model, norm, w0[order], v0[order], 30.0, r2_frames=r0[order])
    assert np.allclose(est0.temperature_c, hand0, atol=1e-3)
    assert not np.allclose(est0.temperature_c,
                           run_network(model, norm, w0[order], v0[order], 30.0, r2_frames=r0),
                           atol=1e-2)
    with pytest.raises(InvalidInputError, match="not --registered"):
        estimate_burst(warped, 30.0, model=model, norm=norm, registered=True)
    plain = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, radial=1)).eval()
    with pytest.raises(InvalidInputError, match="without radial_frames"):
        run_network(plain, norm, warped, valid, 30.0, r2_frames=r2f)
    code, err = run(["train", "--out", str(tmp_path / "x.pt"), *small, "--radial", "0",
                     "--radial-frames"], capsys)
    assert code == 2 and "radial" in err and "Traceback" not in err


def test_calibrated_bursts_recover_the_scene_through_their_own_units_model():
    """Physics: a unit that *is* the nominal model (one training unit, its column FPN kept)
    gives calibrated frames equal to the scene up to noise; the untrained calibrated KPN is
    eq. 9 through that model."""
    from dataclasses import replace

    from thermocal.nn.data import UnitCache, make_burst
    from thermocal.nn.train import batch_tensors

    cfg = BurstConfig(n_frames=3, crop=32, units=(5,), sensor_size=(64, 48), calibrated=True,
                      redraw_column_fpn=False)
    units = UnitCache(cfg.preset, cfg.sensor_size)
    b = make_burst(ScenePool.training(seed=1, n_procedural=2), cfg,
                   rng=np.random.default_rng(3), units=units)
    assert b.frames_c is not None and b.frames_c.shape == b.frames.shape
    ok = ~units.get(5).crop(0, 0, 48, 64).defects.any()  # no stuck pixel in this small unit
    pivot = b.frames_c[1]  # the pivot's own frame: no warping
    err = np.abs(pivot - b.truth_c)
    assert np.median(err) < 0.1, np.median(err)  # temporal noise σ² = 5 counts² only
    assert ok or np.percentile(err, 99) < 2.0
    norm = Normalisation()
    mc = ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, radiance=True, calibrated=True)
    model = KPN(mc, temp_range_c=(norm.temp_min_c, norm.temp_max_c)).eval()
    frames, fpa, valid, truth, mask, _ = batch_tensors([b], norm, band_m=mc.band_m)
    assert torch.allclose(frames[0], torch.from_numpy(
        np.where(b.valid, norm.radiance(b.frames_c, mc.band_m), 0.0).astype(np.float32)))
    with torch.no_grad():
        model.head.net[-1].weight.zero_()  # kernels: exactly the initial 1/N centre taps
        out = norm.temp_inverse(model(frames, fpa, valid)[0, 0].numpy())
        eq9 = norm.temp_inverse(model.to_temperature(frames[0].mean(0)).numpy())
    m = b.valid.all(axis=0)  # (the registration error blurs edges: compared with eq. 9)
    assert m.sum() > 100 and np.abs(out - eq9)[m].max() < 1e-3
    # the same burst uncalibrated: another input, not the scene
    raw = batch_tensors([replace(b, frames_c=None)], norm)[0]
    assert not torch.allclose(raw, frames)


def test_train_and_estimate_a_calibrated_model(tmp_path, capsys, flight, camera):
    """--calibrated: trained, saved (the preset's nominal camera remade at load), run by
    estimate_burst on the frames calibrated before warping; registered bursts are refused."""
    from thermocal.nn.data import UnitCache
    from thermocal.nn.inputs import calibrate_frames

    out = tmp_path / "cal.pt"
    small = ["--frames", "3", "--mu", "4", "--levels", "1", "--kernel", "3", "--crop", "32",
             "--batch", "2", "--steps-per-epoch", "2", "--max-epochs", "1", "--val-bursts", "2",
             "--units", "0-1", "--workers", "0", "--threads", "1", "--scenes", "3", "--radiance"]
    code, err = run(["train", "--out", str(out), *small], capsys)  # --calibrated: the default
    assert code == 0, err
    model, norm, info = load_model(out)
    assert model.config.calibrated and info["data"]["calibrated"] is True
    want = UnitCache("tau2", (336, 256)).nominal((0, 1))
    assert np.array_equal(model.nominal.offset, want.offset)
    assert np.array_equal(model.nominal.gain, want.gain)
    # the flight's frames are 64x48: a nominal camera of the flight's size
    small_model = KPN(model.config, init=False, temp_range_c=(norm.temp_min_c, norm.temp_max_c))
    small_model.load_state_dict(model.state_dict())
    small_model.nominal = UnitCache("tau2", (64, 48)).nominal((0, 1))
    small_model.eval()
    est = estimate_burst(flight.frames, 30.0, model=small_model, norm=norm,
                         homographies=flight.homographies, fill_defects=False)
    temps = calibrate_frames(small_model.nominal, flight.frames, 30.0)
    warped_c, valid = warp_to_pivot(temps, flight.homographies)
    by_hand = run_network(small_model, norm, warped_c, valid, 30.0)
    assert np.allclose(est.temperature_c, by_hand, atol=1e-3)
    raw_warped, _ = warp_to_pivot(flight.frames, flight.homographies)
    assert not np.allclose(run_network(small_model, norm, raw_warped, valid, 30.0), by_hand,
                           atol=1.0)  # counts are not what it takes
    with pytest.raises(InvalidInputError, match="not --registered"):
        estimate_burst(raw_warped, 30.0, model=small_model, norm=norm, registered=True)
    # the preset's nominal camera is made again for the 64x48 frames
    est_big = estimate_burst(flight.frames, 30.0, model=model, norm=norm,
                             homographies=flight.homographies, fill_defects=False)
    assert np.allclose(est_big.temperature_c, est.temperature_c, atol=1e-3)


def test_a_calibrated_chamber_model_keeps_its_camera(tmp_path):
    """A nominal camera that no preset remakes (a chamber fit) is stored in the weights file."""
    from dataclasses import replace

    cam = make_camera("tau2", unit=3, size=(48, 32))
    fitted = replace(cam, info={"fitted_from": "chamber"})
    from thermocal.nn.inputs import nominal_camera

    nominal = nominal_camera([fitted])
    assert nominal.info["preset"] is None
    model = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, calibrated=True))
    model.nominal = nominal
    path = tmp_path / "c.pt"
    save_model(path, model, Normalisation(),
               BurstConfig(n_frames=3, crop=16, units=(0,), sensor_size=(48, 32),
                           calibrated=True))
    loaded, norm, _ = load_model(path)
    for k in ("gain", "offset", "housing", "transient"):
        assert np.array_equal(getattr(loaded.nominal, k), getattr(cam, k)), k
    assert loaded.nominal.t_ref_c == cam.t_ref_c and not loaded.nominal.defects.any()
    rng = np.random.default_rng(0)
    still = np.eye(3)[None].repeat(3, 0)
    frames = rng.integers(7000, 9000, (3, 32, 48)).astype(np.uint16)
    est = estimate_burst(frames, 30.0, model=loaded, norm=norm, homographies=still,
                         fill_defects=False)
    assert est.temperature_c.shape == (32, 48)
    with pytest.raises(ThermocalError, match="48x32"):  # its own size only
        estimate_burst(frames[:, :24, :32], 30.0, model=loaded, norm=norm, homographies=still,
                       fill_defects=False)


def test_train_refuses_a_calibrated_network_on_raw_bursts(tmp_path):
    from thermocal.nn.train import train

    with pytest.raises(InvalidInputError, match="calibrated"):
        train(tmp_path / "m.pt", ModelConfig(n_frames=3, mu=4, levels=1, kernel=3,
                                             calibrated=True),
              BurstConfig(n_frames=3, crop=16, units=(0,), sensor_size=(32, 24)),
              TrainConfig(max_steps=1), val_units=(1,))


def test_calibrated_bursts_are_what_inference_gives_the_network():
    """make_burst's calibrated frames = inference's (stuck pixels filled, then the nominal
    camera of the training units where each frame lies, then warped), also for bursts of other
    units (validation) whose nominal camera stays the training units'."""
    from thermocal.burst import fill_stuck_pixels
    from thermocal.nn.data import UnitCache, make_burst
    from thermocal.nn.inputs import preset_nominal

    cfg = BurstConfig(n_frames=3, crop=48, units=(50,), nominal_units=(0, 1),
                      sensor_size=(48, 48), calibrated=True)
    b = make_burst(ScenePool.training(seed=2, n_procedural=2), cfg,
                   rng=np.random.default_rng(4), units=UnitCache(cfg.preset, cfg.sensor_size))
    model = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, calibrated=True))
    model.nominal = preset_nominal("tau2", (48, 48), (0, 1))
    filled, _ = fill_stuck_pixels(b.raw, b.homographies)
    want = infer.calibrated_warp(model, filled, b.homographies, b.fpa_c)
    assert np.allclose(np.where(b.valid, b.frames_c, 0), np.where(b.valid, want, 0), atol=1e-4)
    own = preset_nominal("tau2", (48, 48), (50,))  # not the unit's own model
    assert not np.allclose(own.offset, model.nominal.offset)


def test_nominal_camera_fills_pixels_without_gain():
    """A chamber fit zeroes its dead pixels' gain: the nominal camera still inverts there."""
    from dataclasses import replace

    from thermocal.nn.inputs import calibrate_frames, nominal_camera

    cam = make_camera("tau2", unit=3, size=(32, 24))
    gain = cam.gain.copy()
    gain[:, 5, 7] = 0.0
    gain[:, 0, 0] = 0.0
    nominal = nominal_camera([replace(cam, gain=gain, info={})])
    assert np.all(nominal.gain[0] > 0) and cam.gain[0, 5, 7] > 0
    assert np.isclose(nominal.gain[0, 5, 7], np.median(cam.gain[0, 4:7, 6:9]), rtol=0.05)
    frames = render(cam, np.full((1, 24, 32), 20.0), 30.0, housing_c=28.5,
                    rng=np.random.default_rng(0))
    t = calibrate_frames(nominal, frames, 30.0)
    # finite and of the scene's order where the fit had no gain (its neighbours' FPN, not the
    # pixel's: a dead pixel's output is replaced at inference anyway), exact elsewhere
    assert np.all(np.isfinite(t)) and abs(float(t[0, 5, 7]) - 20.0) < 10.0
    assert abs(float(np.median(t)) - 20.0) < 0.1
