"""The shipped KPN weights: they load, and beat the calibration-free baselines on a held-out
camera unit and a held-out real scene (a small seeded burst)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from thermocal.calibration.two_point import fit_two_point  # noqa: E402
from thermocal.camera.model import render  # noqa: E402
from thermocal.camera.presets import make_camera  # noqa: E402
from thermocal.nn.data import EVAL_UNITS, TRAIN_UNITS, coverage_mask  # noqa: E402
from thermocal.nn.infer import SHIPPED_MODELS, estimate_burst, shipped_model_path  # noqa: E402
from thermocal.nn.store import load_model  # noqa: E402
from thermocal.scenes.builtin import load_builtin_scene  # noqa: E402
from thermocal.scenes.trajectory import perturb_homographies  # noqa: E402
from thermocal.simulate.flight import simulate_flight  # noqa: E402

UNIT = 101  # held out: never a training or validation unit
FPA_C = 40.0
NOMINAL_FPA_C = 30.0


@pytest.fixture(scope="module")
def shipped():
    from importlib.resources import files

    if not (files("thermocal.nn") / "weights" / SHIPPED_MODELS["kpn"]).is_file():
        pytest.fail("the shipped KPN weights are missing from thermocal/nn/weights")
    return load_model(shipped_model_path("kpn"))


@pytest.fixture(scope="module")
def burst():
    # a whole (small) sensor, not a crop: the network may use where on the sensor a pixel lies
    cam = make_camera("tau2", unit=UNIT, size=(128, 96))
    scene = load_builtin_scene("aerial")  # held out: never trained on
    fl = simulate_flight(scene, cam, n_frames=7, motion="walk", fpa_c=FPA_C, seed=0)
    hs = perturb_homographies(fl.homographies, rng=np.random.default_rng(0),
                              frame_size=(128, 96), pivot=fl.pivot)
    from thermocal.registration.warp import warp_to_pivot

    _, valid = warp_to_pivot(fl.frames, hs)
    return fl, hs, coverage_mask(valid)


def _mae_and_bias_free(est, truth, mask):
    err = (est - truth)[mask]
    return float(np.abs(err).mean()), float(np.abs(err - err.mean()).mean())


def test_shipped_weights_load(shipped):
    model, norm, info = shipped
    assert model.config.n_frames == 7 and model.config.variant == "kpn"
    assert not model.training
    assert set(info["data"]["units"]) <= set(TRAIN_UNITS)
    assert UNIT in EVAL_UNITS and UNIT not in info["data"]["units"]
    assert norm.counts_max > norm.counts_min and norm.temp_max_c > norm.temp_min_c


def test_shipped_kpn_beats_calibration_free_baselines(shipped, burst):
    model, norm, _ = shipped
    fl, hs, mask = burst
    truth = fl.truth_c[fl.pivot]
    est = estimate_burst(fl.frames, fl.fpa_c, model=model, norm=norm, homographies=hs)
    kpn_mae, kpn_rel = _mae_and_bias_free(est.temperature_c, truth, mask)

    # baseline: a two-point calibration of another unit at the nominal FPA temperature
    other = make_camera("tau2", unit=7, size=(128, 96))
    rng = np.random.default_rng(1)
    lo = render(other, np.full(8, 10.0), NOMINAL_FPA_C, housing_c=NOMINAL_FPA_C - 1.5, rng=rng)
    hi = render(other, np.full(8, 50.0), NOMINAL_FPA_C, housing_c=NOMINAL_FPA_C - 1.5, rng=rng)
    cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=NOMINAL_FPA_C)
    tp = cal.apply(fl.frames[fl.pivot : fl.pivot + 1])[0]
    tp_mae, tp_rel = _mae_and_bias_free(tp, truth, mask)

    assert np.all(np.isfinite(est.temperature_c))
    assert kpn_mae < tp_mae, (kpn_mae, tp_mae)
    assert kpn_rel < tp_rel, (kpn_rel, tp_rel)


def test_shipped_kpn_leaves_no_trail_of_stuck_pixels(shipped):
    """Four hot pixels on the sensor: unless they are replaced before registration, each leaves
    a trail along the motion in the network's output."""
    from dataclasses import replace

    cam = make_camera("tau2", unit=UNIT, size=(128, 96))
    defects = np.zeros(cam.shape, bool)
    defects[[20, 30, 60, 75], [30, 90, 50, 100]] = True
    cam = replace(cam, defects=defects, defect_counts=np.where(defects, 16383, 0).astype(np.uint16))
    fl = simulate_flight(load_builtin_scene("aerial"), cam, n_frames=7, motion="walk",
                         fpa_c=FPA_C, seed=0)
    model, norm, _ = shipped
    truth = fl.truth_c[fl.pivot]
    trail = np.zeros(cam.shape, bool)  # 5×5 around where each frame's defects fall on the pivot
    rows, cols = np.nonzero(defects)
    for h in fl.homographies:
        p = h @ np.stack([cols, rows, np.ones_like(rows)]).astype(float)
        for x, y in np.rint(p[:2] / p[2]).T.astype(int):
            trail[max(y - 2, 0) : y + 3, max(x - 2, 0) : x + 3] = True
    err = {}
    for fill in (False, True):
        est = estimate_burst(fl.frames, fl.fpa_c, model=model, norm=norm,
                             homographies=fl.homographies, fill_defects=fill)
        e = np.abs(est.temperature_c - truth)
        err[fill] = (float(e[trail].mean()), float(e[~trail].mean()))
    assert err[True][0] < 0.5 * err[False][0], err  # the trails are gone ...
    assert err[True][0] < 2 * err[True][1], err  # ... down to the error elsewhere



