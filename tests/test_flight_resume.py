"""thermocal flight: an interrupted run resumes to the same bytes, resume checks what it keeps,
failed runs say so, and bad input leaves nothing behind."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import thermocal.pipeline.flight as flight
from thermocal.calibration.report import fit_with_report
from thermocal.camera import make_camera
from thermocal.errors import InvalidInputError, ThermocalError
from thermocal.io.recording import (
    SERIES_KEYS,
    read_recording,
    write_recording,
    write_temperature_tiff,
)
from thermocal.pipeline.flight import FlightOptions, process_flight
from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
from thermocal.simulate.flight import plan_flight, write_simulated_flight

SIZE = (64, 48)
UNIT = 9
#: Small batches, so that these short recordings have several (BATCH // stride pivots each).
BATCH = 16


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A polynomial calibration of one unit and a 43-frame UAV pass of the same unit (13 pivots
    at stride 3, in batches of 5)."""
    tmp = tmp_path_factory.mktemp("resume")
    camera = make_camera("tau2", unit=UNIT, size=SIZE)
    plan = ChamberPlan(setpoints_c=(10.0, 20.0, 30.0, 40.0, 50.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.2,
                       interval_s=20.0)
    write_simulated_chamber(tmp / "chamber.h5", camera, plan, seed=1)
    fit_with_report(tmp / "chamber.h5", "polynomial", frames="settled")[0].save(tmp / "cal.h5")
    scene = 20.0 + 10.0 * np.random.default_rng(0).random((64, 64))
    write_simulated_flight(tmp / "flight",
                           plan_flight(scene, camera, n_frames=43, motion="uav", fpa_c=28.0,
                                       seed=2), camera)
    return tmp


@pytest.fixture(autouse=True)
def small_batches(monkeypatch):
    monkeypatch.setattr(flight, "BATCH_FRAMES", BATCH)


def _options(data: Path, method: str = "mean", **kw) -> FlightOptions:
    kw.setdefault("stride", 3)
    kw.setdefault("preview_every", 4)
    calibration = None if method == "kpn" else str(data / "cal.h5")
    if method == "kpn":  # 64×48 frames: too small to check the network's camera family
        kw.setdefault("force", True)
    return FlightOptions(method=method, calibration=calibration, **kw)


def _outputs(out: Path) -> dict[str, bytes]:
    """Every output but the summary and the report (their timings differ), by path, hidden
    files included."""
    found = {}
    for path in sorted(out.rglob("*")):
        if path.is_file() and path.name not in ("summary.json", "report.html"):
            found[str(path.relative_to(out))] = path.read_bytes()
    return found


_REFERENCE: dict[tuple, dict[str, bytes]] = {}


def _reference(data: Path, options: FlightOptions, tmp_path_factory) -> dict[str, bytes]:
    """The outputs of one uninterrupted run (kept per options for the module)."""
    key = (data, options)
    if key not in _REFERENCE:
        out = tmp_path_factory.mktemp("reference") / "out"
        summary = process_flight(data / "flight" / "frames.tiff", out, options)
        assert summary["failed"] == 0 and summary["processed"] == summary["groups"]
        _REFERENCE[key] = _outputs(out)
    return _REFERENCE[key]


def _interrupt_after(monkeypatch, k: int, pivots: list[int]) -> None:
    """The run stops (Ctrl-C) at its ``k+1``-th pivot of ``pivots`` (whichever worker starts
    it, whenever: the pivots may run at once)."""
    real = flight._process_pivot

    def stop(run, pivot, *args, **kwargs):
        if pivot == pivots[k]:
            raise KeyboardInterrupt
        return real(run, pivot, *args, **kwargs)

    monkeypatch.setattr(flight, "_process_pivot", stop)


@pytest.mark.parametrize(("method", "k", "workers"), [
    ("mean", 1, 1), ("mean", 5, 1), ("mean", 11, 1), ("calibration", 6, 1), ("kpn", 3, 1),
    ("mean", 5, 3), ("kpn", 3, 2)])
def test_interrupted_run_resumes_to_the_same_bytes(data, tmp_path, tmp_path_factory,
                                                    monkeypatch, method, k, workers):
    """Interrupted after ``k`` pivots (in the first, second or last batch) and rerun: every map,
    preview and log line is the uninterrupted run's, byte for byte, the pivots estimated one at
    a time or ``workers`` at once (each run, and the reference, one at a time)."""
    if method == "kpn":
        pytest.importorskip("torch")
    options = _options(data, method, pivot_workers=workers,
                       **({"stride": 7} if method == "kpn" else {}))
    reference = _reference(data, dataclasses.replace(options, pivot_workers=1), tmp_path_factory)
    out = tmp_path / "out"
    with monkeypatch.context() as m:
        _interrupt_after(m, k, flight.pivots_of(43, options.frames, options.stride))
        with pytest.raises(KeyboardInterrupt):
            process_flight(data / "flight" / "frames.tiff", out, options)
    maps = [p for p in (out / "temps").iterdir() if not p.stem.endswith("_sigma")]
    sigmas = [p for p in (out / "temps").iterdir() if p.stem.endswith("_sigma")]
    # pivots after the k-th that other workers were estimating finish their maps, not their
    # log lines: the rerun redoes them
    assert k <= len(maps) <= k + (0 if workers == 1 else 2 * workers)
    assert len(sigmas) == len(maps)  # every method here has its σ (the calibration its report)
    summary = process_flight(data / "flight" / "frames.tiff", out, options)
    assert summary["skipped_already_done"] == k
    assert summary["processed"] == summary["groups"] - k
    assert _outputs(out) == reference


@pytest.mark.parametrize(("method", "backend"), [
    ("mean", "torch"), ("kpn", "torch"), ("calibration", "torch"),
    pytest.param("kpn", "onnxruntime", marks=pytest.mark.skipif(
        importlib.util.find_spec("onnxruntime") is None, reason="onnxruntime not installed"))])
def test_pivots_at_once_give_the_bytes_of_one_at_a_time(data, tmp_path, tmp_path_factory,
                                                         method, backend):
    """Every map, σ map, preview and log line of three pivots estimated at once (each network
    call on its share of the cores) is that of one at a time (on all of them), and so are the
    summary's counts."""
    if method == "kpn":
        pytest.importorskip("torch")
    options = _options(data, method, preview_every=1, backend=backend,
                       **({"stride": 7} if method == "kpn" else {}))
    reference = _reference(data, dataclasses.replace(options, pivot_workers=1), tmp_path_factory)
    summary = process_flight(data / "flight" / "frames.tiff", tmp_path / "out",
                             dataclasses.replace(options, pivot_workers=3))
    assert summary["failed"] == 0 and summary["processed"] == summary["groups"]
    assert _outputs(tmp_path / "out") == reference


def test_each_pivot_logs_its_own_warnings_when_pivots_run_at_once(data, tmp_path):
    """A warning of every group's estimate (the calibration applied above its FPA range,
    forced) lands in that group's log line, three at once as one at a time."""
    logs = {}
    for workers in (1, 3):
        options = _options(data, "calibration", fpa_c=40.5, force=True, pivot_workers=workers)
        out = tmp_path / f"out{workers}"
        summary = process_flight(data / "flight" / "frames.tiff", out, options)
        assert summary["processed"] == summary["groups"] == 13
        logs[workers] = (out / "log.jsonl").read_bytes()
        lines = [json.loads(line) for line in logs[workers].splitlines()]
        assert all(any("leave the calibrated range" in w for w in e["warnings"]) for e in lines)
    assert logs[1] == logs[3]


def test_previews_follow_the_pivots_place_not_the_run(data, tmp_path, tmp_path_factory):
    """Every ``preview_every``-th pivot of the recording, however the runs were split."""
    options = _options(data)
    reference = _reference(data, options, tmp_path_factory)
    pivots = flight.pivots_of(43, 7, 3)
    expected = [f"previews/frame_{p:06d}.png" for p in pivots[::4]]
    assert sorted(k for k in reference if k.startswith("previews/")) == expected


@pytest.mark.parametrize("cut", ["map_only", "map_and_preview", "preview_only", "half_line"])
def test_a_pivot_is_finished_only_with_its_log_line(data, tmp_path, tmp_path_factory, cut):
    """A run killed between a pivot's outputs and its log line: the pivot is redone whole (the
    audit's case: a map without its preview and log line was taken as done)."""
    options = _options(data)
    reference = _reference(data, options, tmp_path_factory)
    out = tmp_path / "out"
    out.mkdir()
    for name, content in reference.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_bytes(content)
    (out / "log.csv").unlink()
    lines = reference["log.jsonl"].splitlines(keepends=True)
    last = json.loads(lines[-1])["frame"]  # the 13th pivot: a preview is due (12 % 4 == 0)
    map_, png = out / "temps" / f"frame_{last:06d}.tiff", out / "previews" / f"frame_{last:06d}.png"
    assert png.exists()
    if cut == "half_line":
        (out / "log.jsonl").write_bytes(b"".join(lines[:-1]) + lines[-1][:25])
    else:
        (out / "log.jsonl").write_bytes(b"".join(lines[:-1]))
    if cut == "map_only":
        png.unlink()
    elif cut == "preview_only":
        map_.unlink()
    summary = process_flight(data / "flight" / "frames.tiff", out, options)
    assert summary["processed"] == 1 and summary["skipped_already_done"] == summary["groups"] - 1
    assert _outputs(out) == reference


def _copy_reference(reference: dict[str, bytes], out: Path) -> None:
    for name, content in reference.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_bytes(content)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "cut_in_its_tags", "empty",
                                    "wrong_shape", "float64", "nan", "other_values",
                                    "directory"])
