"""Tests for thermocal.io.recording: recordings (TIFF + sidecar) and temperature TIFFs."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tifffile

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.recording import (
    Recording,
    iter_recording,
    read_recording,
    read_temperature_tiff,
    sidecar_path,
    write_recording,
    write_temperature_tiff,
)

N, H, W = 7, 12, 16


@pytest.fixture
def frames():
    rng = np.random.default_rng(1)
    return rng.integers(0, 2**14, size=(N, H, W)).astype(np.uint16)


@pytest.fixture
def rec(frames):
    return Recording(
        frames,
        fpa_c=np.linspace(25.0, 26.0, N),
        time_s=np.arange(N) / 30.0,
        housing_c=np.full(N, 27.5),
        extra={"pivot": 3, "scene": "procedural"},
    )


def _names(directory):
    return sorted(p.name for p in directory.iterdir())


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


# ------------------------------------------------------------------------------ Recording


def test_recording_validates_and_normalises(frames):
    rec = Recording(frames.astype(np.int32), fpa_c=[25.0] * N)
    assert rec.frames.dtype == np.uint16
    assert rec.fpa_c.dtype == np.float64
    assert rec.n_frames == N and rec.frame_shape == (H, W)
    assert rec.time_s is None and rec.bit_depth == 14 and rec.extra == {}
    with pytest.raises(ValueError):
        rec.frames[0, 0, 0] = 1  # read-only view


def test_recording_does_not_modify_or_lock_inputs(frames):
    before = frames.copy()
    fpa = np.full(N, 25.0)
    Recording(frames, fpa_c=fpa)
    assert np.array_equal(frames, before)
    assert frames.flags.writeable and fpa.flags.writeable


def test_recording_single_frame_becomes_n1(frames):
    rec = Recording(frames[0], fpa_c=[25.0])
    assert rec.frames.shape == (1, H, W)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"fpa_c": np.full(N - 1, 25.0)}, "expected 7 values"),
        ({"time_s": np.full(N, np.nan)}, "NaN"),
        ({"ambient_c": np.full(N, -300.0)}, "absolute zero"),
        ({"housing_c": np.full((N, 2), 25.0)}, "1-D"),
        ({"extra": {"fpa_c": 1}}, "reserved"),
        ({"bit_depth": 17}, "between 1 and 16"),
    ],
)
def test_recording_rejects_bad_metadata(frames, kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        Recording(frames, **kwargs)


def test_recording_rejects_counts_above_bit_depth(frames):
    bad = frames.copy()
    bad[0, 0, 0] = 2**14
    with pytest.raises(InvalidInputError, match="14-bit"):
        Recording(bad)
    assert Recording(bad, bit_depth=16).bit_depth == 16


def test_recording_rejects_float_frames(frames):
    with pytest.raises(InvalidInputError, match="integers"):
        Recording(frames.astype(np.float32))


# ------------------------------------------------------------------------------ round trips


def test_round_trip(tmp_path, rec):
    tiff, js = write_recording(tmp_path / "frames.tiff", rec)
    assert (tiff, js) == (tmp_path / "frames.tiff", tmp_path / "frames.json")
    assert _names(tmp_path) == ["frames.json", "frames.tiff"]
    side = json.loads(js.read_text())
    assert set(side) == {"fpa_c", "time_s", "housing_c", "bit_depth", "pivot", "scene"}
    assert side["bit_depth"] == 14 and len(side["fpa_c"]) == N
    with tifffile.TiffFile(tiff) as tif:
        assert len(tif.pages) == N  # one page per frame
        assert tif.pages[0].dtype == np.uint16
    back = read_recording(tiff)
    assert np.array_equal(back.frames, rec.frames)
    assert back.frames.dtype == np.uint16
    for key in ("fpa_c", "time_s", "housing_c"):
        assert np.array_equal(getattr(back, key), getattr(rec, key))
    assert back.ambient_c is None
    assert back.extra == {"pivot": 3, "scene": "procedural"}


def test_round_trip_single_frame(tmp_path, frames):
    write_recording(tmp_path / "one.tiff", Recording(frames[:1]))
    back = read_recording(tmp_path / "one.tiff")
    assert back.frames.shape == (1, H, W)
    assert np.array_equal(back.frames, frames[:1])


def test_read_without_sidecar(tmp_path, frames):
    tifffile.imwrite(tmp_path / "raw.tiff", frames, photometric="minisblack")
    rec = read_recording(tmp_path / "raw.tiff")
    assert np.array_equal(rec.frames, frames)
    assert rec.fpa_c is None and rec.time_s is None and rec.bit_depth == 14


def test_read_2d_tiff_is_one_frame(tmp_path, frames):
    tifffile.imwrite(tmp_path / "f.tiff", frames[0])
    assert read_recording(tmp_path / "f.tiff").frames.shape == (1, H, W)


def test_read_generic_multipage_tiff(tmp_path, frames):
    with tifffile.TiffWriter(tmp_path / "g.tiff") as tw:
        for frame in frames:
            tw.write(frame, metadata=None, compression="zlib")
    assert np.array_equal(read_recording(tmp_path / "g.tiff").frames, frames)


def test_fpa_override_replaces_series(tmp_path, rec):
    write_recording(tmp_path / "r.tiff", rec)
    back = read_recording(tmp_path / "r.tiff", fpa_c=31.5)
    assert np.array_equal(back.fpa_c, np.full(N, 31.5))
    assert np.array_equal(back.time_s, rec.time_s)


def test_fpa_override_without_sidecar(tmp_path, frames):
    tifffile.imwrite(tmp_path / "raw.tiff", frames)
    assert np.array_equal(read_recording(tmp_path / "raw.tiff", fpa_c=20).fpa_c, np.full(N, 20.0))


@pytest.mark.parametrize("bad", [float("nan"), -300.0, "warm"])
def test_fpa_override_must_be_a_temperature(tmp_path, rec, bad):
    write_recording(tmp_path / "r.tiff", rec)
    with pytest.raises(InvalidInputError):
        read_recording(tmp_path / "r.tiff", fpa_c=bad)


# ------------------------------------------------------------------------------ bad sidecars


def _edit_sidecar(path, **changes):
    js = sidecar_path(path)
    side = json.loads(js.read_text())
    side.update(changes)
    js.write_text(json.dumps(side))


def test_sidecar_length_mismatch(tmp_path, rec):
    write_recording(tmp_path / "r.tiff", rec)
    _edit_sidecar(tmp_path / "r.tiff", time_s=[0.0, 1.0])
    with pytest.raises(FileFormatError, match="'time_s' has 2 values but the recording has 7"):
        read_recording(tmp_path / "r.tiff")


def test_sidecar_fpa_mismatch_is_ignored_under_override(tmp_path, rec):
    write_recording(tmp_path / "r.tiff", rec)
    _edit_sidecar(tmp_path / "r.tiff", fpa_c=[1.0])
    with pytest.raises(FileFormatError, match="fpa_c"):
        read_recording(tmp_path / "r.tiff")
    assert read_recording(tmp_path / "r.tiff", fpa_c=25.0).fpa_c[0] == 25.0


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"fpa_c": [None] * N}, "list of numbers"),
        ({"housing_c": "hot"}, "list of numbers"),
        ({"bit_depth": 99}, "between 1 and 16"),
    ],
)
def test_sidecar_bad_values(tmp_path, rec, changes, match):
    write_recording(tmp_path / "r.tiff", rec)
    _edit_sidecar(tmp_path / "r.tiff", **changes)
    with pytest.raises(FileFormatError, match=match):
        read_recording(tmp_path / "r.tiff")


def test_sidecar_not_json(tmp_path, rec):
    write_recording(tmp_path / "r.tiff", rec)
    sidecar_path(tmp_path / "r.tiff").write_text("{not json")
    with pytest.raises(FileFormatError, match="not valid JSON"):
        read_recording(tmp_path / "r.tiff")


def test_sidecar_with_a_byte_order_mark_reads_and_a_key_twice_is_refused(tmp_path, rec):
    """A sidecar saved with a UTF-8 byte-order mark (a Windows editor) reads as without it (it
    said "decode using utf-8-sig"); a key given twice is refused, naming it (JSON took the last
    silently: which FPA did the user mean?)."""
    write_recording(tmp_path / "r.tiff", rec)
    side = sidecar_path(tmp_path / "r.tiff")
    text = side.read_text(encoding="utf-8")
    side.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    np.testing.assert_array_equal(read_recording(tmp_path / "r.tiff").fpa_c, rec.fpa_c)
    side.write_text(text.replace("{", '{"fpa_c": [1, 2], ', 1), encoding="utf-8")
    with pytest.raises(FileFormatError, match="the key 'fpa_c' is given twice"):
        read_recording(tmp_path / "r.tiff")


def test_sidecar_bit_depth_allows_wider_counts(tmp_path, frames):
    wide = frames.copy()
    wide[0, 0, 0] = 60000
    tifffile.imwrite(tmp_path / "w.tiff", wide)
    with pytest.raises(FileFormatError, match="14-bit"):
        read_recording(tmp_path / "w.tiff")
    (tmp_path / "w.json").write_text('{"bit_depth": 16}')
    assert read_recording(tmp_path / "w.tiff").frames[0, 0, 0] == 60000


# ------------------------------------------------------------------------------ bad TIFFs


def test_truncated_tiff(tmp_path, rec):
    write_recording(tmp_path / "r.tiff", rec)
    _truncate(tmp_path / "r.tiff")
    with pytest.raises(FileFormatError, match="truncated"):
        read_recording(tmp_path / "r.tiff")
    with pytest.raises(FileFormatError, match="truncated"):
        iter_recording(tmp_path / "r.tiff")


def test_truncated_generic_tiff(tmp_path, frames):
    with tifffile.TiffWriter(tmp_path / "g.tiff") as tw:
        for frame in frames:
            tw.write(frame, metadata=None)
    data = (tmp_path / "g.tiff").read_bytes()
    (tmp_path / "g.tiff").write_bytes(data[:-40])  # cut into the last page's data
    with pytest.raises(FileFormatError):
        read_recording(tmp_path / "g.tiff")


def test_garbage_file(tmp_path):
    (tmp_path / "x.tiff").write_bytes(b"this is not a tiff at all")
    with pytest.raises(FileFormatError, match="not a readable TIFF"):
        read_recording(tmp_path / "x.tiff")


def test_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="no such file"):
        read_recording(tmp_path / "missing.tiff")


@pytest.mark.parametrize("dtype", [np.float32, np.uint8, np.int16])
def test_non_uint16_tiff(tmp_path, frames, dtype):
    tifffile.imwrite(tmp_path / "f.tiff", (frames % 100).astype(dtype))
    with pytest.raises(FileFormatError, match="expected uint16"):
        read_recording(tmp_path / "f.tiff")


def test_rgb_tiff(tmp_path):
    tifffile.imwrite(tmp_path / "rgb.tiff", np.zeros((H, W, 3), np.uint16), photometric="rgb")
    with pytest.raises(FileFormatError, match="colour"):
        read_recording(tmp_path / "rgb.tiff")


# ------------------------------------------------------------------------------ atomic writes


def test_failed_write_leaves_nothing(tmp_path, rec, monkeypatch):
    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(tifffile.TiffWriter, "write", fail)
    with pytest.raises(OSError, match="disk full"):
        write_recording(tmp_path / "r.tiff", rec)
    assert _names(tmp_path) == []


def test_failed_write_keeps_existing_recording(tmp_path, rec, frames, monkeypatch):
    write_recording(tmp_path / "r.tiff", rec)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(tifffile.TiffWriter, "write", fail)
    with pytest.raises(OSError):
        write_recording(tmp_path / "r.tiff", Recording(frames[:2]))
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_unserialisable_extra_writes_nothing(tmp_path, frames):
    with pytest.raises(InvalidInputError, match="JSON"):
        write_recording(tmp_path / "r.tiff", Recording(frames, extra={"x": object()}))
    assert _names(tmp_path) == []


def test_write_needs_tiff_name(tmp_path, rec):
    with pytest.raises(InvalidInputError, match=".tiff"):
        write_recording(tmp_path / "r.png", rec)


# ------------------------------------------------------------------------------ iteration


@pytest.mark.parametrize("chunk", [1, 3, 7, 64])
def test_iter_recording_chunks(tmp_path, rec, chunk):
    write_recording(tmp_path / "r.tiff", rec)
    blocks = list(iter_recording(tmp_path / "r.tiff", chunk=chunk))
    assert [start for start, _ in blocks] == list(range(0, N, chunk))
    assert all(b.dtype == np.uint16 and b.ndim == 3 for _, b in blocks)
    assert np.array_equal(np.concatenate([b for _, b in blocks]), rec.frames)
    assert all(not isinstance(b, np.memmap) and b.flags.writeable for _, b in blocks)


@pytest.mark.parametrize("start", [0, 1, 4, N - 1, N])
def test_iter_recording_from_a_frame(tmp_path, rec, frames, start):
    """From frame ``start`` on, memory-mapped and page by page: the same frames, numbered in
    the recording."""
    write_recording(tmp_path / "r.tiff", rec)
    with tifffile.TiffWriter(tmp_path / "g.tiff") as tw:
        for frame in frames:
            tw.write(frame, metadata=None, compression="zlib")
    for path, data in ((tmp_path / "r.tiff", rec.frames), (tmp_path / "g.tiff", frames)):
        blocks = list(iter_recording(path, chunk=3, start=start))
        assert [s for s, _ in blocks] == list(range(start, len(data), 3))
        got = np.concatenate([b for _, b in blocks]) if blocks else data[:0]
        np.testing.assert_array_equal(got, data[start:])
    with pytest.raises(InvalidInputError, match="start"):
        iter_recording(tmp_path / "r.tiff", start=-1)


def test_iter_recording_generic_pages(tmp_path, frames):
    with tifffile.TiffWriter(tmp_path / "g.tiff") as tw:
        for frame in frames:
            tw.write(frame, metadata=None, compression="zlib")
    blocks = list(iter_recording(tmp_path / "g.tiff", chunk=3))
    assert [s for s, _ in blocks] == [0, 3, 6]
    assert np.array_equal(np.concatenate([b for _, b in blocks]), frames)


def test_iter_recording_single_frame(tmp_path, frames):
    tifffile.imwrite(tmp_path / "f.tiff", frames[0])
    [(start, block)] = list(iter_recording(tmp_path / "f.tiff"))
    assert start == 0 and block.shape == (1, H, W)


def test_iter_recording_checks_counts(tmp_path, frames):
    wide = frames.copy()
    wide[-1, 0, 0] = 20000
    tifffile.imwrite(tmp_path / "w.tiff", wide)
    it = iter_recording(tmp_path / "w.tiff", chunk=4)
    assert next(it)[0] == 0
    with pytest.raises(FileFormatError, match=r"frame 6 holds counts above the 14-bit maximum "
                       r"16383: .*\"bit_depth\": 16 in w.json"):
        next(it)


@pytest.mark.parametrize("chunk", [0, -1, 2.5, True])
def test_iter_recording_bad_chunk(tmp_path, rec, chunk):
    write_recording(tmp_path / "r.tiff", rec)
    with pytest.raises(InvalidInputError, match="chunk"):
        iter_recording(tmp_path / "r.tiff", chunk=chunk)


def test_iter_recording_rejects_float_tiff(tmp_path):
    write_temperature_tiff(tmp_path / "t.tiff", np.full((2, H, W), 20.0))
    with pytest.raises(FileFormatError, match="uint16"):
        iter_recording(tmp_path / "t.tiff")


# ------------------------------------------------------------------------------ temperatures


@pytest.mark.parametrize("shape", [(H, W), (3, H, W), (1, H, W)])
def test_temperature_round_trip(tmp_path, shape):
    temps = np.random.default_rng(2).normal(25.0, 3.0, size=shape)
    write_temperature_tiff(tmp_path / "t.tiff", temps)
    back = read_temperature_tiff(tmp_path / "t.tiff")
    assert back.dtype == np.float32 and back.shape == shape
    np.testing.assert_allclose(back, temps.astype(np.float32))


def test_temperature_tiff_rejects_nan_and_writes_nothing(tmp_path):
    temps = np.full((H, W), 25.0)
    temps[1, 1] = np.nan
    with pytest.raises(InvalidInputError, match="NaN"):
        write_temperature_tiff(tmp_path / "t.tiff", temps)
    assert _names(tmp_path) == []


def test_temperature_tiff_rejects_bad_shape(tmp_path):
    with pytest.raises(InvalidInputError, match="2-D or 3-D"):
        write_temperature_tiff(tmp_path / "t.tiff", np.zeros(5))


def test_read_temperature_tiff_rejects_counts(tmp_path, frames):
    tifffile.imwrite(tmp_path / "c.tiff", frames)
    with pytest.raises(FileFormatError, match="float temperatures"):
        read_temperature_tiff(tmp_path / "c.tiff")


def test_read_temperature_tiff_rejects_nan(tmp_path):
    data = np.full((H, W), 20.0, np.float32)
    data[0, 0] = np.nan
    tifffile.imwrite(tmp_path / "n.tiff", data)
    with pytest.raises(FileFormatError, match="NaN"):
        read_temperature_tiff(tmp_path / "n.tiff")


def test_read_temperature_tiff_truncated(tmp_path):
    write_temperature_tiff(tmp_path / "t.tiff", np.full((4, H, W), 20.0))
    _truncate(tmp_path / "t.tiff")
    with pytest.raises(FileFormatError):
        read_temperature_tiff(tmp_path / "t.tiff")


def test_recording_writer_streams_chunks(tmp_path):
    from thermocal.io.recording import RecordingWriter, iter_recording

    rng = np.random.default_rng(0)
    chunks = [rng.integers(0, 16384, (k, 12, 16), dtype=np.uint16) for k in (3, 5, 1)]
    path = tmp_path / "s.tiff"
    with RecordingWriter(path, extra={"pivot": 4}) as writer:
        t = 0.0
        for c in chunks:
            writer.append(c, fpa_c=np.full(len(c), 30.0), time_s=t + np.arange(len(c)))
            t += len(c)
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.frames, np.concatenate(chunks))
    np.testing.assert_array_equal(rec.time_s, np.arange(9.0))
    assert rec.extra["pivot"] == 4 and rec.housing_c is None
    starts = [start for start, _ in iter_recording(path, chunk=4)]
    assert starts == [0, 4, 8]


@pytest.mark.parametrize("second", [
    {"frames": np.zeros((2, 12, 16), np.uint16)},  # fpa_c missing in the second chunk
    {"frames": np.zeros((2, 10, 16), np.uint16), "fpa_c": [30.0, 30.0]},  # other size
    {"frames": np.full((2, 12, 16), 20000, np.uint16), "fpa_c": [30.0, 30.0]},  # > 14 bits
])
def test_recording_writer_rejects_inconsistent_chunks_and_writes_nothing(tmp_path, second):
    from thermocal.io.recording import RecordingWriter

    path = tmp_path / "s.tiff"
    with pytest.raises(InvalidInputError), RecordingWriter(path) as writer:
        writer.append(np.zeros((2, 12, 16), np.uint16), fpa_c=[30.0, 30.0])
        writer.append(**second)
    assert list(tmp_path.iterdir()) == []


def test_recording_writer_without_frames_writes_nothing(tmp_path):
    from thermocal.io.recording import RecordingWriter

    with pytest.raises(InvalidInputError, match="no frames"), RecordingWriter(tmp_path / "e.tiff"):
        pass
    assert list(tmp_path.iterdir()) == []


def test_quiet_tifffile_restores_the_logger_after_overlapping_reads():
    """Two reads in two threads inside quiet_tifffile, the first leaving first: the logger
    passes records up again once both have left (each restoring its own saved state left it
    silenced for good), and stays quiet while either is inside."""
    import logging
    import threading

    from thermocal.io.recording import quiet_tifffile

    logger = logging.getLogger("tifffile")
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen = []

    def first() -> None:
        with quiet_tifffile():
            a_in.set()
            b_in.wait(5)
        a_out.set()

    def second() -> None:
        a_in.wait(5)
        with quiet_tifffile():
            b_in.set()
            a_out.wait(5)
            seen.append(logger.propagate)

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert seen == [False] and logger.propagate
    assert not any(isinstance(h, logging.NullHandler) for h in logger.handlers)
