"""Synthetic bursts for the KPN (numpy only): physics, determinism, held-out sets."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from thermocal.camera.model import invert
from thermocal.camera.presets import make_camera
from thermocal.errors import InvalidInputError
from thermocal.nn.data import (
    EVAL_SCENES,
    EVAL_UNITS,
    TRAIN_EXCLUDED_SCENES,
    TRAIN_UNITS,
    VAL_UNITS,
    BurstConfig,
    ScenePool,
    UnitCache,
    coverage_mask,
    draw_pixel_fpn,
    make_burst,
    make_bursts,
    redraw_column_fpn,
    redraw_pixel_fpn,
    window_offsets,
)
from thermocal.nn.inputs import Normalisation, sensor_r2
from thermocal.scenes.procedural import procedural_scene


@pytest.fixture(scope="module")
def pool():
    rng = np.random.default_rng(3)
    maps = [procedural_scene((160, 160), rng=rng, kind=k) for k in ("farmland", "urban")]
    return ScenePool(maps, ["a", "b"])


@pytest.fixture(scope="module")
def cfg():
    return BurstConfig(n_frames=5, crop=32, units=(0, 1))


def test_torch_not_imported_by_data_or_commands():
    import thermocal.nn.commands  # noqa: F401
    import thermocal.nn.data  # noqa: F401

    if "torch" in sys.modules:  # another test may have imported it: check in a fresh process
        import subprocess

        code = ("import sys, thermocal, thermocal.cli, thermocal.nn.data, thermocal.nn.commands; "
                "assert 'torch' not in sys.modules and 'kornia' not in sys.modules")
        subprocess.run([sys.executable, "-c", code], check=True)


def test_burst_shapes_and_masks(pool, cfg):
    b = make_burst(pool, cfg, rng=np.random.default_rng(0))
    assert b.frames.shape == b.valid.shape == b.raw.shape == (5, 32, 32)
    assert b.truth_c.shape == (32, 32)
    assert b.frames.dtype == np.float32 and b.raw.dtype == np.uint16
    assert b.valid[2].all()  # the pivot sees itself
    assert np.all(b.frames[~b.valid] == 0)
    assert np.allclose(b.homographies[2], np.eye(3))
    # 60-80 % overlap: every frame sees much, but not all, of the pivot
    frac = b.valid.reshape(5, -1).mean(axis=1)
    assert np.all(frac[[0, 1, 3, 4]] > 0.4) and np.any(frac < 0.95)
    m = coverage_mask(b.valid)
    assert m.shape == (32, 32) and m.mean() > 0.5
    assert b.unit in (0, 1)


def test_burst_is_deterministic(pool, cfg):
    a = make_bursts(pool, cfg, seed=42, start=3, count=2)
    b = make_bursts(pool, cfg, seed=42, start=3, count=2)
    c = make_bursts(pool, cfg, seed=42, start=4, count=1)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.raw, y.raw) and np.array_equal(x.truth_c, y.truth_c)
    assert np.array_equal(a[1].raw, c[0].raw)  # burst i depends on (seed, i) only
    assert not np.array_equal(a[0].raw, a[1].raw)


def test_pivot_frame_is_the_camera_model_of_the_truth(pool, cfg):
    """The pivot's raw counts invert (oracle calibration) to the target temperature."""
    b = make_burst(pool, cfg, rng=np.random.default_rng(5), fpa_c=30.0)
    est = invert(b.camera, b.raw[2], 30.0, housing_c=30.0 - 1.5)[0]
    ok = ~b.camera.defects
    err = np.abs(est - b.truth_c)[ok]
    assert np.median(err) < 0.1  # only the temporal noise (NETD ≈ 50 mK) separates them


def test_column_fpn_is_redrawn(cfg):
    units = UnitCache("tau2", (336, 256))
    cam = units.get(0).crop(10, 20, 32, 32)
    new = redraw_column_fpn(cam, 20, np.random.default_rng(1))
    ratio = new.gain[0] / cam.gain[0]
    assert np.allclose(ratio, ratio[0:1, :])  # a factor per column (eq. 19)
    assert ratio.std() > 0.01
    assert 0.85 < ratio.min() and ratio.max() < 1.15
    assert np.array_equal(new.offset[1:], cam.offset[1:])


