"""Stuck pixels of a raw burst: found from the burst alone, replaced before registration."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from thermocal.burst import burst_window, fill_stuck_pixels, scene_motion_px, stuck_pixels
from thermocal.calibration.two_point import fit_two_point
from thermocal.camera.model import render
from thermocal.camera.presets import make_camera
from thermocal.estimation.calibrated import naive_mean
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

DEFECTS = [(5, 7, 16383), (20, 30, 16383), (40, 60, 16383), (12, 50, 300), (33, 9, 1500)]


@pytest.fixture(scope="module")
def camera():
    """A 64×48 unit with five known defects (three hot, two dead) and no others."""
    cam = make_camera("tau2", unit=101, size=(64, 48))
    defects = np.zeros(cam.shape, bool)
    counts = np.zeros(cam.shape, np.uint16)
    for r, c, v in DEFECTS:
        defects[r, c], counts[r, c] = True, v
    return replace(cam, defects=defects, defect_counts=counts)


@pytest.fixture(scope="module")
def scene():
    """An urban map with single-pixel hot spots (a small hot object is not a defect)."""
    s = procedural_scene((200, 200), rng=np.random.default_rng(2), kind="urban")
    s[::17, ::13] = 90.0
    return s


@pytest.mark.parametrize("motion", ["walk", "hover"])
def test_stuck_pixels_are_the_units_defects(camera, scene, motion):
    fl = simulate_flight(scene, camera, n_frames=5, motion=motion, fpa_c=30.0, seed=4)
    found = stuck_pixels(fl.frames)
    assert np.array_equal(found, camera.defects)


def test_a_static_scene_keeps_its_point_sources(camera, scene):
    """A camera that does not move: the scene's single-pixel hot spots and thin lines stand out of
    their neighbourhood in every frame too, and only the homographies tell them from defects."""
    truth = scene[40:88, 40:104].copy()
    truth[10, :] = 60.0  # a one-pixel-wide warm line
    rng = np.random.default_rng(3)
    frames = render(camera, np.repeat(truth[None], 5, axis=0), 30.0, housing_c=28.5, rng=rng)
    still = np.repeat(np.eye(3)[None], 5, axis=0)
    without = stuck_pixels(frames)
    assert (without & ~camera.defects).sum() > 10  # the scene's spots and line look stuck ...
    assert np.array_equal(stuck_pixels(frames, still), np.zeros(camera.shape, bool))  # ... not
    moved = still.copy()
    moved[:, 0, 2] = [-4.0, -2.0, 0.0, 2.0, 4.0]  # a 2 px-per-frame pan
    assert scene_motion_px(moved, camera.shape).min() == pytest.approx(4.0)
    assert scene_motion_px(still, camera.shape).max() == 0.0


def test_stuck_pixels_take_any_array_and_keep_its_dtype(camera, scene):
    fl = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=30.0, seed=4)
    as_float = fl.frames.astype(np.float64) + 0.25
    filled, bad = fill_stuck_pixels(as_float, fl.homographies)
    assert filled.dtype == np.float64 and np.array_equal(bad, camera.defects)
    assert np.array_equal(filled[:, ~bad], as_float[:, ~bad])  # bit for bit
    listed, bad_l = fill_stuck_pixels(fl.frames.tolist())
    assert np.array_equal(bad_l, bad) and listed.dtype == np.asarray(fl.frames.tolist()).dtype


def test_too_short_a_burst_gives_no_defects(camera, scene):
    fl = simulate_flight(scene, camera, n_frames=3, motion="walk", fpa_c=30.0, seed=4)
    assert not stuck_pixels(fl.frames[:2]).any()
    assert stuck_pixels(fl.frames).sum() == len(DEFECTS)


def test_fill_stuck_pixels_replaces_them_alone(camera, scene):
    fl = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=30.0, seed=4)
    before = fl.frames.copy()
    filled, bad = fill_stuck_pixels(fl.frames)
    assert np.array_equal(fl.frames, before)  # the input is not changed
    assert filled.dtype == fl.frames.dtype and np.array_equal(bad, camera.defects)
    assert np.array_equal(filled[:, ~bad], fl.frames[:, ~bad])
    for r, c, _ in DEFECTS:  # the median of the 8 neighbours (none of them is a defect)
        around = fl.frames[:, r - 1 : r + 2, c - 1 : c + 2].reshape(len(filled), 9).astype(float)
        expected = np.median(np.delete(around, 4, axis=1), axis=1)
        assert np.all(np.abs(filled[:, r, c] - expected) <= 0.5)


def test_eq9_mean_leaves_no_defect_trail(camera):
    """Through a two-point calibration of the unit made before its pixels failed (so that it
    does not know the defects), each defect leaves a trail along the motion unless it is
    replaced first."""
    scene = procedural_scene((200, 200), rng=np.random.default_rng(2), kind="urban")
    fl = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=30.0, seed=4)
    rng = np.random.default_rng(0)
    fpa, housing = float(fl.fpa_true_c.mean()), float(fl.housing_c.mean())
    healthy = replace(camera, defects=np.zeros(camera.shape, bool))
    lo = render(healthy, np.full(8, 10.0), fpa, housing_c=housing, rng=rng)
    hi = render(healthy, np.full(8, 50.0), fpa, housing_c=housing, rng=rng)
    cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=fpa)
    truth = fl.truth_c[fl.pivot]
    errs = {}
    for fill in (False, True):
        est = naive_mean(fl.frames, cal, homographies=fl.homographies, fill_defects=fill)
        inner = est.coverage == 5
        errs[fill] = np.abs(est.temperature_c - truth)[inner]
    assert errs[False].max() > 10.0  # a hot pixel's share of a 5-frame mean
    assert errs[True].max() < 5.0 and errs[True].mean() < errs[False].mean()


def _stuck_by_the_rule(frames, homographies, min_counts, k):
    """The rule of stuck_pixels taken literally: every frame's full median, every pixel."""
    import cv2

    out = np.ones(frames.shape[1:], dtype=bool)
    for f in np.asarray(frames, dtype=np.float32):
        d = np.abs(f - cv2.medianBlur(f, 3))
        out &= d > max(min_counts, k * 1.4826 * float(np.median(d)))
    if homographies is not None:
        out &= scene_motion_px(homographies, out.shape) >= 2.0
    return out


