"""Bad input on the command line (issue 18, items 5 and 6): one line on stderr, exit status 2,
no traceback, nothing written, never an input overwritten; warnings as one clean line. The table
covers every command (item 6: at least 60 bad inputs)."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from cli_run import run

from thermocal.cli import main
from thermocal.nn.infer import shipped_model_path

SIZE = "48x32"


def snapshot(*folders: Path) -> dict[str, tuple[str, int]]:
    """Every file under ``folders``: its bytes' hash and its mtime."""
    files = {}
    for folder in folders:
        for path in sorted(folder.rglob("*")):
            if path.is_file() and not path.is_symlink():
                files[str(path)] = (hashlib.sha256(path.read_bytes()).hexdigest(),
                                    path.stat().st_mtime_ns)
    return files


def assert_refused(code: int, out: str, err: str, message: str) -> None:
    """Exit status 2 and one line on stderr, ``thermocal: error: ...`` holding ``message``."""
    lines = err.strip().splitlines()
    assert code == 2, (code, out, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("thermocal: error: "), err
    assert "Traceback" not in err
    assert message in lines[0], lines[0]


def main_ok(args: list) -> None:
    """Run ``thermocal ARGS``, which is to succeed (the fixtures' set-up)."""
    try:
        main([str(a) for a in args])
    except SystemExit as exc:  # pragma: no cover - a broken set-up
        assert exc.code in (0, None), args


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    """A chamber file, polynomial and two-point calibrations of it, a recording of the same unit
    (FPA 30 °C) and variants of it; made once, never to be changed by any test."""
    root = tmp_path_factory.mktemp("inputs")
    chamber = root / "chamber.h5"
    flight = root / "flight"
    for args in (
        ["simulate", "chamber", chamber, "--size", SIZE, "--frames-per-point", "2"],
        ["simulate", "flight", flight, "--size", SIZE, "--frames", "7", "--fpa-c", "30"],
        ["calibrate", chamber, "--method", "polynomial", "--out", root / "cal.h5"],
        ["calibrate", chamber, "--method", "two-point", "--out", root / "cal2.h5"],
    ):
        try:
            main([str(a) for a in args])
        except SystemExit as exc:  # pragma: no cover - a broken set-up
            assert exc.code in (0, None), args
    rec = root / "rec.tiff"
    shutil.copy(flight / "frames.tiff", rec)
    # a chamber session under the name of a checkpoint that `train --out session.pt` writes
    shutil.copy(chamber, root / "session.ckpt")
    shutil.copy(flight / "frames.json", root / "rec.json")
    sidecar = json.loads((flight / "frames.json").read_text())
    for name, fpa in (("fpa1e50", "[1e50, 1e50, 1e50, 1e50, 1e50, 1e50, 1e50]"),
                      ("fpahuge", f"[{10**400}, 30, 30, 30, 30, 30, 30]"),
                      ("fpa_minus100", "[30, 30, 30, 30, 30, 30, -100]")):
        shutil.copy(rec, root / f"{name}.tiff")
        text = json.dumps(sidecar | {"fpa_c": "FPA"}).replace('"FPA"', fpa)
        (root / f"{name}.json").write_text(text)
    # frame times going backwards in the sidecar; one frame above the 14-bit maximum
    shutil.copy(rec, root / "timeback.tiff")
    back = list(sidecar["time_s"])
    back[3], back[4] = back[4], back[3]
    (root / "timeback.json").write_text(json.dumps(sidecar | {"time_s": back}))
    over = tifffile.imread(rec)
    over[3, 0, 0] = 20000
    tifffile.imwrite(root / "over14.tiff", over, photometric="minisblack")
    shutil.copy(root / "rec.json", root / "over14.json")
    frames = tifffile.imread(rec)
    frames[3] = 0
    tifffile.imwrite(root / "deadframe.tiff", frames, photometric="minisblack")
    shutil.copy(root / "rec.json", root / "deadframe.json")
    frames[3] = 5000  # a blank frame: constant, not zero
    tifffile.imwrite(root / "blankframe.tiff", frames, photometric="minisblack")
    shutil.copy(root / "rec.json", root / "blankframe.json")
    # a chamber file whose FPA series is in the wrong unit (1/100 °C)
    shutil.copy(chamber, root / "fpa_centi.h5")
    with h5py.File(root / "fpa_centi.h5", "a") as f:
        f["fpa_c"][...] = f["fpa_c"][()] * 100
    (root / "weights.pt").write_bytes(b"not really weights")
    (root / "empty.pt").write_bytes(b"")
    (root / "notes.txt").write_text("a text file, not weights\n")
    (root / "notes.md").write_text("# my notes, not a benchmark report\n")
    (root / "notes.tiff").write_text("a text file under a map's name\n")
    tifffile.imwrite(root / "camera_frame.tiff", frames[0], photometric="minisblack")  # raw
    # a session held at one ambient (no FPA span)
    main_ok(["simulate", "chamber", root / "constant.h5", "--size", "40x24",
             "--frames-per-point", "2", "--ambient-profile", "constant", "--ambient-c", "25:25"])
    # a session of 2 set points at one ambient, which no fold can cross-validate, and the
    # calibration written from it all the same (--force): without a report
    main_ok(["simulate", "chamber", root / "twopoints.h5", "--size", SIZE, "--frames-per-point",
             "2", "--blackbody-c", "20:40:20", "--ambient-profile", "constant", "--ambient-c",
             "25:25"])
    main_ok(["calibrate", root / "twopoints.h5", "--method", "two-point", "--out",
             root / "cal_unreported.h5", "--force"])
    # a calibration of another size
    main_ok(["simulate", "chamber", root / "small.h5", "--size", "40x24",
             "--frames-per-point", "2"])
    main_ok(["calibrate", root / "small.h5", "--method", "two-point", "--out",
             root / "cal_small.h5"])
    # a burst of 5 frames (the shipped network takes 7)
    tifffile.imwrite(root / "rec5.tiff", tifffile.imread(rec)[:5], photometric="minisblack")
    (root / "rec5.json").write_text(json.dumps({k: (v[:5] if isinstance(v, list) else v)
                                                for k, v in sidecar.items()} | {"pivot": 2}))
    # a measured chamber session (an EnvChamberCtrl conversion says so in its source), and a
    # camera's own recording in a folder as simulate flight would name it
    shutil.copy(chamber, root / "measured.h5")
    with h5py.File(root / "measured.h5", "a") as f:
        f.attrs["source"] = "EnvChamberCtrl"
    (root / "capture").mkdir()
    shutil.copy(rec, root / "capture" / "frames.tiff")
    own = {k: v for k, v in sidecar.items() if k not in ("scene", "preset", "seed", "motion")}
    (root / "capture" / "frames.json").write_text(json.dumps(own))
    # the same flight by another unit of the family (the calibrations are unit 0's)
    main_ok(["simulate", "flight", root / "other_unit", "--size", SIZE, "--frames", "7",
             "--fpa-c", "30", "--unit", "1"])
    shutil.copy(root / "other_unit" / "frames.tiff", root / "other.tiff")
    shutil.copy(root / "other_unit" / "frames.json", root / "other.json")
    # frames with times but no FPA temperature (a sidecar without fpa_c)
    shutil.copy(rec, root / "times_only.tiff")
    (root / "times_only.json").write_text(json.dumps(
        {k: v for k, v in sidecar.items() if k not in ("fpa_c", "fpa_true_c")}))
    # a recording whose sidecar is not JSON
    shutil.copy(rec, root / "badjson.tiff")
    (root / "badjson.json").write_text('{"fpa_c": [30, 30,')
    _bad_recordings(root)
    return {"root": root, "chamber": chamber, "flight": flight, "cal": root / "cal.h5",
            "cal2": root / "cal2.h5", "rec": rec}


def _bad_recordings(root: Path) -> None:
    """Recordings in the other formats that cannot be read as a whole (issue 19)."""
    from PIL import Image
    from test_open_recording import _dualtau_file, _fff, _frames, _rjpeg

    (root / "cut.seq").write_bytes(_fff(_frames(1)[0])[:-50])
    Image.new("RGB", (8, 8)).save(root / "photo.jpg", "JPEG")
    (root / "mixed").mkdir()
    (root / "mixed" / "a.fff").write_bytes(_fff(_frames(1)[0]))
    (root / "mixed" / "b.jpg").write_bytes(_rjpeg(_fff(_frames(1)[0])))
    (root / "sizes").mkdir()
    (root / "sizes" / "a.fff").write_bytes(_fff(_frames(1)[0]))
    (root / "sizes" / "b.fff").write_bytes(_fff(_frames(1, 4, 4)[0]))
    (root / "emptydir").mkdir()
    np.savez(root / "nokeys.npz", frames=_frames(3), time_ns_start=np.arange(3))
    np.savez(root / "backwards.npz", frames=_frames(3), fpa=np.full(3, 3000, np.uint16),
             time_ns_start=np.array([0, 200, 100]))
    np.savez(root / "whole_c.npz", frames=_frames(3), fpa=np.full(3, 31),
             time_ns_start=np.arange(3))
    (root / "overlap").mkdir()
    _dualtau_file(root / "overlap" / "a.npz", _frames(4), np.full(4, 3000), 0)
    _dualtau_file(root / "overlap" / "b.npz", _frames(4), np.full(4, 3000), 150_000_000)
    # a valid DualTauUAV flight of the recording's frames (FPA 30 °C), in two files
    frames = tifffile.imread(root / "rec.tiff")
    (root / "dual").mkdir()
    _dualtau_file(root / "dual" / "a.npz", frames[:4], np.full(4, 3000), 0)
    _dualtau_file(root / "dual" / "b.npz", frames[4:], np.full(3, 3000), 400_000_000)


# ---------------------------------------------------------------------------------------------
# the table: argv -> a piece of the one-line message
# ---------------------------------------------------------------------------------------------

# {root}: the inputs' folder (never changed); {tmp}: this test's own folder (nothing is to be
# created in it); {link}: a symbolic link {tmp}/link.tiff to {root}/rec.tiff
CASES = [
    # a calibration that cannot be cross-validated, written all the same (--force): its report
    # measured no error (it said 'no cross-validation report', though it has one): unchecked
    ("calibrate-two-setpoints-not-cross-validated",
     ["calibrate", "{root}/twopoints.h5", "--method", "two-point", "--out", "{tmp}/c.h5"],
     "cannot be cross-validated on this session"),
    ("correct-with-a-calibration-without-report",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal_unreported.h5", "--out",
      "{tmp}/t.tiff"], "cross-validation report measured no error"),
    ("correct-forced-sigma-of-a-calibration-without-report",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal_unreported.h5", "--out",
      "{tmp}/t.tiff", "--sigma-out", "{tmp}/s.tiff", "--force"],
     "no σ to write to --sigma-out: the calibration's cross-validation report measured no error"),
    ("estimate-with-a-calibration-without-report",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration",
      "{root}/cal_unreported.h5", "--out", "{tmp}/t.tiff"],
     "cross-validation report measured no error"),
    ("flight-with-a-calibration-without-report",
     ["flight", "{root}/flight", "--out", "{tmp}/out", "--method", "calibration",
      "--calibration", "{root}/cal_unreported.h5"], "cross-validation report measured no error"),
    ("selfcal-from-a-calibration-without-report",
     ["flight", "{root}/flight", "--out", "{tmp}/out", "--method", "selfcal",
      "--calibration", "{root}/cal_unreported.h5"], "cross-validation report measured no error"),
    # another camera's frames through a calibration (its fixed pattern left printed on them)
    ("correct-another-units-recording",
     ["correct", "{root}/other.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "not raw frames of the camera the polynomial calibration was made for"),
    ("estimate-another-units-burst",
     ["estimate", "{root}/other.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--out", "{tmp}/t.tiff"], "not raw frames of the camera the polynomial calibration"),
    # a camera whose stillness nothing shows, through a session that never settled
    ("estimate-one-fpa-value-through-an-unsettled-session",
     ["estimate", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal2.h5", "--fpa-c", "30", "--out", "{tmp}/t.tiff"],
     "how long the camera had held it still is not known"),
    ("correct-times-without-fpa-through-an-unsettled-session",
     ["correct", "{root}/times_only.tiff", "--calibration", "{root}/cal2.h5", "--out",
      "{tmp}/t.tiff"], "no history of its FPA was given"),
    # an HDF5 file of the project's given as a recording: which one, and what reads it
    ("flight-on-a-chamber-session", ["flight", "{root}/chamber.h5", "--out", "{tmp}/o"],
     "a chamber session (HDF5), not a recording: `thermocal calibrate` reads it"),
    ("info-on-a-calibration", ["info", "{root}/cal.h5"],
     "a calibration (HDF5), not a recording: `thermocal correct --calibration` uses it"),
    # data loss: an output that would replace a file of another kind
    ("simulate-chamber-over-a-calibration",
     ["simulate", "chamber", "{root}/cal.h5", "--size", "16x16"], "holds a calibration"),
    ("calibrate-over-a-chamber-session",
     ["calibrate", "{root}/chamber.h5", "--method", "two-point", "--out", "{root}/small.h5"],
     "holds a chamber session"),
    ("simulate-chamber-over-a-measured-session",
     ["simulate", "chamber", "{root}/measured.h5", "--size", "16x16"],
     "holds a chamber session from EnvChamberCtrl"),
    ("simulate-flight-over-a-cameras-recording",
     ["simulate", "flight", "{root}/capture", "--size", "48x32"],
     "holds a recording simulate flight did not write"),
    ("calibrate-report-over-a-recordings-sidecar",
     ["calibrate", "{root}/chamber.h5", "--method", "two-point", "--out", "{tmp}/c.h5",
      "--report", "{root}/rec.json"], "not a calibration report"),
    ("simulate-flight-into-a-folder-of-other-files",
     ["simulate", "flight", "{root}", "--size", "48x32"], "simulate flight does not write"),
    # data loss: an output that is an input
    ("correct-over-recording",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{root}/rec.tiff"], "is an input"),
    ("correct-over-a-link-to-the-recording",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out", "{link}"],
     "is an input"),
    ("correct-over-recording-by-another-path",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{root}/../{rootname}/./rec.tiff"], "is an input"),
    ("correct-sigma-over-recording",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out", "{tmp}/t.tiff",
      "--sigma-out", "{root}/rec.tiff"], "--sigma-out"),
    ("correct-sigma-over-its-temperatures",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out", "{tmp}/t.tiff",
      "--sigma-out", "{tmp}/t.tiff"], "is the --out file"),
    ("estimate-sigma-over-recording",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--out", "{tmp}/t.tiff", "--sigma-out", "{root}/rec.tiff"], "--sigma-out"),
    ("estimate-sigma-over-its-temperatures",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--out", "{tmp}/t.tiff", "--sigma-out", "{tmp}/./t.tiff"], "is the --out file"),
    ("calibrate-report-over-chamber",
     ["calibrate", "{root}/chamber.h5", "--out", "{tmp}/c.h5", "--report", "{root}/chamber.h5"],
     "must end in .json"),
    ("calibrate-report-is-the-calibration",
     ["calibrate", "{root}/chamber.h5", "--out", "{tmp}/c.json", "--report", "{tmp}/c.json"],
     "must end in .h5"),
    ("simulate-flight-preset-unknown",
     ["simulate", "flight", "{tmp}/fl", "--preset", "nikon"], "'nikon' is not one of"),
    ("calibrate-over-chamber",
     ["calibrate", "{root}/chamber.h5", "--method", "polynomial", "--out", "{root}/chamber.h5"],
     "is an input"),
    ("nuc-over-recording",
     ["nuc", "{root}/rec.tiff", "--method", "admire", "--out", "{root}/rec.tiff"],
     "is an input"),
    ("estimate-over-recording",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--out", "{root}/rec.tiff"], "is an input"),
    ("flight-over-recording",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration", "{root}/cal.h5",
      "--out", "{root}/rec.tiff"], "is an input"),
    ("flight-over-calibration",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration", "{root}/cal.h5",
      "--out", "{root}/cal.h5"], "is an input"),
    ("train-over-chamber",
     ["train", "--chamber", "{root}/chamber.h5", "--out", "{root}/chamber.h5"], "is an input"),
    ("train-over-init",
     ["train", "--init", "{root}/weights.pt", "--out", "{root}/weights.pt"], "is an input"),
    # what train writes beside --out (a helper's audit: the chamber file was replaced, exit 0)
    ("train-checkpoint-over-chamber",
     ["train", "--chamber", "{root}/session.ckpt", "--out", "{root}/session.pt"],
     "session.ckpt is an input of this command"),
    ("simulate-flight-beside-another-format",
     ["simulate", "flight", "{root}/flight", "--size", SIZE, "--format", "csq"],
     "holds a recording (frames.tiff)"),
    ("estimate-selfcal-sigma-out",
     ["estimate", "{root}/rec.tiff", "--method", "selfcal", "--out", "{tmp}/t.tiff",
      "--sigma-out", "{tmp}/s.tiff"], "selfcal fits a whole pass"),
    ("estimate-camera-fpa-c",
     ["estimate", "{root}/rec.tiff", "--method", "camera", "--fpa-c", "30", "--out",
      "{tmp}/t.tiff"], "leave --fpa-c out"),
    ("flight-camera-force-no-constants",
     ["flight", "{root}/rec.tiff", "--method", "camera", "--force", "--out", "{tmp}/o"],
     "needs the camera's Planck constants in every frame"),
    ("export-a-file-and-a-method",
     ["export", "{root}/weights.pt", "--method", "e2e", "--out", "{tmp}/e.onnx"],
     "leave --method out"),
    ("campaign-scheduler-and-workers",
     ["campaign", "{root}/rec.tiff", "--out", "{tmp}/c", "--scheduler", "tcp://127.0.0.1:1",
      "--workers", "3"], "leave --workers out"),
    # the remedy is a session that would pass: not the same narrow ambient range again
    ("calibrate-one-ambient",
     ["calibrate", "{root}/constant.h5", "--method", "polynomial", "--out", "{tmp}/c.h5"],
     "or all the frames; record steps: `thermocal simulate chamber OUT.h5 --preset tau2 "
     "--unit 0 --size 40x24 --ambient-profile steps --ambient-c 10:40"),
    ("info-times-going-backwards", ["info", "{root}/timeback.tiff"],
     "frame times go backwards (frame 4 is"),
    ("correct-times-going-backwards",
     ["correct", "{root}/timeback.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "frame times go backwards"),
    ("correct-one-frame-above-14-bit",
     ["correct", "{root}/over14.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "counts outside the 14-bit range 0..16383 from frame 3 on"),
    ("flight-hfov-without-geotiff",
     ["flight", "{root}/rec.tiff", "--hfov-deg", "45", "--out", "{tmp}/o"],
     "give --geotiff, or leave --hfov-deg out"),
    ("flight-hfov-400", ["flight", "{root}/rec.tiff", "--geotiff", "--hfov-deg", "400",
                         "--out", "{tmp}/o"], "--hfov-deg must be between 0 and 180 degrees"),
    ("mosaic-of-a-recording", ["mosaic", "{root}/rec.tiff"],
     "is a file; mosaic takes the folder"),
    # counts of threads or processes no machine of this size can run (one allocated 4 GB)
    ("flight-threads-a-million",
     ["flight", "{root}/rec.tiff", "--out", "{tmp}/o", "--threads", "1000000"],
     "--threads 1000000: more than 4 per CPU core"),
    ("campaign-workers-a-million",
     ["campaign", "{root}/rec.tiff", "--out", "{tmp}/c", "--workers", "1000000", "--method",
      "mean", "--calibration", "{root}/cal.h5"], "--workers 1000000: more than 4 per CPU core"),
    # options a flight refuses up front, refused before a cluster starts (a helper's audit:
    # the campaign folder and campaign.json were written first)
    ("campaign-fpa-1e12",
     ["campaign", "{root}/rec.tiff", "--out", "{tmp}/c", "--fpa-c", "1e12"],
     "--fpa-c: 1e+12 °C is not a plausible FPA temperature"),
    ("campaign-fpa-below-absolute-zero",
     ["campaign", "{root}/rec.tiff", "--out", "{tmp}/c", "--fpa-c", "-300"],
     "--fpa-c: -300 °C is at or below absolute zero"),
    ("campaign-fpa-nan",
     ["campaign", "{root}/rec.tiff", "--out", "{tmp}/c", "--fpa-c", "nan"],
     "--fpa-c: nan °C is not a plausible FPA temperature"),
    ("campaign-group-longer-than-every-recording",
     ["campaign", "{root}/rec.tiff", "--out", "{tmp}/c", "--frames", "1000000000000"],
     "--frames 1000000000000: a group longer than every recording (the longest has 7"),
    # outputs mixed in beside another recording's frames
    ("flight-into-a-recordings-folder",
     ["flight", "{root}/rec.tiff", "--out", "{root}/flight", "--method", "mean",
      "--calibration", "{root}/cal.h5"], "flight: holds a recording (frames.tiff"),
    ("campaign-into-a-recordings-folder",
     ["campaign", "{root}/rec.tiff", "--out", "{root}/flight", "--method", "mean",
      "--calibration", "{root}/cal.h5"], "flight: holds a recording (frames.tiff"),
    ("flight-selfcal-family-and-calibration",
     ["flight", "{root}/rec.tiff", "--out", "{tmp}/o", "--method", "selfcal", "--family",
      "boson", "--calibration", "{root}/cal.h5"], "with --calibration it starts from that"),
    ("info-of-network-weights", ["info", "{shipped}"],
     "a PyTorch file (network weights?), not a recording"),
    # the unit's Planck constants are fitted before any work: nothing left behind
    ("simulate-flight-seq-saturating",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--preset", "boson", "--fpa-c", "120",
      "--format", "seq"], "saturates at FPA 120 °C"),
    ("simulate-flight-over-its-scene",
     ["simulate", "flight", "{root}/flight", "--size", SIZE, "--scene",
      "{root}/flight/truth.tiff"], "is an input"),
    # impossible FPA temperatures
    ("correct-fpa-1e6",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--fpa-c", "1e6",
      "--out", "{tmp}/t.tiff"], "--fpa-c: 1e+06 °C is not a plausible FPA temperature"),
    ("correct-fpa-minus-270",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--fpa-c", "-270",
      "--out", "{tmp}/t.tiff"], "not a plausible FPA temperature"),
    ("correct-fpa-nan",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--fpa-c", "nan",
      "--out", "{tmp}/t.tiff"], "not a plausible FPA temperature"),
    ("correct-sidecar-fpa-1e50",
     ["correct", "{root}/fpa1e50.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "fpa1e50.json: fpa_c: value 0: 1e+50 °C is not a plausible"),
    ("correct-sidecar-fpa-huge-integer",
     ["correct", "{root}/fpahuge.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "fpahuge.json: 'fpa_c' holds a number too large"),
    ("correct-sidecar-fpa-minus-100",
     ["correct", "{root}/fpa_minus100.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "value 6: -100 °C is not a plausible FPA temperature"),
    ("estimate-fpa-1e6",
     ["estimate", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--fpa-c", "1e6", "--out", "{tmp}/t.tiff"], "not a plausible FPA"),
    ("flight-fpa-1e6",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration", "{root}/cal.h5",
      "--fpa-c", "1e6", "--out", "{tmp}/out"], "not a plausible FPA"),
    ("simulate-flight-fpa-1e6",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--fpa-c", "1e6"],
     "--fpa-c: 1e+06 °C is not a plausible FPA temperature"),
    ("calibrate-fpa-ref-500",
     ["calibrate", "{root}/chamber.h5", "--method", "two-point", "--fpa-ref-c", "500",
      "--out", "{tmp}/c.h5"], "--fpa-ref-c: 500 °C is not a plausible FPA"),
    ("calibrate-chamber-fpa-in-centi-degrees",
     ["calibrate", "{root}/fpa_centi.h5", "--method", "polynomial", "--out", "{tmp}/c.h5"],
     "fpa_centi.h5: dataset 'fpa_c': value"),
    ("simulate-chamber-ambient-beyond-the-fpa-range",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--ambient-c", "200:300"],
     "puts the FPA at 205.5 °C"),
    # tracebacks before: NaN, inf, sizes beyond reason
    ("simulate-chamber-blackbody-nan",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--blackbody-c", "nan:70:10"],
     "finite numbers"),
    ("simulate-chamber-blackbody-inf",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--blackbody-c", "10:inf:10"],
     "finite numbers"),
    ("simulate-chamber-blackbody-step-nan",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--blackbody-c", "10:70:nan"],
     "finite numbers"),
    ("simulate-chamber-blackbody-step-tiny",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--blackbody-c", "10:1e308:1e-300"],
     "set points is too many"),
    ("simulate-chamber-interval-nan",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--interval-s", "nan"],
     "--interval-s: expected a finite number"),
    ("simulate-chamber-rate-nan",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--rate-c-per-min", "nan"],
     "--rate-c-per-min: expected a finite number"),
    ("simulate-chamber-duration-1e12",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--duration-min", "1e12"],
     "6e+12 frames"),
    ("simulate-chamber-interval-tiny",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--interval-s", "1e-300",
      "--duration-min", "1e300"], "inf frames"),
    ("simulate-chamber-8192",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", "8192x8192"],
     "frames of 8192x8192 are 5.64e+10 pixels, more than thermocal makes in one run"),
    ("simulate-flight-1e12-frames",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--frames", "1000000000000"],
     "1000000000000 frames is more than thermocal makes"),
    ("simulate-flight-8192",
     ["simulate", "flight", "{tmp}/out", "--size", "8192x8192", "--frames", "1000"],
     "more than thermocal makes in one run"),
    ("simulate-flight-fps-nan",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--fps", "nan"],
     "frame rate must be > 0"),
    # misleading messages before
    ("correct-dead-frame",
     ["correct", "{root}/deadframe.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "deadframe.tiff: frames: frame 3 is all zero (a dead frame"),
    ("nuc-dead-frame",
     ["nuc", "{root}/deadframe.tiff", "--method", "admire", "--out", "{tmp}/t.tiff"],
     "deadframe.tiff: frames: frame 3 is all zero"),
    # late checks before
    ("simulate-flight-fps-0",
     ["simulate", "flight", "{tmp}/out/sub", "--size", SIZE, "--fps", "0"],
     "frame rate must be > 0"),
    ("simulate-chamber-into-a-tiff",
     ["simulate", "chamber", "{tmp}/c.tiff", "--size", SIZE], "must end in .h5 or .hdf5"),
    ("bench-json-into-a-missing-folder",
     ["bench", "--quick", "--json", "{tmp}/missing/r.json"], "does not exist"),
    # every command (issue 18, item 6)
    # simulate chamber
    ("simulate-chamber-size-malformed",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", "48by32"],
     "size '48by32': expected WIDTHxHEIGHT"),
    ("simulate-chamber-preset-unknown",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--preset", "nope"],
     "'nope' is not one of 'tau2', 'boson'"),
    ("simulate-chamber-frames-per-point-0",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--frames-per-point", "0"],
     "frames per point must be >= 1, got 0"),
    ("simulate-chamber-emissivity-2",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--emissivity", "2"],
     "--emissivity must be <= 1, got 2"),
    ("simulate-chamber-into-a-missing-folder",
     ["simulate", "chamber", "{tmp}/missing/c.h5", "--size", SIZE],
     "missing: output folder does not exist"),
    # simulate flight
    ("simulate-flight-frames-0",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--frames", "0"],
     "a flight needs at least 1 frame, got 0"),
    ("simulate-flight-scene-missing",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--scene", "{root}/nope.tiff"],
     "nope.tiff: file not found"),
    ("simulate-flight-size-zero",
     ["simulate", "flight", "{tmp}/out", "--size", "0x32"],
     "width and height must be between 8 and 8192"),
    ("simulate-flight-into-a-file",
     ["simulate", "flight", "{root}/notes.txt", "--size", SIZE], "notes.txt: exists and is a file"),
    # calibrate
    ("calibrate-chamber-missing",
     ["calibrate", "{root}/nope.h5", "--out", "{tmp}/c.h5"], "nope.h5: no such file"),
    ("calibrate-chamber-a-text-file",
     ["calibrate", "{root}/notes.txt", "--out", "{tmp}/c.h5"],
     "notes.txt: not a readable HDF5 file"),
    ("calibrate-out-not-h5",
     ["calibrate", "{root}/chamber.h5", "--out", "{tmp}/c.tiff"],
     "c.tiff: the output must end in .h5 or .hdf5"),
    ("calibrate-method-unknown",
     ["calibrate", "{root}/chamber.h5", "--method", "nope", "--out", "{tmp}/c.h5"],
     "Invalid value for '--method': 'nope'"),
    # correct
    ("correct-recording-missing",
     ["correct", "{root}/nope.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "nope.tiff: no such file"),
    ("correct-calibration-of-another-size",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal_small.h5", "--out",
      "{tmp}/t.tiff"], "rec.tiff: each frame is 48x32 but the calibration is 40x24 ("),
    ("correct-calibration-a-text-file",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/notes.txt", "--out",
      "{tmp}/t.tiff"], "notes.txt: unreadable calibration file"),
    ("correct-sidecar-not-json",
     ["correct", "{root}/badjson.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "badjson.json: not valid JSON"),
    ("correct-out-not-tiff",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.png"], "t.png: the output must end in .tif or .tiff"),
    # nuc
    ("nuc-recording-missing",
     ["nuc", "{root}/nope.tiff", "--method", "admire", "--out", "{tmp}/t.tiff"],
     "nope.tiff: no such file"),
    ("nuc-method-missing",  # click lists the choices a line each: one line here
     ["nuc", "{root}/rec.tiff", "--out", "{tmp}/t.tiff"],
     "Missing option '--method'. Choose from: harris1999, scribner"),
    ("report-of-a-folder-that-is-not-a-flights-output",
     ["report", "{root}/emptydir"], "summary.json: missing"),
    ("report-of-no-folder",
     ["report", "{root}/nope"], "not a folder"),
    ("nuc-method-unknown",
     ["nuc", "{root}/rec.tiff", "--method", "nope", "--out", "{tmp}/t.tiff"],
     "Invalid value for '--method': 'nope'"),
    ("nuc-out-into-a-missing-folder",
     ["nuc", "{root}/rec.tiff", "--method", "admire", "--out", "{tmp}/missing/t.tiff"],
     "missing: output folder does not exist"),
    # estimate
    ("estimate-mean-without-calibration",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--out", "{tmp}/t.tiff"],
     "--method mean needs a per-pixel calibration"),
    ("estimate-calibration-without-calibration",
     ["estimate", "{root}/rec.tiff", "--method", "calibration", "--out", "{tmp}/t.tiff"],
     "--method calibration needs a per-pixel calibration"),
    # refused outside the calibration's FPA range: the refusal alone, not the calibration's
    # warning that its temperatures may be off before it
    ("estimate-calibration-fpa-outside-its-range",
     ["estimate", "{root}/rec.tiff", "--method", "calibration", "--calibration", "{root}/cal.h5",
      "--fpa-c", "60", "--out", "{tmp}/t.tiff"], "the polynomial calibration was fitted on"),
    ("estimate-mean-fpa-outside-its-range",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--fpa-c", "60", "--out", "{tmp}/t.tiff"], "the polynomial calibration was fitted on"),
    ("estimate-kpn-pivot-out-of-range",
     ["estimate", "{root}/rec.tiff", "--pivot", "7", "--out", "{tmp}/t.tiff"],
     "pivot 7 is outside the burst (frames 0..6)"),
    ("estimate-mean-pivot-negative",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--pivot", "-1", "--out", "{tmp}/t.tiff"], "pivot -1 is outside the burst (frames 0..6)"),
    ("estimate-registered-with-the-shipped-network",
     ["estimate", "{root}/rec.tiff", "--registered", "--out", "{tmp}/t.tiff"],
     "(not --registered)"),
    ("estimate-calibration-of-another-size",
     ["estimate", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal_small.h5", "--out", "{tmp}/t.tiff"],
     "frames are 48x32 but the calibration is 40x24"),
    ("estimate-mean-calibration-of-another-size",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration",
      "{root}/cal_small.h5", "--out", "{tmp}/t.tiff"],
     "frames are 48x32 but the calibration is 40x24"),
    ("estimate-burst-of-the-wrong-length",
     ["estimate", "{root}/rec5.tiff", "--out", "{tmp}/t.tiff"], "trained for N = 7 frames, got 5"),
    ("estimate-model-empty-file",
     ["estimate", "{root}/rec.tiff", "--model", "{root}/empty.pt", "--out", "{tmp}/t.tiff"],
     "empty.pt: not a thermocal weights file"),
    ("estimate-model-a-text-file",
     ["estimate", "{root}/rec.tiff", "--model", "{root}/notes.txt", "--out", "{tmp}/t.tiff"],
     "notes.txt: not a thermocal weights file"),
    ("estimate-model-a-calibration-file",
     ["estimate", "{root}/rec.tiff", "--model", "{root}/cal.h5", "--out", "{tmp}/t.tiff"],
     "cal.h5: not a thermocal weights file"),
    ("estimate-kpn-no-offset-not-shipped",
     ["estimate", "{root}/rec.tiff", "--method", "kpn-no-offset", "--out", "{tmp}/t.tiff"],
     "no kpn-no-offset model is shipped"),
    ("estimate-e2e-with-a-kpn-model",
     ["estimate", "{root}/rec.tiff", "--method", "e2e", "--model", "{shipped}", "--out",
      "{tmp}/t.tiff"], "kpn_n7.pt holds the variant kpn, not e2e"),
    ("estimate-method-unknown",
     ["estimate", "{root}/rec.tiff", "--method", "nope", "--out", "{tmp}/t.tiff"],
     "Invalid value for '--method': 'nope'"),
    # train (each refused before any training)
    # options the method would ignore (the user would believe them used)
    ("estimate-kpn-with-a-calibration",
     ["estimate", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out", "{tmp}/t.tiff"],
     "--method kpn does not use one"),
    ("estimate-mean-with-a-model",
     ["estimate", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/cal.h5",
      "--model", "{root}/weights.pt", "--out", "{tmp}/t.tiff"], "--method mean runs none"),
    ("flight-kpn-with-a-family",
     ["flight", "{root}/rec.tiff", "--family", "boson", "--out", "{tmp}/out"],
     "--method kpn does not use one"),
    ("calibrate-two-point-with-a-scene-term",
     ["calibrate", "{root}/chamber.h5", "--method", "two-point", "--scene-term", "t4", "--out",
      "{tmp}/c.h5"], "--scene-term applies to --method polynomial only"),
    ("calibrate-polynomial-with-a-reference-fpa",
     ["calibrate", "{root}/chamber.h5", "--method", "polynomial", "--fpa-ref-c", "30", "--out",
      "{tmp}/c.h5"], "--method polynomial takes no reference FPA temperature"),
    # a bad option named as the user gave it (the function's keyword named it before)
    ("mosaic-clip-sigma-nan", ["mosaic", "{tmp}", "--clip-sigma", "nan"],
     "--clip-sigma: expected a finite number"),
    ("mosaic-memory-too-small", ["mosaic", "{tmp}", "--memory-mb", "0"],
     "--memory-mb must be >= 16"),
    ("export-a-folder", ["export", "{tmp}", "--out", "{tmp}/e.onnx"],
     "a folder, not a weights file"),
    ("export-a-variant-not-shipped",
     ["export", "--method", "e2e", "--out", "{tmp}/e.onnx"], "export: MODEL.pt"),
    ("bench-one-file-for-both-outputs",
     ["bench", "--quick", "--json", "{tmp}/b.md", "--markdown", "{tmp}/b.md"],
     "is the --json file"),
    ("demo-out-empty", ["demo", "--out", ""], "--out: an empty value (an unset shell"),
    ("correct-blank-frame-forced",  # blamed on the scene range; forced, written at -60 °C
     ["correct", "{root}/blankframe.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff", "--force"], "blankframe.tiff: frames: frame 3 is constant"),
    ("estimate-camera-registered",  # accepted, and without any effect
     ["estimate", "{root}/rec.tiff", "--method", "camera", "--registered", "--out",
      "{tmp}/t.tiff"], "--registered: --method camera maps the pivot frame alone"),
    ("estimate-fpa-sigma-without-fpa",
     ["estimate", "{root}/rec.tiff", "--fpa-sigma-c", "2", "--out", "{tmp}/t.tiff"],
     "--fpa-sigma-c is the uncertainty of --fpa-c: give --fpa-c too"),
    ("estimate-fpa-sigma-without-sigma-out",  # a second pass for nothing
     ["estimate", "{root}/rec.tiff", "--fpa-c", "30", "--fpa-sigma-c", "2", "--out",
      "{tmp}/t.tiff"], "--fpa-sigma-c grows σ: give --sigma-out too"),
    ("correct-fpa-sigma-without-sigma-out",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--fpa-c", "30",
      "--fpa-sigma-c", "2", "--out", "{tmp}/t.tiff"], "--fpa-sigma-c grows σ: give --sigma-out"),
    ("flight-fpa-sigma-negative",
     ["flight", "{root}/rec.tiff", "--fpa-c", "30", "--fpa-sigma-c", "-1", "--out",
      "{tmp}/o"], "--fpa-sigma-c must be 0-20 °C, got -1"),
    ("simulate-chamber-visits-one-set-point",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--frames-per-point", "1000"],
     "--frames-per-point 1000: the session's 840 frames visit 1 of its 7 set points"),
    # an output over a file of another kind (a helper's audit: each replaced it, exit 0)
    ("correct-over-another-recording",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{root}/other.tiff"], "exists and holds raw counts, a recording's frames (its sidecar"),
    ("nuc-over-a-camera-frame",
     ["nuc", "{root}/rec.tiff", "--method", "admire", "--out", "{root}/camera_frame.tiff"],
     "camera_frame.tiff: exists and holds raw counts, which writing it would lose"),
    ("estimate-sigma-over-a-recording",
     ["estimate", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--out", "{tmp}/t.tiff", "--sigma-out", "{root}/other.tiff"],
     "other.tiff: exists and holds raw counts, a recording's frames"),
    ("correct-over-a-text-file",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/cal.h5", "--out",
      "{root}/notes.tiff"], "exists and holds a file that is not a TIFF"),
    ("bench-json-over-a-chamber", ["bench", "--json", "{root}/chamber.h5"],
     "must end in .json"),
    ("bench-json-over-a-sidecar", ["bench", "--json", "{root}/rec.json"],
     "exists and is not a benchmark JSON"),
    ("bench-markdown-over-notes", ["bench", "--markdown", "{root}/notes.md"],
     "exists and is not a benchmark report"),
    ("flight-out-empty", ["flight", "{root}/rec.tiff", "--out", ""], "--out: an empty value"),
    ("campaign-out-empty-equals", ["campaign", "{root}/rec.tiff", "--out="],
     "--out: an empty value"),
    ("correct-empty-recording", ["correct", "", "--calibration", "{root}/cal.h5", "--out",
                                 "{tmp}/t.tiff"], "argument 2: an empty value"),
    ("simulate-chamber-blackbody-beyond-the-simulator",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--blackbody-c", "10:10000:10"],
     "blackbody set points: 10…10000 °C go beyond the -123.15…626.85 °C the camera simulator"),
    # numbers no run can use (they started a 30-minute training run, or a traceback)
    ("train-max-minutes-nan", ["train", "--out", "{tmp}/w.pt", "--max-minutes", "nan"],
     "--max-minutes must be a number > 0, got nan"),
    ("train-lr-inf", ["train", "--out", "{tmp}/w.pt", "--lr", "inf"],
     "--lr must be a number > 0, got inf"),
    ("train-lr-nan", ["train", "--out", "{tmp}/w.pt", "--lr", "nan"], "--lr must be a number > 0"),
    ("train-seed-negative", ["train", "--out", "{tmp}/w.pt", "--seed", "-3"],
     "'--seed': -3 is not in the range"),
    ("simulate-chamber-seed-negative",
     ["simulate", "chamber", "{tmp}/c.h5", "--size", SIZE, "--seed", "-1"],
     "'--seed': -1 is not in the range"),
    ("simulate-flight-seed-negative",
     ["simulate", "flight", "{tmp}/f", "--size", SIZE, "--seed", "-1"],
     "'--seed': -1 is not in the range"),
    ("train-chamber-missing",
     ["train", "--chamber", "{root}/nope.h5", "--out", "{tmp}/w.pt"], "nope.h5: no such file"),
    ("train-chamber-a-text-file",
     ["train", "--chamber", "{root}/notes.txt", "--out", "{tmp}/w.pt"],
     "notes.txt: not a readable HDF5 file"),
    ("train-init-not-weights",
     ["train", "--init", "{root}/notes.txt", "--out", "{tmp}/w.pt"],
     "notes.txt: not a thermocal weights file"),
    ("train-init-missing",
     ["train", "--init", "{root}/nope.pt", "--out", "{tmp}/w.pt"], "nope.pt: no such weights file"),
    ("train-out-not-pt",
     ["train", "--out", "{tmp}/w.h5"], "w.h5: the weights file must end in .pt"),
    ("train-units-malformed",
     ["train", "--units", "0-x", "--out", "{tmp}/w.pt"], "units '0-x': expected e.g. 0-23"),
    ("train-fpa-range-reversed",
     ["train", "--fpa-range-c", "50:10", "--out", "{tmp}/w.pt"],
     "--fpa-range-c '50:10': A must be below B"),
    ("train-steps-0",
     ["train", "--steps", "0", "--out", "{tmp}/w.pt"], "--steps must be >= 1, got 0"),
    ("train-steps-negative",
     ["train", "--steps", "-5", "--out", "{tmp}/w.pt"], "--steps must be >= 1, got -5"),
    ("train-preset-unknown",
     ["train", "--preset", "nope", "--out", "{tmp}/w.pt"], "Invalid value for '--preset': 'nope'"),
    ("train-val-units-among-training-units",
     ["train", "--val-units", "3", "--out", "{tmp}/w.pt"],
     "validation units must not be training units"),
    pytest.param(
        "train-device-cuda-without-a-gpu",
        ["train", "--device", "cuda", "--out", "{tmp}/w.pt"],
        "device cuda asked for, but PyTorch sees no GPU",
        marks=pytest.mark.skipif("_has_gpu()", reason="this machine has a GPU")),
    # flight
    ("flight-recording-missing",
     ["flight", "{root}/nope.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--out", "{tmp}/out"], "nope.tiff: no such file"),
    ("flight-sidecar-not-json",
     ["flight", "{root}/badjson.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--out", "{tmp}/out"], "badjson.json: not valid JSON"),
    ("flight-frames-0",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--frames", "0", "--out", "{tmp}/out"],
     "--frames and --stride must be >= 1"),
    ("flight-stride-0",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--stride", "0", "--out", "{tmp}/out"],
     "--frames and --stride must be >= 1"),
    ("flight-calibration-of-another-size",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal_small.h5", "--out", "{tmp}/out"],
     "the calibration is 40x24 but the frames are 48x32"),
    ("flight-mean-without-calibration",
     ["flight", "{root}/rec.tiff", "--method", "mean", "--out", "{tmp}/out"],
     "--method mean needs --calibration"),
    ("flight-model-of-another-variant",
     ["flight", "{root}/rec.tiff", "--method", "kpn-no-offset", "--model", "{shipped}",
      "--out", "{tmp}/out"], "kpn_n7.pt holds the variant kpn, not kpn-no-offset"),
    ("flight-model-a-text-file",
     ["flight", "{root}/rec.tiff", "--model", "{root}/notes.txt", "--out", "{tmp}/out"],
     "notes.txt: not a thermocal weights file"),
    # bench
    ("bench-only-unknown",
     ["bench", "--quick", "--only", "nope"], "Invalid value for '--only': 'nope'"),
    ("bench-markdown-a-directory",
     ["bench", "--quick", "--only", "simulator", "--markdown", "{root}/flight"],
     "flight' is a directory"),
    ("flight-recording-shorter-than-a-group",
     ["flight", "{root}/rec5.tiff", "--out", "{tmp}/out"],
     "the recording has 5 frames, fewer than a group of 7"),
    ("flight-preview-every-negative",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--preview-every", "-1", "--out", "{tmp}/out"],
     "--preview-every must be >= 0"),
    ("flight-calibration-a-weights-file",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration", "{shipped}",
      "--out", "{tmp}/out"], "kpn_n7.pt: unreadable calibration file"),
    ("flight-calibration-a-chamber-file-into-new-folders",
     ["flight", "{root}/rec.tiff", "--method", "mean", "--calibration", "{root}/chamber.h5",
      "--out", "{tmp}/new/out"], "chamber.h5: a chamber session, not a calibration"),
    ("flight-fpa-nan",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--fpa-c", "nan", "--out", "{tmp}/out"],
     "--fpa-c: nan °C is not a plausible FPA temperature"),
    ("flight-out-an-existing-file",
     ["flight", "{root}/rec.tiff", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--out", "{root}/notes.txt"], "notes.txt: exists and is a file"),
    ("correct-calibration-a-chamber-file",
     ["correct", "{root}/rec.tiff", "--calibration", "{root}/chamber.h5", "--out",
      "{tmp}/t.tiff"], "chamber.h5: a chamber session, not a calibration: fit one from it"),
    ("calibrate-chamber-a-calibration-file",
     ["calibrate", "{root}/cal.h5", "--out", "{tmp}/c.h5"],
     "cal.h5: a calibration, not a chamber session: give the chamber session"),
    ("nuc-out-a-directory",
     ["nuc", "{root}/rec.tiff", "--method", "admire", "--out", "{root}/flight"],
     "flight' is a directory"),
    ("simulate-flight-scene-a-text-file",
     ["simulate", "flight", "{tmp}/out", "--size", SIZE, "--scene", "{root}/notes.txt"],
     "notes.txt: unknown file format"),
    # recordings of any format, files or folders (issue 19)
    ("estimate-a-folder-without-a-recording",
     ["estimate", "{root}/emptydir", "--out", "{tmp}/t.tiff"], "no recording in the folder"),
    ("info-a-folder-without-a-recording",
     ["info", "{root}/emptydir"], "emptydir: no recording in the folder"),
    ("correct-seq-truncated",
     ["correct", "{root}/cut.seq", "--calibration", "{root}/cal.h5", "--fpa-c", "30", "--out",
      "{tmp}/t.tiff"], "cut.seq: truncated"),
    ("nuc-jpeg-without-flir-records",
     ["nuc", "{root}/photo.jpg", "--method", "admire", "--out", "{tmp}/t.tiff"],
     "photo.jpg: JPEG without FLIR radiometric data"),
    ("flight-folder-of-mixed-formats",
     ["flight", "{root}/mixed", "--method", "camera", "--out", "{tmp}/out"],
     "files of mixed formats"),
    ("estimate-folder-of-mixed-sizes",
     ["estimate", "{root}/sizes", "--method", "camera", "--out", "{tmp}/t.tiff"],
     "b.fff: frames of 4x4 in a folder of 8x6"),
    ("correct-npz-missing-keys",
     ["correct", "{root}/nokeys.npz", "--calibration", "{root}/cal.h5", "--out",
      "{tmp}/t.tiff"], "nokeys.npz: missing array(s) ['fpa']"),
    ("flight-npz-times-backwards",
     ["flight", "{root}/backwards.npz", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--out", "{tmp}/out"], "frame times go backwards inside the file"),
    ("nuc-npz-fpa-in-whole-degrees",
     ["nuc", "{root}/whole_c.npz", "--method", "admire", "--out", "{tmp}/t.tiff"],
     "more likely whole °C"),
    ("nuc-out-inside-the-recording-folder",
     ["nuc", "{root}/dual", "--method", "admire", "--out", "{root}/dual/t.tiff"],
     "is inside the recording's folder"),
    ("correct-sigma-out-inside-the-recording-folder",
     ["correct", "{root}/dual", "--calibration", "{root}/cal.h5", "--out", "{tmp}/t.tiff",
      "--sigma-out", "{root}/dual/s.tiff"], "--sigma-out"),
    ("estimate-npz-files-overlapping-in-time",
     ["estimate", "{root}/overlap", "--method", "calibration", "--calibration",
      "{root}/cal.h5", "--out", "{tmp}/t.tiff"], "b.npz: its frames overlap in time those of"),
    ("estimate-model-a-directory",
     ["estimate", "{root}/rec.tiff", "--model", "{root}/flight", "--out", "{tmp}/t.tiff"],
     "flight' is a directory"),
    ("estimate-fpa-inf",
     ["estimate", "{root}/rec.tiff", "--fpa-c", "inf", "--out", "{tmp}/t.tiff"],
     "fpa_c: inf °C is not a plausible FPA temperature"),
    ("train-chamber-a-calibration-file",
     ["train", "--chamber", "{root}/cal.h5", "--out", "{tmp}/w.pt"],
     "cal.h5: a calibration, not a chamber session: give the chamber session"),
    ("train-chamber-a-directory",
     ["train", "--chamber", "{root}/flight", "--out", "{tmp}/w.pt"], "flight' is a directory"),
    ("train-init-a-calibration-file",
     ["train", "--init", "{root}/cal.h5", "--out", "{tmp}/w.pt"],
     "cal.h5: not a thermocal weights file"),
    ("train-frames-0",
     ["train", "--frames", "0", "--out", "{tmp}/w.pt"], "--frames must be >= 1, got 0"),
    ("train-crop-larger-than-the-sensor",
     ["train", "--crop", "1000", "--out", "{tmp}/w.pt"],
     "--crop 1000 (the training crop, px) is larger than the sensor, 336x256: give --crop 256"),
    ("train-out-into-a-missing-folder",
     ["train", "--out", "{tmp}/missing/w.pt"], "missing: output folder does not exist"),
    ("train-resume-without-a-checkpoint",
     ["train", "--resume", "--out", "{tmp}/w.pt"], "w.ckpt: no checkpoint to resume from"),
    ("bench-markdown-into-a-missing-folder",
     ["bench", "--quick", "--only", "simulator", "--markdown", "{tmp}/missing/r.md"],
     "missing: output folder does not exist"),
    ("demo-out-under-a-file",
     ["demo", "--out", "{root}/notes.txt/sub"], "notes.txt/sub: cannot create the directory"),
    # demo
    ("demo-out-an-existing-file",
     ["demo", "--out", "{root}/notes.txt"], "notes.txt: exists and is a file"),
]


def _has_gpu() -> bool:
    import torch

    return torch.cuda.is_available()


def _case(case):
    """A table row as a pytest parameter whose id is the row's name."""
    name, *values = case.values if hasattr(case, "marks") else case
    return pytest.param(*values, id=name, marks=getattr(case, "marks", ()))


@pytest.mark.parametrize("args, message", [_case(c) for c in CASES])
def test_bad_input_is_one_line_and_exit_2_and_changes_nothing(inputs, tmp_path, capsys, args,
                                                               message):
    root = inputs["root"]
    (tmp_path / "link.tiff").symlink_to(root / "rec.tiff")
    args = [a.format(root=root, tmp=tmp_path, link=tmp_path / "link.tiff", rootname=root.name,
                     shipped=shipped_model_path("kpn"))
            for a in args]
    before = snapshot(root)
    code, out, err = run(args, capsys)
    assert_refused(code, out, err, message)
    assert snapshot(root) == before  # no input changed, nothing written beside them
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.tiff"]  # nothing created


@pytest.mark.parametrize("command", [
    ["correct", "{fifo}", "--calibration", "{cal}", "--out", "{tmp}/t.tiff"],
    ["flight", "{fifo}", "--out", "{tmp}/o"],
    ["estimate", "{rec}", "--method", "calibration", "--calibration", "{fifo}", "--out",
     "{tmp}/t.tiff"],
    ["flight", "{rec}", "--method", "selfcal", "--reference={fifo}", "--out", "{tmp}/o"],
])
def test_a_fifo_is_refused_not_waited_on(inputs, tmp_path, capsys, command):
    """A FIFO named like a recording blocked a reading command for good (a helper's audit):
    refused in one line before anything opens it, nothing written."""
    import os

    fifo = tmp_path / "pipe.tiff"
    os.mkfifo(fifo)
    args = [a.format(fifo=fifo, cal=inputs["cal"], rec=inputs["rec"], tmp=tmp_path)
            for a in command]
    code, out, err = run(args, capsys)
    assert_refused(code, out, err, f"{fifo}: not a file or a folder (a pipe, a device)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe.tiff"]


def test_a_sidecar_that_is_a_fifo_is_refused_not_waited_on(inputs, tmp_path, capsys):
    """A recording whose sidecar is a FIFO hung every command that read it (a review)."""
    import os

    shutil.copy(inputs["rec"], tmp_path / "r.tiff")
    os.mkfifo(tmp_path / "r.json")
    code, out, err = run(["info", tmp_path / "r.tiff"], capsys)
    assert_refused(code, out, err, "r.json: not a file (a pipe, a device)")


def test_an_empty_placeholder_or_a_dangling_link_is_an_output_to_write(inputs, tmp_path,
                                                                       capsys):
    """An empty file at --out (mktemp's placeholder) or a link to nothing holds nothing to
    lose: written (a review: both were refused as files of another kind)."""
    (tmp_path / "empty.tiff").write_bytes(b"")
    (tmp_path / "dangling.tiff").symlink_to(tmp_path / "nowhere.tiff")
    for name in ("empty.tiff", "dangling.tiff"):
        code, _, err = run(["correct", inputs["rec"], "--calibration", inputs["cal"], "--out",
                            tmp_path / name], capsys)
        assert code == 0, err
        assert (tmp_path / name).stat().st_size > 0


def test_a_flight_into_a_folder_of_the_users_files_is_refused(inputs, tmp_path, capsys):
    """A flight into a folder holding a report, summary or log it did not write replaced them,
    exit 0 (a helper's audit): refused, naming them, nothing written; a folder of other files
    is used."""
    out = tmp_path / "u"
    out.mkdir()
    (out / "report.html").write_text("<html>mine</html>")
    (out / "log.csv").write_text("a,b\n")
    args = ["flight", inputs["rec"], "--method", "calibration", "--calibration", inputs["cal"],
            "--frames", "1", "--stride", "3", "--preview-every", "0", "--out", out]
    code, stdout, err = run(args, capsys)
    assert_refused(code, stdout, err, "holds report.html, log.csv, which thermocal flight did "
                                      "not write and would replace")
    assert sorted(p.name for p in out.iterdir()) == ["log.csv", "report.html"]
    assert (out / "report.html").read_text() == "<html>mine</html>"
    (out / "report.html").unlink()
    (out / "log.csv").rename(out / "notes.csv")
    code, _, err = run(args, capsys)
    assert code == 0, err
    assert (out / "notes.csv").read_text() == "a,b\n" and (out / "report.html").is_file()


def test_a_typed_fpa_sigma_grows_the_sigma_of_flight_and_correct(inputs, tmp_path, capsys):
    """--fpa-sigma-c in a flight and in correct: σ takes in how far a °C of the typed FPA
    moves each map (the calibration's own sensitivity), the temperatures unchanged; a flight's
    run record holds it (a rerun with another is refused as another run's); without it, a
    warning that σ takes --fpa-c as exact."""
    import tifffile

    cal, rec = inputs["cal"], inputs["rec"]
    flight = ["flight", rec, "--method", "calibration", "--calibration", cal, "--fpa-c", "30",
              "--frames", "1", "--stride", "3", "--preview-every", "0"]
    code, _, err = run([*flight, "--out", tmp_path / "a"], capsys)
    assert code == 0 and "σ takes --fpa-c 30 as exact" in err, err
    code, _, err = run([*flight, "--fpa-sigma-c", "2", "--out", tmp_path / "b"], capsys)
    assert code == 0 and "as exact" not in err, err
    for name in ("frame_000000", "frame_000003"):
        a, b = (tmp_path / x / "temps" for x in "ab")
        np.testing.assert_array_equal(tifffile.imread(a / f"{name}.tiff"),
                                      tifffile.imread(b / f"{name}.tiff"))
        exact, grown = (tifffile.imread(d / f"{name}_sigma.tiff") for d in (a, b))
        assert np.all(grown >= exact) and np.median(grown - exact) > 0.05
    code, _, err = run([*flight, "--fpa-sigma-c", "3", "--out", tmp_path / "b"], capsys)
    assert code == 2 and "--fpa-sigma-c 2.0 → 3.0" in err, err
    correct = ["correct", rec, "--calibration", cal, "--fpa-c", "30"]
    for extra, out in (([], "c"), (["--fpa-sigma-c", "2"], "d")):
        code, _, err = run([*correct, *extra, "--out", tmp_path / f"{out}.tiff", "--sigma-out",
                            tmp_path / f"{out}_s.tiff"], capsys)
        assert code == 0, err
    np.testing.assert_array_equal(tifffile.imread(tmp_path / "c.tiff"),
                                  tifffile.imread(tmp_path / "d.tiff"))
    exact, grown = (tifffile.imread(tmp_path / f"{x}_s.tiff") for x in "cd")
    assert np.all(grown >= exact) and np.median(grown - exact) > 0.05


def test_a_flight_of_another_unit_makes_no_map_and_says_why(inputs, tmp_path, capsys):
    """`thermocal flight` of another unit's recording through this unit's calibration: every
    group refused as another camera's; exit 2, one line naming it, the log kept (where each
    group's reason is); the inputs unchanged."""
    root = inputs["root"]
    before = snapshot(root)
    code, out, err = run(["flight", root / "other_unit", "--out", tmp_path / "out", "--method",
                          "calibration", "--calibration", inputs["cal"]], capsys)
    assert_refused(code, out, err, "no temperature map made")
    assert "not raw frames of the camera the polynomial calibration was made for" in err
    assert (tmp_path / "out" / "log.csv").is_file() and snapshot(root) == before


def test_an_output_hard_linked_to_the_input_is_refused(inputs, tmp_path, capsys):
    """An output that is the input under another name (a hard link) is refused too."""
    rec = tmp_path / "rec.tiff"
    shutil.copy(inputs["rec"], rec)
    shutil.copy(inputs["root"] / "rec.json", tmp_path / "rec.json")
    os.link(rec, tmp_path / "same.tiff")
    before = snapshot(tmp_path)
    code, out, err = run(["correct", rec, "--calibration", inputs["cal"], "--out",
                          tmp_path / "same.tiff"], capsys)
    assert_refused(code, out, err, "(the same file as")
    assert snapshot(tmp_path) == before


# ---------------------------------------------------------------------------------------------
# damaged files
# ---------------------------------------------------------------------------------------------


def _damaged_header(src: Path, dst: Path) -> None:
    """A copy of ``src`` whose ``frames`` dataset's object header is overwritten."""
    shutil.copy(src, dst)
    with h5py.File(dst, "r") as f:
        address = h5py.h5o.get_info(f["frames"].id).addr
    with open(dst, "r+b") as fh:
        fh.seek(address)
        fh.write(b"\xa5" * 64)


def _damaged_chunk(src: Path, dst: Path) -> None:
    """A copy of ``src`` with gzip-compressed frames, one of whose chunks is overwritten."""
    from thermocal.io.chamber import read_chamber, write_chamber

    write_chamber(dst, read_chamber(src, frames=False), compression="gzip")
    with h5py.File(dst, "r") as f:
        chunk = f["frames"].id.get_chunk_info(5)
    with open(dst, "r+b") as fh:
        fh.seek(chunk.byte_offset + 8)
        fh.write(b"\x00\xff" * 32)


@pytest.mark.parametrize("damage", [_damaged_header, _damaged_chunk], ids=["header", "chunk"])
def test_a_damaged_chamber_file_is_named_not_blamed_on_the_outputs(inputs, tmp_path, capsys,
                                                                   damage):
    bad = tmp_path / "damaged.h5"
    damage(inputs["chamber"], bad)
    before = snapshot(tmp_path)
    code, out, err = run(["calibrate", bad, "--method", "polynomial", "--out",
                          tmp_path / "cal.h5"], capsys)
    assert_refused(code, out, err, f"{bad}: the chamber file is damaged")
    assert "outputs are written" not in err
    assert snapshot(tmp_path) == before


# ---------------------------------------------------------------------------------------------
# interruptions, memory
# ---------------------------------------------------------------------------------------------

_INTERRUPT_WHILE_LOADING = """
import builtins, os, signal, sys
real_import = builtins.__import__
def interrupting_import(name, *args, **kwargs):
    if name == "thermocal.progress":  # one of the modules thermocal.cli loads
        os.kill(os.getpid(), signal.SIGINT)
    return real_import(name, *args, **kwargs)
builtins.__import__ = interrupting_import
sys.argv = ["thermocal", "--version"]
from thermocal.cli import main
from thermocal.nn.infer import shipped_model_path
main()
"""


def test_ctrl_c_while_the_modules_load_is_one_line_and_status_130():
    import signal

    # SIGINT as in a terminal, even when the tests run in a background job (which ignores it)
    proc = subprocess.run([sys.executable, "-c", _INTERRUPT_WHILE_LOADING],
                          capture_output=True, text=True, timeout=120, check=False,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr == "thermocal: interrupted\n"
    assert proc.stdout == ""


def test_ctrl_c_while_a_command_runs_is_one_line_and_status_130(monkeypatch, capsys):
    """Ctrl-C in a running command: ``thermocal: interrupted`` alone (click's own handling
    wrote an empty line and then ``thermocal: aborted``)."""
    from thermocal import cli

    def interrupted(ctx):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli.cli, "invoke", interrupted)
    with pytest.raises(SystemExit) as exc:
        main(["demo"])
    assert exc.value.code == 130
    assert capsys.readouterr().err == "thermocal: interrupted\n"


def test_importing_the_cli_leaves_ctrl_c_as_it_was():
    import signal

    assert signal.getsignal(signal.SIGINT) is not None
    from thermocal import cli

    assert signal.getsignal(signal.SIGINT) is not cli._interrupted_while_loading


def test_too_little_memory_is_refused_before_the_camera_is_made(tmp_path, capsys, monkeypatch):
    import thermocal._validate as validate

    monkeypatch.setattr(validate, "_available_memory", lambda: 2**30)
    code, out, err = run(["simulate", "flight", tmp_path / "out", "--size", "8192x8192",
                          "--frames", "7"], capsys)
    assert_refused(code, out, err, "of memory, this machine has 1.0 GiB available")
    assert not (tmp_path / "out").exists()


def test_out_of_memory_is_one_line(tmp_path, capsys, monkeypatch):
    import thermocal.simulate.flight as flight

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(flight, "plan_flight", no_memory)
    code, out, err = run(["simulate", "flight", tmp_path / "out", "--size", SIZE], capsys)
    assert_refused(code, out, err, "out of memory")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------------------------
# messages that named no input, or the wrong one
# ---------------------------------------------------------------------------------------------


def test_nan_from_a_calibration_names_the_calibration_file(inputs, tmp_path, capsys,
                                                           monkeypatch):
    """A calibration whose coefficients give NaN (a damaged file the store let through) is
    named, not reported as "radiance: contains NaN"."""
    import thermocal.calibration.registry as registry
    from thermocal.errors import InvalidInputError

    real = registry.load_any_calibration(inputs["cal"])

    class NaNCalibration:
        info = real.info  # its cross-validation report: a file without one is refused first

        def apply(self, frames, **kwargs):
            raise InvalidInputError("radiance: contains NaN")

    monkeypatch.setattr(registry, "load_any_calibration", lambda path: NaNCalibration())
    code, out, err = run(["correct", inputs["rec"], "--calibration", inputs["cal"], "--out",
                          tmp_path / "t.tiff"], capsys)
    assert_refused(code, out, err, f"{inputs['cal']}: the calibration gives NaN for")
    assert not (tmp_path / "t.tiff").exists()


def test_calibrate_says_how_many_frames_it_used_and_why_not_the_others(inputs, tmp_path,
                                                                       capsys):
    from thermocal.io.chamber import read_chamber

    n = read_chamber(inputs["chamber"], frames=False).n_frames
    code, out, err = run(["calibrate", inputs["chamber"], "--method", "polynomial", "--out",
                          tmp_path / "c.h5"], capsys)
    assert code == 0, err
    found = re.search(rf"from (\d+) of {n} frames", out)
    assert found, out
    used = int(found.group(1))
    assert 0 < used < n
    assert f"left out: {n - used} with a changing FPA" in out


def test_warnings_are_one_clean_line(inputs, tmp_path, capsys):
    """A calibration used outside its FPA range warns in one line, without Python's source path
    and line (forced: the two-point's session never settled, so a burst whose stillness its
    7 frames cannot show is outside too, and says so in a line of its own)."""
    code, out, err = run(["estimate", inputs["rec"], "--method", "calibration",
                          "--calibration", inputs["cal2"], "--out", tmp_path / "t.tiff",
                          "--force"], capsys)
    assert code == 0, err
    warnings = [line for line in err.splitlines() if not line.startswith("wrote ")]
    assert warnings, err
    for line in warnings:
        assert line.startswith("thermocal: warning: "), err
    assert any("leave the calibrated range" in line for line in warnings), err
    assert ".py:" not in err and "return " not in err
    assert (tmp_path / "t.tiff").is_file()


def test_a_flight_without_uncertainty_says_so(inputs, tmp_path, capsys):
    """Maps forced through a calibration without its report have no σ: the flight says so in
    a warning line with the remedy, not only in its report."""
    code, out, err = run(["flight", inputs["flight"], "--out", tmp_path / "o", "--method",
                          "calibration", "--calibration", inputs["root"] / "cal_unreported.h5",
                          "--force"], capsys)
    assert code == 0, err
    (line,) = [w for w in err.splitlines() if "no uncertainty" in w]
    assert line.startswith("thermocal: warning: the maps have no uncertainty (no σ files)")
    assert "calibrate again" in line and not list((tmp_path / "o" / "temps").glob("*_sigma*"))
    import json

    import tifffile

    for path in (tmp_path / "o" / "temps").glob("frame_*.tiff"):  # and each map says so
        with tifffile.TiffFile(path) as tif:
            about = json.loads(tif.pages[0].description)
        assert about["sigma"] == "none" and about["method"] == "calibration"


def test_a_campaign_without_uncertainty_says_so(inputs, tmp_path, capsys):
    """The same maps made by a campaign: one warning line, naming the recordings."""
    code, out, err = run(["campaign", inputs["flight"], "--out", tmp_path / "c", "--workers",
                          "1", "--method", "calibration", "--calibration",
                          inputs["root"] / "cal_unreported.h5", "--force"], capsys)
    assert code == 0, err
    (line,) = [w for w in err.splitlines() if "no uncertainty" in w]
    assert line.startswith("thermocal: warning: the maps of 1 recording (flight) have no "
                           "uncertainty (no σ files)"), line
    assert "calibrate again" in line
    assert not list((tmp_path / "c").rglob("*_sigma*"))


# ---------------------------------------------------------------------------------------------
# output folders
# ---------------------------------------------------------------------------------------------


def test_a_mosaic_whose_report_cannot_follow_writes_nothing(inputs, tmp_path, capsys):
    """A flight folder whose summary.json is damaged: mosaic refuses before mosaicking (it
    left a whole mosaic/ behind, the report saying there was none)."""
    out = tmp_path / "o"
    main_ok(["flight", inputs["rec"], "--out", out, "--method", "mean", "--calibration",
             inputs["cal"], "--frames", "3", "--stride", "2"])
    (out / "summary.json").write_text('{"groups": 3,')
    before = snapshot(out)
    code, stdout, err = run(["mosaic", out], capsys)
    assert_refused(code, stdout, err, "summary.json: unreadable or damaged")
    assert snapshot(out) == before and not (out / "mosaic").exists()


def test_a_cut_log_leaves_maps_out_of_a_mosaic_with_a_warning(inputs, tmp_path, capsys):
    """A log.jsonl cut short: the maps it no longer lists are left out of the mosaic with a
    warning naming the remedy (it took 1 of 3 maps silently); a line of a negative frame is
    not taken for a pivot (the report counted 4 of 3 groups)."""
    from thermocal.pipeline.flight_log import read_log

    out = tmp_path / "o"
    main_ok(["flight", inputs["rec"], "--out", out, "--method", "mean", "--calibration",
             inputs["cal"], "--frames", "3", "--stride", "2"])
    log = out / "log.jsonl"
    lines = log.read_text().splitlines()
    log.write_text(lines[0] + "\n" + '{"frame": -5}\n')
    assert [e["frame"] for e in read_log(log)] == [json.loads(lines[0])["frame"]]
    code, stdout, err = run(["mosaic", out], capsys)
    assert code == 0 and f"{len(lines) - 1} map(s) in temps/ that log.jsonl does not list" in err
    summary = json.loads((out / "mosaic" / "mosaic.json").read_text())
    assert len(summary["maps_used"]) == 1
    assert sum(m["reason"] == "not in log.jsonl" for m in summary["maps_left_out"]) == len(
        lines) - 1


def test_groups_of_one_frame_are_the_frame_through_the_method(inputs, tmp_path, capsys):
    """--frames 1 with a multi-frame method: each map is its pivot alone (a traceback before:
    no pair to take a registration correlation of)."""
    out = tmp_path / "o"
    main_ok(["flight", inputs["rec"], "--out", out, "--method", "mean", "--calibration",
             inputs["cal"], "--frames", "1", "--stride", "3"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["processed"] == 3 and summary["failed"] == 0


def test_a_failed_flight_leaves_no_empty_folders(inputs, tmp_path, capsys):
    bad_cal = tmp_path / "notacal.h5"
    bad_cal.write_bytes(b"not HDF5")
    out = tmp_path / "new" / "flight-out"
    code, _, err = run(["flight", inputs["rec"], "--method", "calibration", "--calibration",
                        bad_cal, "--out", out], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notacal.h5"]


def test_a_flight_whose_groups_all_fail_says_so_in_one_line_into_a_pipe(inputs, tmp_path):
    """stderr a pipe (a log, a scheduler's capture): no progress bar, so nothing before the
    one line (rich's transient bar left an empty line there)."""
    proc = subprocess.run(
        [sys.executable, "-c", "from thermocal.cli import main; main()", "flight",
         str(inputs["rec"]), "--method", "calibration", "--calibration", str(inputs["cal"]),
         "--fpa-c", "60", "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("thermocal: error: no temperature map made"), proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr


def test_new_output_folders_are_removed_when_a_run_fails(tmp_path):
    """The command line's safety net: folders made by ensure_output_dir in a failed run go,
    unless something was written into them; folders that existed stay."""
    from thermocal.errors import ThermocalError
    from thermocal.io.atomic import ensure_output_dir, removing_new_dirs_on_error

    (tmp_path / "old").mkdir()
    with pytest.raises(ThermocalError), removing_new_dirs_on_error():
        ensure_output_dir(tmp_path / "old" / "a" / "b")
        ensure_output_dir(tmp_path / "kept" / "c")
        (tmp_path / "kept" / "c" / "log.txt").write_text("a finished output")
        raise ThermocalError("bad input")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept", "old"]
    assert not any((tmp_path / "old").iterdir())
    assert (tmp_path / "kept" / "c" / "log.txt").is_file()
    with removing_new_dirs_on_error():  # success: kept
        ensure_output_dir(tmp_path / "ok")
    assert (tmp_path / "ok").is_dir()


def test_valid_runs_are_unchanged_by_the_checks(inputs, tmp_path, capsys):
    """The checks refuse nothing valid: a recording corrected, at its sidecar's FPA and at an
    --fpa-c, gives finite temperatures."""
    for extra in ([], ["--fpa-c", "30"]):
        out = tmp_path / f"t{len(extra)}.tiff"
        code, _, err = run(["correct", inputs["rec"], "--calibration", inputs["cal"], "--out",
                            out, *extra], capsys)
        assert code == 0, err
        temps = tifffile.imread(out)
        assert temps.shape == (7, 32, 48) and np.all(np.isfinite(temps))


def test_every_command_takes_a_folder(inputs, tmp_path, capsys):
    """A DualTauUAV folder (and the folder `simulate flight` writes) through correct, nuc,
    estimate and flight: the frames of the project's TIFF, the same temperatures."""
    root = inputs["root"]
    base = tmp_path / "base.tiff"
    code, _, err = run(["correct", inputs["rec"], "--calibration", inputs["cal"], "--fpa-c", "30",
                        "--out", base], capsys)
    assert code == 0, err
    for folder in (root / "dual", root / "flight"):
        out = tmp_path / f"{folder.name}.tiff"
        code, _, err = run(["correct", folder, "--calibration", inputs["cal"], "--fpa-c", "30",
                            "--out", out], capsys)
        assert code == 0, err
        np.testing.assert_array_equal(tifffile.imread(out), tifffile.imread(base))
    for args in (["nuc", root / "dual", "--method", "admire", "--out", tmp_path / "n.tiff"],
                 ["estimate", root / "dual", "--method", "mean", "--calibration",
                  inputs["cal"], "--out", tmp_path / "e.tiff"],
                 ["flight", root / "dual", "--method", "calibration", "--calibration",
                  inputs["cal"], "--frames", "1", "--stride", "1", "--out", tmp_path / "fl"]):
        code, _, err = run(args, capsys)
        assert code == 0, (args, err)
    assert len(list((tmp_path / "fl" / "temps").glob("frame_??????.tiff"))) == 7


def test_calibrate_whose_report_cannot_be_written_leaves_no_calibration(inputs, tmp_path,
                                                                        capsys, monkeypatch):
    """The report is written before the calibration file: a report that cannot be written (a
    full disk, a folder that refuses it) leaves neither."""
    import thermocal.io.atomic as atomic

    def refuse(path, *args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic, "write_json_atomic", refuse)
    code, _, err = run(["calibrate", inputs["chamber"], "--method", "two-point", "--out",
                        tmp_path / "c.h5", "--report", tmp_path / "r.json"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.iterdir())


def test_a_reader_that_went_away_is_no_error(inputs):
    """``thermocal info REC | head -c0``: the pipe closed before the output, status 141 as a
    shell gives a command ended by SIGPIPE, and nothing on stderr (it said "Broken pipe" as an
    error)."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "thermocal.cli", "info", str(inputs["rec"])],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # before the child has imported anything: its first write fails
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err
    assert err == ""


def test_info_on_a_pipe_says_it_is_not_a_file(tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    code, _, err = run(["info", fifo], capsys)
    assert code == 2 and "not a file or a folder (a pipe, a device)" in err


def test_calibrate_whose_calibration_cannot_be_written_keeps_the_earlier_report(
        inputs, tmp_path, capsys, monkeypatch):
    """The report is put in place only once the calibration is: a calibration that cannot be
    written leaves no new file and an earlier run's report as it was."""
    from thermocal.calibration.two_point import TwoPointCalibration

    (tmp_path / "r.json").write_text('{"earlier": true}\n')

    def refuse(self, path):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(TwoPointCalibration, "save", refuse)
    code, _, err = run(["calibrate", inputs["chamber"], "--method", "two-point", "--out",
                        tmp_path / "c.h5", "--report", tmp_path / "r.json"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
    assert (tmp_path / "r.json").read_text() == '{"earlier": true}\n'