def test_shipped_network_keeps_its_camera_model_when_the_preset_changes(burst, monkeypatch):
    """The weights hold the network's nominal camera (and the preset parameters to make it
    again at another size): a changed preset coefficient changes nothing it outputs."""
    from dataclasses import replace

    from thermocal.camera import presets
    from thermocal.nn import inputs

    fl, hs, _ = burst
    big = simulate_flight(load_builtin_scene("aerial"), make_camera("tau2", unit=UNIT),
                          n_frames=7, motion="walk", fpa_c=FPA_C, seed=0)
    before = [estimate_burst(f.frames, f.fpa_c, model=m, norm=n, homographies=f.homographies)
              .temperature_c for f in (fl, big) for m, n, _ in [load_model(
                  shipped_model_path("kpn"))]]
    changed = replace(presets.PRESETS["tau2"], gain=90.0, offset_radial=-300.0)
    monkeypatch.setitem(presets.PRESETS, "tau2", changed)
    inputs.preset_nominal.cache_clear()
    model, norm, _ = load_model(shipped_model_path("kpn"))
    after = [estimate_burst(f.frames, f.fpa_c, model=model, norm=norm,
                            homographies=f.homographies).temperature_c for f in (fl, big)]
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1])
    # the nominal camera the version-1 file format made from the preset does change
    remade = inputs.preset_nominal("tau2", (336, 256), tuple(range(24)))
    assert not np.allclose(remade.gain, model.nominal.gain)
    inputs.preset_nominal.cache_clear()


def test_damaged_camera_model_in_weights_is_refused(tmp_path):
    from thermocal.errors import FileFormatError

    payload = torch.load(shipped_model_path("kpn"), map_location="cpu", weights_only=True)
    payload["nominal"]["gain"][0, 10, 10] *= 1.01
    torch.save(payload, tmp_path / "bad.pt")
    with pytest.raises(FileFormatError, match="checksum"):
        load_model(tmp_path / "bad.pt")


def test_version_1_weights_upgrade_to_the_same_network(tmp_path):
    from thermocal.nn.store import VERSION, upgrade

    payload = torch.load(shipped_model_path("kpn"), map_location="cpu", weights_only=True)
    del payload["nominal"], payload["sha256"]
    payload["version"] = 1
    torch.save(payload, tmp_path / "v1.pt")
    upgrade(tmp_path / "v1.pt", tmp_path / "v3.pt")
    shipped = torch.load(shipped_model_path("kpn"), map_location="cpu", weights_only=True)
    again = torch.load(tmp_path / "v3.pt", map_location="cpu", weights_only=True)
    assert again["version"] == VERSION
    assert again["nominal"]["sha256"] == shipped["nominal"]["sha256"]
    assert again["sha256"] == shipped["sha256"]  # the same file as the shipped one


@pytest.mark.parametrize("damage", ["no checksum", "no camera", "units", "preset parameters"])
def test_weights_without_a_whole_camera_model_are_refused(tmp_path, damage):
    """A version-2 file must carry its camera model, its checksum, and what the checksum covers
    (where the model came from, used to make it again at another size)."""
    from thermocal.errors import FileFormatError
    from thermocal.nn.store import weights_digest

    payload = torch.load(shipped_model_path("kpn"), map_location="cpu", weights_only=True)
    if damage == "no checksum":
        del payload["nominal"]["sha256"]
    elif damage == "no camera":
        del payload["nominal"]
    elif damage == "units":
        payload["nominal"]["units"] = payload["nominal"]["units"][:-1]
    else:
        payload["nominal"]["preset_parameters"]["gain"] = 90.0
    torch.save(payload, tmp_path / "bad.pt")
    with pytest.raises(FileFormatError, match="damaged weights file"):  # the file's checksum
        load_model(tmp_path / "bad.pt")
    payload["sha256"] = weights_digest(payload)  # made whole: the camera model's checks tell
    torch.save(payload, tmp_path / "bad.pt")
    with pytest.raises(FileFormatError, match="damaged weights file.*camera"):
        load_model(tmp_path / "bad.pt")
