"""Tests for thermocal.io.chamber: the HDF5 chamber format, streaming writer and npz import."""

from __future__ import annotations

import os
import time

import h5py
import numpy as np
import pytest

from thermocal.errors import FileFormatError, InvalidInputError, ResolutionMismatchError
from thermocal.io.chamber import (
    CHAMBER_FORMAT,
    ChamberSession,
    ChamberWriter,
    LazyFrames,
    chamber_problems,
    iter_chamber_frames,
    read_chamber,
    validate_chamber,
    write_chamber,
)
from thermocal.io.envchamber import import_envchamberctrl_npz

M, H, W = 10, 8, 12


@pytest.fixture
def session():
    rng = np.random.default_rng(3)
    return ChamberSession(
        frames=rng.integers(0, 2**14, size=(M, H, W)).astype(np.uint16),
        blackbody_c=np.repeat([20.0, 40.0], M // 2),
        fpa_c=np.linspace(24.0, 26.0, M),
        time_s=np.arange(M) / 30.0,
        housing_c=np.linspace(25.0, 27.0, M),
        attrs={"unit": 3, "preset": "tau2", "seed": 7},
    )


def _names(directory):
    return sorted(p.name for p in directory.iterdir())


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _valid_file(path, m=M, **overrides):
    """Write a chamber file by hand with h5py, with datasets/attributes replaced or removed."""
    data = {
        "frames": np.zeros((m, H, W), np.uint16),
        "blackbody_c": np.full(m, 30.0),
        "fpa_c": np.full(m, 25.0),
        "time_s": np.arange(m, dtype=float),
    }
    attrs = {"format": CHAMBER_FORMAT, "version": 1, "bit_depth": 14}
    for key, value in overrides.items():
        target = attrs if key in attrs else data
        if value is None:
            target.pop(key)
        else:
            target[key] = value
    with h5py.File(path, "w") as f:
        for key, value in data.items():
            f[key] = value
        f.attrs.update(attrs)
    return path


# ------------------------------------------------------------------------------ session


def test_session_normalises(session):
    assert session.n_frames == M and session.frame_shape == (H, W)
    assert session.bit_depth == 14 and session.attrs["bit_depth"] == 14
    assert session.frames.dtype == np.uint16 and not session.frames.flags.writeable
    assert session.ambient_c is None


@pytest.mark.parametrize(
    ("changes", "err", "match"),
    [
        ({"fpa_c": np.full(M - 1, 25.0)}, InvalidInputError, "expected 10 values"),
        ({"time_s": np.full(M, np.inf)}, InvalidInputError, "NaN or infinite"),
        ({"blackbody_c": np.full(M, -280.0)}, InvalidInputError, "absolute zero"),
        ({"fpa_c": None}, InvalidInputError, "required"),
        ({"attrs": {"nested": {"a": 1}}}, InvalidInputError, "json.dumps"),
        ({"attrs": {"format": "other"}}, InvalidInputError, "format"),
        ({"attrs": {"version": 2}}, InvalidInputError, "version"),
        ({"frames": np.full((M, H, W), 2**14, np.uint16)}, InvalidInputError, "14-bit"),
        ({"frames": np.zeros((M, H, W), np.float32)}, InvalidInputError, "integers"),
    ],
)
def test_session_rejects(session, changes, err, match):
    fields = {
        "frames": session.frames,
        "blackbody_c": session.blackbody_c,
        "fpa_c": session.fpa_c,
        "time_s": session.time_s,
        "attrs": session.attrs,
    }
    fields.update(changes)
    with pytest.raises(err, match=match):
        ChamberSession(**fields)


# ------------------------------------------------------------------------------ round trips


def test_round_trip(tmp_path, session):
    out = write_chamber(tmp_path / "c.h5", session)
    assert out == tmp_path / "c.h5" and _names(tmp_path) == ["c.h5"]
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == CHAMBER_FORMAT
        assert f.attrs["version"] == 1 and f.attrs["bit_depth"] == 14
        assert f["frames"].dtype == np.uint16 and f["frames"].chunks == (1, H, W)
        assert f["fpa_c"].dtype == np.float64
        assert "ambient_c" not in f
    back = read_chamber(out)
    assert np.array_equal(back.frames, session.frames)
    for key in ("blackbody_c", "fpa_c", "time_s", "housing_c"):
        assert np.array_equal(getattr(back, key), getattr(session, key))
    assert back.ambient_c is None
    assert back.attrs == {"unit": 3, "preset": "tau2", "seed": 7, "bit_depth": 14}
    assert isinstance(back.attrs["unit"], int)


def test_attribute_types_round_trip(tmp_path, session):
    attrs = {"names": ["a", "bc"], "coeffs": np.arange(3.0), "flag": True, "x": 1.5, "seed": 2}
    s = ChamberSession(
        session.frames, session.blackbody_c, session.fpa_c, session.time_s, attrs=attrs
    )
    write_chamber(tmp_path / "a.h5", s)
    back = read_chamber(tmp_path / "a.h5").attrs
    assert back["names"] == ["a", "bc"] and back["flag"] is True and back["x"] == 1.5
    assert np.array_equal(back["coeffs"], [0.0, 1.0, 2.0]) and back["seed"] == 2
    write_chamber(tmp_path / "b.h5", read_chamber(tmp_path / "a.h5"))  # attrs as read re-write
    assert read_chamber(tmp_path / "b.h5").attrs["names"] == ["a", "bc"]


def test_read_lazy_frames(tmp_path, session):
    write_chamber(tmp_path / "c.h5", session)
    lazy = read_chamber(tmp_path / "c.h5", frames=False)
    assert isinstance(lazy.frames, LazyFrames)
    assert lazy.n_frames == M and lazy.frame_shape == (H, W)
    assert np.array_equal(lazy.frames[2], session.frames[2])
    assert np.array_equal(lazy.frames[3:6], session.frames[3:6])
    assert np.array_equal(lazy.frames[[5, 1, 5]], session.frames[[5, 1, 5]])
    # index arrays are read as runs of consecutive frames: runs, gaps, repeats, negative, empty
    for idx in ([0, 1, 2, 5, 6, M - 1], [3], [M - 1, 0, 1, 2], [-1, -2, 4, 4], []):
        got = lazy.frames[np.array(idx, dtype=np.int64)]
        assert got.shape == (len(idx), H, W) and got.dtype == np.uint16
        assert np.array_equal(got, session.frames[np.array(idx, dtype=np.int64)])
    mask = session.blackbody_c == 40.0
    assert np.array_equal(lazy.frames[mask], session.frames[mask])
    assert np.array_equal(np.asarray(lazy.frames), session.frames)
    assert not any(isinstance(v, h5py.HLObject) for v in vars(lazy.frames).values())


def test_rewrite_lazy_session_onto_its_own_file(tmp_path, session):
    path = tmp_path / "c.h5"
    write_chamber(path, session)
    write_chamber(path, read_chamber(path, frames=False))
    assert np.array_equal(read_chamber(path).frames, session.frames)
    assert _names(tmp_path) == ["c.h5"]


@pytest.mark.parametrize("chunk", [1, 4, 10, 256])
def test_iter_chamber_frames(tmp_path, session, chunk):
    write_chamber(tmp_path / "c.h5", session)
    blocks = list(iter_chamber_frames(tmp_path / "c.h5", chunk=chunk))
    assert [sl.start for sl, _ in blocks] == list(range(0, M, chunk))
    assert np.array_equal(np.concatenate([b for _, b in blocks]), session.frames)
    sl, block = blocks[0]
    assert len(session.fpa_c[sl]) == len(block)


def test_iter_chamber_frames_bad_chunk(tmp_path, session):
    write_chamber(tmp_path / "c.h5", session)
    with pytest.raises(InvalidInputError, match="chunk"):
        iter_chamber_frames(tmp_path / "c.h5", chunk=0)


# ------------------------------------------------------------------------------ writer


def test_writer_streams_blocks(tmp_path):
    with ChamberWriter(tmp_path / "s.h5", (H, W), attrs={"preset": "tau2"}) as writer:
        for i in range(3):
            block = np.full((4, H, W), 100 * i, np.uint16)
            writer.append(
                block,
                blackbody_c=20.0 + i,
                fpa_c=np.full(4, 25.0),
                time_s=np.arange(4) + 4.0 * i,
                ambient_c=22.0,
            )
        writer.append(np.full((H, W), 7, np.uint16), 30.0, 25.5, 12.0, ambient_c=[22.5])
        assert writer.n_frames == 13
        assert not (tmp_path / "s.h5").exists()  # written to a temporary file until the end
    s = read_chamber(tmp_path / "s.h5")
    assert s.n_frames == 13
    assert np.array_equal(s.blackbody_c, [20.0] * 4 + [21.0] * 4 + [22.0] * 4 + [30.0])
    assert np.array_equal(s.time_s, np.arange(13.0))
    assert s.ambient_c[-1] == 22.5 and s.housing_c is None
    assert s.frames[12, 0, 0] == 7 and s.attrs["preset"] == "tau2"
    assert _names(tmp_path) == ["s.h5"]


def test_writer_resolution_mismatch_leaves_nothing(tmp_path):
    with (
        pytest.raises(ResolutionMismatchError, match="12x8"),
        ChamberWriter(tmp_path / "s.h5", (H, W)) as writer,
    ):
        writer.append(np.zeros((2, H, W), np.uint16), 20.0, 25.0, [0.0, 1.0])
        writer.append(np.zeros((2, W, H), np.uint16), 20.0, 25.0, [2.0, 3.0])
    assert _names(tmp_path) == []


def test_writer_optional_series_must_be_consistent(tmp_path):
    with (
        pytest.raises(InvalidInputError, match="housing_c"),
        ChamberWriter(tmp_path / "s.h5", (H, W)) as writer,
    ):
        writer.append(np.zeros((1, H, W), np.uint16), 20.0, 25.0, 0.0, housing_c=26.0)
        writer.append(np.zeros((1, H, W), np.uint16), 20.0, 25.0, 1.0)
    assert _names(tmp_path) == []


def test_writer_rejects_bad_append_without_partial_write(tmp_path):
    with ChamberWriter(tmp_path / "s.h5", (H, W)) as writer:
        writer.append(np.zeros((2, H, W), np.uint16), 20.0, 25.0, [0.0, 1.0])
        with pytest.raises(InvalidInputError, match="time_s"):
            writer.append(np.zeros((2, H, W), np.uint16), 20.0, 25.0, [2.0])
        assert writer.n_frames == 2
    assert read_chamber(tmp_path / "s.h5").n_frames == 2


def test_writer_without_frames_writes_nothing(tmp_path):
    with (
        pytest.raises(InvalidInputError, match="no frames"),
        ChamberWriter(tmp_path / "s.h5", (H, W)),
    ):
        pass
    assert _names(tmp_path) == []


def test_failed_write_keeps_existing_file(tmp_path, session):
    path = tmp_path / "c.h5"
    write_chamber(path, session)
    before = path.read_bytes()
    with (
        pytest.raises(RuntimeError, match="camera unplugged"),
        ChamberWriter(path, (H, W)) as writer,
    ):
        writer.append(np.zeros((3, H, W), np.uint16), 20.0, 25.0, [0.0, 1.0, 2.0])
        raise RuntimeError("camera unplugged")
    assert path.read_bytes() == before
    assert _names(tmp_path) == ["c.h5"]


def test_append_outside_with_block(tmp_path):
    writer = ChamberWriter(tmp_path / "s.h5", (H, W))
    with pytest.raises(RuntimeError, match="with"):
        writer.append(np.zeros((1, H, W), np.uint16), 20.0, 25.0, 0.0)


@pytest.mark.parametrize("shape", [(0, 4), (4,), "big"])
def test_writer_bad_frame_shape(tmp_path, shape):
    with pytest.raises(InvalidInputError, match="frame_shape"):
        ChamberWriter(tmp_path / "s.h5", shape)


def test_writer_compression(tmp_path, session):
    write_chamber(tmp_path / "z.h5", session, compression="gzip")
    with h5py.File(tmp_path / "z.h5", "r") as f:
        assert f["frames"].compression == "gzip"
    assert np.array_equal(read_chamber(tmp_path / "z.h5").frames, session.frames)


def test_writer_full_size_blocks_are_fast(tmp_path):
    """300 frames of 256x336 in blocks of 100 (the 10,000-frame case is test_writer_10k)."""
    block = np.random.default_rng(0).integers(0, 2**14, (100, 256, 336)).astype(np.uint16)
    start = time.perf_counter()
    with ChamberWriter(tmp_path / "big.h5", (256, 336)) as writer:
        for i in range(3):
            writer.append(block, 30.0, 25.0, np.arange(100) + 100.0 * i)
    assert time.perf_counter() - start < 5.0
    assert read_chamber(tmp_path / "big.h5", frames=False).n_frames == 300


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("THERMOCAL_SLOW"), reason="set THERMOCAL_SLOW=1 (1.7 GB)")
def test_writer_10k(tmp_path):
    block = np.random.default_rng(0).integers(0, 2**14, (100, 256, 336)).astype(np.uint16)
    start = time.perf_counter()
    with ChamberWriter(tmp_path / "big.h5", (256, 336)) as writer:
        for i in range(100):
            writer.append(block, 30.0, 25.0, np.arange(100) + 100.0 * i)
    assert time.perf_counter() - start < 60.0
    assert read_chamber(tmp_path / "big.h5", frames=False).n_frames == 10_000


