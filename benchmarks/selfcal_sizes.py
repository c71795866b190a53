"""selfcal's calibration-free σ against the frame size: coverage and the error beyond the
unit's level, by size (why frames under ``selfcal.MIN_FREE_SHAPE`` are outside).

Each case: ``thermocal simulate flight`` (a ``tau2`` unit, UAV motion over the default
procedural scene, 120 frames, seed 6), then ``thermocal flight --method selfcal`` (forced where
the size is outside), scored against the simulation's truth over every map: the mean error
(the unit's level), the RMS of the error less that mean (what the pass's pattern fit leaves),
the median σ and the shares within 1σ and 2σ.

    python benchmarks/selfcal_sizes.py [--sizes 160x120,320x256,336x256,640x512]
        [--units 9,12,5001,5002] [--frames 120] [--out results/selfcal_sizes_DATE.md]
"""

from __future__ import annotations

import argparse
import glob
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import tifffile

THERMOCAL = [sys.executable, "-c", "from thermocal.cli import main; main()"]


def run_case(work: Path, size: str, unit: int, frames: int) -> dict:
    """One pass: simulated, mapped (forced where outside), scored."""
    rec, out = work / f"p_{size}_{unit}", work / f"o_{size}_{unit}"
    subprocess.run([*THERMOCAL, "simulate", "flight", rec, "--size", size, "--frames",
                    str(frames), "--seed", "6", "--unit", str(unit), "--motion", "uav"],
                   check=True, capture_output=True)
    plain = subprocess.run([*THERMOCAL, "flight", rec / "frames.tiff", "--out", out,
                            "--method", "selfcal", "--preview-every", "0"],
                           capture_output=True, text=True)
    forced = plain.returncode != 0
    if forced:
        subprocess.run(["rm", "-rf", str(out)], check=True)
        subprocess.run([*THERMOCAL, "flight", rec / "frames.tiff", "--out", out, "--method",
                        "selfcal", "--preview-every", "0", "--force"], check=True,
                       capture_output=True)
    truth = tifffile.imread(rec / "truth.tiff")
    errors, sigmas = [], []
    for f in sorted(glob.glob(str(out / "temps" / "frame_??????.tiff"))):
        k = int(Path(f).stem.split("_")[1])
        errors.append(tifffile.imread(f) - truth[k])
        sigmas.append(tifffile.imread(f.replace(".tiff", "_sigma.tiff")))
    e, s = np.array(errors, np.float64), np.array(sigmas, np.float64)
    return {"size": size, "unit": unit, "forced": forced, "maps": len(errors),
            "level": float(e.mean()), "beyond_level": float((e - e.mean()).std()),
            "median_sigma": float(np.median(s)),
            "within_1": float(np.mean(np.abs(e) <= s)),
            "within_2": float(np.mean(np.abs(e) <= 2 * s))}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="160x120,320x256,336x256,640x512")
    ap.add_argument("--units", default="9,12,5001,5002")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--out", default=None, help="Also write the Markdown here.")
    args = ap.parse_args(argv)
    started = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes.split(","):
            for unit in (int(u) for u in args.units.split(",")):
                rows.append(run_case(Path(tmp), size, unit, args.frames))
    lines = [
        "## selfcal's calibration-free σ by frame size", "",
        f"command: `python benchmarks/selfcal_sizes.py --sizes {args.sizes} --units "
        f"{args.units} --frames {args.frames}`", "",
        f"machine: {platform.processor() or platform.machine()}, Python "
        f"{platform.python_version()}; {time.perf_counter() - started:.0f} s", "",
        f"data: `tau2` units {args.units}, {args.frames}-frame UAV passes (seed 6) over the "
        "default procedural scene (19-63 °C), FPA 30 °C; every map of `thermocal flight "
        "--method selfcal` (forced where the size is outside `selfcal.MIN_FREE_SHAPE`, σ "
        "grown by `SMALL_FRAME_SIGMA_C`) against the simulation's truth. Level: the mean error "
        "(the unit's, which no motion reveals); beyond: the RMS of the error less it.", "",
        "| size | unit | forced | maps | level °C | beyond the level °C | median σ °C | "
        "within 1σ | within 2σ |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['size']} | {r['unit']} | {'yes' if r['forced'] else 'no'} | "
                     f"{r['maps']} | {r['level']:+.2f} | {r['beyond_level']:.2f} | "
                     f"{r['median_sigma']:.2f} | {100 * r['within_1']:.1f} % | "
                     f"{100 * r['within_2']:.1f} % |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