def test_fpn_drawn_on_a_chamber_model_keeps_its_mean_responsivity():
    """A smooth model fitted on a chamber file already holds the unit's mean column factor
    (≈ 0.955): the FPN drawn on it must not lower the responsivity again, and its pixel part
    has the spread measured on the chamber file."""
    from dataclasses import replace

    # stands in for a model fitted on a chamber file: no column FPN of its own in its info
    smooth = replace(UnitCache("tau2", (64, 48)).get(0), info={
        "pixel_fpn": {"offset_sigma_counts": 30.0, "gain_sigma": 0.015}})
    rng = np.random.default_rng(2)
    draws = [draw_pixel_fpn(redraw_column_fpn(smooth, 0, rng), rng) for _ in range(40)]
    ratio = np.mean([float((d.gain[0] / smooth.gain[0]).mean()) for d in draws])
    assert ratio == pytest.approx(1.0, abs=0.005)
    one = draw_pixel_fpn(smooth, rng)
    d_off = one.offset[0] - smooth.offset[0]
    assert np.std(d_off) == pytest.approx(30.0, rel=0.1)
    assert np.std(one.gain[0] / smooth.gain[0] - 1.0) == pytest.approx(0.015, rel=0.1)
    assert np.array_equal(one.offset[1:], smooth.offset[1:])
    unit = UnitCache("tau2", (64, 48)).get(0)
    assert draw_pixel_fpn(unit, rng) is unit  # a preset unit has FPN of its own


def test_pixel_fpn_of_a_preset_unit_is_redrawn():
    """The unit's own pixel patterns are replaced by a new draw of the preset's spreads; the rest
    of the camera (radial maps, column FPN, tempcos) stays."""
    full = UnitCache("tau2", (64, 48)).get(3)
    cam = full.crop(8, 16, 32, 40)
    new = redraw_pixel_fpn(cam, 8, 16, np.random.default_rng(4))
    old_off = full.info["pixel_offset"][8:40, 16:56]
    old_gain = full.info["pixel_gain"][8:40, 16:56]
    smooth_off = cam.offset[0] - old_off  # the unit without its pixel offset pattern
    new_off = new.offset[0] - smooth_off
    assert np.std(new_off) == pytest.approx(30.0, rel=0.1)
    assert abs(np.corrcoef(new_off.ravel(), old_off.ravel())[0, 1]) < 0.1
    new_gain = new.gain[0] / (cam.gain[0] / old_gain)
    assert np.std(new_gain - 1.0) == pytest.approx(0.015, rel=0.1)
    assert np.allclose(new.gain[1] / new.gain[0], cam.gain[1] / cam.gain[0], rtol=1e-5)
    assert np.array_equal(new.offset[1:], cam.offset[1:])
    chamber_like = replace(cam, info={})
    assert redraw_pixel_fpn(chamber_like, 8, 16, np.random.default_rng(4)) is chamber_like


def test_redrawn_pixel_fpn_is_an_option_of_the_stream(pool):
    cfg = BurstConfig(n_frames=3, crop=32, units=(3,))
    same = [make_burst(pool, cfg, rng=np.random.default_rng(9)) for _ in range(2)]
    assert np.array_equal(same[0].frames, same[1].frames)  # off: the unit's own pattern
    redrawn = make_burst(pool, replace(cfg, redraw_pixel_fpn=True), rng=np.random.default_rng(9))
    assert not np.array_equal(redrawn.camera.offset[0], same[0].camera.offset[0])
    assert np.array_equal(redrawn.truth_c, same[0].truth_c)


def test_walk_frames_keep_the_middle_of_a_longer_walk(pool):
    cfg = BurstConfig(n_frames=3, crop=32, units=(0,), motions=("walk",))
    # as long as the burst: the very same burst as without the option
    a = make_burst(pool, cfg, rng=np.random.default_rng(4))
    b = make_burst(pool, replace(cfg, walk_frames=3), rng=np.random.default_rng(4))
    assert np.array_equal(a.frames, b.frames) and np.array_equal(a.homographies, b.homographies)

    def spread_px(walk_frames):  # mean largest shift of a view from the pivot
        bursts = [make_burst(pool, replace(cfg, walk_frames=walk_frames),
                             rng=np.random.default_rng(k)) for k in range(12)]
        return np.mean([np.abs(x.homographies[:, :2, 2]).max() for x in bursts])

    longer = make_burst(pool, replace(cfg, walk_frames=9), rng=np.random.default_rng(4))
    assert longer.frames.shape == a.frames.shape
    assert spread_px(9) < 0.6 * spread_px(None)  # 2 of 8 steps instead of 2 of 2
    with pytest.raises(InvalidInputError):
        replace(cfg, walk_frames=1)  # shorter than the burst
    with pytest.raises(InvalidInputError):
        replace(cfg, walk_frames=4)  # pivots would not line up


