"""Calibrations forced (`thermocal correct --force`) on a recording whose FPA changes at paces
their chamber session never held: does the stated σ cover the errors?

A `boson` unit's session of ambient steps (its FPA only rises) fits each method; a held-out
sawtooth session of the same unit (another seed; its FPA rises and falls) is corrected as a
recording, forced, with `--sigma-out`, and scored against the blackbody's radiance-equivalent
temperature. "Silent": frames whose mean error exceeds both 1 °C and twice their median σ;
beside them, how many a σ would leave silent were each frame's error a level drawn from a
Gaussian of its median σ (the coverage benchmark's share).

Run: ``python benchmarks/forced_paces.py [--unit 101] [--size 80x64]`` (5–10 s on 2
cores)."""

import argparse
import contextlib
import io
import tempfile
import time
from pathlib import Path

import numpy as np
import tifffile

from thermocal.bench import machine
from thermocal.calibration.dataset import prepare_chamber
from thermocal.cli import main as thermocal
from thermocal.evaluation.suites.coverage import silent_share
from thermocal.io.chamber import read_chamber
from thermocal.io.recording import Recording, write_recording

METHODS = ("lin-level", "lin", "polynomial")


def _run(*args: object) -> None:
    """``thermocal ARGS`` in this process, its own output kept out of the report; a failure
    stops the benchmark, saying what it printed."""
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            thermocal([str(a) for a in args])
    except SystemExit as exc:
        if exc.code not in (0, None):
            raise SystemExit(f"thermocal {' '.join(map(str, args))}: {said.getvalue()}") from None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--unit", type=int, default=101)
    ap.add_argument("--size", default="80x64")
    args = ap.parse_args()
    started = time.time()
    camera = ["--preset", "boson", "--unit", str(args.unit), "--size", args.size]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        _run("simulate", "chamber", d / "steps.h5", *camera)
        _run("simulate", "chamber", d / "held.h5", *camera, "--ambient-profile", "sawtooth",
             "--seed", "7")
        held = read_chamber(d / "held.h5")
        write_recording(d / "held.tiff", Recording(held.frames, fpa_c=held.fpa_c,
                                                   time_s=held.time_s))
        truth = prepare_chamber(d / "held.h5").scene_c
        for method in METHODS:
            _run("calibrate", d / "steps.h5", "--method", method, "--out", d / f"{method}.h5")
            _run("correct", d / "held.tiff", "--calibration", d / f"{method}.h5", "--force",
                 "--out", d / "t.tiff", "--sigma-out", d / "s.tiff")
            n = held.n_frames
            err = np.abs(tifffile.imread(d / "t.tiff") - truth[:, None, None]).reshape(n, -1)
            sigma = tifffile.imread(d / "s.tiff").reshape(n, -1)
            frame_err, frame_sigma = err.mean(axis=1), np.median(sigma, axis=1)
            silent = int(np.count_nonzero((frame_err > 1.0) & (frame_err > 2.0 * frame_sigma)))
            expected = sum(silent_share(s) for s in sigma)  # were each error a Gaussian's
            within = [100 * np.mean(err <= k * sigma) for k in (1, 2)]
            rows.append(f"| {method} | {n} | {err.mean():.2f} | {within[0]:.1f} % "
                        f"| {within[1]:.1f} % | {np.median(sigma):.2f} | {silent} "
                        f"| {expected:.0f} |")
    print("## Forced at paces the session never held\n")
    print(f"machine: {machine()}; {time.time() - started:.0f} s\n")
    print(f"data: `boson` unit {args.unit} at {args.size}: fitted on its default steps session "
          "(`thermocal simulate chamber --preset boson`; the FPA only rises), corrected with "
          "`--force` on a sawtooth session of it (`--ambient-profile sawtooth --seed 7`) as a "
          "recording\n")
    print("| method | frames | MAE °C | within 1σ | within 2σ | median σ °C | silent frames "
          "| a Gaussian σ's share |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
