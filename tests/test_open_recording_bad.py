"""Bad input and damaged frames in the recordings any command takes (issue 19).

Bad input (a recording that cannot be read as a whole): one line, exit status 2, no traceback,
nothing written, through ``thermocal info``, ``estimate`` and ``flight``. Damaged frames (some
records or files of a recording): left out, named in one warning line, listed by ``info`` and
in ``RecordingSource.damaged``.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_run import run
from PIL import Image
from test_bad_input_cli import assert_refused
from test_open_recording import _dji_xmp, _dualtau_file, _fff, _frames, _rjpeg

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.open import open_recording, open_stream, read_any_recording

T0 = 1_700_000_000_000_000_000


def _undecodable(record: bytes) -> bytes:
    """A JPEG-LS record whose compressed image is damaged inside (its markers intact)."""
    bad = bytearray(record)
    end = bad.rfind(b"\xff\xd9")
    bad[end - 40 : end] = b"\x00" * 40
    return bytes(bad)


def _seq(path: Path, n: int, *, ms=None, codec: str = "plain") -> list[bytes]:
    records = [_fff(fr, codec=codec, ms=(40 * k if ms is None else ms[k]))
               for k, fr in enumerate(_frames(n, h=40, w=48) + 9000)]
    path.write_bytes(b"".join(records))
    return records


# --------------------------------------------------------------------------------------------
# bad input: the table
# --------------------------------------------------------------------------------------------
def _only_record_truncated(d: Path) -> Path:
    (d / "cut.seq").write_bytes(_fff(_frames(1)[0])[:-50])
    return d / "cut.seq"


def _all_records_corrupt(d: Path) -> Path:
    (d / "bad.seq").write_bytes((b"FFF\x00" + b"\xff" * 200) * 3)
    return d / "bad.seq"


def _jpeg_without_flir(d: Path) -> Path:
    Image.new("RGB", (8, 8)).save(d / "photo.jpg", "JPEG")
    return d / "photo.jpg"


def _rjpeg_raw_does_not_decode(d: Path) -> Path:
    rec = _undecodable(_fff(_frames(1, h=40, w=48)[0], codec="jpegls"))
    (d / "bad.jpg").write_bytes(_rjpeg(rec))
    return d / "bad.jpg"


def _folder_mixed_sizes(d: Path) -> Path:
    (d / "f").mkdir()
    (d / "f" / "a.fff").write_bytes(_fff(_frames(1)[0]))
    (d / "f" / "b.fff").write_bytes(_fff(_frames(1, 4, 4)[0]))
    return d / "f"


def _folder_mixed_formats(d: Path) -> Path:
    (d / "f").mkdir()
    (d / "f" / "a.fff").write_bytes(_fff(_frames(1)[0]))
    (d / "f" / "b.jpg").write_bytes(_rjpeg(_fff(_frames(1)[0])))
    return d / "f"


def _folder_empty(d: Path) -> Path:
    (d / "f").mkdir()
    (d / "f" / "notes.txt").write_text("nothing here")
    return d / "f"


def _folder_of_unreadable_files(d: Path) -> Path:
    (d / "f").mkdir()
    for name in ("a.jpg", "b.jpg"):
        (d / "f" / name).write_bytes(b"")
    return d / "f"


def _npz_missing_keys(d: Path) -> Path:
    np.savez(d / "a.npz", frames=_frames(3), time_ns_start=np.arange(3))
    return d / "a.npz"


def _npz_fpa_in_no_unit(d: Path) -> Path:
    _dualtau_file(d / "a.npz", _frames(3), np.zeros(3), T0)
    np.savez(d / "a.npz", frames=_frames(3), fpa=np.full(3, 1e7),
             time_ns_start=T0 + np.arange(3))
    return d / "a.npz"


def _npz_fpa_whole_degrees(d: Path) -> Path:
    np.savez(d / "a.npz", frames=_frames(3), fpa=np.full(3, 31, np.int64),
             time_ns_start=T0 + np.arange(3))
    return d / "a.npz"


def _npz_times_backwards(d: Path) -> Path:
    np.savez(d / "a.npz", frames=_frames(3), fpa=np.full(3, 3000, np.uint16),
             time_ns_start=T0 + np.array([0, 200, 100]))
    return d / "a.npz"


def _npz_files_overlap(d: Path) -> Path:
    (d / "f").mkdir()
    _dualtau_file(d / "f" / "a.npz", _frames(4), np.full(4, 3000), T0)
    _dualtau_file(d / "f" / "b.npz", _frames(4), np.full(4, 3000), T0 + 150_000_000)
    return d / "f"


def _seq_times_backwards(d: Path) -> Path:
    _seq(d / "t.seq", 3, ms=[0, 500, 100])
    return d / "t.seq"


BAD = [
    ("seq-only-record-truncated", _only_record_truncated, "cut.seq: truncated"),
    ("seq-every-record-corrupt", _all_records_corrupt, "none of its 3 frames can be read"),
    ("jpeg-without-flir-records", _jpeg_without_flir,
     "photo.jpg: JPEG without FLIR radiometric data"),
    ("rjpeg-raw-does-not-decode", _rjpeg_raw_does_not_decode,
     "bad.jpg: raw image does not decode"),
    ("folder-mixed-sizes", _folder_mixed_sizes, "b.fff: frames of 4x4 in a folder of 8x6"),
    ("folder-mixed-formats", _folder_mixed_formats, "files of mixed formats"),
    ("folder-without-recording", _folder_empty, "no recording in the folder"),
    ("folder-of-empty-files", _folder_of_unreadable_files,
     "no recording in the folder: none of its 2 files is an FFF, R-JPEG or .npz file that can be "
     "read (the first, "),
    ("npz-missing-keys", _npz_missing_keys, "a.npz: missing array(s) ['fpa']"),
    ("npz-fpa-in-no-unit", _npz_fpa_in_no_unit,
     "a.npz: 'fpa' holds 1e+07..1e+07, no plausible FPA temperature"),
    ("npz-fpa-whole-degrees-names-the-file", _npz_fpa_whole_degrees, "a.npz: 'fpa' holds 31..31"),
    ("npz-fpa-whole-degrees", _npz_fpa_whole_degrees, "more likely whole °C"),
    ("npz-times-backwards-in-a-file", _npz_times_backwards,
     "a.npz: frame times go backwards inside the file (frame 2"),
    ("npz-files-overlap-in-time", _npz_files_overlap,
     "b.npz: its frames overlap in time those of a.npz"),
    ("seq-times-backwards", _seq_times_backwards,
     "frame times go backwards (frame 2 is 0.400 s before frame 1)"),
]


@pytest.mark.parametrize("make, message", [pytest.param(m, t, id=n) for n, m, t in BAD])
@pytest.mark.parametrize("command", ["info", "estimate", "flight"])
def test_bad_recording_is_one_line_exit_2_nothing_written(tmp_path, capsys, make, message,
                                                          command):
    data = tmp_path / "data"
    data.mkdir()
    path = make(data)
    out = tmp_path / "out"
    args = {"info": ["info", path],
            "estimate": ["estimate", path, "--method", "camera", "--out", out / "t.tiff"],
            "flight": ["flight", path, "--method", "camera", "--frames", "1", "--out", out]}
    if command == "estimate":
        out.mkdir()
    code, stdout, err = run(args[command], capsys)
    assert_refused(code, stdout, err, message)
    assert not out.exists() or not any(out.iterdir())


# --------------------------------------------------------------------------------------------
# damaged frames: left out and named
# --------------------------------------------------------------------------------------------
def test_seq_with_damaged_records_goes_on_without_them(tmp_path, capsys):
    path = tmp_path / "x.seq"
    records = _seq(tmp_path / "ok.seq", 6)
    broken = bytearray(records[1])
    broken[0x14:0x20] = b"\xff" * 12  # a record header that does not parse
    short = bytearray(records[3])
    struct.pack_into(">HH", short, 64 + 64 + 2, 48, 41)  # declares more rows than it holds
    path.write_bytes(records[0] + bytes(broken) + records[2] + bytes(short) + records[4]
                     + records[5][:-30])
    src = open_recording(path)
    assert src.n_frames == 3
    assert [w for w, _ in src.damaged] == ["1", "3", "5"]
    assert "unsupported FFF version" in src.damaged[0][1]
    assert "need" in src.damaged[1][1] and src.damaged[2][1].startswith("truncated")
    rec = src.read_all()
    assert [m["index"] for m in rec.extra["frame_metadata"]] == [0, 2, 4]
    expected = open_recording(tmp_path / "ok.seq").read_all().frames[[0, 2, 4]]
    np.testing.assert_array_equal(rec.frames, expected)
    np.testing.assert_allclose(rec.time_s, [0.0, 0.08, 0.16])
    # one warning line from every command, and info lists them
    code, out, err = run(["info", path], capsys)
    assert code == 0, err
    assert err.count("thermocal: warning: skipped 3 damaged frames of") == 1
    assert "damaged frames left out: 1 (" in out and "3 frame(s)" in out
    code, _, err = run(["estimate", path, "--method", "camera", "--out", tmp_path / "t.tiff"],
                       capsys)
    assert code == 0, err
    assert [line for line in err.splitlines() if "warning" in line] == [
        f"thermocal: warning: {src.damaged_summary()}"]
    code, _, err = run(["flight", path, "--method", "camera", "--frames", "1", "--stride", "1",
                        "--out", tmp_path / "fl"], capsys)
    assert code == 0, err
    assert err.count("skipped 3 damaged frames") == 1
    assert len(list((tmp_path / "fl" / "temps").glob("frame_??????.tiff"))) == 3


def test_a_record_whose_signature_is_damaged_is_skipped(tmp_path):
    records = _seq(tmp_path / "ok.seq", 3)
    big = [_fff(fr) for fr in _frames(3, h=200, w=200)]  # records larger than 64 KiB
    path = tmp_path / "x.seq"
    path.write_bytes(big[0] + b"XXXX" + big[1][4:] + big[2])
    src = open_recording(path)
    assert src.n_frames == 2 and [w for w, _ in src.damaged] == ["1"]
    assert "no FFF signature" in src.damaged[0][1]
    assert records  # the small ones: padding between them is not damage
    (tmp_path / "p.seq").write_bytes(records[0] + b"\x00" * 9 + records[1])
    assert open_recording(tmp_path / "p.seq").damaged == []


def test_csq_frame_that_does_not_decode(tmp_path, capsys):
    path = tmp_path / "x.csq"
    records = [_fff(fr, codec="jpegls", ms=40 * k) for k, fr in enumerate(_frames(4))]
    records[2] = _undecodable(records[2])
    path.write_bytes(b"".join(records))
    src = open_recording(path)
    assert src.n_frames == 4 and src.damaged == []  # its header is whole
    rec = src.read_all()  # reading all of it: left out, and named
    assert rec.frames.shape[0] == 3 and src.damaged[0][0] == "2"
    assert src.damaged[0][1].startswith("raw image does not decode")
    assert len(src.read_all().frames) == 3 and len(src.damaged) == 1  # listed once
    code, out, err = run(["info", path], capsys)
    assert code == 0 and "3 frame(s)" in out and "2 (raw image does not decode" in out, err
    # streamed (a fixed count of frames): zeros in its place, named by its index in the
    # recording in its chunk; the source's list is left as it is
    chunks = list(open_stream(path).stream(8))
    assert [(a, len(f)) for a, f, _ in chunks] == [(0, 4)]
    (index, where, reason), = chunks[0][2]
    assert (index, where) == (2, "2") and reason == src.damaged[0][1]
    assert not chunks[0][1][2].any() and chunks[0][1][[0, 1, 3]].all()
    np.testing.assert_array_equal(chunks[0][1][[0, 1, 3]], rec.frames)
    placeholders = list(src.iter_frames(3, placeholders=True))
    assert [c.undecodable for c in placeholders] == [((2, "2", reason),), ()]
    assert placeholders[0].metadata[2]["undecodable"] == ["2", reason]
    assert len(src.damaged) == 1
    with pytest.raises(InvalidInputError, match="not both"):
        src.iter_frames(3, skip_undecodable=True, placeholders=True)
    # chunks(): the frame ends the stream, named
    long = tmp_path / "long.csq"
    more = [_fff(fr, codec="jpegls", ms=40 * k) for k, fr in enumerate(_frames(23))]
    long.write_bytes(b"".join(more[:22]) + _undecodable(more[22]))
    stream = open_stream(long)
    with pytest.raises(FileFormatError,
                       match=r"long\.csq: frame 22 does not decode \(raw image does not"):
        list(stream.chunks(8))
    # a recording none of whose first frames decodes: refused before anything is written
    (tmp_path / "none.csq").write_bytes(b"".join(_undecodable(r) for r in records))
    with pytest.raises(FileFormatError, match=r"none\.csq: none of its 4 frames can be read"):
        open_stream(tmp_path / "none.csq")
    (tmp_path / "first.csq").write_bytes(b"".join(map(_undecodable, more[:16])) + more[16])
    with pytest.raises(FileFormatError, match=r"first\.csq: none of its first 16 frames decodes "
                                              r"\(the first, frame 0 does not decode \(raw"):
        open_stream(tmp_path / "first.csq")


def _flight_outputs(out: Path) -> dict[str, bytes]:
    """Every output of a flight but the summary and the report (their timings differ)."""
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*"))
            if p.is_file() and p.name not in ("summary.json", "report.html")}


def test_flight_goes_on_past_a_frame_that_does_not_decode(tmp_path, capsys, monkeypatch):
    """A CSQ frame beyond the first 16 whose JPEG-LS data is damaged (its header whole, after a
    frame left out at open): the groups that hold it fail, naming it by its index in the
    recording; the others have maps; summary.json lists it; a rerun, from scratch or resumed,
    gives the same bytes."""
    import json

    import thermocal.pipeline.flight as flight

    path = tmp_path / "x.csq"
    records = [_fff(fr, codec="jpegls", ms=40 * k)
               for k, fr in enumerate(_frames(41, h=40, w=48) + 9000)]
    broken = bytearray(records[5])
    broken[0x14:0x20] = b"\xff" * 12  # a record header that does not parse: left out at open
    records[5] = bytes(broken)
    records[23] = _undecodable(records[23])  # frame 22 of the recording
    path.write_bytes(b"".join(records))
    src = open_recording(path)
    assert src.n_frames == 40 and [w for w, _ in src.damaged] == ["5"]  # it passes at open
    with pytest.raises(FileFormatError, match=r"\(frame 23\): raw image does not decode"):
        list(src.iter_frames(64))  # and fails only when decoded
    args = ["flight", path, "--method", "camera", "--frames", "3", "--stride", "3",
            "--preview-every", "5"]
    code, stdout, err = run([*args, "--out", tmp_path / "a"], capsys)
    assert code == 0, err
    assert "12 temperature maps written" in stdout and "1 failed" in stdout
    warned = [line for line in err.splitlines() if "warning" in line]
    assert len(warned) == 2 and "skipped 1 damaged frame of" in warned[0]
    assert warned[1].startswith(f"thermocal: warning: {path}: 1 frame did not decode while "
                                "streamed, 1 group skipped: frame 22 (frame 23 of its file) "
                                "does not decode (raw image does not decode (")
    log = [json.loads(line) for line in (tmp_path / "a" / "log.jsonl").read_text().splitlines()]
    failed = {e["frame"]: e["error"] for e in log if "error" in e}
    assert list(failed) == [22]
    assert failed[22].startswith("frame 22 (frame 23 of its file) does not decode (raw image "
                                 "does not decode (JpeglsError")
    assert failed[22].endswith("; group of frames 21-23 skipped")
    maps = sorted(p.name for p in (tmp_path / "a" / "temps").glob("frame_??????.tiff"))
    assert maps == [f"frame_{p:06d}.tiff" for p in range(1, 38, 3) if p != 22]
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["damaged_frames"][0]["frame"] == "5"
    assert {k: v for k, v in summary["damaged_frames"][1].items() if k != "reason"} == {
        "frame": "23", "recording_index": 22}
    assert summary["damaged_frames"][1]["reason"].startswith("raw image does not decode")
    reference = _flight_outputs(tmp_path / "a")
    # from scratch: the same bytes; rerun: the failed group redone, failing the same way
    assert run([*args, "--out", tmp_path / "b"], capsys)[0] == 0
    assert _flight_outputs(tmp_path / "b") == reference
    code, stdout, _ = run([*args, "--out", tmp_path / "a"], capsys)
    assert code == 0 and "0 temperature maps written" in stdout and "1 failed" in stdout
    again = _flight_outputs(tmp_path / "a")
    failed_line = [line for line in reference["log.jsonl"].splitlines(keepends=True)
                   if b'"error"' in line]
    assert again == {**reference, "log.jsonl": reference["log.jsonl"] + failed_line[0]}
    reference_log = reference["log.jsonl"].splitlines(keepends=True)
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["damaged_frames"] == \
        summary["damaged_frames"]
    # interrupted before the group (and after it), then resumed: the same bytes
    real = flight._process_pivot
    for k in (3, 9):
        calls = {"n": 0}

        def stop(*a, _k=k, _calls=calls, **kw):
            if _calls["n"] == _k:
                raise KeyboardInterrupt
            _calls["n"] += 1
            return real(*a, **kw)

        out = tmp_path / f"r{k}"
        options = flight.FlightOptions(method="camera", frames=3, stride=3, preview_every=5)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the warnings are those of the command above
            with monkeypatch.context() as m:
                m.setattr(flight, "_process_pivot", stop)
                with pytest.raises(KeyboardInterrupt):
                    flight.process_flight(path, out, options)
            resumed = flight.process_flight(path, out, options)
        assert resumed["skipped_already_done"] == k - (k > 7) and resumed["failed"] == 1
        lines = reference_log[:k] + (failed_line if k > 7 else []) + reference_log[k:]
        assert _flight_outputs(out) == {**reference, "log.jsonl": b"".join(lines)}


def test_rjpeg_folder_with_damaged_files(tmp_path, capsys):
    folder = tmp_path / "flight"
    folder.mkdir()
    frames = _frames(5, h=40, w=48) + 9000
    for k, fr in enumerate(frames):
        (folder / f"DJI_{k:04d}.jpg").write_bytes(
            _rjpeg(_fff(fr, ms=100 * k), parts=2, xmp=_dji_xmp(30)))
    whole = (folder / "DJI_0001.jpg").read_bytes()
    (folder / "DJI_0001.jpg").write_bytes(whole[: len(whole) // 3])  # cut short
    Image.new("RGB", (8, 8)).save(folder / "DJI_0003.jpg", "JPEG")  # a visible-light photo
    (folder / "DJI_0004.jpg").write_bytes(b"")
    src = open_recording(folder)
    assert src.n_frames == 2 and [w for w, _ in src.damaged] == [
        "DJI_0001.jpg", "DJI_0003.jpg", "DJI_0004.jpg"]
    assert "no FLIR APP1" in src.damaged[1][1] and "empty" in src.damaged[2][1]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = read_any_recording(folder)
    np.testing.assert_array_equal(rec.frames, frames[[0, 2]])
    assert [str(w.message) for w in caught] == [src.damaged_summary()]
    # a file of another kind beside them is no damaged frame: refused
    (folder / "x.bin").write_bytes(b"hello")
    with pytest.raises(FileFormatError, match=r"x\.bin: unknown recording format"):
        open_recording(folder)


def test_dualtau_folder_with_a_damaged_file(tmp_path):
    frames = _frames(9)
    for k, name in enumerate(("a", "b", "c")):
        _dualtau_file(tmp_path / f"{name}.npz", frames[3 * k : 3 * k + 3], np.full(3, 3000),
                      T0 + k * 300_000_000)
    data = (tmp_path / "b.npz").read_bytes()
    (tmp_path / "b.npz").write_bytes(data[: len(data) // 2])
    src = open_recording(tmp_path)
    assert src.n_frames == 6 and src.damaged[0][0] == "b.npz"
    np.testing.assert_array_equal(src.read_all().frames, frames[[0, 1, 2, 6, 7, 8]])
    with pytest.warns(UserWarning, match=r"skipped 1 damaged frame of .*: b\.npz \(not a"):
        header = open_stream(tmp_path)
    assert header.damaged == tuple(src.damaged) and header.n_frames == 6


@pytest.mark.parametrize(("values", "unit", "expected"), [
    (np.full(3, 303.15 + 0.01), "K", 30.01),
    (np.full(3, 30.25), "°C", 30.25),
    (np.full(3, 303_150, np.int64), "mK", 30.0),
])
def test_dualtau_fpa_in_other_units_is_converted_with_a_warning(tmp_path, values, unit,
                                                                 expected):
    np.savez(tmp_path / "a.npz", frames=_frames(3), fpa=values, time_ns_start=T0 + np.arange(3))
    with pytest.warns(UserWarning, match=f"'fpa' is in {unit}, not the rig's 1/100 °C"):
        rec = open_recording(tmp_path / "a.npz").read_all()
    np.testing.assert_allclose(rec.fpa_c, expected, atol=1e-9)


def test_open_stream_reads_no_raw_image_for_its_series(tmp_path, monkeypatch):
    """The series pass reads headers and metadata only (the first frames are decoded once, to
    refuse a short recording that does not decode before anything is written, and streamed
    from there); frame_metadata is kept for GPS too."""
    import thermocal.io.fff as fff
    from thermocal.io.open import _PREFETCH

    n = _PREFETCH + 5
    path = tmp_path / "x.csq"
    path.write_bytes(b"".join(_fff(fr, codec="jpegls", ms=40 * k, gps=(1.0, 2.0, 3.0))
                              for k, fr in enumerate(_frames(n))))
    calls = []
    real = fff._raw_image
    monkeypatch.setattr(fff, "_raw_image", lambda *a: calls.append(1) or real(*a))
    header = open_stream(path)
    assert len(calls) == _PREFETCH
    np.testing.assert_allclose(header.series["time_s"], 0.04 * np.arange(n))
    assert header.series["frame_metadata"][1]["gps"]["latitude"] == 1.0
    starts = [(a, len(f)) for a, f in header.chunks(8)]
    assert sum(k for _, k in starts) == n and len(calls) == n  # each frame decoded once
    assert [a for a, _ in starts] == [0, _PREFETCH]  # chunks of 8 or more, in order
    frames = np.concatenate([f for _, f in open_stream(path).chunks(_PREFETCH + 1)])
    np.testing.assert_array_equal(frames, open_recording(path).read_all().frames)
