"""Benchmark of ``thermocal mosaic``: canvas size, wall time and peak memory for a long pass.

The per-pivot maps are synthesised directly (no flight is simulated or processed): crops of a
procedural scene (smooth noise at 4 px and 30 px, about ±3 °C around 25 °C) at the offsets of
a UAV pass (3.82 px per frame, ``--stride`` frames between pivots, a slow 2 px sideways
drift), bilinear for the sub-pixel part, plus 0.05 °C of noise, each with a 0.3 °C σ map, and a
``log.jsonl``. :func:`thermocal.pipeline.mosaic.build_mosaic` then runs in a child process,
whose peak resident memory is reported (``ru_maxrss`` of the children). The error is the
mosaic against the scene where two or more views were kept (the canvas placed by the first
map's known origin).

    .venv/bin/python benchmarks/mosaic.py --frames 1000 --out /tmp/mosaic-bench
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import tifffile
from scipy.ndimage import gaussian_filter

PX_PER_FRAME = 3.82  # thermocal.scenes.trajectory.pixel_motion_per_frame() defaults


def _scene(shape: tuple[int, int], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    fine = gaussian_filter(rng.normal(size=shape).astype(np.float32), 4.0)
    coarse = gaussian_filter(rng.normal(size=shape).astype(np.float32), 30.0)
    return 25.0 + 2.0 * fine / fine.std() + 2.0 * coarse / coarse.std()


def synthesise(out: Path, *, frames: int, stride: int, size: tuple[int, int], seed: int
               ) -> list[tuple[float, float]]:
    """Write a flight output of the pivots of ``frames`` frames; the maps' origins (x, y)."""
    w, h = size
    pivots = list(range(stride // 2 + 3, frames - stride // 2, stride))
    step = PX_PER_FRAME * stride
    origins = [(8.0 + step * k, 8.0 + 2.0 * np.sin(k / 25.0)) for k in range(len(pivots))]
    scene = _scene((h + 24, int(w + step * len(pivots)) + 24), seed)
    rng = np.random.default_rng(seed + 1)
    (out / "temps").mkdir(parents=True, exist_ok=True)
    sigma = np.full((h, w), 0.3, np.float32)
    lines = []
    for pivot, (x, y) in zip(pivots, origins, strict=True):
        to_scene = np.array([[1.0, 0.0, x], [0.0, 1.0, y]])
        crop = cv2.warpAffine(scene, to_scene, (w, h),
                              flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
        temp = crop + rng.normal(0.0, 0.05, crop.shape).astype(np.float32)
        tifffile.imwrite(out / "temps" / f"frame_{pivot:06d}.tiff", temp)
        tifffile.imwrite(out / "temps" / f"frame_{pivot:06d}_sigma.tiff", sigma)
        lines.append(json.dumps({"frame": pivot, "mean_c": float(temp.mean())}))
    (out / "log.jsonl").write_text("\n".join(lines) + "\n")
    np.save(out / "scene.npy", scene)
    return origins


def _error(out: Path, origins: list[tuple[float, float]]) -> dict[str, float]:
    """The mosaic against the scene (placed by the first map's true origin) where two views or
    more were kept, and how far from its true place the chain put the last map."""
    summary = json.loads((out / "mosaic" / "mosaic.json").read_text())
    temp = tifffile.imread(out / "mosaic" / "temperature.tiff")
    views = tifffile.imread(out / "mosaic" / "views.tiff")
    scene = np.load(out / "scene.npy")
    ox, oy = summary["canvas"]["offset_px"]
    truth = cv2.warpAffine(scene, np.array([[1.0, 0.0, origins[0][0] - ox],
                                            [0.0, 1.0, origins[0][1] - oy]]),
                           (temp.shape[1], temp.shape[0]),
                           flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    err = np.abs(temp - truth)[views >= 2]
    last = np.array(summary["maps_used"][-1]["to_canvas"])[:2, 2] - (ox, oy)
    drift = last - (np.array(origins[-1]) - origins[0])  # the last map's place, pixels
    return {"median_abs_error_c": float(np.median(err)),
            "p95_abs_error_c": float(np.percentile(err, 95)),
            "last_map_misplaced_px": float(np.hypot(*drift))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000, help="frames of the pass")
    parser.add_argument("--stride", type=int, default=7, help="frames between pivots")
    parser.add_argument("--size", default="640x512", help="map size WxH")
    parser.add_argument("--out", type=Path, required=True, help="a scratch folder")
    parser.add_argument("--memory-mb", type=float, default=512.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    t = time.perf_counter()
    origins = synthesise(args.out, frames=args.frames, stride=args.stride, size=(w, h),
                         seed=args.seed)
    synth_s = time.perf_counter() - t
    code = ("import sys; from thermocal.pipeline.mosaic import build_mosaic; "
            "build_mosaic(sys.argv[1], memory_mb=float(sys.argv[2]))")
    t = time.perf_counter()
    subprocess.run([sys.executable, "-c", code, str(args.out), str(args.memory_mb)], check=True)
    wall = time.perf_counter() - t
    peak_mib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    summary = json.loads((args.out / "mosaic" / "mosaic.json").read_text())
    result = {
        "maps": len(origins), "frames": args.frames, "stride": args.stride, "size": args.size,
        "canvas": f"{summary['canvas']['width']}x{summary['canvas']['height']}",
        "maps_used": len(summary["maps_used"]), "maps_left_out": len(summary["maps_left_out"]),
        "views_median": summary["views"]["median"], "views_max": summary["views"]["max"],
        "seconds": {k: round(v, 1) for k, v in summary["seconds"].items()},
        "wall_s_with_start": round(wall, 1), "peak_rss_mib": round(peak_mib),
        "memory_mb": args.memory_mb, "synthesis_s": round(synth_s, 1),
        **_error(args.out, origins),
        "machine": f"{platform.machine()}, {__import__('os').cpu_count()} CPUs, "
                   f"Python {platform.python_version()}",
    }
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
