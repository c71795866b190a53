"""Tests of thermocal.registration.warp: render_views and warp_to_pivot."""

from __future__ import annotations

import time

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.registration.warp import as_homographies, render_views, warp_to_pivot
from thermocal.scenes import trajectory as tr
from thermocal.scenes.procedural import fractal_noise

FRAME = (336, 256)
MAP = (2 * 336 + 16, 2 * 256 + 16)


def _translation(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _smooth_map(seed: int = 0) -> np.ndarray:
    n = fractal_noise((MAP[1], MAP[0]), beta=4.5, rng=np.random.default_rng(seed))
    return (30.0 + 5.0 * n).astype(np.float32)


# --------------------------------------------------------------------------------------------
# render_views
# --------------------------------------------------------------------------------------------


def test_render_identity_gives_the_crop():
    rng = np.random.default_rng(0)
    m = (20.0 + 10.0 * rng.random((60, 80))).astype(np.float32)
    hs = np.stack([_translation(0, 0), _translation(7, 11), _translation(50, 30)])
    views = render_views(m, hs, (30, 20))
    assert views.shape == (3, 20, 30)
    assert views.dtype == np.float32
    np.testing.assert_array_equal(views[0], m[0:20, 0:30])
    np.testing.assert_array_equal(views[1], m[11:31, 7:37])
    np.testing.assert_array_equal(views[2], m[30:50, 50:80])


def test_render_subpixel_is_bilinear():
    m = np.tile(np.arange(40, dtype=np.float32) + 20.0, (30, 1))  # linear in x
    views = render_views(m, _translation(2.25, 3.0), (10, 10))
    assert views.shape == (1, 10, 10)
    np.testing.assert_allclose(views[0], m[3:13, 2:12] + 0.25, atol=1e-5)


def test_render_single_homography_and_float64_map():
    m = np.full((40, 50), 25.0)
    out = render_views(m, np.eye(3), (20, 10))
    assert out.shape == (1, 10, 20)
    assert out.dtype == np.float32


def test_render_does_not_modify_inputs():
    m = _smooth_map()
    hs = tr.walk_homographies(5, FRAME, MAP, rng=np.random.default_rng(0))
    m0, h0 = m.copy(), hs.copy()
    render_views(m, hs, FRAME)
    np.testing.assert_array_equal(m, m0)
    np.testing.assert_array_equal(hs, h0)


@pytest.mark.parametrize(
    "h",
    [_translation(-1.0, 0.0), _translation(0.0, 31.0), _translation(21.0, 0.0),
     np.array([[1.0, 0, 0], [0, 1, 0], [-0.2, 0, 1]])],
)
def test_render_view_leaving_the_map_raises(h):
    m = np.full((40, 50), 25.0, dtype=np.float32)
    with pytest.raises(InvalidInputError):
        render_views(m, h, (30, 10))


def test_render_map_smaller_than_frame_raises():
    with pytest.raises(InvalidInputError):
        render_views(np.full((20, 20), 25.0), np.eye(3), (30, 30))


def test_render_bad_inputs():
    m = np.full((40, 50), 25.0, dtype=np.float32)
    bad = m.copy()
    bad[1, 1] = np.nan
    with pytest.raises(InvalidInputError):
        render_views(bad, np.eye(3), (10, 10))
    with pytest.raises(InvalidInputError):
        render_views(np.full((40, 50), -280.0), np.eye(3), (10, 10))
    with pytest.raises(InvalidInputError):
        render_views(m[None], np.eye(3), (10, 10))
    with pytest.raises(InvalidInputError):
        render_views(m, np.eye(2), (10, 10))
    with pytest.raises(InvalidInputError):
        render_views(m, np.zeros((3, 3)), (10, 10))
    with pytest.raises(InvalidInputError):
        render_views(m, np.full((3, 3), np.nan), (10, 10))
    with pytest.raises(InvalidInputError):
        render_views(m, np.eye(3), (0, 10))


# --------------------------------------------------------------------------------------------
# warp_to_pivot
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dx,dy", [(3, 2), (-4, 1), (0, -5), (7, -3)])
def test_warp_integer_translation_known_answer(dx, dy):
    rng = np.random.default_rng(1)
    h, w = 20, 30
    frames = rng.random((2, h, w)).astype(np.float32)
    hs = np.stack([np.eye(3), _translation(dx, dy)])
    warped, valid = warp_to_pivot(frames, hs)
    expected_valid = np.zeros((h, w), dtype=bool)
    expected_valid[max(0, dy) : h + min(0, dy), max(0, dx) : w + min(0, dx)] = True
    np.testing.assert_array_equal(valid[1], expected_valid)
    expected = np.zeros((h, w), dtype=np.float32)
    expected[expected_valid] = frames[1][
        max(0, -dy) : h + min(0, -dy), max(0, -dx) : w + min(0, -dx)
    ].ravel()
    np.testing.assert_array_equal(warped[1], expected)
    np.testing.assert_array_equal(warped[0], frames[0])
    assert valid[0].all()


def test_warp_subpixel_translation_valid_mask_per_interpolation():
    h, w = 12, 16
    frame = np.tile(np.arange(w, dtype=np.float32), (h, 1))
    hs = _translation(2.5, 0.0)[None]
    first_valid = {"linear": 3, "nearest": 3, "cubic": 4}
    last_valid = {"linear": w - 1, "nearest": w - 1, "cubic": w - 1}  # source x = 12.5
    for interp, x0 in first_valid.items():
        warped, valid = warp_to_pivot(frame[None], hs, interpolation=interp)
        cols = np.flatnonzero(valid[0][h // 2])
        assert cols[0] == x0, interp
        assert cols[-1] == last_valid[interp], interp
        assert valid[0].all(axis=1).sum() == 0  # every row has invalid columns
        assert np.all(warped[0][~valid[0]] == 0.0)
    warped, valid = warp_to_pivot(frame[None], hs, interpolation="linear")
    np.testing.assert_allclose(warped[0][valid[0]], (frame[0] - 2.5)[None].repeat(h, 0)[valid[0]],
                               atol=1e-4)


def test_warp_uint16_input_pivot_unchanged_and_not_modified():
    rng = np.random.default_rng(2)
    frames = rng.integers(0, 16384, size=(3, 24, 32), dtype=np.uint16)
    before = frames.copy()
    hs = np.stack([_translation(1.5, -0.5), np.eye(3), _translation(-2.0, 3.0)])
    warped, valid = warp_to_pivot(frames, hs)
    np.testing.assert_array_equal(frames, before)
    assert warped.dtype == np.float32
    assert valid.dtype == bool
    assert warped.shape == valid.shape == (3, 24, 32)
    np.testing.assert_array_equal(warped[1], frames[1].astype(np.float32))
    assert valid[1].all()
    assert not valid[0].all() and valid[0].any()


def test_warp_round_trip_reproduces_the_pivot_view():
    m = _smooth_map(3)
    for seed in range(3):
        hs = tr.walk_homographies(7, FRAME, MAP, rng=np.random.default_rng(seed))
        views = render_views(m, hs, FRAME)
        hp = tr.to_pivot(hs, 3)
        warped, valid = warp_to_pivot(views, hp)
        np.testing.assert_array_equal(warped[3], views[3])
        ov = tr.overlap_fraction(hp, FRAME)
        for i in range(7):
            err = np.abs(warped[i] - views[3])[valid[i]]  # map gradients up to ~0.5 °C/px
            assert err.max() < 0.1, (seed, i, err.max())
            assert err.mean() < 0.01, (seed, i, err.mean())
            # the valid area is the overlap with the pivot
            assert valid[i].mean() == pytest.approx(ov[i], abs=0.01)


def test_warp_round_trip_with_projective_homographies():
    m = _smooth_map(4)
    hs = tr.hover_homographies(5, FRAME, MAP, rng=np.random.default_rng(0), overlap=(0.6, 0.8))
    hp = tr.perturb_homographies(tr.to_pivot(hs, 2), rng=np.random.default_rng(1),
                                 frame_size=FRAME, translation_px=0.0)
    # make the map views agree with the perturbed (now projective) homographies
    hs_true = hs[2][None] @ hp
    views = render_views(m, hs_true, FRAME)
    warped, valid = warp_to_pivot(views, hp)
    for i in range(5):
        assert np.abs(warped[i] - views[2])[valid[i]].max() < 0.1


def test_warp_bad_inputs():
    frames = np.zeros((2, 10, 12), dtype=np.float32)
    good = np.stack([np.eye(3)] * 2)
    with pytest.raises(InvalidInputError):
        warp_to_pivot(frames, good[:1])
    with pytest.raises(InvalidInputError):
        warp_to_pivot(frames, np.zeros((2, 3, 4)))
    sing = good.copy()
    sing[1] = 0.0
    with pytest.raises(InvalidInputError):
        warp_to_pivot(frames, sing)
    nan = frames.copy()
    nan[0, 0, 0] = np.nan
    with pytest.raises(InvalidInputError):
        warp_to_pivot(nan, good)
    with pytest.raises(InvalidInputError):
        warp_to_pivot(frames, good, interpolation="lanczos")
    with pytest.raises(InvalidInputError):
        warp_to_pivot(np.zeros((2, 3, 10, 12)), good)
    with pytest.raises(InvalidInputError):
        warp_to_pivot(frames.astype(str), good)


def test_as_homographies_shapes():
    assert as_homographies(np.eye(3)).shape == (1, 3, 3)
    assert as_homographies(np.stack([np.eye(3)] * 4), n=4).shape == (4, 3, 3)
    with pytest.raises(InvalidInputError):
        as_homographies(np.zeros((0, 3, 3)))
    with pytest.raises(InvalidInputError):
        as_homographies([[1, 2], [3, 4]])


def test_render_and_warp_speed():
    rng = np.random.default_rng(5)
    m = _smooth_map(5)
    hs = tr.walk_homographies(7, FRAME, MAP, rng=rng)
    hp = tr.to_pivot(hs, 3)
    render_views(m, hs, FRAME)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        views = render_views(m, hs, FRAME)
        warp_to_pivot(views, hp)
        best = min(best, time.perf_counter() - t0)
    assert best < 0.1
