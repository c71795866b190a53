"""Tests of thermocal.scenes.maps: make_map, augment, random_augment, crop."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.scenes.maps import augment, crop, make_map, random_augment


def _ramp(h: int, w: int) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return (20.0 + 0.1 * xx + 0.01 * yy).astype(np.float32)


# --------------------------------------------------------------------------------------------
# make_map
# --------------------------------------------------------------------------------------------


def test_make_map_upsamples_to_cover_and_keeps_range():
    rng = np.random.default_rng(0)
    scene = (25.0 + 10.0 * rng.random((50, 80))).astype(np.float32)
    m = make_map(scene, (300, 400))
    assert m.shape == (300, 400)
    assert m.dtype == np.float32
    # cubic overshoot is clipped to the scene's range
    assert float(m.min()) >= float(scene.min()) - 1e-6
    assert float(m.max()) <= float(scene.max()) + 1e-6


def test_make_map_keeps_aspect_ratio():
    # a 40x40 square of the scene stays square: the factor is max(300/50, 400/80) = 6
    scene = np.full((50, 80), 20.0, dtype=np.float32)
    scene[20:30, 35:45] = 40.0  # a 10x10 square in the middle
    m = make_map(scene, (300, 400))
    hot = m > 30.0
    rows = np.flatnonzero(hot.any(axis=1))
    cols = np.flatnonzero(hot.any(axis=0))
    assert rows.size == pytest.approx(60, abs=2)
    assert cols.size == pytest.approx(60, abs=2)


def test_make_map_ramp_stays_monotone():
    m = make_map(_ramp(40, 60), (200, 250))
    assert np.all(np.diff(m, axis=1) > 0)
    assert np.all(np.diff(m, axis=0) > 0)


def test_make_map_same_shape_is_exact_copy():
    scene = _ramp(30, 40)
    m = make_map(scene, (30, 40))
    np.testing.assert_array_equal(m, scene)
    assert m is not scene
    m[0, 0] = -1.0
    assert scene[0, 0] == 20.0


def test_make_map_centre_crop_without_resize():
    scene = _ramp(10, 20)
    m = make_map(scene, (10, 10))  # factor max(1, 0.5) = 1: no resize, centre crop
    np.testing.assert_array_equal(m, scene[:, 5:15])


def test_make_map_explicit_scale_and_crop():
    scene = np.tile(np.arange(20, dtype=np.float32) + 20.0, (10, 1))
    m = make_map(scene, (20, 30), scale=2.0)  # 20x40 after resize, crop columns 5..35
    assert m.shape == (20, 30)
    big = make_map(scene, (20, 40), scale=2.0)
    np.testing.assert_allclose(m, big[:, 5:35])


def test_make_map_downsample_area_preserves_mean():
    rng = np.random.default_rng(1)
    scene = (30.0 + rng.normal(0, 3, (400, 600))).astype(np.float32)
    m = make_map(scene, (100, 150))  # exactly 1/4, area averaging
    assert m.shape == (100, 150)
    assert float(m.mean()) == pytest.approx(float(scene.mean()), abs=1e-3)
    assert float(m.std()) < float(scene.std()) / 2  # 4x4 averaging reduces noise
    uniform = np.full((400, 600), 21.5, dtype=np.float32)
    np.testing.assert_allclose(make_map(uniform, (90, 130)), 21.5, atol=1e-5)


def test_make_map_does_not_modify_input():
    scene = _ramp(40, 60).astype(np.float64)
    before = scene.copy()
    make_map(scene, (100, 100))
    np.testing.assert_array_equal(scene, before)


def test_make_map_bad_inputs():
    good = _ramp(20, 20)
    with pytest.raises(InvalidInputError):
        make_map(good, (40, 40), scale=1.5)  # does not cover
    with pytest.raises(InvalidInputError):
        make_map(good, (10, 10), scale=0.0)
    with pytest.raises(InvalidInputError):
        make_map(good, (10, 10), scale=float("nan"))
    bad = good.copy()
    bad[3, 3] = np.nan
    with pytest.raises(InvalidInputError):
        make_map(bad, (10, 10))
    with pytest.raises(InvalidInputError):
        make_map(np.full((5, 5), -300.0), (10, 10))
    with pytest.raises(InvalidInputError):
        make_map(np.zeros((4, 5, 6)), (10, 10))
    with pytest.raises(InvalidInputError):
        make_map(good, (0, 10))
    with pytest.raises(InvalidInputError):
        make_map(good, (10,))


# --------------------------------------------------------------------------------------------
# augment / random_augment / crop
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [0, 1, 2, 3, 4, -1])
@pytest.mark.parametrize("flip_h", [False, True])
@pytest.mark.parametrize("flip_v", [False, True])
def test_augment_known_answer(k, flip_h, flip_v):
    m = _ramp(6, 9)
    expected = m
    if flip_h:
        expected = expected[:, ::-1]
    if flip_v:
        expected = expected[::-1, :]
    expected = np.rot90(expected, k)
    out = augment(m, k_rot90=k, flip_h=flip_h, flip_v=flip_v)
    np.testing.assert_array_equal(out, expected)
    assert out.dtype == np.float32
    assert out.flags["C_CONTIGUOUS"]


def test_augment_returns_a_copy():
    m = _ramp(6, 9)
    out = augment(m)
    out[:] = 0.0
    assert m[0, 0] == 20.0


def test_augment_bad_inputs():
    with pytest.raises(InvalidInputError):
        augment(_ramp(4, 4), k_rot90=1.5)
    with pytest.raises(InvalidInputError):
        augment(_ramp(4, 4), flip_h="yes")
    with pytest.raises(InvalidInputError):
        augment(np.full((4, 4), np.inf))


def test_random_augment_covers_the_dihedral_group():
    m = _ramp(5, 7)
    variants = []
    for k in range(4):
        for fh in (False, True):
            variants.append(augment(m, k_rot90=k, flip_h=fh))
    seen = set()
    rng = np.random.default_rng(0)
    for _ in range(200):
        out = random_augment(m, rng=rng)
        matches = [i for i, v in enumerate(variants) if v.shape == out.shape and
                   np.array_equal(v, out)]
        assert len(matches) == 1
        seen.add(matches[0])
    assert seen == set(range(8))


def test_random_augment_seeded_and_needs_generator():
    m = _ramp(5, 7)
    a = random_augment(m, rng=np.random.default_rng(3))
    b = random_augment(m, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(InvalidInputError):
        random_augment(m, rng=3)


def test_crop_known_answer_and_copy():
    m = _ramp(20, 30)
    out = crop(m, (3, 5), (4, 6))
    np.testing.assert_array_equal(out, m[3:7, 5:11])
    out[:] = 0
    assert m[3, 5] != 0
    np.testing.assert_array_equal(crop(m, (0, 0), (20, 30)), m)


@pytest.mark.parametrize("top_left,shape", [((-1, 0), (4, 4)), ((0, 27), (4, 4)),
                                            ((17, 0), (4, 4)), ((0, 0), (0, 4)),
                                            ((0.5, 0), (4, 4))])
def test_crop_outside_raises(top_left, shape):
    with pytest.raises(InvalidInputError):
        crop(_ramp(20, 30), top_left, shape)


def test_long_map_mirror_tiles_instead_of_blowing_up():
    from thermocal.scenes.maps import make_long_map

    scene = np.tile(np.linspace(10.0, 20.0, 40, dtype=np.float32), (30, 1))  # 30x40, ramp in x
    long_map = make_long_map(scene, (60, 500))
    assert long_map.shape == (60, 500)
    # scaled x2 to cover the height: each tile is 80 wide, every other one mirrored
    np.testing.assert_allclose(long_map[:, 79], long_map[:, 80], atol=0.3)
    assert long_map.min() >= 10.0 and long_map.max() <= 20.0
    np.testing.assert_allclose(make_long_map(scene, (30, 40)), scene, atol=1e-6)