# ------------------------------------------------------------------------------ validation


def test_truncated_hdf5(tmp_path, session):
    path = tmp_path / "c.h5"
    write_chamber(path, session)
    _truncate(path)
    with pytest.raises(FileFormatError, match="truncated"):
        validate_chamber(path)
    with pytest.raises(FileFormatError, match="truncated"):
        read_chamber(path)
    with pytest.raises(FileFormatError, match="truncated"):
        iter_chamber_frames(path)


def test_not_hdf5(tmp_path):
    (tmp_path / "x.h5").write_bytes(b"plain text")
    with pytest.raises(FileFormatError, match="not a readable HDF5"):
        read_chamber(tmp_path / "x.h5")
    with pytest.raises(FileFormatError, match="no such file"):
        read_chamber(tmp_path / "missing.h5")


def test_valid_hand_written_file(tmp_path):
    path = _valid_file(tmp_path / "v.h5")
    assert chamber_problems(path) == []
    validate_chamber(path)
    assert read_chamber(path).n_frames == M


@pytest.mark.parametrize(
    ("overrides", "problem"),
    [
        ({"frames": None}, "dataset 'frames' is missing"),
        ({"fpa_c": None}, "dataset 'fpa_c' is missing"),
        ({"format": None}, "attribute 'format' is missing"),
        ({"format": "flir"}, "attribute 'format' is 'flir'"),
        ({"version": 2}, "unsupported version 2"),
        ({"bit_depth": None}, "attribute 'bit_depth' is missing"),
        ({"time_s": np.arange(M - 1.0)}, "'time_s' has 9 values but 'frames' has 10 frames"),
        ({"frames": np.zeros((M, H, W), np.float32)}, "'frames' has dtype float32"),
        ({"blackbody_c": np.arange(M)}, "'blackbody_c' has dtype int64, expected float"),
        ({"housing_c": np.full(M, np.nan)}, "'housing_c' holds 10 NaN"),
        ({"fpa_c": np.full(M, -300.0)}, "'fpa_c' holds temperatures at or below"),
    ],
)
def test_validate_names_the_problem(tmp_path, overrides, problem):
    path = _valid_file(tmp_path / "v.h5", **overrides)
    with pytest.raises(FileFormatError, match=problem) as info:
        validate_chamber(path)
    assert str(info.value).startswith(str(path))
    assert "\n" not in str(info.value)
    with pytest.raises(FileFormatError):
        read_chamber(path)


