"""thermocal._validate: one home, and one rule, for each input check."""

from __future__ import annotations

import numpy as np
import pytest

from thermocal._validate import (
    SATURATED_FRACTION,
    as_frames,
    check_frame_index,
    check_not_constant,
    check_not_saturated,
    check_output_file,
    is_constant,
    parse_range,
    pivot_index,
    saturated_fraction,
)
from thermocal.burst import check_burst
from thermocal.calibration.base import check_frames
from thermocal.calibration.dataset import FrameScan
from thermocal.errors import InvalidInputError


def clipped_frames(fraction: float, *, value: int = 16383) -> np.ndarray:
    """Two 20x50 frames of varied counts, the second with ``fraction`` of its pixels at
    ``value``."""
    frames = (np.arange(2000, dtype=np.uint16) % 997 + 1000).reshape(2, 20, 50)
    frames[1].flat[: int(round(fraction * 1000))] = value
    return frames


@pytest.mark.parametrize("value", [0, 16383])
def test_one_saturation_rule_for_bursts_calibrations_and_chamber_fits(value):
    ok = clipped_frames(SATURATED_FRACTION, value=value)  # at the limit: accepted
    bad = clipped_frames(SATURATED_FRACTION + 0.001, value=value)
    assert saturated_fraction(ok)[1] == pytest.approx(SATURATED_FRACTION)
    check_burst(ok)
    check_frames(ok, (20, 50))
    scan = FrameScan((20, 50))
    assert scan.check(np.arange(2), ok).all() and not scan.check(np.arange(2), bad)[1]
    for check in (check_burst, lambda f: check_frames(f, (20, 50))):
        with pytest.raises(InvalidInputError, match="frame 1 is saturated"):
            check(bad)


def test_frame_scan_counts_the_same_with_or_without_clipped_pixels():
    clean = clipped_frames(0.0)
    scan = FrameScan((20, 50))
    assert scan.check(np.arange(2), clean).all() and scan.n_seen == 2
    assert not scan.clipped_per_pixel.any() and not scan.excluded
    one = clean.copy()
    one[0, 3, 4] = 16383  # a pixel at the top: counted where it is
    assert scan.check(np.arange(2, 4), one).all() and scan.n_seen == 4
    assert scan.clipped_per_pixel.sum() == 1 and scan.clipped_per_pixel[3, 4] == 1


def test_saturation_counts_only_integer_counts_and_covered_pixels():
    bad = clipped_frames(0.2)
    check_not_saturated(bad.astype(np.float32))  # not the ADC's output: not checked
    registered = clipped_frames(0.2, value=0)  # 0: not covered
    check_not_saturated(registered, registered=True)
    registered[1, 10:12] = 16383  # 100 of the 800 covered pixels
    assert saturated_fraction(registered, registered=True)[1] == pytest.approx(100 / 800)
    with pytest.raises(InvalidInputError, match=r"frame 1 is saturated \(12 % .* at 16383\)"):
        check_not_saturated(registered, registered=True)


def test_constant_frames():
    frames = clipped_frames(0.0)
    assert not is_constant(frames[0]) and is_constant(np.full((4, 4), 3000.0))
    assert is_constant(np.full((4, 4), 3000.0) + np.float32(1e-4))  # float32 precision
    frames[1] = 5000
    with pytest.raises(InvalidInputError, match="frame 1 is constant"):
        check_burst(frames)
    registered = frames.copy()
    registered[1, :10] = 0  # a constant frame that covers half the pivot
    with pytest.raises(InvalidInputError, match="frame 1 is constant"):
        check_not_constant(registered, registered=True)


def test_as_frames_layout_and_values():
    assert as_frames(np.zeros((3, 4), np.uint16)).shape == (1, 3, 4)
    with pytest.raises(InvalidInputError, match="mixed sizes"):
        as_frames([np.zeros((4, 4)), np.zeros((4, 5))])
    nan = np.ones((3, 4, 4))
    nan[2, 1, 1] = np.nan
    with pytest.raises(InvalidInputError, match="frame 2 contains NaN"):
        as_frames(nan)
    with pytest.raises(InvalidInputError, match="14-bit range"):
        as_frames(np.full((2, 4, 4), 20000, np.uint16))
    assert as_frames(np.full((2, 4, 4), 20000, np.uint16), bit_depth=None).dtype == np.uint16
    with pytest.raises(InvalidInputError, match="at least 16x16"):
        as_frames(np.ones((2, 8, 40)), min_size=16)
    with pytest.raises(InvalidInputError, match="at least 3 frames"):
        as_frames(np.ones((2, 4, 4)), min_frames=3)
    with pytest.raises(InvalidInputError, match=r"expected \(N, H, W\) frames"):
        as_frames(np.ones((4, 4)), ndim=3)


def test_frame_indices_and_the_pivot():
    assert pivot_index(None, 7) == 3 and pivot_index(np.int64(6), 7) == 6
    with pytest.raises(InvalidInputError, match=r"pivot 7 is outside the burst \(frames 0..6\)"):
        pivot_index(7, 7)
    for bad in (True, 2.0, "1"):
        with pytest.raises(InvalidInputError, match="expected a frame index"):
            check_frame_index(bad, 7)
    with pytest.raises(InvalidInputError, match="frame -1 is outside the recording"):
        check_frame_index(-1, 7, "frame", within="the recording")


def test_output_files(tmp_path):
    assert check_output_file(tmp_path / "a.TIFF", (".tif", ".tiff")) == tmp_path / "a.TIFF"
    with pytest.raises(InvalidInputError, match="is a directory"):
        check_output_file(tmp_path)
    with pytest.raises(InvalidInputError, match="output folder does not exist"):
        check_output_file(tmp_path / "missing" / "a.h5")
    with pytest.raises(InvalidInputError, match=r"must end in \.h5 or \.hdf5"):
        check_output_file(tmp_path / "a.tiff", (".h5", ".hdf5"))


def test_parse_range():
    assert parse_range("10:40", "--a") == (10.0, 40.0)
    assert parse_range("40:10", "--a") == (40.0, 10.0)  # a falling range, unless increasing
    assert parse_range("10:70:10", "--a", step=True) == (10.0, 70.0, 10.0)
    with pytest.raises(InvalidInputError, match="A must be below B"):
        parse_range("40:10", "--a", increasing=True)
    with pytest.raises(InvalidInputError, match="expected A:B in °C"):
        parse_range("10", "--a")
    assert parse_range("70:10:10", "--a", step=True) == (70.0, 10.0, 10.0)  # falling
    with pytest.raises(InvalidInputError, match="STEP > 0"):
        parse_range("10:70:0", "--a", step=True)
