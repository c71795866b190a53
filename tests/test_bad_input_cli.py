"""Bad input on the command line (issue 18, item 5): one line on stderr, exit status 2, no
traceback, nothing written, never an input overwritten; warnings as one clean line."""

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

from thermocal.cli import main

SIZE = "48x32"


def run(args: list[str], capsys) -> tuple[int, str, str]:
    """Run ``thermocal ARGS`` in this process: (exit status, stdout, stderr)."""
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err


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
    shutil.copy(flight / "frames.json", root / "rec.json")
    sidecar = json.loads((flight / "frames.json").read_text())
    for name, fpa in (("fpa1e50", "[1e50, 1e50, 1e50, 1e50, 1e50, 1e50, 1e50]"),
                      ("fpahuge", f"[{10**400}, 30, 30, 30, 30, 30, 30]"),
                      ("fpa_minus100", "[30, 30, 30, 30, 30, 30, -100]")):
        shutil.copy(rec, root / f"{name}.tiff")
        text = json.dumps(sidecar | {"fpa_c": "FPA"}).replace('"FPA"', fpa)
        (root / f"{name}.json").write_text(text)
    frames = tifffile.imread(rec)
    frames[3] = 0
    tifffile.imwrite(root / "deadframe.tiff", frames, photometric="minisblack")
    shutil.copy(root / "rec.json", root / "deadframe.json")
    # a chamber file whose FPA series is in the wrong unit (1/100 °C)
    shutil.copy(chamber, root / "fpa_centi.h5")
    with h5py.File(root / "fpa_centi.h5", "a") as f:
        f["fpa_c"][...] = f["fpa_c"][()] * 100
    (root / "weights.pt").write_bytes(b"not really weights")
    return {"root": root, "chamber": chamber, "flight": flight, "cal": root / "cal.h5",
            "cal2": root / "cal2.h5", "rec": rec}


# ---------------------------------------------------------------------------------------------
# the table: argv -> a piece of the one-line message
# ---------------------------------------------------------------------------------------------

# {root}: the inputs' folder (never changed); {tmp}: this test's own folder (nothing is to be
# created in it); {link}: a symbolic link {tmp}/link.tiff to {root}/rec.tiff
CASES = [
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
]


@pytest.mark.parametrize("args, message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_exit_2_and_changes_nothing(inputs, tmp_path, capsys, args,
                                                               message):
    root = inputs["root"]
    (tmp_path / "link.tiff").symlink_to(root / "rec.tiff")
    args = [a.format(root=root, tmp=tmp_path, link=tmp_path / "link.tiff", rootname=root.name)
            for a in args]
    before = snapshot(root)
    code, out, err = run(args, capsys)
    assert_refused(code, out, err, message)
    assert snapshot(root) == before  # no input changed, nothing written beside them
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.tiff"]  # nothing created


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
main()
"""


def test_ctrl_c_while_the_modules_load_is_one_line_and_status_130():
    proc = subprocess.run([sys.executable, "-c", _INTERRUPT_WHILE_LOADING],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr == "thermocal: interrupted\n"
    assert proc.stdout == ""


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

    class NaNCalibration:
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
    and line."""
    code, out, err = run(["estimate", inputs["rec"], "--method", "calibration",
                          "--calibration", inputs["cal2"], "--out", tmp_path / "t.tiff"], capsys)
    assert code == 0, err
    warnings = [line for line in err.splitlines() if not line.startswith("wrote ")]
    assert warnings, err
    for line in warnings:
        assert line.startswith("thermocal: warning: "), err
        assert "leave the calibrated range" in line
    assert ".py:" not in err and "return " not in err
    assert (tmp_path / "t.tiff").is_file()


# ---------------------------------------------------------------------------------------------
# output folders
# ---------------------------------------------------------------------------------------------


def test_a_failed_flight_leaves_no_empty_folders(inputs, tmp_path, capsys):
    bad_cal = tmp_path / "notacal.h5"
    bad_cal.write_bytes(b"not HDF5")
    out = tmp_path / "new" / "flight-out"
    code, _, err = run(["flight", inputs["rec"], "--method", "calibration", "--calibration",
                        bad_cal, "--out", out], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notacal.h5"]


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
