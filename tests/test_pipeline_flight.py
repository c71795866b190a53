"""thermocal flight: streamed groups, per-pivot outputs, resume, and bad input."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pytest
import tifffile

from thermocal.calibration.report import fit_with_report
from thermocal.camera import make_camera
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.recording import read_temperature_tiff
from thermocal.pipeline.flight import FlightOptions, pivots_of, process_flight
from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
from thermocal.simulate.flight import plan_flight, write_simulated_flight

SIZE = (64, 48)
UNIT = 9


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """A polynomial calibration of one unit and a 23-frame flight of the same unit."""
    tmp = tmp_path_factory.mktemp("pipeline")
    camera = make_camera("tau2", unit=UNIT, size=SIZE)
    plan = ChamberPlan(setpoints_c=(10.0, 20.0, 30.0, 40.0, 50.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.2,
                       interval_s=20.0)
    write_simulated_chamber(tmp / "chamber.h5", camera, plan, seed=1)
    cal, _ = fit_with_report(tmp / "chamber.h5", "polynomial", frames="settled")
    cal.save(tmp / "cal.h5")
    scene = 20.0 + 10.0 * np.random.default_rng(0).random((64, 64))
    flight = plan_flight(scene, camera, n_frames=23, motion="uav", fpa_c=28.0, seed=2)
    write_simulated_flight(tmp / "flight", flight, camera)
    return tmp


def test_pivots_cover_whole_groups():
    assert pivots_of(23, 7, 7) == [3, 10, 17]
    assert pivots_of(7, 7, 3) == [3]
    with pytest.raises(InvalidInputError, match="fewer than a group"):
        pivots_of(5, 7, 7)


def test_calibration_method_writes_one_map_per_pivot_and_resumes(setup, tmp_path):
    options = FlightOptions(method="calibration", calibration=str(setup / "cal.h5"),
                            preview_every=2)
    out = tmp_path / "out"
    summary = process_flight(setup / "flight" / "frames.tiff", out, options)
    assert summary["processed"] == 3 and summary["failed"] == 0
    names = sorted(p.name for p in (out / "temps").iterdir())
    maps = ["frame_000003.tiff", "frame_000010.tiff", "frame_000017.tiff"]
    assert names == sorted(maps + [m.replace(".tiff", "_sigma.tiff") for m in maps])
    assert sorted(p.name for p in (out / "previews").iterdir()) == ["frame_000003.png",
                                                                    "frame_000017.png"]
    truth = read_temperature_tiff(setup / "flight" / "truth.tiff")
    temp = read_temperature_tiff(out / "temps" / "frame_000010.tiff")
    assert np.median(np.abs(temp - truth[10])) < 0.15
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert [e["frame"] for e in log] == [3, 10, 17]
    assert (out / "log.csv").read_text().count("\n") == 4

    (out / "temps" / "frame_000010.tiff").unlink()  # as if interrupted before this pivot
    again = process_flight(setup / "flight" / "frames.tiff", out, options)
    assert again["processed"] == 1 and again["skipped_already_done"] == 2
    assert (out / "temps" / "frame_000010.tiff").exists()


def test_mean_of_registered_group(setup, tmp_path):
    options = FlightOptions(method="mean", calibration=str(setup / "cal.h5"), preview_every=0)
    summary = process_flight(setup / "flight" / "frames.tiff", tmp_path / "o", options)
    assert summary["processed"] + summary["failed"] == 3
    assert not (tmp_path / "o" / "previews").exists() or not any(
        (tmp_path / "o" / "previews").iterdir())


@pytest.fixture
def registrations(monkeypatch):
    """The keyword arguments of each call the flight makes to ``register_sequence``."""
    from thermocal.pipeline import flight

    asked, register = [], flight.register_sequence

    def spy(frames, **kwargs):
        asked.append(kwargs)
        return register(frames, **kwargs)

    monkeypatch.setattr(flight, "register_sequence", spy)
    return asked


def test_registration_runs_on_the_threads_it_is_given(setup, tmp_path, registrations):
    options = FlightOptions(method="mean", calibration=str(setup / "cal.h5"), preview_every=0,
                            registration_threads=1)
    process_flight(setup / "flight" / "frames.tiff", tmp_path / "o", options)
    assert registrations and {kw.get("workers") for kw in registrations} == {1}


def test_registration_aligns_only_the_pairs_inside_groups(setup, tmp_path, registrations):
    """N = 5 at stride 7 over 23 frames: groups 1–5, 8–12, 15–19; the pairs a group composes
    through are registered, not those that join groups or frames no group holds."""
    options = FlightOptions(method="mean", calibration=str(setup / "cal.h5"), preview_every=0,
                            frames=5, stride=7)
    summary = process_flight(setup / "flight" / "frames.tiff", tmp_path / "o", options)
    assert summary["processed"] == 3 and summary["failed"] == 0
    (call,) = registrations  # frames 1 … 19 of the recording
    assert np.flatnonzero(call["pairs"]).tolist() == [1, 2, 3, 4, 8, 9, 10, 11, 15, 16, 17, 18]


def test_a_rerun_with_other_options_is_refused_not_mixed(setup, tmp_path):
    """A folder resumes only the run that made it: another method, FPA, calibration file or
    recording is refused, naming what changed, and nothing in the folder changes; threads and
    previews may change; a folder with maps but no record (an older thermocal) is refused."""
    import shutil

    rec = setup / "flight" / "frames.tiff"
    out = tmp_path / "out"
    cal = str(setup / "cal.h5")
    options = FlightOptions(method="calibration", calibration=cal, preview_every=0)
    process_flight(rec, out, options)
    before = _outputs(out)
    record = json.loads((out / "run.json").read_text())
    assert record["options"]["method"] == "calibration" and record["files"]["calibration"]
    for other, says in ((FlightOptions(method="mean", calibration=cal),
                         "--method calibration → mean"),
                        (FlightOptions(method="calibration", calibration=cal, fpa_c=31.0),
                         "--fpa-c None → 31.0"),
                        (FlightOptions(method="calibration", calibration=cal, frames=5),
                         "--frames 7 → 5")):
        with pytest.raises(InvalidInputError, match=f"holds maps of another run \\({says}"):
            process_flight(rec, out, other)
    shutil.copy(setup / "cal.h5", tmp_path / "renamed.h5")  # the same content: the same run
    again = process_flight(rec, out, FlightOptions(method="calibration",
                                                   calibration=str(tmp_path / "renamed.h5"),
                                                   preview_every=3, pivot_workers=1))
    assert again["skipped_already_done"] == 3 and again["processed"] == 0
    changed = tmp_path / "changed.h5"
    shutil.copy(setup / "cal.h5", changed)
    with open(changed, "ab") as f:
        f.write(b"\0")
    with pytest.raises(InvalidInputError, match="another calibration file"):
        process_flight(rec, out, FlightOptions(method="calibration", calibration=str(changed)))
    other_rec = tmp_path / "rec" / "frames.tiff"
    other_rec.parent.mkdir()
    frames = tifffile.imread(rec)
    tifffile.imwrite(other_rec, frames[::-1].copy(), photometric="minisblack")
    shutil.copy(setup / "flight" / "frames.json", other_rec.with_suffix(".json"))
    with pytest.raises(InvalidInputError, match="another recording"):
        process_flight(other_rec, out, options)
    assert {k: v for k, v in _outputs(out).items() if not k.startswith("previews")} == {
        k: v for k, v in before.items() if not k.startswith("previews")}
    (out / "run.json").unlink()
    with pytest.raises(InvalidInputError, match="whose recording and options were not recorded"):
        process_flight(rec, out, options)
    # a run that failed before its first map (its record written, no log line) is no run to
    # resume: another run takes the folder (it blocked every rerun with other options)
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    (fresh / "run.json").write_text(json.dumps(record | {"options": record["options"] | {
        "backend": "onnxruntime"}}))
    (fresh / "log.jsonl").write_text("")
    assert process_flight(rec, fresh, options)["processed"] == 3
    assert json.loads((fresh / "run.json").read_text()) == record
    (fresh / "run.json").write_text("{damaged")  # and a damaged record with maps is refused
    with pytest.raises(InvalidInputError, match="not a run record"):
        process_flight(rec, fresh, options)


def _outputs(out) -> dict[str, bytes]:
    """Every output but those holding timings (summary, report), by path."""
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*"))
            if p.is_file() and p.name not in ("summary.json", "report.html")}


def test_a_flight_in_segments_gives_the_bytes_of_one_run(setup, tmp_path, monkeypatch):
    """Batches of 2 groups: segments (0, 2) and (2, 3) of a 6-group flight, finished, are the
    bytes of one run; a segment rerun and a second finish (an interrupted campaign resumed)
    change nothing; the segments' counts add up; a selfcal flight is not split."""
    from thermocal.pipeline import flight

    monkeypatch.setattr(flight, "BATCH_FRAMES", 7)
    rec = setup / "flight" / "frames.tiff"
    options = FlightOptions(method="mean", calibration=str(setup / "cal.h5"), stride=3,
                            preview_every=2)
    assert flight.flight_batches(23, options) == 3
    whole = process_flight(rec, tmp_path / "one", options)
    parts = [process_flight(rec, tmp_path / "seg", options, segment=span)
             for span in ((2, 3), (0, 2))]  # in any order, as a cluster runs them
    assert sorted(p["groups"] for p in parts) == [2, 4]
    assert sorted((tmp_path / "seg").glob("log.segment-*.jsonl"))
    summary = flight.finish_segments(rec, tmp_path / "seg", options, parts)
    assert not list((tmp_path / "seg").glob("log.segment-*.jsonl"))
    assert summary["processed"] == whole["processed"] == 6 and summary["segments"] == 2
    assert _outputs(tmp_path / "seg") == _outputs(tmp_path / "one")
    again = process_flight(rec, tmp_path / "seg", options, segment=(2, 3))
    assert again["processed"] == 0 and again["skipped_already_done"] == 2
    flight.finish_segments(rec, tmp_path / "seg", options, [parts[1], again])
    assert _outputs(tmp_path / "seg") == _outputs(tmp_path / "one")
    with pytest.raises(InvalidInputError, match="do not cover"):
        flight.finish_segments(rec, tmp_path / "seg", options, [parts[1]])
    with pytest.raises(InvalidInputError, match="segment"):
        process_flight(rec, tmp_path / "x", options, segment=(2, 9))
    with pytest.raises(InvalidInputError, match="fits across the whole recording"):
        process_flight(rec, tmp_path / "x", FlightOptions(method="selfcal"), segment=(0, 1))
    assert not (tmp_path / "x").exists()


