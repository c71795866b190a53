"""Oz et al. Fig. 9: nonuniformity correction compared at N = 11 on held-out bursts.

Held-out camera units (``tau2`` 100–104) fly UAV passes (:func:`thermocal.evaluation.passes
.simulate_pass`, 301 frames of 160×128 by default: DeepIR's per-burst optimisation takes
minutes at the network's 336×256 on 2 cores) over held-out real scenes; at a few pivots of
each pass a burst of N = 11 frames is cut and every method corrects it:

* ``kpn + offset``: the shipped network (Oz et al.; trained for N = 7, so it gets the burst's
  middle 7 frames), calibration-free, in °C;
* ``hardie2000``: registration-based NUC of the 11 frames (Hardie et al. 2000), counts-like;
* ``admire``: the pivot frame alone, ADMIRE-style (Tendero & Gilles 2012), counts-like;
* ``he2018``: the pivot frame alone through the single-image CNN (He et al. 2018, trained on
  the simulator's training units and scenes), counts-like;
* ``deepir``: the 11 frames through DeepIR's per-burst optimisation with a network prior
  (Saragadam et al. 2021), counts-like;
* ``selfcal``: the pass's own fixed pattern, fitted over all its frames (``thermocal flight
  --method selfcal --frames 11``), calibration-free, in °C; its time is the whole pass's over
  its maps.

Each pivot map is scored against the truth after its best affine map (what Fig. 9 compares:
these NUC outputs are not radiometric), over the unit's good pixels: MAE, roughness (Wolf et al.
2016 eq. 13) of the mapped output, column bands (the SD of the error's column means) and the
seconds per burst on this machine.

Run: ``python benchmarks/fig9.py [--quick] [--json R.json] [--markdown R.md] [--out FIG.png]``.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from thermocal import metrics

#: (unit, scene) of each pass: held-out units over held-out scenes the network accepts.
PASSES = ((100, "builtin:aerial"), (101, "02_irwatercooler"), (102, "11_ir_moving_car"),
          (103, "12_ir_moving_mercedes"), (104, "builtin:aerial"))
N = 11
METHODS = ("kpn + offset", "hardie2000", "admire", "he2018", "deepir", "selfcal")


def _pivots(n_frames: int, per_pass: int, stride: int) -> list[int]:
    """``per_pass`` pivots of the flight's grid (``N // 2 + k·stride``), spread over the pass."""
    grid = list(range(N // 2, n_frames - N // 2, stride))
    picks = np.linspace(0, len(grid) - 1, per_pass + 2)[1:-1]
    return [grid[int(round(i))] for i in picks]


def _score(out: np.ndarray, truth: np.ndarray, good: np.ndarray) -> dict[str, float]:
    mapped = metrics.best_affine_fit(out, truth, good)
    return {"affine_free_mae_c": metrics.mae(mapped, truth, valid=good),
            "roughness": float(metrics.roughness(mapped)),
            "column_bands_c": metrics.column_bands(mapped, truth, valid=good)}


def _burst_methods(burst: np.ndarray, fpa: np.ndarray, methods: tuple[str, ...]
                   ) -> dict[str, tuple[np.ndarray, float]]:
    """Each burst method's pivot output and its seconds."""
    from thermocal.estimation.pipeline import estimate
    from thermocal.estimation.registry import make_estimator
    from thermocal.nuc import correct_nonuniformity

    p = N // 2
    runs = {
        "kpn + offset": lambda: estimate(burst[p - 3 : p + 4], make_estimator("kpn"),
                                         fpa_c=fpa[p - 3 : p + 4]).temperature_c,
        "hardie2000": lambda: correct_nonuniformity(burst, method="hardie2000")[p],
        "admire": lambda: correct_nonuniformity(burst[p : p + 1], method="admire")[0],
        "he2018": lambda: correct_nonuniformity(burst[p : p + 1], method="he2018")[0],
        "deepir": lambda: correct_nonuniformity(burst, method="deepir")[p],
    }
    out = {}
    for name in methods:
        if name in runs:
            t = time.perf_counter()
            out[name] = (np.asarray(runs[name](), np.float64), time.perf_counter() - t)
    return out


def run_pass(unit: int, scene: str, work: Path, *, n_frames: int, per_pass: int,
             methods: tuple[str, ...], size: tuple[int, int] = (160, 128)
             ) -> list[dict[str, Any]]:
    """Every method on ``per_pass`` bursts of one pass; one row per burst and method."""
    import tifffile

    from thermocal.camera.presets import make_camera
    from thermocal.evaluation.passes import PassSpec, simulate_pass
    from thermocal.nn.data import EVAL_SCENES
    from thermocal.pipeline.flight import FlightOptions, process_flight

    seed = 1000 * EVAL_SCENES.index(scene) + unit
    spec = PassSpec(scene=scene, unit=unit, n_frames=n_frames, seed=seed, size=size)
    folder = work / f"pass_{unit}_{EVAL_SCENES.index(scene)}"
    recording = simulate_pass(spec, folder)
    frames = tifffile.imread(recording)
    truth = tifffile.imread(folder / "truth.tiff")
    fpa = np.asarray(json.loads(recording.with_suffix(".json").read_text())["fpa_c"])
    good = ~make_camera("tau2", unit=unit, size=spec.size).defects
    stride = N
    pivots = _pivots(n_frames, per_pass, stride)
    selfcal_maps: dict[int, np.ndarray] = {}
    selfcal_s = float("nan")
    if "selfcal" in methods:
        out = folder / "selfcal"
        t = time.perf_counter()
        # forced: its σ was measured on larger frames than 160×128 (σ grown; not scored here)
        summary = process_flight(recording, out, FlightOptions(method="selfcal", frames=N,
                                                               stride=stride, preview_every=0,
                                                               force=True))
        selfcal_s = (time.perf_counter() - t) / max(summary["processed"], 1)
        for p in pivots:
            selfcal_maps[p] = tifffile.imread(out / "temps" / f"frame_{p:06d}.tiff")
    rows = []
    for p in pivots:
        burst = frames[p - N // 2 : p + N // 2 + 1]
        outs = _burst_methods(burst, fpa[p - N // 2 : p + N // 2 + 1], methods)
        if "selfcal" in methods:
            outs["selfcal"] = (selfcal_maps[p].astype(np.float64), selfcal_s)
        raw = burst[N // 2].astype(np.float64)
        outs = {"raw pivot": (raw, 0.0), **outs}
        for name, (est, seconds) in outs.items():
            rows.append({"unit": unit, "scene": scene, "pivot": p, "method": name,
                         "seconds": seconds, **_score(est, truth[p], good)})
    return rows


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per method: the means over the bursts."""
    out = []
    for name in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == name]
        out.append({"method": name, "bursts": len(mine),
                    **{k: float(np.mean([r[k] for r in mine]))
                       for k in ("affine_free_mae_c", "roughness", "column_bands_c", "seconds")}})
    return out


def figure(summary: list[dict[str, Any]], path: Path) -> None:
    """Fig. 9's comparison as bars: MAE after the best affine map, roughness, column bands,
    seconds."""
    from thermocal.plotting import pyplot, save_figure

    fig, axes = pyplot().subplots(1, 4, figsize=(15, 3.6))
    names = [s["method"] for s in summary]
    for ax, key, label in zip(axes, ("affine_free_mae_c", "roughness", "column_bands_c",
                                     "seconds"),
                              ("MAE after the best affine map, °C", "roughness (Wolf eq. 13)",
                               "column bands, °C", "seconds per burst (log)"), strict=True):
        ax.bar(range(len(names)), [s[key] for s in summary], color="tab:blue")
        ax.set_xticks(range(len(names)), names, rotation=35, ha="right", fontsize=8)
        ax.set_title(label, fontsize=9)
        if key == "seconds":
            ax.set_yscale("log")
    fig.suptitle(f"NUC at N = {N} on held-out bursts (tau2 units 100–104, held-out scenes)",
                 fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


def report(summary: list[dict[str, Any]], info: dict[str, Any]) -> str:
    from thermocal.evaluation.tables import markdown_table

    cells = [(s["method"], s["bursts"], f"{s['affine_free_mae_c']:.3f}", f"{s['roughness']:.4f}",
              f"{s['column_bands_c']:.3f}", f"{s['seconds']:.2f}") for s in summary]
    table = markdown_table(("method", "bursts", "MAE after best affine °C", "roughness",
                            "column bands °C", "s per burst"), cells)
    return (f"## Oz et al. Fig. 9: NUC at N = {N}\n\nmachine: {info['machine']}; "
            f"{info['wall_s']:.0f} s\n\ncommand: `{info['command']}`\n\ndata: {info['data']}\n\n"
            f"{table}\n")


def main(argv: list[str] | None = None) -> None:
    import sys

    from thermocal.bench import machine

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 passes, 1 burst each, 121 frames")
    ap.add_argument("--per-pass", type=int, default=2, help="Bursts per pass.")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--size", default="160x128", help="Frame size WxH.")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--markdown", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None, help="The figure (PNG).")
    args = ap.parse_args(argv)
    passes = PASSES[:2] if args.quick else PASSES
    per_pass = 1 if args.quick else args.per_pass
    n_frames = 121 if args.quick else 301
    methods = tuple(args.methods.split(","))
    from thermocal._validate import parse_size

    size = parse_size(args.size)
    started = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for unit, scene in passes:
            rows += run_pass(unit, scene, Path(tmp), n_frames=n_frames, per_pass=per_pass,
                             methods=methods, size=size)
            print(f"unit {unit} over {scene}: done", flush=True)
    summary = summarise(rows)
    import torch

    gpu = (f"; deepir on {torch.cuda.get_device_name(0)} (the other methods on the CPU)"
           if torch.cuda.is_available() else "")
    info = {"machine": machine() + gpu, "wall_s": time.perf_counter() - started,
            "command": "python benchmarks/fig9.py " + " ".join(sys.argv[1:] if argv is None
                                                               else argv),
            "data": (f"{len(passes)} UAV passes of {n_frames} frames ({size[0]}×{size[1]}, FPA "
                     "30 °C) of "
                     f"tau2 units {', '.join(str(u) for u, _ in passes)} over held-out scenes "
                     f"({', '.join(sorted({s for _, s in passes}))}); {per_pass} bursts of "
                     f"N = {N} per pass; scored against the pivot's truth after each output's "
                     "best affine map, over the unit's good pixels; load average "
                     f"{', '.join(f'{x:.1f}' for x in os.getloadavg())} at the end")}
    text = report(summary, info)
    print(text)
    if args.markdown:
        args.markdown.write_text(text, encoding="utf-8")
    if args.json:
        args.json.write_text(json.dumps({"info": info, "summary": summary, "rows": rows},
                                        indent=1), encoding="utf-8")
    if args.out:
        figure(summary, args.out)


if __name__ == "__main__":
    main()
