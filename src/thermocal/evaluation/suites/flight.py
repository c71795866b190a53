"""Speed of the whole-flight product (``thermocal flight``) on a recording the size of the paper's.

Simulates a UAV pass of a held-out camera unit over the built-in aerial scene (7,152 frames of
336×256 as in Oz et al. §V-A; ``--quick``: 714), then processes it with N = 7 and stride 7 and
reports the wall time, frames per second per stage and the peak memory of the processing.

With ``--campaign-workers W`` the same recording then goes through ``thermocal campaign`` on a
``LocalCluster`` of ``W`` workers (a recording this long runs as segments, each a task): its wall
time beside the flight's, and whether its maps are the flight's bytes.

Run: ``python benchmarks/flight.py [--quick] [--method kpn] [--backend auto]
[--campaign-workers W] [--json OUT.json]``.
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
from thermocal.nn.backends import resolve_backend
from thermocal.pipeline.flight import FlightOptions, process_flight
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.flight import plan_flight, write_simulated_flight

UNIT = 101  # never a training unit of the network


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="714 frames instead of 7,152")
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--method", default="kpn")
    ap.add_argument("--backend", default="auto", help="What runs a network (--backend of "
                    "thermocal flight: torch, onnxruntime, openvino, auto; default auto, "
                    "OpenVINO where installed, as issue 21's figure was measured).")
    ap.add_argument("--campaign-workers", type=int, default=None,
                    help="Also run the recording as a campaign on this many workers.")
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
        options = FlightOptions(method=args.method, preview_every=50, backend=args.backend)
        summary = process_flight(Path(tmp) / "rec" / "frames.tiff", Path(tmp) / "out", options)
        rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        split = (None if args.campaign_workers is None else
                 _as_campaign(Path(tmp), options, args.campaign_workers))
    fps = summary["frames_per_second"]
    print(f"machine: {machine()}")
    print(f"recording: {n_frames} frames of 336x256, tau2 unit {UNIT}, UAV pass (3.8 px/frame) "
          f"over the built-in aerial scene, FPA 32 °C; simulated in {simulate_s:.0f} s")
    print()
    print("| method, backend | groups (N = 7, stride 7) | processed | failed | wall time "
          "| peak RSS |")
    print("|---|---|---|---|---|---|")
    ran = resolve_backend(args.backend)
    backend = args.backend if ran == args.backend else f"{args.backend} ({ran})"
    print(f"| {args.method}, {backend} | {summary['groups']} | {summary['processed']} "
          f"| {summary['failed']} "
          f"| {summary['wall_time_s']:.0f} s (targets ≤ {600 * n_frames / 7152:.0f} s, "
          f"issue 21's ≤ {150 * n_frames / 7152:.0f} s on 2 idle cores) "
          f"| {max(rss_before, rss_after):.0f} MB |")
    print()
    print("| stage | seconds | frames/s |")
    print("|---|---|---|")
    for stage, seconds in summary["stage_seconds"].items():
        rate = fps[stage]
        print(f"| {stage} | {seconds:.1f} | {rate:.0f} |" if rate else f"| {stage} | 0 | – |")
    if split is not None:
        print()
        print("| run | wall time | maps |")
        print("|---|---|---|")
        print(f"| `thermocal flight` (one process) | {summary['wall_time_s']:.0f} s | "
              f"{summary['processed']} |")
        print(f"| `thermocal campaign --workers {split['workers']}` ({split['segments']} "
              f"segments and a finishing task) | {split['wall_time_s']:.0f} s (cluster start "
              f"{split['cluster_start_s']:.1f} s) | {split['processed']}, "
              f"{'the same bytes' if split['identical'] else 'NOT the same bytes'} |")
    if args.json:
        args.json.write_text(json.dumps({"machine": machine(), "n_frames": n_frames,
                                         "simulate_s": simulate_s, "summary": summary,
                                         "campaign": split,
                                         "peak_rss_mb": max(rss_before, rss_after)}, indent=2))


def _as_campaign(tmp: Path, options: FlightOptions, workers: int) -> dict:
    """The recording ``tmp/rec`` through ``thermocal campaign`` on ``workers`` workers into
    ``tmp/campaign``: its wall time, segments, maps, and whether they are the bytes of the
    flight in ``tmp/out``."""
    from thermocal.pipeline.campaign import campaign_tasks, run_campaign

    tasks = campaign_tasks([tmp / "rec"], tmp / "campaign", options)
    result = run_campaign(tasks, tmp / "campaign", workers=workers)
    (rec,) = result["recordings"]
    flight_maps = sorted((tmp / "out" / "temps").iterdir())
    ours = tmp / "campaign" / "rec" / "temps"
    identical = all((ours / p.name).is_file() and (ours / p.name).read_bytes() == p.read_bytes()
                    for p in flight_maps) and len(list(ours.iterdir())) == len(flight_maps)
    return {"workers": workers, "segments": len(tasks), "wall_time_s": result["wall_time_s"],
            "cluster_start_s": result["cluster_start_s"], "processed": rec.get("processed"),
            "ok": rec["ok"], "identical": identical}


if __name__ == "__main__":
    main()