def test_held_out_sets_are_disjoint():
    assert not set(TRAIN_UNITS) & set(EVAL_UNITS)
    assert not set(TRAIN_UNITS) & set(VAL_UNITS)
    assert not set(VAL_UNITS) & set(EVAL_UNITS)
    assert set(EVAL_SCENES) <= TRAIN_EXCLUDED_SCENES
    assert "example_radiometric" in TRAIN_EXCLUDED_SCENES  # the aerial scene's copy


def test_training_pool_never_holds_evaluation_scenes(shared_data):
    pool = ScenePool.training(n_procedural=3, size=64)
    assert not set(pool.names) & TRAIN_EXCLUDED_SCENES
    assert any(not n.startswith("procedural") for n in pool.names)


def test_normalisation_round_trip():
    n = Normalisation()
    t = np.array([-40.0, 0.0, 100.0])
    assert np.allclose(n.temp(t), [0.0, 40 / 140, 1.0])
    assert np.allclose(n.temp_inverse(n.temp(t)), t)
    assert n.fpa(10.0) == 0.0 and n.fpa(50.0) == 1.0


def test_bad_config():
    with pytest.raises(InvalidInputError):
        BurstConfig(n_frames=0)
    with pytest.raises(InvalidInputError):
        BurstConfig(crop=8)
    with pytest.raises(InvalidInputError):
        BurstConfig(motions=("uav",))
    with pytest.raises(InvalidInputError):
        ScenePool([], [])


def test_burst_knows_where_its_pixels_lie_on_the_sensor(pool):
    from thermocal.camera.presets import radial_map

    full = radial_map((256, 336)) ** 2
    assert np.array_equal(sensor_r2((256, 336), 10, 20, (32, 48)), full[10:42, 20:68])
    with pytest.raises(InvalidInputError, match="leaves the sensor"):
        sensor_r2((256, 336), 230, 20, (32, 48))
    # on a 48 x 40 (W x H) sensor, find each burst's window from its camera's gain (the column
    # FPN is redrawn: a factor per column) and compare its R² with the window's
    cfg = BurstConfig(n_frames=3, crop=32, units=(0,), sensor_size=(48, 40))
    full = UnitCache("tau2", (48, 40)).get(0)
    for seed in range(3):
        b = make_burst(pool, cfg, rng=np.random.default_rng(seed))
        hits = [(t, le) for t in range(9) for le in range(17)
                if np.allclose(np.std(b.camera.gain[0] / full.gain[0][t:t + 32, le:le + 32],
                                      axis=0), 0.0, atol=1e-6)]
        assert len(hits) == 1
        assert np.array_equal(b.r2, (radial_map((40, 48)) ** 2)[hits[0][0]:hits[0][0] + 32,
                                                                hits[0][1]:hits[0][1] + 32])


def _radial_only_camera(size: tuple[int, int], per_r2: float) -> UnitCache:
    """A unit cache holding unit 0: no FPN, noise or housing term, an offset of ``per_r2``·R²
    counts (R² of :func:`sensor_r2`): each pixel's counts tell where on the sensor it is."""
    w, h = size
    base = make_camera("tau2", unit=0, size=size)
    offset = np.zeros_like(base.offset)
    offset[0] = 4000.0 + per_r2 * sensor_r2((h, w))
    gain = np.broadcast_to(base.gain.mean(axis=(1, 2))[:, None, None], base.gain.shape)
    cam = replace(base, gain=gain.astype(np.float32), offset=offset,
                  housing=np.zeros_like(base.housing), transient=np.zeros_like(base.transient),
                  defects=np.zeros_like(base.defects),
                  defect_counts=np.zeros_like(base.defect_counts), noise_sigma=0.0)
    cache = UnitCache("tau2", size)
    cache._units[0] = cam
    return cache


