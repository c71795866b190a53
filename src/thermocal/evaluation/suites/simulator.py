"""Speed of the camera simulator (issue: foundation).

Measures, on this machine:

- one 640×512 frame rendered with every term of the camera model (target ≤ 10 ms);
- a 7-frame 336×256 burst: views rendered from a map, camera model, warped to the pivot
  (target ≤ 0.2 s);
- a chamber session of 10,000 frames of 336×256 streamed into HDF5 (target ≤ 60 s, memory bounded).

Run: ``python benchmarks/simulator.py [--quick] [--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from thermocal.bench import machine
from thermocal.camera import make_camera, render
from thermocal.registration.warp import warp_to_pivot
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
from thermocal.simulate.flight import simulate_flight


def best_of(fn, repeats: int) -> float:
    """Best wall time of ``repeats`` calls, s (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times), float(np.median(times))


def bench_frame(repeats: int) -> dict:
    camera = make_camera("tau2", unit=0, size=(640, 512))
    rng = np.random.default_rng(0)
    scene = procedural_scene((512, 640), rng=rng, kind="mixed")
    best, median = best_of(
        lambda: render(camera, scene, 31.0, housing_c=29.0, fpa_rate_c_per_min=0.4, rng=rng),
        repeats,
    )
    return {"name": "one 640x512 frame, every term", "best_s": best, "median_s": median,
            "target_s": 0.010}


def bench_burst(repeats: int) -> dict:
    camera = make_camera("tau2", unit=0, size=(336, 256))
    scene = procedural_scene((512, 512), rng=np.random.default_rng(1), kind="farmland")
    seeds = iter(range(10**6))

    def burst():
        flight = simulate_flight(scene, camera, n_frames=7, motion="walk", seed=next(seeds))
        warp_to_pivot(flight.frames, flight.homographies)

    best, median = best_of(burst, repeats)
    return {"name": "7-frame 336x256 burst: views, camera model, warp to pivot",
            "best_s": best, "median_s": median, "target_s": 0.2}


def bench_chamber(n_frames: int) -> dict:
    camera = make_camera("tau2", unit=0, size=(336, 256))
    plan = ChamberPlan(frames_per_point=5, profile="sawtooth", ambient_c=(10.0, 40.0),
                       rate_c_per_min=1.0, interval_s=3600.0 / n_frames, duration_s=3600.0)
    assert plan.n_frames == n_frames
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "chamber.h5"
        t = time.perf_counter()
        write_simulated_chamber(path, camera, plan, seed=0)
        elapsed = time.perf_counter() - t
        size_mb = path.stat().st_size / 2**20
    rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"name": f"chamber session, {n_frames} frames of 336x256 to HDF5",
            "best_s": elapsed, "median_s": elapsed, "target_s": 60.0 * n_frames / 10000,
            "file_mb": size_mb, "peak_rss_growth_mb": rss_after - rss_before}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats, 1,000-frame chamber")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    repeats = 5 if args.quick else 20
    # the chamber first, so that its peak-memory growth is not hidden by earlier allocations
    results = [bench_chamber(1000 if args.quick else 10000), bench_frame(repeats),
               bench_burst(repeats)]
    print(f"machine: {machine()}")
    print("| benchmark | best | median | target | |")
    print("|---|---|---|---|---|")
    for r in results:
        ok = "ok" if r["median_s"] <= r["target_s"] else "MISSED"
        extra = ""
        if "file_mb" in r:
            extra = f" ({r['file_mb']:.0f} MB file, peak RSS +{r['peak_rss_growth_mb']:.0f} MB)"
        print(f"| {r['name']}{extra} | {r['best_s'] * 1000:.1f} ms | {r['median_s'] * 1000:.1f} ms"
              f" | {r['target_s'] * 1000:.0f} ms | {ok} |")
    if args.json:
        args.json.write_text(json.dumps({"machine": machine(), "results": results}, indent=2))


if __name__ == "__main__":
    main()
