"""Robustness of the NUC methods (issue 18, item 5): no method diverges on short walks or long
UAV passes, torres-kalman's filter stays well-posed, and ``thermocal nuc`` writes counts (not
°C) and refuses saturated and dead frames."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from scipy.ndimage import binary_dilation

from thermocal.camera.presets import make_camera
from thermocal.cli import main
from thermocal.errors import InvalidInputError
from thermocal.io.recording import Recording, write_recording
from thermocal.metrics import roughness
from thermocal.nuc import NUC_METHODS, TorresKalman, correct_nonuniformity
from thermocal.nuc._common import GAIN_RANGE, write_counts_tiff
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

SIZE = (96, 72)
#: (motion, frames, unit, seed): the audit's 40-frame walks and 300-frame UAV passes
CASES = [("walk", 40, 0, 0), ("walk", 40, 3, 1), ("walk", 40, 5, 2),
         ("uav", 300, 0, 0), ("uav", 300, 3, 1), ("uav", 300, 5, 2)]


@pytest.fixture(scope="module")
def flights():
    out = []
    for motion, n, unit, seed in CASES:
        cam = make_camera("tau2", unit=unit, size=SIZE)
        scene = procedural_scene((384, 384), rng=np.random.default_rng(seed), kind="mixed")
        fl = simulate_flight(scene, cam, n_frames=n, motion=motion, seed=seed)
        out.append((f"{motion} of {n} frames, unit {unit}, seed {seed}", fl, cam.defects))
    return out


#: Methods that run a network per frame or burst (no state to diverge, seconds per frame).
PER_BURST_NETWORKS = ("he2018", "deepir")


def _correct(method, fl):
    opts = {"homographies": fl.homographies} if method in ("hardie2000", "zuo2011") else {}
    if method == "deepir":  # a per-burst optimisation: a short one
        opts = {"iterations": 60}
    return correct_nonuniformity(fl.frames, method=method, **opts)


def _rough(frames, defects):
    """Mean roughness of frames with the camera's dead and hot pixels set to each frame's median:
    the fixed-pattern noise a NUC removes, not the stuck pixels (filled elsewhere)."""
    f = np.array(frames, dtype=np.float32)
    f[:, defects] = np.median(f, axis=(1, 2))[:, None]
    return float(np.mean(roughness(f)))


@pytest.mark.parametrize("method", sorted(NUC_METHODS))
def test_no_method_diverges_on_walks_and_uav_passes(flights, method):
    for name, fl, defects in flights:
        if method in PER_BURST_NETWORKS and "uav" in name:
            continue  # a network per frame or burst, 100× slower: the walks show it
        raw = fl.frames.astype(np.float32)
        out = _correct(method, fl)
        assert out.shape == raw.shape and np.all(np.isfinite(out)), name
        # within the input's count range ± half of it (torres-kalman went 1.4…5 ranges out)
        lo, hi = float(raw.min()), float(raw.max())
        margin = 0.5 * (hi - lo)
        assert lo - margin <= out.min() and out.max() <= hi + margin, (name, out.min(), out.max())
        # no pixel away from the stuck ones leaves the good pixels' range by more than 1.5 of
        # it (a gain within GAIN_RANGE multiplies a scene change by 1.5 at most)
        far = ~binary_dilation(defects, iterations=4)
        glo, ghi = float(raw[:, ~defects].min()), float(raw[:, ~defects].max())
        o = out[:, far]
        worst = max(glo - float(o.min()), float(o.max()) - ghi) / (ghi - glo)
        assert worst < 1.5, (name, worst)
        # and the fixed-pattern noise goes down (last 10 frames)
        assert _rough(out[-10:], defects) < _rough(raw[-10:], defects), name


def test_torres_kalman_state_stays_physical_and_well_posed(flights):
    for name, fl, _ in flights:
        tk = TorresKalman()
        for frame in fl.frames:
            tk.update(frame)
            if tk.n_blocks:
                lo, hi = GAIN_RANGE[0] * (1 - 1e-5), GAIN_RANGE[1] * (1 + 1e-5)  # float32
                assert lo <= tk.gain.min() and tk.gain.max() <= hi, name
                for p in (tk.p_gain, tk.p_offset):
                    assert np.isfinite(p) and p > 0, name
        assert tk.n_blocks == len(fl.frames) // tk.block


def test_torres_kalman_does_not_amplify_a_pixel_that_saw_a_static_scene():
    """The audit's failure, made on purpose: a patch of the scene stays still during the first
    block (its spread is the noise only), then the scene changes there. A gain measured from that
    spread (the old 5 % floor: 20x) made the output there diverge; bounded, the change grows by
    1/GAIN_RANGE[0] = 1.5 at most."""
    rng = np.random.default_rng(0)
    n, h, w = 60, 32, 32
    frames = 8000.0 + rng.normal(0.0, 300.0, (n, h, w))  # a busy scene: constant statistics
    frames[:10, :8, :8] = 8000.0 + rng.normal(0.0, 2.0, (10, 8, 8))  # still for block 1
    frames[10:, :8, :8] += 1500.0  # then a hot object sits there
    out = TorresKalman().correct(frames)
    assert np.all(np.isfinite(out))
    change = float(np.abs(frames[10:, :8, :8] - 8000.0).max())
    assert float(np.abs(out[10:, :8, :8] - np.median(out[10:])).max()) < 2.0 * change


def test_torres_kalman_survives_a_block_of_identical_frames():
    rng = np.random.default_rng(1)
    frames = 8000.0 + rng.normal(0.0, 300.0, (40, 16, 16))
    frames[10:20] = frames[10]  # the camera froze for a block: no spread anywhere
    out = TorresKalman().correct(frames)
    assert np.all(np.isfinite(out)) and abs(float(out.mean()) - 8000.0) < 500.0


# --------------------------------------------------------------------------------------------
# thermocal nuc: counts out, bad frames refused
# --------------------------------------------------------------------------------------------


def _run(args, capsys):
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr()


def test_write_counts_tiff_writes_any_finite_counts_with_their_units(tmp_path):
    frames = np.array([[[-12706.0, 49878.0], [0.5, 1.0]]], np.float32)
    out = write_counts_tiff(tmp_path / "c.tiff", frames, extra={"method": "x"})
    np.testing.assert_array_equal(tifffile.imread(out), frames)
    with tifffile.TiffFile(out) as tif:
        meta = tif.shaped_metadata[0]
    assert meta["units"] == "counts" and meta["radiometric"] is False and meta["method"] == "x"
    bad = frames.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        write_counts_tiff(tmp_path / "bad.tiff", bad)
    with pytest.raises(InvalidInputError, match="tif"):
        write_counts_tiff(tmp_path / "c.png", frames)
    assert not (tmp_path / "bad.tiff").exists() and not (tmp_path / "c.png").exists()


def test_cli_nuc_torres_kalman_on_a_walk_writes_counts(flights, tmp_path, capsys):
    _, fl, _ = flights[0]
    src = tmp_path / "frames.tiff"
    write_recording(src, Recording(frames=fl.frames))
    out = tmp_path / "o.tiff"
    code, io = _run(["nuc", str(src), "--method", "torres-kalman", "--out", str(out)], capsys)
    assert code == 0, io.err
    data = tifffile.imread(out)
    assert data.dtype == np.float32 and data.shape == fl.frames.shape
    with tifffile.TiffFile(out) as tif:
        meta = tif.shaped_metadata[0]
    assert meta["units"] == "counts" and meta["method"] == "torres-kalman"


@pytest.mark.parametrize("defect", ["saturated", "dead"])
def test_cli_nuc_refuses_saturated_and_dead_frames(flights, tmp_path, capsys, defect):
    _, fl, _ = flights[0]
    frames = fl.frames[:12].copy()
    if defect == "saturated":
        frames[5, :20] = 2**14 - 1  # 20 of 72 rows clipped at the top count
    else:
        frames[5] = frames[5, 0, 0]  # one value: a dead (constant) frame
    src = tmp_path / "frames.tiff"
    write_recording(src, Recording(frames=frames))
    out = tmp_path / "o.tiff"
    code, io = _run(["nuc", str(src), "--method", "ecr", "--out", str(out)], capsys)
    assert code == 2 and len(io.err.strip().splitlines()) == 1, io.err
    assert "frame 5" in io.err and ("saturated" if defect == "saturated" else "constant") in io.err
    assert not out.exists()


def test_methods_that_need_more_frames_than_given_say_so():
    """torres-kalman has no estimate before its first block ends: a shorter stack is refused
    (it came back raw, 'corrected'); the constant-statistics methods on fewer frames than
    their window warn that their first frames may be worse than raw (a helper's audit); a
    single frame is told of the single-frame methods."""
    import warnings

    from thermocal.calibration.base import ThermocalWarning

    rng = np.random.default_rng(0)
    frames = rng.normal(8000, 50, size=(7, 16, 16))
    with pytest.raises(InvalidInputError, match="needs at least 10 frames, got 7$"):
        correct_nonuniformity(frames, method="torres-kalman")
    with pytest.warns(ThermocalWarning, match="its first 4 of 7 frames pass through "
                                              "uncorrected"):
        got = correct_nonuniformity(frames, method="torres-kalman", block=5)
    np.testing.assert_array_equal(got[:4], frames[:4].astype(np.float32))  # as it says
    with warnings.catch_warnings():  # a tenth of the stack or less: not worth a warning
        warnings.simplefilter("error")
        correct_nonuniformity(rng.normal(8000, 50, size=(40, 16, 16)), method="torres-kalman",
                              block=5)
    for method in ("harris1999", "ecr"):
        with pytest.warns(ThermocalWarning, match="7 frames, fewer than the 200-frame window"):
            correct_nonuniformity(frames, method=method)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            correct_nonuniformity(frames, method=method, window=5)
    with pytest.raises(InvalidInputError, match=r"got 1; use a single-frame method \(admire or "
                                                r"he2018\)"):
        correct_nonuniformity(frames[:1], method="harris1999")