@pytest.mark.parametrize("sensor_motion", [False, True])
def test_frame_r2_tells_where_each_frame_saw_each_pixel(sensor_motion):
    size = (128, 96)
    units = _radial_only_camera(size, 2000.0)
    flat = ScenePool([np.full((64, 64), 20.0, np.float32)], ["uniform"])
    cfg = BurstConfig(n_frames=5, crop=32, units=(0,), sensor_size=size, augment=False,
                      redraw_column_fpn=False, motions=("walk",), translation_px=0.0,
                      perspective_sigma=0.0, sensor_motion=sensor_motion)
    b = make_burst(flat, cfg, rng=np.random.default_rng(3), units=units)
    assert b.r2_frames.shape == b.frames.shape and np.array_equal(b.r2_frames[2], b.r2)
    # a uniform scene: the counts are 4000 + (scene) + 2000·R² of the sensor pixel that saw it
    inner = b.valid.all(axis=0)
    inner[:2], inner[-2:], inner[:, :2], inner[:, -2:] = False, False, False, False
    level = b.frames - 2000.0 * b.r2_frames
    assert np.ptp(level[:, inner]) < 3.0  # counts; bilinear sampling of a smooth map
    # the frames saw the pivot's pixels elsewhere (4× farther away with sensor motion)
    spread = np.abs(b.r2_frames - b.r2[None])[:, inner].max()
    assert spread > (0.1 if sensor_motion else 0.02)
    assert np.ptp((b.frames - 2000.0 * b.r2[None])[:, inner]) > 100.0  # the pivot's R²: wrong


def test_sensor_motion_moves_the_windows_as_whole_sensor_frames():
    # a pure translation: frame 0 sees the pivot window's centre 6 px left and 3 px up
    hs = np.repeat(np.eye(3)[None], 3, 0)
    hs[0, :2, 2] = (6.0, 3.0)  # frame 0 → pivot: x + 6, y + 3
    moves = window_offsets(hs, 32, (128, 96), pivot=1)
    # whole 128×96 frames would be displaced by 4× and 3× as much: the window moves the rest
    assert moves.tolist() == [[-6, -18], [0, 0], [0, 0]]
    far = hs.copy()
    far[0, :2, 2] = (40.0, 40.0)  # the windows would not fit on the sensor: moves shrunk
    moves = window_offsets(far, 32, (128, 96), pivot=1)
    assert np.ptp(moves[:, 0]) <= 96 - 32 and np.ptp(moves[:, 1]) <= 128 - 32
    # in a burst: frame i saw the pivot window's centre c at the sensor pixel top + c + f·δ_i
    size, s = (128, 96), 32
    full = sensor_r2(size[::-1])
    flat = ScenePool([np.full((64, 64), 20.0, np.float32)], ["uniform"])
    cfg = BurstConfig(n_frames=5, crop=s, units=(0,), sensor_size=size, augment=False,
                      redraw_column_fpn=False, motions=("walk",), translation_px=0.0,
                      perspective_sigma=0.0, sensor_motion=True)
    for seed in range(4):
        b = make_burst(flat, cfg, rng=np.random.default_rng(seed),
                       units=_radial_only_camera(size, 0.0))
        hits = [(t, lf) for t in range(96 - s + 1) for lf in range(128 - s + 1)
                if np.array_equal(full[t : t + s, lf : lf + s], b.r2)]
        assert len(hits) == 1
        top, left = hits[0]
        c = (s - 1) / 2.0
        for i, h in enumerate(b.homographies):
            q = np.linalg.solve(h, [c, c, 1.0])
            delta = q[1::-1] / q[2] - c  # rows, columns, in the crop
            row, col = np.array([top, left]) + c + delta * np.array([96 / s, 128 / s])
            r0, c0 = int(row), int(col)
            fy, fx = row - r0, col - c0  # bilinear R² of the sensor at that point
            want = ((1 - fy) * ((1 - fx) * full[r0, c0] + fx * full[r0, c0 + 1])
                    + fy * ((1 - fx) * full[r0 + 1, c0] + fx * full[r0 + 1, c0 + 1]))
            k = int(c)  # c lies between pixels k and k + 1
            got = b.r2_frames[i][k : k + 2, k : k + 2].mean()
            assert abs(got - want) < 0.012, (seed, i)  # R² changes ≤ 0.011 per px here