def test_validate_lists_every_problem(tmp_path):
    path = _valid_file(
        tmp_path / "v.h5", format=None, fpa_c=None, time_s=np.full(3, np.nan), version=5
    )
    problems = chamber_problems(path)
    assert len(problems) == 5  # format, version, fpa_c missing, time_s length, time_s NaN
    with pytest.raises(FileFormatError, match=r"\(and 4 other problems\)") as info:
        validate_chamber(path)
    assert info.value.problems == problems


def test_counts_above_bit_depth_in_file(tmp_path):
    frames = np.zeros((M, H, W), np.uint16)
    frames[-1, 0, 0] = 20000
    path = _valid_file(tmp_path / "v.h5", frames=frames)
    with pytest.raises(FileFormatError, match="14-bit"):
        read_chamber(path)
    assert read_chamber(path, frames=False).n_frames == M  # counts not read lazily
    blocks = iter_chamber_frames(path, chunk=5)
    next(blocks)
    with pytest.raises(FileFormatError, match=f"frame {M - 1} holds counts above the 14-bit "
                       "maximum 16383: .* bit_depth attribute"):
        next(blocks)


# ------------------------------------------------------------------------------ npz import


def _npz(path, **arrays):
    np.savez(path, **arrays)
    return path


@pytest.fixture
def npz_arrays():
    t0 = 1_700_000_000_123_456_789  # an epoch time stamp in ns
    return {
        "frames": np.arange(4 * H * W, dtype=np.uint16).reshape(4, H, W),
        "fpa": np.array([2534, 2535, 2600, 2601], dtype=np.uint16),
        "housing": np.array([3000, 3001, 3002, 3003], dtype=np.uint16),
        "blackbody": np.array([1000, 1000, 4550, 4550], dtype=np.uint16),
        "time_ns": np.array([t0, t0 + 16_666_667, t0 + 33_333_333, t0 + 1_000_000_000]),
    }


