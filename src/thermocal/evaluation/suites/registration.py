"""Registration benchmark: corner error, failure rate and time on simulated flights.

Three parts, all with the tau2 preset's FPN and noise at 336x256:

* **burst** -- 5-frame walks (60-80 % overlap with the pivot) over the real scenes of
  ``shared/data/scenes``, the built-in aerial scene and procedural scenes, registered by
  :func:`register_burst` (the fixed pattern estimated from the burst itself).
* **pair** -- each extreme view of those walks registered to the pivot by :func:`register_pair`:
  from the two frames only, and with the camera's fixed pattern known -- estimated by
  :func:`estimate_fixed_pattern` on a *different* recording: a 200-frame UAV pass of the same
  unit over the same scene (the gain part of the pattern scales with the scene level, so a
  pattern does not carry over to a scene at another temperature), never registered itself.
* **sequence** -- 200-frame UAV passes (3.8 px per frame, ``plan_flight(motion="uav")``) over the
  aerial scene and real scenes, registered frame to previous frame by
  :func:`register_sequence` (pattern estimated from the pass); the chained frame -> pivot
  homographies (:meth:`SequenceRegistration.to_pivot`) are scored for frames 1, 2, 3 and 5 away
  from pivots spread along the pass.

Corner error: the mean distance (px) of the four frame corners mapped by the estimated and by
the true homography. A burst that raises RegistrationError counts its frames as raised
failures; a frame with a corner error above 5 px counts as a silent failure. Times: wall clock
with the default 2 threads and the process CPU time (all threads) per frame or pair, which is
what one core would need; the machine may be shared, so wall times can exceed CPU times.

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
from thermocal.registration import (
    estimate_fixed_pattern,
    register_burst,
    register_pair,
    register_sequence,
)
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.scenes.procedural import procedural_scene
from thermocal.scenes.real import list_shared_scenes, load_scene
from thermocal.simulate.flight import iter_flight, plan_flight, simulate_flight

SIZE = (336, 256)
N_BURST = 5
N_PASS = 200
DISTANCES = (1, 2, 3, 5)
SILENT_PX = 5.0


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


def uav_pass(scene: np.ndarray, unit: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Frames (N_PASS, H, W) uint16 and frame -> map homographies of a UAV pass."""
    cam = make_camera("tau2", unit=unit, size=SIZE)
    plan = plan_flight(scene, cam, n_frames=N_PASS, motion="uav", seed=seed)
    frames = np.concatenate([c.frames for c in iter_flight(plan, cam)])
    return frames, plan.to_map


def run_bursts(quick: bool) -> list[dict]:
    units = (1, 2) if quick else (1, 2, 3)
    rows = []
    for (name, scene), seed in zip(scenes(quick).items(), range(1000), strict=False):
        kind = "procedural" if name.startswith("procedural") else "real"
        for unit in units:
            cam = make_camera("tau2", unit=unit, size=SIZE)
            fl = simulate_flight(scene, cam, n_frames=N_BURST, motion="walk",
                                 seed=seed * 7 + unit)
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                reg = register_burst(fl.frames, pivot=fl.pivot)
                errs = [corner_error(reg.homographies[i], fl.homographies[i])
                        for i in range(N_BURST) if i != fl.pivot]
                failed = False
            except RegistrationError:
                errs, failed = [], True
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            # the pattern of this unit over this scene, from a separate pass never registered
            known = estimate_fixed_pattern(uav_pass(scene, unit, seed=500 + seed * 7 + unit)[0])
            pair = {"alone": [], "known FPN": []}
            pair_s = {"alone": [], "known FPN": []}
            for i in (0, N_BURST - 1):  # the two extreme views (least overlap)
                for mode, fp in (("alone", None), ("known FPN", known)):
                    c1 = time.process_time()
                    try:
                        h, _ = register_pair(fl.frames[i], fl.frames[fl.pivot], fixed_pattern=fp)
                        pair[mode].append(corner_error(h, fl.homographies[i]))
                    except RegistrationError:
                        pair[mode].append(float("inf"))
                    pair_s[mode].append(time.process_time() - c1)
            rows.append(dict(scene=name, kind=kind, unit=unit, failed=failed, errors=errs,
                             wall_s=wall, cpu_s=cpu, pair=pair, pair_cpu_s=pair_s))
    return rows


