"""The command line: the contract of DESIGN.md, help, version, and bad input → exit 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import tifffile

from thermocal.cli import main
from thermocal.io.chamber import read_chamber


def run(args: list[str], capsys) -> tuple[int, str, str]:
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err


def test_version_and_help(capsys):
    code, out, _ = run(["--version"], capsys)
    assert code == 0 and "thermocal" in out
    for cmd in (["--help"], ["simulate", "--help"], ["simulate", "chamber", "--help"],
                ["simulate", "flight", "--help"], ["demo", "--help"]):
        code, out, _ = run(cmd, capsys)
        assert code == 0 and "Usage" in out


@pytest.mark.parametrize("command", ["calibrate", "correct", "nuc"])
def test_method_names_and_help_come_from_the_registries(command):
    """calibrate's and nuc's --method choices, and every method's summary in the help of
    calibrate, correct and nuc, are their family's registry."""
    from click.testing import CliRunner

    from thermocal.calibration import CALIBRATION_METHODS
    from thermocal.cli import cli
    from thermocal.nuc import NUC_METHODS

    registry = NUC_METHODS if command == "nuc" else CALIBRATION_METHODS
    text = CliRunner().invoke(cli, [command, "--help"], terminal_width=2000).output
    flat = " ".join(text.split())
    for name, info in registry.items():
        assert f" {name} {info.summary} ({info.source})" in flat, (command, name)
    if command != "correct":  # calibrate also offers auto (every method, the best kept)
        assert f"[{'|'.join([*registry] + (['auto'] if command == 'calibrate' else []))}]" in flat


def test_simulate_chamber_writes_a_valid_file(tmp_path, capsys):
    out = tmp_path / "c.h5"
    code, _, err = run(["simulate", "chamber", str(out), "--size", "32x24", "--seed", "3",
                        "--unit", "2", "--blackbody-c", "10:40:15", "--ambient-profile", "ramp",
                        "--ambient-c", "15:25", "--rate-c-per-min", "1", "--frames-per-point",
                        "2", "--duration-min", "5"], capsys)
    assert code == 0, err
    session = read_chamber(out)
    assert session.frames.shape == (30, 24, 32)
    assert set(np.unique(session.blackbody_c)) == {10.0, 25.0, 40.0}
    assert session.attrs["unit"] == 2


def test_simulate_flight_writes_the_contract(tmp_path, capsys):
    out = tmp_path / "flight"
    code, _, err = run(["simulate", "flight", str(out), "--frames", "5", "--size", "64x48",
                        "--motion", "hover", "--fpa-c", "35", "--seed", "1"], capsys)
    assert code == 0, err
    frames = tifffile.imread(out / "frames.tiff")
    truth = tifffile.imread(out / "truth.tiff")
    meta = json.loads((out / "frames.json").read_text())
    homographies = np.load(out / "homographies.npy")
    assert frames.shape == (5, 48, 64) and frames.dtype == np.uint16
    assert truth.shape == (5, 48, 64) and truth.dtype == np.float32
    assert homographies.shape == (5, 3, 3)
    assert meta["pivot"] == 2 and len(meta["fpa_c"]) == 5 and meta["bit_depth"] == 14
    assert abs(np.mean(meta["fpa_c"]) - 35.0) < 0.1
    np.testing.assert_allclose(homographies[2], np.eye(3), atol=1e-9)


def test_simulate_flight_over_a_real_scene(tmp_path, capsys, shared_data):
    out = tmp_path / "flight"
    scene = shared_data / "scenes" / "10_ir_fussbodenheizung.jpg"
    code, _, err = run(["simulate", "flight", str(out), "--scene", str(scene), "--frames", "3",
                        "--size", "64x48", "--motion", "uav"], capsys)
    assert code == 0, err
    truth = tifffile.imread(out / "truth.tiff")
    assert 16.0 < truth.min() and truth.max() < 35.0


def test_simulate_chamber_sweeps_a_falling_range_from_its_start(tmp_path, capsys):
    """``--blackbody-c 70:10:30`` (A > B) visits 70, 40 and 10 °C in that order: a chamber run
    from hot to cold (it was refused as "A <= B")."""
    out = tmp_path / "c.h5"
    code, _, err = run(["simulate", "chamber", str(out), "--size", "16x12", "--blackbody-c",
                        "70:10:30", "--ambient-profile", "constant", "--frames-per-point", "2",
                        "--duration-min", "1"], capsys)
    assert code == 0, err
    bb = read_chamber(out, frames=False).blackbody_c
    assert list(bb[:6]) == [70.0, 70.0, 40.0, 40.0, 10.0, 10.0]
    # what calibrate says to record keeps the sweep falling (a review: it turned it round)
    code, _, err = run(["calibrate", str(out), "--method", "polynomial", "--out",
                        str(tmp_path / "cal.h5")], capsys)
    assert code == 2 and "--blackbody-c 70:10:30" in err, err


@pytest.mark.parametrize(
    "args, message",
    [
        (["simulate", "chamber", "{tmp}/c.h5", "--blackbody-c", "70:10:-5"], "STEP > 0"),
        (["simulate", "chamber", "{tmp}/c.h5", "--blackbody-c", "10:x"], "A:B:STEP"),
        (["simulate", "chamber", "{tmp}/c.h5", "--ambient-c", "10"], "A:B"),
        (["simulate", "chamber", "{tmp}/c.h5", "--size", "0x10"], "between 8 and 8192"),
        (["simulate", "chamber", "{tmp}/c.h5", "--blackbody-c", "-300:10:10"], "absolute zero"),
        (["simulate", "chamber", "{tmp}/missing/c.h5"], "does not exist"),
        (["simulate", "chamber", "{tmp}"], "is a directory"),
        (["simulate", "flight", "{tmp}/file.txt"], "file"),
        (["simulate", "flight", "{tmp}/f", "--scene", "{tmp}/file.txt"], "file.txt"),
        (["simulate", "flight", "{tmp}/f", "--size", "99999x5"], "between 8 and 8192"),
        (["simulate", "flight", "{tmp}/f", "--frames", "0"], "at least 1 frame"),
        (["simulate", "flight", "{tmp}/f", "--fpa-c", "-400"], "absolute zero"),
        (["demo", "--out", "{tmp}/file.txt"], "file"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    (tmp_path / "file.txt").write_text("not a scene")
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    code, _, err = run(args, capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert message in lines[0]
    assert "Traceback" not in err
    assert not (tmp_path / "c.h5").exists()
    assert not (tmp_path / "f").exists() or not any((tmp_path / "f").iterdir())


def test_console_script_entry_point_runs():
    proc = subprocess.run([sys.executable, "-m", "thermocal.cli", "--version"],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and "thermocal" in proc.stdout