def test_bad_input(setup, tmp_path):
    rec = setup / "flight" / "frames.tiff"
    with pytest.raises(InvalidInputError, match="needs --calibration"):
        FlightOptions(method="mean")
    with pytest.raises(InvalidInputError, match="registration threads"):
        FlightOptions(method="mean", calibration=str(setup / "cal.h5"), registration_threads=0)
    (tmp_path / "file").write_text("")
    with pytest.raises(InvalidInputError):
        process_flight(rec, tmp_path / "file", FlightOptions(method="calibration",
                                                            calibration=str(setup / "cal.h5")))
    # a sidecar whose length does not match the frames
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "frames.tiff").write_bytes(rec.read_bytes())
    meta = json.loads((setup / "flight" / "frames.json").read_text())
    meta["fpa_c"] = meta["fpa_c"][:-1]
    (bad / "frames.json").write_text(json.dumps(meta))
    with pytest.raises(FileFormatError, match="fpa_c"):
        process_flight(bad / "frames.tiff", tmp_path / "o2", FlightOptions(method="kpn"))
    # a truncated recording
    (bad / "frames.json").unlink()
    (bad / "frames.tiff").write_bytes(rec.read_bytes()[: rec.stat().st_size // 2])
    with pytest.raises(FileFormatError):
        process_flight(bad / "frames.tiff", tmp_path / "o3", FlightOptions(method="kpn"))
    assert not (tmp_path / "o2").exists() and not (tmp_path / "o3").exists()


def test_disk_full_keeps_finished_outputs_and_resumes(setup, tmp_path, monkeypatch, capsys):
    """A full disk mid-run: one line, exit 2, finished maps kept, no temporary files, resume."""
    import errno

    from thermocal.cli import main

    real_imwrite = tifffile.imwrite
    calls = {"n": 0}
    lock = threading.Lock()  # the pivots write at once

    def imwrite_then_full(*args, **kwargs):
        with lock:  # the disk fills at the second map (a pivot writes its σ map first)
            calls["n"] += "_sigma" not in Path(str(args[0])).name
            full = calls["n"] > 1
        if full:
            raise OSError(errno.ENOSPC, "No space left on device", str(args[0]))
        return real_imwrite(*args, **kwargs)

    monkeypatch.setattr(tifffile, "imwrite", imwrite_then_full)
    out = tmp_path / "out"
    argv = ["flight", str(setup / "flight" / "frames.tiff"), "--out", str(out), "--method",
            "calibration", "--calibration", str(setup / "cal.h5"), "--preview-every", "0"]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "No space left on device" in err
    assert "rerun to resume" in err
    # the one map written before the disk filled is kept (which one: the pivots run at once)
    kept = [p.name for p in (out / "temps").iterdir() if not p.stem.endswith("_sigma")]
    assert len(kept) == 1 and kept[0] in ("frame_000003.tiff", "frame_000010.tiff",
                                          "frame_000017.tiff")
    assert (out / "temps" / kept[0].replace(".tiff", "_sigma.tiff")).is_file()
    monkeypatch.setattr(tifffile, "imwrite", real_imwrite)
    main(argv)
    names = sorted(p.name for p in (out / "temps").iterdir() if not p.stem.endswith("_sigma"))
    assert names == ["frame_000003.tiff", "frame_000010.tiff", "frame_000017.tiff"]


@pytest.mark.parametrize("method", ["kpn", "mean", "calibration"])
def test_flight_end_to_end_through_the_cli(setup, tmp_path, method, capsys):
    """``thermocal flight`` on a small recording, every kind of estimator: one map per pivot,
    close to the simulator's truth (the unit's own polynomial calibration for ``mean`` and
    ``calibration``; the shipped network, calibration-free, for ``kpn``)."""
    if method == "kpn":
        pytest.importorskip("torch")
    import tifffile

    from thermocal.cli import main

    out = tmp_path / "out"
    argv = ["flight", str(setup / "flight" / "frames.tiff"), "--out", str(out), "--method", method,
            "--preview-every", "2"]
    if method != "kpn":
        argv += ["--calibration", str(setup / "cal.h5")]
    else:  # frames too small for the network's family check: estimated all the same
        argv += ["--force"]
    main(argv)
    assert "3 temperature maps written" in capsys.readouterr().out
    truth = tifffile.imread(setup / "flight" / "truth.tiff")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["processed"] == 3 and summary["failed"] == 0
    for pivot in (3, 10, 17):
        temp = read_temperature_tiff(out / "temps" / f"frame_{pivot:06d}.tiff")
        err = np.abs(temp - truth[pivot])[4:-4, 4:-4]
        limit = {"kpn": 1.5, "mean": 0.5, "calibration": 0.2}[method]
        assert np.median(err) < limit, (method, pivot, float(np.median(err)))
    assert sorted(p.name for p in (out / "previews").iterdir()) == [
        "frame_000003.png", "frame_000017.png"]


def test_a_hovering_camera_whose_chain_breaks_is_registered_group_by_group(tmp_path, capsys):
    """A camera hovering over a 160×120 scene: the recording's fixed-pattern estimate (a
    temporal median) keeps the scene that hardly moves, and the chain of pairs breaks (every
    group failed, "ECC correlation 0.32"); each group is then registered on its own, as a
    burst, and says so."""
    pytest.importorskip("torch")
    from thermocal.cli import main

    rec = tmp_path / "hover"
    main(["simulate", "flight", str(rec), "--frames", "14", "--seed", "0", "--unit", "100",
          "--size", "160x120", "--motion", "hover"])
    out = tmp_path / "out"
    main(["flight", str(rec), "--out", str(out), "--preview-every", "0"])
    assert "2 temperature maps written" in capsys.readouterr().out
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert all(any(w.startswith("registered as a burst (") for w in e["warnings"]) for e in log)
    truth = tifffile.imread(rec / "truth.tiff")
    for pivot in (3, 10):
        temp = read_temperature_tiff(out / "temps" / f"frame_{pivot:06d}.tiff")
        assert np.median(np.abs(temp - truth[pivot])) < 1.5


def test_fpa_rates_come_from_the_whole_recording_when_it_is_long_enough():
    """A calibration's σ depends on the FPA rate: taken from the recording's series when they
    span the smoothing window, else unknown (None)."""
    from thermocal.calibration.dataset import recording_fpa_rates

    def _fpa_rates(series):
        return recording_fpa_rates(series["fpa_c"], series["time_s"])

    t = np.arange(0.0, 300.0, 1.0)
    rates = _fpa_rates({"fpa_c": 20.0 + t / 60.0, "time_s": t})
    assert rates is not None and np.allclose(rates, 1.0, atol=1e-6)
    assert _fpa_rates({"fpa_c": 20.0 + t[:30] / 60.0, "time_s": t[:30]}) is None
    assert _fpa_rates({"fpa_c": None, "time_s": t}) is None
    assert _fpa_rates({"fpa_c": np.ones(300), "time_s": t[::-1].copy()}) is None


def test_every_group_holding_a_frame_that_does_not_decode_fails(tmp_path):
    """Overlapping groups (5 frames, stride 2): the three groups that hold the undecodable frame
    20 fail naming it, the others are processed; the summary lists it by its recording index."""
    from test_open_recording import _fff, _frames
    from test_open_recording_bad import _undecodable

    records = [_fff(fr, codec="jpegls", ms=40 * k)
               for k, fr in enumerate(_frames(30, h=40, w=48) + 9000)]
    records[20] = _undecodable(records[20])
    (tmp_path / "x.csq").write_bytes(b"".join(records))
    options = FlightOptions(method="camera", frames=5, stride=2, preview_every=0)
    with pytest.warns(UserWarning, match=r"x\.csq: 1 frame did not decode while streamed, 3 "
                                         r"groups skipped: frame 20 does not decode \(raw"):
        summary = process_flight(tmp_path / "x.csq", tmp_path / "out", options)
    log = [json.loads(line) for line in (tmp_path / "out" / "log.jsonl").read_text().splitlines()]
    failed = {e["frame"]: e["error"] for e in log if "error" in e}
    assert sorted(failed) == [18, 20, 22] and summary["failed"] == 3
    assert failed[18].endswith("; group of frames 16-20 skipped")
    assert failed[20].startswith("frame 20 does not decode (raw image does not decode (")
    assert failed[20].endswith("; group of frames 18-22 skipped")
    assert failed[22].endswith("; group of frames 20-24 skipped")
    assert summary["processed"] == summary["groups"] - 3 == 10
    (entry,) = summary["damaged_frames"]
    assert (entry["frame"], entry["recording_index"]) == ("20", 20)


def test_registration_sees_the_frame_before_an_undecodable_one():
    """What registration sees of frames that do not decode (zeros): the nearest frame before
    them, after them at the start; a new array, the frames left as they are."""
    from thermocal.pipeline.flight import _stand_ins

    frames = np.arange(1, 6, dtype=np.uint16)[:, None, None] * np.ones((1, 2, 2), np.uint16)
    frames[[0, 2, 3]] = 0
    seen = _stand_ins(frames, [0, 2, 3])
    assert seen[:, 0, 0].tolist() == [2, 2, 2, 2, 5]
    assert frames[:, 0, 0].tolist() == [0, 2, 0, 0, 5]
    assert _stand_ins(frames, []) is frames


@pytest.mark.parametrize("chunk", [1, 3, 7, 64])
def test_frame_window_returns_each_batch_as_sliced_from_the_recording(chunk):
    """The flight's reading window: batches overlapping or with gaps between them, from a
    stream that starts anywhere, in chunks of any size, give the recording's frames and only
    the undecodable frames among them."""
    from thermocal.pipeline.flight import _FrameWindow

    frames = np.arange(40 * 2 * 3, dtype=np.uint16).reshape(40, 2, 3)
    bad = {(11, "x", "torn"), (30, "x", "torn")}
    start = 4

    def chunks():
        for a in range(start, 40, chunk):
            z = min(a + chunk, 40)
            yield a, frames[a:z].copy(), tuple(sorted(e for e in bad if a <= e[0] < z))

    window = _FrameWindow(chunks(), (2, 3))
    for a, z in [(4, 11), (9, 16), (16, 23), (30, 31), (33, 40)]:
        got, undecodable = window.frames(a, z)
        np.testing.assert_array_equal(got, frames[a:z])
        assert set(undecodable) == {e for e in bad if a <= e[0] < z}


def test_a_resume_refusal_names_the_files_without_options_never_given():
    """The record keeps a network's weights whether given (--model) or the shipped default: a
    rerun without them names the file, not an option the user never gave."""
    from thermocal.pipeline.run_record import _changes

    old = {"recording": "r", "options": {"method": "kpn"}, "files": {"model": "abc",
                                                                       "calibration": None}}
    new = {"recording": "r", "options": {"method": "mean"}, "files": {"model": None,
                                                                        "calibration": "x"}}
    assert _changes(old, new) == ["--method kpn → mean", "the model file used before, none now",
                                  "a calibration file used now, none before"]