def test_a_damaged_map_is_redone(data, tmp_path, tmp_path_factory, damage, caplog):
    """A damaged map is redone, and silently: tifffile's log lines on the damaged file are
    not printed (a map cut inside its tags printed three of them)."""
    options = _options(data)
    reference = _reference(data, options, tmp_path_factory)
    out = tmp_path / "out"
    _copy_reference(reference, out)
    path = out / "temps" / "frame_000006.tiff"
    good = path.read_bytes()
    path.unlink()
    if damage == "garbage":
        path.write_bytes(b"not a tiff at all" * 10)
    elif damage == "truncated":
        path.write_bytes(good[: len(good) // 2])
    elif damage == "cut_in_its_tags":
        path.write_bytes(good[:199])  # its IFD whole, the values of its tags cut off
    elif damage == "empty":
        path.write_bytes(b"")
    elif damage == "wrong_shape":
        write_temperature_tiff(path, np.full((10, 10), 20.0, np.float32))
    elif damage == "float64":
        import tifffile

        tifffile.imwrite(path, tifffile.imread(out / "temps" / "frame_000003.tiff")
                         .astype(np.float64))
    elif damage == "nan":
        import tifffile

        tifffile.imwrite(path, np.full(SIZE[::-1], np.nan, np.float32))
    elif damage == "other_values":  # a readable map, but not the one logged
        write_temperature_tiff(path, np.full(SIZE[::-1], 20.0, np.float32))
    elif damage == "directory":
        path.mkdir()
    if damage == "directory":
        with pytest.raises(InvalidInputError, match="is a directory"):
            process_flight(data / "flight" / "frames.tiff", out, options)
        return
    with caplog.at_level(logging.DEBUG):
        summary = process_flight(data / "flight" / "frames.tiff", out, options)
    assert summary["processed"] == 1
    assert path.read_bytes() == good
    assert not [r for r in caplog.records if r.name.startswith("tifffile")]


def test_stray_files_are_ignored_and_kept(data, tmp_path, tmp_path_factory):
    options = _options(data)
    reference = _reference(data, options, tmp_path_factory)
    out = tmp_path / "out"
    _copy_reference(reference, out)
    strays = {"temps/frame_abc.tiff": b"x", "temps/frame_.tiff": b"", "temps/frame_12.tiff": b"",
              "temps/notes.txt": b"mine", "previews/frame_abc.png": b"x",
              "temps/frame_000006.tiff.bak": b"old", "temps/.frame_000006.tiff": b"mine",
              "frame_000006.tiff": b"mine"}
    for name, content in strays.items():
        (out / name).write_bytes(content)
    (out / "temps" / "frame_9999.tiff").mkdir()
    summary = process_flight(data / "flight" / "frames.tiff", out, options)
    assert summary["processed"] == 0 and summary["skipped_already_done"] == summary["groups"]
    for name, content in strays.items():
        assert (out / name).read_bytes() == content, name


def test_bad_log_lines_are_tolerated(data, tmp_path, tmp_path_factory):
    """Lines that are not one JSON object with an integer frame are skipped: by resume (their
    pivot is redone) and by log.csv."""
    options = _options(data)
    reference = _reference(data, options, tmp_path_factory)
    out = tmp_path / "out"
    _copy_reference(reference, out)
    lines = reference["log.jsonl"].splitlines(keepends=True)
    junk = [b"not json\n", b"[1, 2, 3]\n", b"42\n", b"null\n", b"{}\n", b'{"frame": "abc"}\n',
            b'{"frame": true}\n', b'{"frame": 3.5}\n', b"\xff\xfe\x00garbage\n", b"\n",
            b"[" * 100_000 + b"\n", b'"a string"\n']
    # the first pivot's line replaced by junk: it is redone; the rest stay
    (out / "log.jsonl").write_bytes(b"".join(junk) + b"".join(lines[1:]))
    summary = process_flight(data / "flight" / "frames.tiff", out, options)
    assert summary["processed"] == 1 and summary["skipped_already_done"] == summary["groups"] - 1
    assert (out / "log.csv").read_bytes() == reference["log.csv"]
    for name in reference:
        if name != "log.jsonl":
            assert (out / name).read_bytes() == reference[name], name


def test_stale_temporary_files_are_removed(data, tmp_path, tmp_path_factory):
    """The hidden temporary files a killed run leaves (atomic_path's names) go; others stay."""
    options = _options(data)
    reference = _reference(data, options, tmp_path_factory)
    out = tmp_path / "out"
    _copy_reference(reference, out)
    stale = ["temps/.frame_000003.k2j_9xq1.tiff", "previews/.frame_000015.abcdefgh.png",
             ".log.a1b2c3d4.csv", ".summary.zz__zz__.json", "temps/.frame_1234567.abcdefgh.tiff"]
    kept = ["temps/.frame_000003.tiff", "temps/.frame_000003.abc.tiff", ".log.a1b2c3d4.txt",
            "previews/.frame_000015.abcdefgh.tiff", ".frame_000003.abcdefgh.tiff",
            "temps/.other.abcdefgh.tiff", ".notes", "temps/.frame_000003.ABCDEFGH.tiff"]
    for name in stale + kept:
        (out / name).write_bytes(b"partial")
    process_flight(data / "flight" / "frames.tiff", out, options)
    for name in stale:
        assert not (out / name).exists(), name
    for name in kept:
        assert (out / name).read_bytes() == b"partial", name


def _saturated_copy(data: Path, dest: Path, frames: slice) -> Path:
    rec = read_recording(data / "flight" / "frames.tiff")
    raw = rec.frames.copy()
    raw[frames, : SIZE[1] // 2 + 6] = 2**14 - 1  # 62 % of the pixels clipped
    dest.mkdir()
    return write_recording(dest / "frames.tiff", dataclasses.replace(rec, frames=raw))[0]


def test_a_saturated_group_says_saturated_not_registration(data, tmp_path):
    """Frames 14–20 saturated: registration cannot chain through them, but each group that
    holds one says which frame is saturated."""
    rec = _saturated_copy(data, tmp_path / "rec", slice(14, 21))
    out = tmp_path / "out"
    summary = process_flight(rec, out, _options(data, preview_every=0))
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    failed = {e["frame"]: e["error"] for e in log if "error" in e}
    assert sorted(failed) == [12, 15, 18, 21] and summary["failed"] == 4
    assert failed[12].startswith("frame 14 (group of frames 9-15) is saturated")
    assert all("saturated" in e and "registered" not in e for e in failed.values())
    assert summary["processed"] == summary["groups"] - 4


def test_a_run_where_every_group_fails_exits_2(data, tmp_path, capsys):
    from thermocal.cli import main

    rec = _saturated_copy(data, tmp_path / "rec", slice(None))
    out = tmp_path / "out"
    argv = ["flight", str(rec), "--out", str(out), "--method", "mean", "--calibration",
            str(data / "cal.h5"), "--stride", "7"]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "all 6 groups failed" in err and "frame 0 (group of frames 0-6) is saturated" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failed"] == summary["groups"] == 6 and summary["processed"] == 0
    assert "saturated" in summary["first_error"]
    assert (out / "log.csv").read_text().count("saturated") == 6
    assert not list(out.rglob("*.tiff")) and not list(out.rglob("*.png"))


def test_a_rerun_of_a_finished_flight_exits_0(data, tmp_path, capsys):
    from thermocal.cli import main

    argv = ["flight", str(data / "flight" / "frames.tiff"), "--out", str(tmp_path / "o"),
            "--method", "calibration", "--calibration", str(data / "cal.h5"),
            "--preview-every", "0"]
    main(argv)
    main(argv)
    assert "0 temperature maps written" in capsys.readouterr().out


def test_bad_input_creates_no_folder(data, tmp_path, capsys):
    """Every check runs before out/, out/temps and out/previews are made."""
    from thermocal.cli import main

    rec = data / "flight" / "frames.tiff"
    other = make_camera("tau2", unit=UNIT, size=(32, 24))
    plan = ChamberPlan(setpoints_c=(10.0, 30.0, 50.0), frames_per_point=2, profile="sawtooth",
                       ambient_c=(15.0, 35.0), rate_c_per_min=0.2, interval_s=20.0)
    write_simulated_chamber(tmp_path / "small.h5", other, plan, seed=1)
    fit_with_report(tmp_path / "small.h5", "polynomial",
                    frames="settled")[0].save(tmp_path / "small_cal.h5")
    short = tmp_path / "short"
    short.mkdir()
    recording = read_recording(rec)
    series = {k: None if getattr(recording, k) is None else getattr(recording, k)[:5]
              for k in SERIES_KEYS}
    write_recording(short / "frames.tiff",
                    dataclasses.replace(recording, frames=recording.frames[:5], **series))
    cases = {
        "calibration of another size": (rec, ["--method", "calibration", "--calibration",
                                              str(tmp_path / "small_cal.h5")]),
        "missing calibration file": (rec, ["--method", "mean", "--calibration",
                                           str(tmp_path / "nope.h5")]),
        "too few frames": (short / "frames.tiff", ["--method", "calibration", "--calibration",
                                                   str(data / "cal.h5")]),
        "missing recording": (tmp_path / "nope.tiff", ["--method", "calibration",
                                                       "--calibration", str(data / "cal.h5")]),
        "bad model": (rec, ["--method", "kpn", "--model", str(tmp_path / "nope.pt")]),
        "stride 0": (rec, ["--method", "calibration", "--calibration", str(data / "cal.h5"),
                           "--stride", "0"]),
    }
    for i, (what, (recording_path, extra)) in enumerate(cases.items()):
        out = tmp_path / f"out{i}" / "deeper"
        with pytest.raises(SystemExit) as stop:
            main(["flight", str(recording_path), "--out", str(out), *extra])
        assert stop.value.code == 2, what
        assert len(capsys.readouterr().err.strip().splitlines()) == 1, what
        assert not (tmp_path / f"out{i}").exists(), what
    # the API as well: no FPA temperature for a method that needs one
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "frames.tiff").write_bytes(rec.read_bytes())
    with pytest.raises(InvalidInputError, match="no FPA temperature"):
        process_flight(bare / "frames.tiff", tmp_path / "out_api", _options(data))
    assert not (tmp_path / "out_api").exists()
    # temps taken by a file: nothing is created beside it
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "temps").write_text("")
    with pytest.raises(ThermocalError, match="temps: exists and is a file"):
        process_flight(rec, tmp_path / "taken", _options(data))
    assert sorted(p.name for p in (tmp_path / "taken").iterdir()) == ["temps"]


@pytest.mark.slow
def test_sigkill_then_rerun_gives_the_same_bytes(data, tmp_path):
    """The real thing: ``thermocal flight`` killed (SIGKILL) once its first map is written, then
    rerun, against an uninterrupted run (the shipped batch size: one batch here)."""
    rec = data / "flight" / "frames.tiff"
    args = ["--method", "mean", "--calibration", str(data / "cal.h5"), "--stride", "1",
            "--preview-every", "2"]
    cli = [sys.executable, "-m", "thermocal.cli", "flight", str(rec)]
    env = {**os.environ, "PYTHONHASHSEED": "0"}

    def run(out: Path) -> None:
        subprocess.run([*cli, "--out", str(out), *args], check=True, env=env,
                       capture_output=True, timeout=600)

    run(tmp_path / "reference")
    out = tmp_path / "killed"
    proc = subprocess.Popen([*cli, "--out", str(out), *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while proc.poll() is None and time.monotonic() < deadline:
            if (out / "temps").is_dir() and any((out / "temps").glob("frame_*.tiff")):
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.01)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
    killed = proc.returncode == -signal.SIGKILL
    run(out)
    assert _outputs(out) == _outputs(tmp_path / "reference"), f"killed: {killed}"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["processed"] + summary["skipped_already_done"] == summary["groups"] == 37


def test_a_damaged_sigma_map_is_redone(data, tmp_path, tmp_path_factory):
    """A finished pivot whose σ map is damaged is redone: the resumed outputs are the
    uninterrupted run's, σ maps included."""
    pytest.importorskip("torch")
    options = _options(data, "kpn", stride=7)
    reference = _reference(data, options, tmp_path_factory)
    assert any(k.endswith("_sigma.tiff") for k in reference)
    out = tmp_path / "out"
    process_flight(data / "flight" / "frames.tiff", out, options)
    damaged = sorted((out / "temps").glob("*_sigma.tiff"))[0]
    damaged.write_bytes(damaged.read_bytes()[:-100])
    summary = process_flight(data / "flight" / "frames.tiff", out, options)
    assert summary["processed"] == 1 and summary["sigma_c"]["maps"] == summary["groups"]
    got = _outputs(out)
    log, ref_log = got.pop("log.jsonl").splitlines(), reference["log.jsonl"].splitlines()
    assert log[: len(ref_log)] == ref_log and log[-1] == ref_log[0]  # pivot 3, redone the same
    assert got == {k: v for k, v in reference.items() if k != "log.jsonl"}
