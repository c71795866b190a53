"""Registration benchmark: corner error, failure rate and time on simulated flights.

Bursts are simulated walks (60-80 % overlap with the pivot, the tau2 preset's FPN and noise) over
the real scenes of ``shared/data/scenes`` plus the built-in aerial scene and procedural scenes.
Each non-pivot frame's estimated homography is compared with the true one by the mean distance of
the four mapped frame corners (pixels). A burst that raises RegistrationError counts its frames
as failures; a frame with a corner error above 5 px counts as a silent failure.

    .venv/bin/python benchmarks/registration.py [--quick] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

from thermocal.camera.presets import make_camera
from thermocal.errors import RegistrationError
from thermocal.registration import register_burst, register_pair
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.scenes.procedural import procedural_scene
from thermocal.scenes.real import list_shared_scenes, load_scene
from thermocal.simulate.flight import simulate_flight

SIZE = (336, 256)


def corner_error(h_est: np.ndarray, h_true: np.ndarray, size=SIZE) -> float:
    w, h = size
    c = np.array([[0, 0, 1], [w - 1, 0, 1], [w - 1, h - 1, 1], [0, h - 1, 1]], float).T
    a, b = h_est @ c, h_true @ c
    return float(np.linalg.norm(a[:2] / a[2] - b[:2] / b[2], axis=0).mean())


def scenes(quick: bool) -> dict[str, np.ndarray]:
    out = {}
    shared = list_shared_scenes()
    for name, path in list(shared.items())[: 4 if quick else None]:
        out[name] = load_scene(path)
    out["builtin:aerial"] = load_builtin_scene("aerial")
    for k in range(2 if quick else 6):
        kind = ("mixed", "urban", "farmland")[k % 3]
        out[f"procedural:{k}"] = procedural_scene(
            (512, 512), rng=np.random.default_rng(100 + k), kind=kind
        )
    return out


def run(quick: bool) -> dict:
    n_frames = 5
    units = (1, 2) if quick else (1, 2, 3)
    rows = []
    for (name, scene), seed in zip(scenes(quick).items(), range(1000), strict=False):
        kind = "procedural" if name.startswith("procedural") else "real"
        for unit in units:
            cam = make_camera("tau2", unit=unit, size=SIZE)
            fl = simulate_flight(scene, cam, n_frames=n_frames, motion="walk", seed=seed * 7 + unit)
            t0 = time.perf_counter()
            try:
                reg = register_burst(fl.frames, pivot=fl.pivot)
                errs = [corner_error(reg.homographies[i], fl.homographies[i])
                        for i in range(n_frames) if i != fl.pivot]
                failed = False
            except RegistrationError:
                errs, failed = [], True
            dt = time.perf_counter() - t0
            pair_errs, pair_times = [], []
            for i in (0, n_frames - 1):  # the two extreme views (least overlap)
                t1 = time.perf_counter()
                try:
                    h, _ = register_pair(fl.frames[i], fl.frames[fl.pivot])
                    pair_errs.append(corner_error(h, fl.homographies[i]))
                except RegistrationError:
                    pair_errs.append(np.inf)
                pair_times.append(time.perf_counter() - t1)
            rows.append(dict(scene=name, kind=kind, unit=unit, failed=failed, errors=errs,
                             burst_s=dt, pair_errors=pair_errs, pair_s=pair_times))
    return dict(rows=rows, n_frames=n_frames, units=list(units))


def summarise(rows: list[dict], kind: str | None, n_frames: int) -> dict:
    sel = [r for r in rows if kind is None or r["kind"] == kind]
    errs = np.array([e for r in sel for e in r["errors"]])
    n_total = sum(n_frames - 1 for _ in sel)
    raised = sum(n_frames - 1 for r in sel if r["failed"])
    silent = int(np.sum(errs > 5.0)) if errs.size else 0
    ok = errs[errs <= 5.0] if errs.size else errs
    pair = np.array([e for r in sel for e in r["pair_errors"]])
    per_frame_ms = [1000 * r["burst_s"] / (n_frames - 1) for r in sel if not r["failed"]]
    pair_ms = [1000 * t for r in sel for t in r["pair_s"]]
    return dict(
        bursts=len(sel),
        frames=n_total,
        median_px=float(np.median(errs)) if errs.size else float("nan"),
        p95_px=float(np.percentile(errs, 95)) if errs.size else float("nan"),
        median_ok_px=float(np.median(ok)) if ok.size else float("nan"),
        raised=raised,
        silent=silent,
        failure_rate=(raised + silent) / max(n_total, 1),
        pair_median_px=float(np.median(pair)) if pair.size else float("nan"),
        pair_p95_px=float(np.percentile(pair, 95)) if pair.size else float("nan"),
        ms_per_frame=float(np.median(per_frame_ms)) if per_frame_ms else float("nan"),
        ms_per_pair=float(np.median(pair_ms)) if pair_ms else float("nan"),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = run(args.quick)
    table = {k or "all": summarise(res["rows"], k, res["n_frames"])
             for k in (None, "real", "procedural")}
    print(f"## Registration benchmark{' (quick)' if args.quick else ''}\n")
    print(f"- machine: {platform.node()} {platform.machine()}, {os.cpu_count()} CPUs, "
          f"{platform.python_version()}")
    print(f"- data: simulated walks of {res['n_frames']} frames at {SIZE[0]}x{SIZE[1]}, "
          f"tau2 units {res['units']}, over real scenes (shared/data/scenes + built-in aerial) "
          "and procedural scenes; pivot = middle frame; corner error = mean distance of the 4 "
          "mapped corners to the true ones, px")
    print("- burst = register_burst (FPN estimated jointly); pair = register_pair of each "
          "extreme view to the pivot (2 frames only)\n")
    print("| scenes | bursts | frames | median px | p95 px | raised | >5 px | failure rate | "
          "pair median px | pair p95 px | ms/frame in burst | ms/pair |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for k, s in table.items():
        print(f"| {k} | {s['bursts']} | {s['frames']} | {s['median_px']:.2f} | {s['p95_px']:.2f} "
              f"| {s['raised']} | {s['silent']} | {s['failure_rate']:.1%} | "
              f"{s['pair_median_px']:.2f} | {s['pair_p95_px']:.2f} | {s['ms_per_frame']:.0f} | "
              f"{s['ms_per_pair']:.0f} |")
    print("\nTargets: median <= 0.5 px, p95 <= 2 px, <= 50 ms per 336x256 pair.")
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(dict(summary=table, rows=res["rows"]), fh, indent=1, default=float)


if __name__ == "__main__":
    main()