def test_import_envchamberctrl_known_values(tmp_path, npz_arrays):
    s = import_envchamberctrl_npz(_npz(tmp_path / "run.npz", **npz_arrays))
    assert np.array_equal(s.frames, npz_arrays["frames"])
    np.testing.assert_allclose(s.fpa_c, [25.34, 25.35, 26.00, 26.01], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.housing_c, [30.00, 30.01, 30.02, 30.03], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.blackbody_c, [10.0, 10.0, 45.5, 45.5], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.time_s, [0.0, 0.016666667, 0.033333333, 1.0], rtol=0, atol=1e-12)
    assert s.ambient_c is None
    assert s.attrs["source"] == "EnvChamberCtrl" and s.attrs["source_file"] == "run.npz"
    assert s.attrs["time_origin_ns"] == npz_arrays["time_ns"][0]
    # and it survives a trip through the chamber format
    write_chamber(tmp_path / "run.h5", s)
    back = read_chamber(tmp_path / "run.h5")
    assert np.array_equal(back.fpa_c, s.fpa_c)
    assert back.attrs["time_origin_ns"] == s.attrs["time_origin_ns"]


def test_import_negative_temperatures_wrapped_in_uint16(tmp_path, npz_arrays):
    npz_arrays["fpa"] = np.array([-500, -1, 0, 250]).astype(np.uint16)
    s = import_envchamberctrl_npz(_npz(tmp_path / "cold.npz", **npz_arrays))
    np.testing.assert_allclose(s.fpa_c, [-5.0, -0.01, 0.0, 2.5])


