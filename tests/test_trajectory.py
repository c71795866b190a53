"""Tests of thermocal.scenes.trajectory: walks, hovers, UAV passes, pivots, perturbations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thermocal.errors import InvalidInputError
from thermocal.registration.warp import frame_corners, map_points, render_views
from thermocal.scenes import trajectory as tr

FRAME = (336, 256)
MAP = (2 * 336 + 16, 2 * 256 + 16)


def _translation(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _inside_map(hs: np.ndarray, frame_size, map_size) -> bool:
    xy, w = map_points(hs, frame_corners(frame_size))
    wm, hm = map_size
    return bool(
        np.all(w > 0)
        and xy[..., 0].min() >= 0
        and xy[..., 0].max() <= wm - 1
        and xy[..., 1].min() >= 0
        and xy[..., 1].max() <= hm - 1
    )


def _normaliser(frame_size) -> np.ndarray:
    w, h = frame_size
    return np.array([[2.0 / (w - 1), 0.0, -1.0], [0.0, 2.0 / (h - 1), -1.0], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------------------------
# overlap and pivot
# --------------------------------------------------------------------------------------------


def test_overlap_identity_and_translation():
    assert tr.overlap_fraction(np.eye(3), FRAME) == pytest.approx(1.0)
    w, h = FRAME
    for dx, dy in [(10, 0), (0, -20), (-33.5, 12.25), (100, 100)]:
        expected = (1 - abs(dx) / w) * (1 - abs(dy) / h)
        assert tr.overlap_fraction(_translation(dx, dy), FRAME) == pytest.approx(expected)
    assert tr.overlap_fraction(_translation(w + 5, 0), FRAME) == 0.0


def test_overlap_batch_rotation_and_scale():
    w, h = 100, 100
    c = (w - 1) / 2
    rot90 = _translation(c, c) @ np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]) @ _translation(
        -c, -c
    )
    half = _translation(c, c) @ np.diag([0.5, 0.5, 1.0]) @ _translation(-c, -c)
    out = tr.overlap_fraction(np.stack([np.eye(3), rot90, half]), (w, h))
    assert isinstance(out, np.ndarray)
    np.testing.assert_allclose(out, [1.0, 1.0, 0.25], atol=1e-9)


def test_overlap_projective_behind_the_view_is_handled():
    h = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-0.01, 0.0, 1.0]])  # w < 0 for x > 100
    ov = tr.overlap_fraction(h, FRAME)
    assert 0.0 <= ov <= 1.0


def test_choose_pivot_known_answer():
    xs = [0.0, 50.0, 60.0, 70.0, 300.0]
    hs = np.stack([_translation(x, 0.0) for x in xs])
    assert tr.choose_pivot(hs, FRAME) == 2
    sym = np.stack([_translation(10.0 * i, 0.0) for i in range(7)])
    assert tr.choose_pivot(sym, FRAME) == 3


def test_to_pivot_identity_and_consistency():
    hs = tr.walk_homographies(7, FRAME, MAP, rng=np.random.default_rng(0))
    for p in (0, 3, 6):
        hp = tr.to_pivot(hs, p)
        assert hp.shape == (7, 3, 3)
        np.testing.assert_array_equal(hp[p], np.eye(3))
        np.testing.assert_allclose(hp[:, 2, 2], 1.0)
        # M_pivot @ H_i == M_i (up to scale)
        for i in range(7):
            a = hs[p] @ hp[i]
            np.testing.assert_allclose(a / a[2, 2], hs[i] / hs[i, 2, 2], atol=1e-9)


def test_to_pivot_bad_inputs():
    good = np.stack([np.eye(3)] * 3)
    with pytest.raises(InvalidInputError):
        tr.to_pivot(good, 3)
    with pytest.raises(InvalidInputError):
        tr.to_pivot(good, -1)
    with pytest.raises(InvalidInputError):
        tr.to_pivot(np.zeros((3, 2, 3)), 0)
    bad = good.copy()
    bad[1, 0, 0] = np.nan
    with pytest.raises(InvalidInputError):
        tr.to_pivot(bad, 0)
    sing = good.copy()
    sing[2] = np.array([[1.0, 2, 3], [2, 4, 6], [0, 0, 1]])
    with pytest.raises(InvalidInputError):
        tr.to_pivot(sing, 0)


# --------------------------------------------------------------------------------------------
# walk and hover
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 3, 7, 12])
@pytest.mark.parametrize("seed", range(4))
def test_walk_overlaps_in_range(n, seed):
    lo, hi = 0.6, 0.8
    hs = tr.walk_homographies(n, FRAME, MAP, rng=np.random.default_rng(seed), overlap=(lo, hi))
    assert hs.shape == (n, 3, 3)
    assert hs.dtype == np.float64
    pivot = n // 2
    ov = tr.overlap_fraction(tr.to_pivot(hs, pivot), FRAME)
    assert ov[pivot] == pytest.approx(1.0)
    others = np.delete(ov, pivot)
    assert np.all(others >= lo - 1e-6)
    # the extremes of the walk overlap the pivot by a fraction drawn from the range
    for end in {0, n - 1} - {pivot}:
        assert lo - 1e-6 <= ov[end] <= hi + 1e-6
    assert _inside_map(hs, FRAME, MAP)
    render_views(np.full((MAP[1], MAP[0]), 25.0, dtype=np.float32), hs, FRAME)  # no raise


def test_walk_custom_range_and_motion():
    rng = np.random.default_rng(42)
    for _ in range(5):
        hs = tr.walk_homographies(9, FRAME, MAP, rng=rng, overlap=(0.7, 0.72), rotation_deg=0.0,
                                  scale_jitter=0.0)
        ov = tr.overlap_fraction(tr.to_pivot(hs, 4), FRAME)
        assert 0.7 - 1e-6 <= ov[0] <= 0.72 + 1e-6
        assert 0.7 - 1e-6 <= ov[8] <= 0.72 + 1e-6
        # without rotation and scale jitter the views are pure translations
        np.testing.assert_allclose(hs[:, :2, :2], np.broadcast_to(np.eye(2), (9, 2, 2)),
                                   atol=1e-12)


def test_walk_rotation_and_scale_jitter_bounded():
    hs = tr.walk_homographies(15, FRAME, MAP, rng=np.random.default_rng(1), rotation_deg=2.0,
                              scale_jitter=0.02)
    scale = np.sqrt(np.linalg.det(hs[:, :2, :2]))
    angle = np.degrees(np.arctan2(hs[:, 1, 0], hs[:, 0, 0]))
    assert np.all(np.abs(scale - 1) <= 0.02 + 1e-12)
    assert np.all(np.abs(angle) <= 2.0 + 1e-9)
    assert np.ptp(angle) > 0.5  # the rotation really varies


def test_walk_is_seeded():
    a = tr.walk_homographies(7, FRAME, MAP, rng=np.random.default_rng(3))
    b = tr.walk_homographies(7, FRAME, MAP, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)


def test_walk_single_frame():
    hs = tr.walk_homographies(1, FRAME, MAP, rng=np.random.default_rng(0))
    assert hs.shape == (1, 3, 3)
    assert _inside_map(hs, FRAME, MAP)


def test_walk_map_too_small():
    with pytest.raises(InvalidInputError):
        tr.walk_homographies(7, FRAME, (300, 300), rng=np.random.default_rng(0))
    # fits one frame but not a walk with 60-80 % overlap
    with pytest.raises(InvalidInputError):
        tr.walk_homographies(7, FRAME, (FRAME[0] + 8, FRAME[1] + 8), rng=np.random.default_rng(0))


@pytest.mark.parametrize(
    "kwargs",
    [{"overlap": (0.8, 0.6)}, {"overlap": (0.0, 0.5)}, {"overlap": (0.5, 1.0)},
     {"rotation_deg": -1.0}, {"scale_jitter": 0.9}],
)
def test_walk_bad_arguments(kwargs):
    with pytest.raises(InvalidInputError):
        tr.walk_homographies(5, FRAME, MAP, rng=np.random.default_rng(0), **kwargs)


def test_walk_bad_n_and_rng():
    with pytest.raises(InvalidInputError):
        tr.walk_homographies(0, FRAME, MAP, rng=np.random.default_rng(0))
    with pytest.raises(InvalidInputError):
        tr.walk_homographies(3, FRAME, MAP, rng=0)
    with pytest.raises(InvalidInputError):
        tr.walk_homographies(3, (336,), MAP, rng=np.random.default_rng(0))


@pytest.mark.parametrize("seed", range(4))
def test_hover_small_jitter(seed):
    hs = tr.hover_homographies(9, FRAME, MAP, rng=np.random.default_rng(seed), jitter_px=3.0,
                               rotation_deg=1.0, scale_jitter=0.01)
    hp = tr.to_pivot(hs, 4)
    ov = tr.overlap_fraction(hp, FRAME)
    assert np.all(ov > 0.95)
    # centre displacement of each view from the pivot: a few pixels
    c = np.array([(FRAME[0] - 1) / 2, (FRAME[1] - 1) / 2])
    xy = map_points(hp, c)[0][:, 0]
    assert np.all(np.abs(xy - c) <= 3.0 * math.sqrt(2) / 0.99 + 1e-6)
    assert _inside_map(hs, FRAME, MAP)


@pytest.mark.parametrize("seed", range(4))
def test_hover_drift_overlaps_in_range(seed):
    hs = tr.hover_homographies(7, FRAME, MAP, rng=np.random.default_rng(seed),
                               overlap=(0.6, 0.8))
    ov = tr.overlap_fraction(tr.to_pivot(hs, 3), FRAME)
    others = np.delete(ov, 3)
    assert np.all(others >= 0.6 - 1e-6)
    assert np.all(others <= 0.8 + 1e-6)
    assert _inside_map(hs, FRAME, MAP)


def test_hover_map_too_small():
    with pytest.raises(InvalidInputError):
        tr.hover_homographies(5, FRAME, (200, 200), rng=np.random.default_rng(0))


# --------------------------------------------------------------------------------------------
# UAV pass
# --------------------------------------------------------------------------------------------


def test_pixel_motion_defaults_and_paper():
    assert tr.pixel_motion_per_frame() == pytest.approx(3.8, abs=0.05)
    # Oz et al. §V-A: 50 m, 10 m/s, 30 Hz, 9.8 mm lens, 4.4 mm per 256 pixels -> 3.80 px/frame
    paper = tr.pixel_motion_per_frame(altitude_m=50.0, speed_m_s=10.0, fps=30.0, focal_mm=9.8,
                                      pitch_um=4400.0 / 256)
    assert paper == pytest.approx(3.80, abs=0.01)
    assert tr.ground_sampling_distance_m(focal_mm=9.8, pitch_um=4400.0 / 256) == pytest.approx(
        0.0877, abs=1e-4
    )
    assert tr.pixel_motion_per_frame(fps=60.0) == pytest.approx(tr.pixel_motion_per_frame() / 2)
    with pytest.raises(InvalidInputError):
        tr.pixel_motion_per_frame(fps=0.0)
    with pytest.raises(InvalidInputError):
        tr.pixel_motion_per_frame(altitude_m=-5.0)


@pytest.mark.parametrize("heading", [0.0, 90.0, 37.0, 200.0])
@pytest.mark.parametrize("axis", ["x", "y"])
def test_uav_motion_per_frame(heading, axis):
    step = tr.pixel_motion_per_frame()
    hs = tr.uav_homographies(10, FRAME, (900, 900), heading_deg=heading, attitude_jitter_deg=0.0,
                             flight_axis=axis, rng=np.random.default_rng(0))
    assert _inside_map(hs, FRAME, (900, 900))
    # a ground point moves by `step` frame pixels between frames, against the flight axis
    for i in range(9):
        h = np.linalg.inv(hs[i + 1]) @ hs[i]
        h /= h[2, 2]
        np.testing.assert_allclose(h[:2, :2], np.eye(2), atol=1e-9)
        expected = (-step, 0.0) if axis == "x" else (0.0, step)
        np.testing.assert_allclose(h[:2, 2], expected, atol=1e-9)
    # on the map the camera moves along the heading
    centre = np.array([(FRAME[0] - 1) / 2, (FRAME[1] - 1) / 2])
    xy = map_points(hs, centre)[0][:, 0]
    d = xy[-1] - xy[0]
    a = math.radians(heading)
    np.testing.assert_allclose(d, 9 * step * np.array([math.cos(a), -math.sin(a)]), atol=1e-9)


def test_uav_with_jitter_average_motion():
    n = 60
    hs = tr.uav_homographies(n, FRAME, (FRAME[0] + 300, FRAME[1] + 40), heading_deg=0.0,
                             rng=np.random.default_rng(1))
    hp = tr.to_pivot(hs, n // 2)
    centre = np.array([(FRAME[0] - 1) / 2, (FRAME[1] - 1) / 2])
    xy = map_points(hp, centre)[0][:, 0]
    motion = np.diff(xy[:, 0])  # frame centres in the pivot frame move along the flight
    assert motion.mean() == pytest.approx(tr.pixel_motion_per_frame(), abs=0.1)
    assert motion.std() > 0  # attitude jitter is there ...
    assert np.abs(xy[:, 1] - centre[1]).max() < 5.0  # ... and small
    # roll and pitch make the views slightly projective
    assert np.abs(hp[:, 2, :2]).max() > 0


@pytest.mark.parametrize("crab", [-4.0, 3.0])
def test_uav_crab_angle_moves_the_ground_across_the_rows(crab):
    step = tr.pixel_motion_per_frame()
    hs = tr.uav_homographies(10, FRAME, (900, 900), heading_deg=0.0, attitude_jitter_deg=0.0,
                             crab_deg=crab, rng=np.random.default_rng(0))
    for i in range(9):  # the frame yawed against the track: the ground drifts across the rows
        h = np.linalg.inv(hs[i + 1]) @ hs[i]
        h /= h[2, 2]
        a = math.radians(crab)
        np.testing.assert_allclose(h[:2, 2], (-step * math.cos(a), step * math.sin(a)),
                                   atol=1e-9)
    with pytest.raises(InvalidInputError, match="crab_deg"):
        tr.uav_homographies(3, FRAME, (900, 900), crab_deg=60.0, rng=np.random.default_rng(0))
    with pytest.raises(InvalidInputError, match="crab_deg"):
        tr.uav_homographies(3, FRAME, (900, 900), crab_deg=float("nan"),
                            rng=np.random.default_rng(0))


def test_uav_map_gsd_scales_the_views():
    gsd = tr.ground_sampling_distance_m()
    hs = tr.uav_homographies(5, FRAME, (800, 800), map_gsd_m=2 * gsd, heading_deg=0.0,
                             attitude_jitter_deg=0.0, rng=np.random.default_rng(0))
    np.testing.assert_allclose(hs[:, :2, :2], np.broadcast_to(0.5 * np.eye(2), (5, 2, 2)),
                               atol=1e-12)
    np.testing.assert_allclose(np.diff(hs[:, 0, 2]), tr.pixel_motion_per_frame() / 2)


def test_uav_flight_module_map_shape_fits():
    """The map size thermocal.simulate.flight uses for a UAV pass is large enough."""
    w, h = FRAME
    for n in (3, 7, 30):
        step = tr.pixel_motion_per_frame()
        map_size = (int(w + 1.1 * step * n) + 32, int(1.25 * h) + 16)
        hs = tr.uav_homographies(n, FRAME, map_size, heading_deg=0.0,
                                 rng=np.random.default_rng(n))
        assert _inside_map(hs, FRAME, map_size)


def test_uav_map_too_small():
    with pytest.raises(InvalidInputError):
        tr.uav_homographies(100, FRAME, (400, 300), heading_deg=0.0, rng=np.random.default_rng(0))
    with pytest.raises(InvalidInputError):
        tr.uav_homographies(3, FRAME, (300, 200), rng=np.random.default_rng(0))
    with pytest.raises(InvalidInputError):
        tr.uav_homographies(3, FRAME, (900, 900), flight_axis="z", rng=np.random.default_rng(0))


# --------------------------------------------------------------------------------------------
# perturbations
# --------------------------------------------------------------------------------------------


def _burst(n: int) -> np.ndarray:
    hs = np.stack([_translation(5.0 * i - 20.0, 2.0 * i) for i in range(n)])
    hs[n // 2] = np.eye(3)
    return hs


def test_perturb_translation_statistics():
    n = 6001
    hs = _burst(n)
    before = hs.copy()
    out = tr.perturb_homographies(hs, rng=np.random.default_rng(0), frame_size=FRAME,
                                  perspective_sigma=0.0)
    np.testing.assert_array_equal(hs, before)  # input untouched
    np.testing.assert_array_equal(out[n // 2], np.eye(3))  # pivot untouched
    d = np.delete(out[:, :2, 2] - hs[:, :2, 2], n // 2, axis=0)
    assert np.abs(d).max() <= 2.0
    assert np.abs(d).max() > 1.99
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.05)
    np.testing.assert_allclose(d.var(axis=0), 4.0 / 3.0, rtol=0.06)  # U(-2, 2)
    np.testing.assert_allclose(out[:, :2, :2], hs[:, :2, :2], atol=1e-12)
    np.testing.assert_allclose(out[:, 2], hs[:, 2], atol=1e-12)


def test_perturb_perspective_statistics():
    n = 6001
    hs = _burst(n)
    out = tr.perturb_homographies(hs, rng=np.random.default_rng(1), frame_size=FRAME)
    norm = _normaliser(FRAME)
    inv = np.linalg.inv(norm)
    hn_in = norm @ hs @ inv
    hn_out = norm @ out @ inv
    hn_in = hn_in / hn_in[:, 2:3, 2:3]
    hn_out = hn_out / hn_out[:, 2:3, 2:3]
    e = np.delete(hn_out[:, 2, :2] - hn_in[:, 2, :2], n // 2, axis=0)
    # N(0, 5e-5) on h31, h32 in kornia's normalised coordinates (5e-5 read as the variance)
    np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=3 * math.sqrt(5e-5 / n) + 1e-5)
    np.testing.assert_allclose(e.var(axis=0), 5e-5, rtol=0.06)
    assert tr.PERSPECTIVE_SIGMA == pytest.approx(math.sqrt(5e-5))
    # and the translation part is still bounded by ±2 px at the frame centre
    centre = np.array([(FRAME[0] - 1) / 2, (FRAME[1] - 1) / 2])
    a = map_points(hs, centre)[0][:, 0]
    b = map_points(out, centre)[0][:, 0]
    shift = np.delete(b - a, n // 2, axis=0)
    assert np.abs(shift).max() <= 2.0 + 1e-6


def test_perturb_pivot_detection_and_explicit_pivot():
    hs = np.stack([_translation(3.0, 0.0), np.eye(3), _translation(-3.0, 1.0)])
    out = tr.perturb_homographies(hs, rng=np.random.default_rng(2), frame_size=FRAME)
    np.testing.assert_array_equal(out[1], np.eye(3))
    assert not np.allclose(out[0], hs[0])
    out = tr.perturb_homographies(hs, rng=np.random.default_rng(2), frame_size=FRAME, pivot=0)
    np.testing.assert_array_equal(out[0], hs[0])
    assert not np.allclose(out[1], np.eye(3))
    single = tr.perturb_homographies(_translation(1.0, 1.0), rng=np.random.default_rng(0),
                                     frame_size=FRAME)
    assert single.shape == (3, 3)


def test_perturb_bad_inputs():
    rng = np.random.default_rng(0)
    with pytest.raises(InvalidInputError):
        tr.perturb_homographies(np.zeros((2, 3, 3)), rng=rng, frame_size=FRAME)
    with pytest.raises(InvalidInputError):
        tr.perturb_homographies(np.eye(4), rng=rng, frame_size=FRAME)
    with pytest.raises(InvalidInputError):
        tr.perturb_homographies(_burst(3), rng=rng, frame_size=FRAME, translation_px=-1.0)
    with pytest.raises(InvalidInputError):
        tr.perturb_homographies(_burst(3), rng=rng, frame_size=FRAME, pivot=5)