@pytest.mark.parametrize("seed", range(4))
def test_stuck_pixels_give_what_the_rule_gives_with_every_median(seed):
    """The medians taken only where they can raise the threshold, the motion only at the
    candidates: the same mask as the rule with a full median per frame, on noisy and quiet
    bursts (where the median does and does not raise the threshold)."""
    rng = np.random.default_rng(seed)
    for _ in range(60):
        n, h, w = int(rng.integers(3, 8)), int(rng.integers(8, 40)), int(rng.integers(8, 40))
        frames = (8000 + rng.normal(0, float(rng.choice([1, 8, 40, 300])), (n, h, w)))
        frames = frames.astype(np.float32 if rng.random() < 0.5 else np.uint16)
        bad = rng.random((h, w)) < 0.04
        frames[:, bad] = rng.choice([0, 16000])
        if rng.random() < 0.3:  # a defect that one frame does not show
            frames[int(rng.integers(n)), bad] = 8000
        hs = None
        if rng.random() < 0.7:  # shifts, rotations, a little perspective
            hs = np.repeat(np.eye(3)[None], n, axis=0)
            hs[:, :2, :2] += rng.normal(0, 0.02, (n, 2, 2))
            hs[:, :2, 2] = rng.uniform(-4, 4, (n, 2)) * float(rng.random() < 0.8)
            hs[:, 2, :2] = rng.normal(0, 1e-4, (n, 2))
        min_counts = float(rng.choice([5.0, 100.0]))
        k = float(rng.choice([0.0, 3.0, 10.0]))
        want = _stuck_by_the_rule(frames, hs, min_counts, k)
        assert np.array_equal(stuck_pixels(frames, hs, min_counts=min_counts, k=k), want)