def test_import_without_time_needs_frame_rate(tmp_path, npz_arrays):
    del npz_arrays["time_ns"], npz_arrays["housing"]
    path = _npz(tmp_path / "old.npz", **npz_arrays)
    with pytest.raises(FileFormatError, match="frame_rate_hz"):
        import_envchamberctrl_npz(path)
    s = import_envchamberctrl_npz(path, frame_rate_hz=60.0)
    np.testing.assert_allclose(s.time_s, np.arange(4) / 60.0)
    assert s.housing_c is None


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"fpa": None}, r"missing array\(s\) \['fpa'\]"),
        ({"fpa": np.array([25340, 25350, 26000, 26010], dtype=np.int32)}, "1/100"),
        ({"blackbody": np.array([1000, 1000, 4550])}, "expected 4 values"),
        ({"frames": np.full((4, H, W), 40000, np.uint16)}, "14-bit"),
        ({"time_ns": np.linspace(0, 1, 4)}, "time_ns"),
    ],
)
def test_import_rejects(tmp_path, npz_arrays, change, match):
    for key, value in change.items():
        if value is None:
            npz_arrays.pop(key)
        else:
            npz_arrays[key] = value
    with pytest.raises(FileFormatError, match=match):
        import_envchamberctrl_npz(_npz(tmp_path / "bad.npz", **npz_arrays))


