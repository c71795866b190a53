"""Tests of register_sequence / estimate_fixed_pattern / FixedPattern on simulated UAV passes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from thermocal.camera.model import expected_counts
from thermocal.camera.presets import make_camera
from thermocal.errors import (
    FileFormatError,
    InvalidInputError,
    RegistrationError,
    ResolutionMismatchError,
)
from thermocal.registration import (
    FixedPattern,
    SequenceRegistration,
    estimate_fixed_pattern,
    register_pair,
    register_sequence,
)
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.flight import iter_flight, plan_flight

SIZE = (128, 96)
N = 60


def corner_error(h_est: np.ndarray, h_true: np.ndarray, size=SIZE) -> float:
    w, h = size
    c = np.array([[0, 0, 1], [w - 1, 0, 1], [w - 1, h - 1, 1], [0, h - 1, 1]], float).T
    a, b = h_est @ c, h_true @ c
    return float(np.linalg.norm(a[:2] / a[2] - b[:2] / b[2], axis=0).mean())


@pytest.fixture(scope="module")
def uav():
    """A 60-frame UAV pass (3.8 px/frame) over the aerial scene: frames, frame→map, camera."""
    cam = make_camera("tau2", unit=3, size=SIZE)
    plan = plan_flight(load_builtin_scene("aerial"), cam, n_frames=N, motion="uav", seed=1)
    chunks = list(iter_flight(plan, cam))
    frames = np.concatenate([c.frames for c in chunks])
    truth = np.concatenate([c.truth_c for c in chunks])
    return frames, plan.to_map, cam, plan, truth


@pytest.fixture(scope="module")
def reg(uav):
    return register_sequence(uav[0])


def test_consecutive_frames_are_registered_through_fpn(uav, reg):
    frames, to_map, *_ = uav
    before = frames.copy()
    assert isinstance(reg, SequenceRegistration) and len(reg) == N
    np.testing.assert_array_equal(frames, before)  # input untouched
    assert reg.to_previous.shape == (N, 3, 3) and reg.to_previous.dtype == np.float64
    np.testing.assert_array_equal(reg.to_previous[0], np.eye(3))
    assert reg.ok.all() and reg.correlation.shape == (N,) and reg.correlation.min() > 0.9
    inv = np.linalg.inv(to_map)
    errs = [corner_error(reg.to_previous[k], inv[k - 1] @ to_map[k]) for k in range(1, N)]
    # the camera moves 3.8 px per frame: a fixed pattern left in would pull toward 0 px
    assert np.median(errs) < 0.6, np.median(errs)
    assert max(errs) < 2.5, max(errs)


def test_to_pivot_composes_the_chain(uav, reg):
    _, to_map, *_ = uav
    idx = np.arange(25, 36)
    hs = reg.to_pivot(idx, 30)
    assert hs.shape == (11, 3, 3)
    np.testing.assert_allclose(hs[5], np.eye(3), atol=1e-12)
    inv = np.linalg.inv(to_map)
    errs = [corner_error(hs[j], inv[30] @ to_map[i]) for j, i in enumerate(idx)]
    assert max(errs) < 3.5, errs  # up to 19 px of motion away from the pivot
    # composing forward and backward are inverse to each other
    np.testing.assert_allclose(reg.to_pivot([30], 35)[0] @ reg.to_pivot([35], 30)[0], np.eye(3),
                               atol=1e-9)
    with pytest.raises(InvalidInputError, match="outside"):
        reg.to_pivot([N], 30)


def test_blocks_in_parallel_agree(uav, reg):
    blocked = register_sequence(uav[0], block=30, workers=2)
    assert len(blocked.patterns) == 2 and blocked.ok.all()
    diff = [corner_error(blocked.to_previous[k], reg.to_previous[k]) for k in range(1, N)]
    assert np.median(diff) < 0.3, np.median(diff)


def test_segments_in_parallel_give_the_same_homographies(uav, monkeypatch):
    """Segments of SEGMENT_FRAMES pairs are registered in parallel: one worker or two, the
    same bytes (the result never depends on the machine's cores)."""
    import thermocal.registration.sequence as sequence

    monkeypatch.setattr(sequence, "SEGMENT_FRAMES", 16)  # several segments in one block
    one = register_sequence(uav[0], workers=1)
    two = register_sequence(uav[0], workers=2)
    assert np.array_equal(one.to_previous, two.to_previous)
    assert np.array_equal(one.correlation, two.correlation) and one.ok.all()


def test_only_the_pairs_asked_for_are_registered(uav, reg):
    """Groups of 7 at stride 10: only the pairs inside each group are registered (the others
    the identity, not ok, correlation NaN), each as close to the truth as in a full run, and
    a group composes onto its pivot as before; a chain across a skipped pair is refused."""
    frames, to_map, *_ = uav
    pairs = np.zeros(N, dtype=bool)
    for first in range(0, N - 6, 10):
        pairs[first + 1 : first + 7] = True
    part = register_sequence(frames, pairs=pairs)
    assert np.array_equal(part.ok, pairs | (np.arange(N) == 0))
    assert np.isnan(part.correlation[~part.ok]).all() and part.correlation[pairs].min() > 0.9
    np.testing.assert_array_equal(part.to_previous[~pairs], np.repeat(np.eye(3)[None],
                                                                      (~pairs).sum(), axis=0))
    inv = np.linalg.inv(to_map)
    for k in np.flatnonzero(pairs):
        truth = inv[k - 1] @ to_map[k]
        assert corner_error(part.to_previous[k], truth) < corner_error(
            reg.to_previous[k], truth) + 0.05, k
    hs = part.to_pivot(np.arange(10, 17), 13)
    full = reg.to_pivot(np.arange(10, 17), 13)
    assert max(corner_error(a, b) for a, b in zip(hs, full, strict=True)) < 0.1
    with pytest.raises(RegistrationError, match="frame 10 was not registered .*not asked for"):
        part.to_pivot([9], 13)
    # every pair asked for: the full run's bytes
    assert np.array_equal(register_sequence(frames, pairs=np.ones(N, bool)).to_previous,
                          reg.to_previous)
    with pytest.raises(InvalidInputError, match="pairs: expected 60 booleans"):
        register_sequence(frames, pairs=np.ones(N - 1, bool))


def test_failed_link_is_refused_by_to_pivot(reg):
    ok = reg.ok.copy()
    ok[33] = False
    broken = SequenceRegistration(reg.to_previous, reg.correlation, ok, reg.fixed_pattern)
    broken.to_pivot(np.arange(20, 33), 30)  # does not cross frame 33
    with pytest.raises(RegistrationError, match="frame 33"):
        broken.to_pivot([35], 30)


def test_chained_to_is_to_pivot_of_every_frame_and_says_which_reach_it(reg):
    ok = reg.ok.copy()
    ok[33] = False
    broken = SequenceRegistration(reg.to_previous, reg.correlation, ok, reg.fixed_pattern)
    hs, reachable = broken.chained_to(30)
    assert reachable[:33].all() and not reachable[33:].any()
    np.testing.assert_allclose(hs[:33], broken.to_pivot(np.arange(33), 30), atol=1e-9)


def test_uniform_recording_is_flagged_not_returned_as_motion():
    cam = make_camera("tau2", unit=0, size=(64, 48))
    from thermocal.camera.model import render

    frames = render(cam, np.full((6, 48, 64), 20.0, np.float32), np.full(6, 30.0),
                    housing_c=np.full(6, 30.0), rng=np.random.default_rng(0))
    reg = register_sequence(frames)
    assert not reg.ok[1:].any()
    with pytest.raises(RegistrationError, match="not registered"):
        reg.to_pivot([0], 5)


def test_fixed_pattern_matches_the_camera(uav):
    frames, _, cam, plan, truth = uav
    fp = estimate_fixed_pattern(frames)
    assert isinstance(fp, FixedPattern) and fp.shape == (SIZE[1], SIZE[0])
    assert fp.frames_used == N
    # the camera's fixed output at the pass's mean scene temperature
    level = np.full((1, SIZE[1], SIZE[0]), float(truth.mean()), np.float32)
    eff = expected_counts(cam, level, plan.fpa_true_c[:1], housing_c=plan.housing_c[:1])[0]
    col_true = eff.mean(axis=0) - eff.mean()
    assert np.corrcoef(fp.column, col_true)[0, 1] > 0.95
    # (stuck pixels are fixed too and in the estimate, but expected_counts leaves them out)
    away = cv2.erode((~cam.defects).astype(np.uint8), np.ones((25, 25), np.uint8)) > 0
    fine = (fp.pattern - cv2.GaussianBlur(fp.pattern, (0, 0), 4))[away]
    fine_true = (eff - cv2.GaussianBlur(eff, (0, 0), 4))[away]
    assert np.corrcoef(fine, fine_true)[0, 1] > 0.99
    assert np.std(fine - fine_true) < 0.1 * np.std(fine_true)
    # removing it leaves less sensor-fixed structure than there was
    corrected = fp.apply(frames[:5])
    assert corrected.shape == (5, SIZE[1], SIZE[0]) and corrected.dtype == np.float32
    def column_jumps(a: np.ndarray) -> float:
        return float(np.std(np.diff(np.mean(a, axis=1), axis=-1)))

    assert column_jumps(corrected) < 0.2 * column_jumps(frames[:5].astype(np.float32))


def test_fixed_pattern_save_load_and_bad_input(uav, tmp_path):
    frames = uav[0]
    fp = estimate_fixed_pattern(frames, max_frames=8)
    assert fp.frames_used == 8
    path = fp.save(tmp_path / "fpn.npz")
    back = FixedPattern.load(path)
    np.testing.assert_array_equal(back.pattern, fp.pattern)
    (tmp_path / "bad.npz").write_bytes(b"not a pattern")
    with pytest.raises(FileFormatError):
        FixedPattern.load(tmp_path / "bad.npz")
    with pytest.raises(ResolutionMismatchError):
        fp.apply(np.zeros((4, 10, 10)))
    with pytest.raises(InvalidInputError, match="3 frames"):
        estimate_fixed_pattern(frames[:2])
    bad = frames[:5].astype(np.float32)
    bad[2, 1, 1] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        estimate_fixed_pattern(bad)


def test_sequence_bad_input(uav):
    frames = uav[0]
    with pytest.raises(InvalidInputError, match="at least 2"):
        register_sequence(frames[:1])
    with pytest.raises(InvalidInputError, match="pass fixed_pattern"):
        register_sequence(frames[:2])
    with pytest.raises(ResolutionMismatchError):
        register_sequence(frames[:4], fixed_pattern=np.zeros((10, 10)))
    with pytest.raises(InvalidInputError, match="block"):
        register_sequence(frames[:4], block=1)
    with pytest.raises(InvalidInputError):
        register_sequence(frames[0])


def test_pair_with_known_pattern(uav):
    frames, to_map, *_ = uav
    fp = estimate_fixed_pattern(frames)
    reg2 = register_sequence(frames[10:12], fixed_pattern=fp)  # two frames: pattern required
    h_true = np.linalg.inv(to_map[10]) @ to_map[11]
    assert corner_error(reg2.to_previous[1], h_true) < 1.0
    h, _ = register_pair(frames[12], frames[10], fixed_pattern=fp)  # 7.6 px apart
    assert corner_error(h, np.linalg.inv(to_map[10]) @ to_map[12]) < 1.5


def test_a_pair_takes_a_good_prediction_alone_and_races_a_bad_one(uav, monkeypatch):
    import thermocal.registration._dense as dense
    from thermocal.registration import sequence
    from thermocal.registration.warp import translation

    frames, to_map, *_ = uav
    pattern = estimate_fixed_pattern(frames).pattern
    moving, fixed = (sequence._Prepared(frames[k], pattern) for k in (11, 10))
    window = dense.hanning(((SIZE[1] + 1) // 2, (SIZE[0] + 1) // 2))
    truth = np.linalg.inv(to_map[10]) @ to_map[11]
    calls = []
    peaks = dense.phase_peaks
    monkeypatch.setattr(dense, "phase_peaks", lambda *a, **k: calls.append(1) or peaks(*a, **k))
    h, cc = sequence._pair(moving, fixed, truth, window)  # the motion went on as predicted
    assert not calls and cc >= sequence.PREDICTION_ACCEPT and corner_error(h, truth) < 0.6
    # a prediction 24 px off (the camera jumped): the peaks are sought, and the race finds it
    h, cc = sequence._pair(moving, fixed, translation(24.0, -16.0) @ truth, window)
    assert calls and corner_error(h, truth) < 0.6