def test_the_median_of_count_differences_is_numpys():
    """The histogram's median of whole numbers (odd and even counts, ties, one value) is
    np.median's, bit for bit."""
    from thermocal.burst import _count_median

    rng = np.random.default_rng(0)
    for size in (1, 2, 7, 8, 1000, 1001):
        for spread in (0, 3, 500, 16383, 65535, 2**24):
            d = rng.integers(0, spread + 1, size).astype(np.float32)
            assert _count_median(d) == float(np.median(d))
    big = np.array([8388609.0, 8388610.0], np.float32)  # float32's inexact mean: np.median's
    assert _count_median(big) == float(np.median(big))


def test_bad_pixels_take_the_median_of_their_good_neighbours():
    """fill_bad_pixels against its rule pixel by pixel (the median of the good ones of the 3×3
    neighbours, the edge's repeated at the border; the frame's median where none is good), in
    place, float32 bit for bit."""
    import warnings

    from thermocal.calibration.base import fill_bad_pixels

    rng = np.random.default_rng(1)
    for trial in range(6):
        temps = (rng.normal(30.0, 5.0, (3, 20, 24))).astype(np.float32)
        bad = rng.random((20, 24)) < (0.05, 0.3, 0.6)[trial % 3]
        bad[:4, :4] = True  # a corner with pixels no good neighbour touches
        temps[trial % 3, 10, 10:13] = np.nan  # good neighbours that are NaN are left out
        want = temps.copy()
        # the border's neighbours: its edge pixels again (nine values, as in the frame)
        padded = np.pad(temps, ((0, 0), (1, 1), (1, 1)), mode="edge")
        padded_bad = np.pad(bad, 1, mode="edge")
        for k in range(3):
            for r, c in zip(*np.nonzero(bad), strict=True):
                block = padded[k, r:r + 3, c:c + 3]
                good = block[~padded_bad[r:r + 3, c:c + 3]]
                good = good[~np.isnan(good)]
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    want[k, r, c] = (np.median(good) if good.size
                                     else np.median(temps[k][~bad]))
        got = fill_bad_pixels(temps.copy(), bad)
        for k in range(3):  # where a frame's own median is NaN too, NaN it is
            assert np.array_equal(got[k], want[k], equal_nan=True)
        temps[np.isnan(temps)] = 30.0
        want = temps.copy()
        for k in range(3):
            for r, c in zip(*np.nonzero(bad), strict=True):
                block = np.pad(temps, ((0, 0), (1, 1), (1, 1)), mode="edge")[k, r:r + 3, c:c + 3]
                good = block[~np.pad(bad, 1, mode="edge")[r:r + 3, c:c + 3]]
                want[k, r, c] = np.median(good) if good.size else np.median(temps[k][~bad])
        got = fill_bad_pixels(temps, bad)
        assert got is temps and np.array_equal(got, want)


@pytest.mark.parametrize(("n_frames", "n", "pivot", "want"), [
    (8, 7, None, (slice(1, 8), 3)),   # the middle frame (4) and three either side
    (8, 7, 0, (slice(0, 7), 0)),      # moved inside at the start
    (8, 7, 7, (slice(1, 8), 6)),      # and at the end
    (20, 7, 10, (slice(7, 14), 3)),
    (20, 6, 10, (slice(7, 13), 3)),
    (7, 7, 2, (slice(0, 7), 2)),      # a burst of the network's own length: as it is
    (5, 7, None, (slice(0, 5), None)),  # too short: left to the network's own check
    (9, None, 4, (slice(0, 9), 4)),   # any length
])
def test_burst_window(n_frames, n, pivot, want):
    assert burst_window(n_frames, n, pivot) == want


def test_burst_window_refuses_a_pivot_outside_the_recording():
    from thermocal.errors import InvalidInputError

    with pytest.raises(InvalidInputError):
        burst_window(9, 7, 9)


def test_clipped_parts_tell_defects_from_saturated_objects():
    """A pixel or two at 0 or at the top, touching (8 neighbours), are defects; a larger group
    is a saturated object."""
    from thermocal._validate import clipped_mask
    from thermocal.burst import MAX_FILLED_CLIP_PX, clipped_parts

    frame = np.full((20, 20), 5000, np.uint16)
    frame[2, 2] = 16383
    frame[5, 5] = frame[6, 6] = 16383  # two, diagonal: one group of two
    frame[10, 10] = 0
    frame[14:17, 14:17] = 16383  # nine
    isolated, clusters = clipped_parts(clipped_mask(frame, 14))
    assert MAX_FILLED_CLIP_PX == 2 and isolated.sum() == 4 and clusters.sum() == 9
    assert isolated[2, 2] and isolated[5, 5] and isolated[10, 10] and clusters[15, 15]
    assert not (isolated & clusters).any()