def run_sequences(quick: bool) -> list[dict]:
    names = ["builtin:aerial", "14_kujawy_wiatrak", "12_ir_moving_mercedes", "frame_000000"]
    names = names[:2] if quick else names
    units = (1,) if quick else (1, 2)
    shared = list_shared_scenes()
    rows = []
    for k, name in enumerate(names):
        if name.startswith("builtin:"):
            scene = load_builtin_scene(name.split(":")[1])
        elif name in shared:
            scene = load_scene(shared[name])
        else:  # pragma: no cover - a scene missing from this checkout
            continue
        for unit in units:
            frames, to_map = uav_pass(scene, unit, seed=10 * k + unit)
            t0, c0 = time.perf_counter(), time.process_time()
            reg = register_sequence(frames)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            inv = np.linalg.inv(to_map)
            pair = [corner_error(reg.to_previous[j], inv[j - 1] @ to_map[j])
                    for j in range(1, N_PASS)]
            chain: dict[int, list[float]] = {d: [] for d in DISTANCES}
            for p in range(10, N_PASS - 10, 7):
                for d in DISTANCES:
                    for i in (p - d, p + d):
                        try:
                            h = reg.to_pivot([i], p)[0]
                            chain[d].append(corner_error(h, inv[p] @ to_map[i]))
                        except RegistrationError:
                            chain[d].append(float("inf"))
            rows.append(dict(scene=name, unit=unit, pair=pair, chain=chain,
                             not_ok=int((~reg.ok).sum()), wall_s=wall, cpu_s=cpu))
    return rows


def _stats(errs: list[float]) -> tuple[float, float]:
    e = np.asarray(errs, float)
    if not e.size:
        return float("nan"), float("nan")
    return float(np.median(e)), float(np.percentile(e, 95))


def summarise_bursts(rows: list[dict], kind: str | None) -> dict:
    sel = [r for r in rows if kind is None or r["kind"] == kind]
    errs = np.array([e for r in sel for e in r["errors"]])
    n_total = (N_BURST - 1) * len(sel)
    raised = sum(N_BURST - 1 for r in sel if r["failed"])
    silent = int(np.sum(errs > SILENT_PX)) if errs.size else 0
    ok = [r for r in sel if not r["failed"]]
    med, p95 = _stats(errs)
    out = dict(
        bursts=len(sel), frames=n_total, median_px=med, p95_px=p95,
        over_2px=float(np.mean(errs > 2.0)) if errs.size else float("nan"),
        raised=raised, silent=silent, failure_rate=(raised + silent) / max(n_total, 1),
        wall_ms_per_frame=1000 * float(np.mean([r["wall_s"] for r in ok])) / (N_BURST - 1),
        cpu_ms_per_frame=1000 * float(np.mean([r["cpu_s"] for r in ok])) / (N_BURST - 1),
    )
    for mode in ("alone", "known FPN"):
        pe = [e for r in sel for e in r["pair"][mode]]
        pm, pp = _stats(pe)
        out[f"pair {mode}"] = dict(
            median_px=pm, p95_px=pp, over_5px=float(np.mean(np.asarray(pe) > SILENT_PX)),
            cpu_ms=1000 * float(np.mean([t for r in sel for t in r["pair_cpu_s"][mode]])),
        )
    return out


