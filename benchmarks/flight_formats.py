"""Whole flights from each recording format, end to end (issue 19, "Measure").

For each format of ``thermocal simulate flight --format``, a simulated UAV pass (640×512, same
unit, seed and scene, so the same counts in every format) is written in that format, then
``thermocal flight`` runs on it as a subprocess::

    thermocal flight FRAMES --out OUT --method mean --calibration CAL.h5 --fpa-c 22 \\
        --preview-every 0

``--method mean`` (registered average through a per-pixel calibration) works on every format
and is fast on a CPU; the calibration comes from ``thermocal simulate chamber`` + ``thermocal
calibrate`` (polynomial) of the same simulated unit at 640×512. ``--fpa-c 22`` is given to
every run, because FLIR SEQ/CSQ/FFF and plain R-JPEGs carry no FPA temperature, so that all
formats do the same work. Each command is timed (wall clock, and CPU time user + system, which
other work on a shared machine disturbs less) with its peak resident memory (``os.wait4``'s
``ru_utime``, ``ru_stime``, ``ru_maxrss``); the maps of each format are compared with those
of the TIFF recording. Prints a Markdown table::

    .venv/bin/python benchmarks/flight_formats.py [--frames N] [--formats seq,csq,...]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import tifffile

from thermocal.bench import machine
from thermocal.evaluation.tables import markdown_table

FORMATS = ("tiff", "seq", "csq", "fff", "rjpeg", "dji-rjpeg", "dualtau")
FPA_C = 22.0  # inside the simulated chamber session's FPA range
SIZE = "640x512"


def _run(args: list[str]) -> tuple[float, float, float]:
    """Run ``thermocal ARGS``; (wall seconds, CPU seconds (user + system), peak resident memory
    of the process in MiB)."""
    cmd = [sys.executable, "-m", "thermocal.cli", *args]
    with tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own rusage
        seconds = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            raise SystemExit(f"failed ({proc.returncode}): thermocal {' '.join(args)}\n"
                             f"{err.read().decode()[-2000:]}")
    return seconds, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0  # Linux: KiB


def frames_path(folder: Path, fmt: str) -> Path:
    """Where ``simulate flight --format FMT`` puts the frames in ``folder``."""
    return folder / {"tiff": "frames.tiff", "seq": "frames.seq", "csq": "frames.csq"}.get(
        fmt, "frames")


def _size_mib(path: Path) -> float:
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    if path.suffix == ".tiff":
        files.append(path.with_suffix(".json"))
    return sum(p.stat().st_size for p in files) / 2**20


def _maps(out: Path) -> dict[str, np.ndarray]:
    return {p.name: tifffile.imread(p) for p in sorted((out / "temps").glob("frame_*[0-9].tiff"))}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300, help="Frames of each flight.")
    parser.add_argument("--formats", default=",".join(FORMATS), help="Comma-separated formats.")
    parser.add_argument("--workdir", type=Path, default=None,
                        help="Keep the files here (default: a temporary folder).")
    args = parser.parse_args(argv)
    formats = [f for f in args.formats.split(",") if f]
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        cal = work / "cal.h5"
        if not cal.exists():
            _run(["simulate", "chamber", str(work / "chamber.h5"), "--size", SIZE,
                  "--blackbody-c", "10:70:20", "--frames-per-point", "2", "--duration-min", "60"])
            _run(["calibrate", str(work / "chamber.h5"), "--out", str(cal)])
        rows, reference = [], None
        for fmt in formats:
            folder = work / f"flight_{fmt}"
            write_s, _, write_mib = _run(
                ["simulate", "flight", str(folder), "--size", SIZE, "--frames", str(args.frames),
                 "--fpa-c", str(FPA_C), "--motion", "uav", "--format", fmt])
            out = work / f"maps_{fmt}"
            run_s, cpu_s, run_mib = _run(
                ["flight", str(frames_path(folder, fmt)), "--out", str(out), "--method", "mean",
                 "--calibration", str(cal), "--fpa-c", str(FPA_C), "--preview-every", "0"])
            maps = _maps(out)
            if reference is None:
                reference = maps
            same = maps.keys() == reference.keys() and all(
                np.array_equal(maps[k], reference[k], equal_nan=True) for k in maps)
            rows.append((fmt, args.frames, f"{_size_mib(frames_path(folder, fmt)):,.0f}",
                         f"{write_s:.1f}", f"{write_mib:,.0f}", f"{run_s:.1f}",
                         f"{args.frames / run_s:.1f}", f"{cpu_s:.1f}", f"{run_mib:,.0f}", len(maps),
                         "yes" if same else "NO"))
            print(f"{fmt}: {run_s:.1f} s", file=sys.stderr, flush=True)
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.1f} at the end\n")
    print(f"{args.frames} frames of {SIZE} per format; `thermocal flight --method mean` with "
          f"`--fpa-c {FPA_C:g}`\n")
    print(markdown_table(("format", "frames", "size MiB", "simulate + write s", "write peak MiB",
                          "flight s", "frames/s", "flight CPU s", "flight peak MiB", "maps",
                          "maps equal to tiff's"), rows))


if __name__ == "__main__":
    main()