def test_clipped_pixels_are_filled_even_when_the_scene_holds_still():
    """A pixel at 0 or at the top count in any frame is filled from its neighbours whatever
    the motion (given ``top``); a static scene's sharp features are kept; without ``top``, as
    before (a hovering burst's saturated pixel read 80 °C where the scene was 17 °C)."""
    rng = np.random.default_rng(0)
    frame = rng.integers(5000, 5100, (40, 48)).astype(np.uint16)
    frame[20, 20] = 9000  # a bright point of the scene: held still, not a defect
    burst = np.repeat(frame[None], 5, axis=0)
    burst[:, 5, 7] = 16383  # saturated in every frame
    burst[2, 30, 40] = 0  # dead in one frame
    still = np.repeat(np.eye(3)[None], 5, axis=0)
    out, bad = fill_stuck_pixels(burst, still, top=16383)
    assert bad[5, 7] and bad[30, 40] and not bad[20, 20] and bad.sum() == 2
    assert 5000 <= out[0, 5, 7] <= 5100 and 5000 <= out[2, 30, 40] <= 5100
    assert out[0, 20, 20] == 9000 and burst[0, 5, 7] == 16383  # the input untouched
    assert not fill_stuck_pixels(burst, still)[1].any()  # without top: motion decides
    burst[:, 30:34, 10:14] = 16383  # a saturated object (16 touching pixels): kept
    out, bad = fill_stuck_pixels(burst, still, top=16383)
    assert bad.sum() == 2 and np.all(out[:, 30:34, 10:14] == 16383)


def test_frozen_pixels_are_filled_when_the_camera_holds_still(camera, scene):
    """A camera held still: its dead and hot pixels never change by a count while every live
    pixel carries temporal noise, so they are filled whatever the motion; the scene's
    single-pixel spots and thin lines, which do change, are kept. Fewer than
    FROZEN_MIN_FRAMES frames, or a noiseless burst, give none."""
    from thermocal.burst import FROZEN_MIN_FRAMES, frozen_pixels

    truth = scene[40:88, 40:104].copy()
    truth[10, :] = 60.0
    rng = np.random.default_rng(3)
    frames = render(camera, np.repeat(truth[None], 7, axis=0), 30.0, housing_c=28.5, rng=rng)
    still = np.repeat(np.eye(3)[None], 7, axis=0)
    out, bad = fill_stuck_pixels(frames, still)
    assert np.array_equal(bad, camera.defects)
    assert np.array_equal(out[:, ~bad], frames[:, ~bad])
    assert np.array_equal(frozen_pixels(frames.min(0), frames.max(0), 7), camera.defects)
    short = frames[:FROZEN_MIN_FRAMES - 1]
    assert not frozen_pixels(short.min(0), short.max(0), len(short)).any()
    quiet = render(camera, np.repeat(truth[None], 7, axis=0), 30.0, housing_c=28.5,
                   noise=False)
    assert not frozen_pixels(quiet.min(0), quiet.max(0), 7).any()
    # rounded noise of live pixels: too quiet for so few frames, nothing flagged by chance; a
    # louder or longer burst tells them from a dead pixel (the audit: 138 of 86,000 live
    # pixels flagged over 5 frames of 1.6 counts of noise)
    for n, noise, flagged in ((5, 1.6, False), (5, 2.0, False), (7, 2.5, True),
                              (5, 8.0, True)):
        live = np.round(rng.normal(8000.0, noise, (n, 256, 336)))
        live[:, 5, 7] = 8000.0  # one dead pixel
        got = frozen_pixels(live.min(0), live.max(0), n)
        assert got[5, 7] == flagged and got.sum() <= (3 if flagged else 0), (n, noise)
