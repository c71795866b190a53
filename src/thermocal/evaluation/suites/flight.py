"""Speed of the whole-flight product (``thermocal flight``) on a recording the size of the paper's.

Simulates a UAV pass of a held-out camera unit over the built-in aerial scene (7,152 frames of
336×256 as in Oz et al. §V-A; ``--quick``: 714), then processes it with N = 7 and stride 7 and
reports the wall time, frames per second per stage and the peak memory of the processing.

Run: ``python benchmarks/flight.py [--quick] [--method kpn] [--backend torch] [--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path

from thermocal.bench import machine
from thermocal.camera import make_camera
from thermocal.pipeline.flight import FlightOptions, process_flight
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.flight import plan_flight, write_simulated_flight

UNIT = 101  # never a training unit of the network


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="714 frames instead of 7,152")
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--method", default="kpn")
    ap.add_argument("--backend", default="torch", help="What runs a network (--backend of "
                    "thermocal flight: torch, onnxruntime, openvino, auto).")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    n_frames = args.frames or (714 if args.quick else 7152)
    camera = make_camera("tau2", unit=UNIT, size=(336, 256))
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        plan = plan_flight(load_builtin_scene("aerial"), camera, n_frames=n_frames,
                           motion="uav", fpa_c=32.0, seed=7)
        write_simulated_flight(Path(tmp) / "rec", plan, camera, chunk=128)
        simulate_s = time.perf_counter() - t
        rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        summary = process_flight(Path(tmp) / "rec" / "frames.tiff", Path(tmp) / "out",
                                 FlightOptions(method=args.method, preview_every=50,
                                               backend=args.backend))
        rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    fps = summary["frames_per_second"]
    print(f"machine: {machine()}")
    print(f"recording: {n_frames} frames of 336x256, tau2 unit {UNIT}, UAV pass (3.8 px/frame) "
          f"over the built-in aerial scene, FPA 32 °C; simulated in {simulate_s:.0f} s")
    print()
    print("| method, backend | groups (N = 7, stride 7) | processed | failed | wall time "
          "| peak RSS |")
    print("|---|---|---|---|---|---|")
    print(f"| {args.method}, {args.backend} | {summary['groups']} | {summary['processed']} "
          f"| {summary['failed']} "
          f"| {summary['wall_time_s']:.0f} s (target ≤ {600 * n_frames / 7152:.0f} s) "
          f"| {max(rss_before, rss_after):.0f} MB |")
    print()
    print("| stage | seconds | frames/s |")
    print("|---|---|---|")
    for stage, seconds in summary["stage_seconds"].items():
        rate = fps[stage]
        print(f"| {stage} | {seconds:.1f} | {rate:.0f} |" if rate else f"| {stage} | 0 | – |")
    if args.json:
        args.json.write_text(json.dumps({"machine": machine(), "n_frames": n_frames,
                                         "simulate_s": simulate_s, "summary": summary,
                                         "peak_rss_mb": max(rss_before, rss_after)}, indent=2))


if __name__ == "__main__":
    main()