def test_import_not_npz(tmp_path):
    (tmp_path / "x.npz").write_bytes(b"not a zip")
    with pytest.raises(FileFormatError, match="npz"):
        import_envchamberctrl_npz(tmp_path / "x.npz")
    np.save(tmp_path / "y.npy", np.zeros(3))
    with pytest.raises(FileFormatError, match="single .npy"):
        import_envchamberctrl_npz(tmp_path / "y.npy")
    with pytest.raises(FileFormatError, match="no such file"):
        import_envchamberctrl_npz(tmp_path / "missing.npz")


@pytest.mark.parametrize("layout", ["written", "contiguous", "gzip", "two frames a chunk"])
def test_frames_are_read_where_they_lie_else_through_h5py(tmp_path, session, layout):
    """Frames stored uncompressed little-endian (as ChamberWriter writes them, or contiguous)
    are read at their file offsets; any other layout through h5py; the same frames either way."""
    from thermocal.io.chamber import frame_offsets

    path = tmp_path / "c.h5"
    if layout in ("written", "gzip"):
        write_chamber(path, session, **({"compression": "gzip"} if layout == "gzip" else {}))
    else:
        _valid_file(path, frames=session.frames)
        if layout != "contiguous":
            with h5py.File(path, "r+") as f:
                del f["frames"]
                f.create_dataset("frames", data=session.frames, chunks=(2, H, W))
    with h5py.File(path, "r") as f:
        offsets = frame_offsets(f["frames"], path.stat().st_size)
    assert (offsets is not None) == (layout in ("written", "contiguous"))
    if offsets is not None:  # an independent reading of the bytes at those offsets
        for i in (0, M // 2, M - 1):
            raw = np.fromfile(path, dtype="<u2", count=H * W, offset=int(offsets[i]))
            assert np.array_equal(raw.reshape(H, W), session.frames[i])
    lazy = read_chamber(path, frames=False).frames
    for idx in ([4, 1, 1, 9], [], list(range(M)), [-1]):
        assert np.array_equal(lazy[np.array(idx, dtype=np.int64)],
                              session.frames[np.array(idx, dtype=np.int64)])
    assert np.array_equal(lazy[2:7], session.frames[2:7])
    assert np.array_equal(lazy[::3], session.frames[::3])
    for idx, rows in (([7, 2, 2], [0, 1, 2, 5, H - 1]), ([0], [3]), ([], [1, 2])):
        assert np.array_equal(lazy.read_rows(idx, rows),
                              session.frames[np.array(idx, dtype=np.int64)][:, rows])
    with pytest.raises(IndexError, match="rows must increase"):
        lazy.read_rows([0], [2, 1])


def test_a_file_cut_after_its_layout_was_read_is_refused(tmp_path, session):
    path = write_chamber(tmp_path / "c.h5", session) or tmp_path / "c.h5"
    lazy = read_chamber(path, frames=False).frames
    assert np.array_equal(lazy[[0, 5]], session.frames[[0, 5]])  # offsets found and kept
    size = path.stat().st_size
    with open(path, "r+b") as f:
        f.truncate(size - H * W)  # the last frame is cut
    with pytest.raises(FileFormatError, match=str(path.name)):
        lazy[[M - 1]]