def summarise_sequences(rows: list[dict]) -> dict:
    out = {}
    for r in rows + [None]:
        sel = rows if r is None else [r]
        key = "all" if r is None else f"{r['scene']} (unit {r['unit']})"
        pair = [e for s in sel for e in s["pair"]]
        out[key] = dict(
            pair=_stats(pair),
            chain={d: _stats([e for s in sel for e in s["chain"][d]]) for d in DISTANCES},
            not_ok=sum(s["not_ok"] for s in sel),
            wall_ms_per_pair=1000 * sum(s["wall_s"] for s in sel) / ((N_PASS - 1) * len(sel)),
            cpu_ms_per_pair=1000 * sum(s["cpu_s"] for s in sel) / ((N_PASS - 1) * len(sel)),
        )
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    bursts = run_bursts(args.quick)
    seqs = run_sequences(args.quick)
    btable = {k or "all": summarise_bursts(bursts, k) for k in (None, "real", "procedural")}
    stable = summarise_sequences(seqs)
    units = sorted({r["unit"] for r in bursts})
    print(f"## Registration benchmark{' (quick)' if args.quick else ''}\n")
    print(f"- machine: {platform.node()} {platform.machine()}, {os.cpu_count()} CPUs "
          f"(load average {os.getloadavg()[0]:.1f} at the end), Python "
          f"{platform.python_version()}")
    print(f"- camera: tau2 preset units {units}, {SIZE[0]}x{SIZE[1]}, its FPN and noise")
    print(f"- bursts: {len(bursts)} simulated walks of {N_BURST} frames (60-80 % overlap), "
          "pivot = middle frame, over shared/data/scenes + built-in aerial (real) and "
          "procedural scenes; register_burst with the default 2 threads")
    print("- pairs: each extreme view to the pivot; 'known FPN' = estimate_fixed_pattern of a "
          "separate 200-frame UAV pass of the same unit over the same scene")
    print(f"- sequences: {len(seqs)} UAV passes of {N_PASS} frames (3.8 px/frame) over "
          f"{sorted({r['scene'] for r in seqs})}; register_sequence (pattern from the pass)")
    print("- corner error = mean distance of the 4 mapped corners to the true ones, px; "
          f"silent failure = corner error > {SILENT_PX:g} px; CPU ms = process CPU time "
          "(all threads) = one core's cost\n")

    print("### Burst (register_burst) and pair (register_pair)\n")
    print("| scenes | bursts | frames | median px | p95 px | > 2 px | raised | > 5 px | "
          "failure rate | wall ms/frame | CPU ms/frame |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for k, s in btable.items():
        print(f"| {k} | {s['bursts']} | {s['frames']} | {s['median_px']:.2f} | "
              f"{s['p95_px']:.2f} | {s['over_2px']:.1%} | {s['raised']} | {s['silent']} | "
              f"{s['failure_rate']:.1%} | {s['wall_ms_per_frame']:.0f} | "
              f"{s['cpu_ms_per_frame']:.0f} |")
    print("\n| scenes | pair | median px | p95 px | > 5 px | CPU ms/pair |")
    print("|---|---|---|---|---|---|")
    for k, s in btable.items():
        for mode in ("alone", "known FPN"):
            p = s[f"pair {mode}"]
            print(f"| {k} | {mode} | {p['median_px']:.2f} | {p['p95_px']:.2f} | "
                  f"{p['over_5px']:.1%} | {p['cpu_ms']:.0f} |")

    print("\n### Sequence (register_sequence, chained to_pivot)\n")
    heads = " | ".join(f"±{d} median / p95 px" for d in DISTANCES)
    print(f"| pass | pair median / p95 px | {heads} | not ok | wall ms/pair | CPU ms/pair |")
    print("|---|---|" + "---|" * len(DISTANCES) + "---|---|---|")
    for k, s in stable.items():
        chain = " | ".join(f"{s['chain'][d][0]:.2f} / {s['chain'][d][1]:.2f}" for d in DISTANCES)
        print(f"| {k} | {s['pair'][0]:.2f} / {s['pair'][1]:.2f} | {chain} | {s['not_ok']} | "
              f"{s['wall_ms_per_pair']:.1f} | {s['cpu_ms_per_pair']:.1f} |")
    cpu_pair = stable["all"]["cpu_ms_per_pair"]
    print(f"\n7,152 frames at {cpu_pair:.1f} CPU ms per pair: about "
          f"{7151 * cpu_pair / 1000:.0f} s on one core.")
    print("\nTargets: burst median <= 0.5 px, p95 <= 2 px, <= 50 ms per frame (2 cores); "
          "sequence <= 20 ms per pair.")
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(dict(burst=btable, sequence=stable, bursts=bursts, sequences=seqs), fh,
                      indent=1, default=float)


if __name__ == "__main__":
    main()
