"""KPN benchmark: multi-frame temperature estimation (Oz et al.) on a held-out evaluation set.

The evaluation set is fixed and seeded and never trained on: the held-out real scenes of
:data:`thermocal.nn.data.EVAL_SCENES` (the built-in aerial scene and a fixed subset of the shared
JPEGs) flown over by the held-out camera units :data:`thermocal.nn.data.EVAL_UNITS` (the training
used units 0-23, its validation units 50-53), half by a walk (extreme views overlapping the pivot by
60-80 %, as in training) and half by a hover (``simulate_flight``'s: views jittered by ±3 px and
±1° around the pivot, which the training's drifting 60-80 % hover does not cover: the burst holds
little parallax to tell the scene from the fixed pattern), an FPA temperature drawn over 15-45 °C,
and the registration error of Oz et al. §IV-D on the true homographies (``--register``: the
homographies found by ``register_burst`` instead). Every method gets the burst with its stuck
pixels replaced (:func:`thermocal.burst.fill_stuck_pixels`, as ``thermocal estimate`` does).

Tables:

1. accuracy at N = 7 on the pixels seen by at least half the frames: MAE, the MAE left after
   removing each burst's mean error ("bias-free", i.e. the non-uniformity and noise left once
   the unit's unknown global offset is set aside) and its smooth and fine parts (a Gaussian of
   6 px of it and the rest: radial patterns against pixel FPN and noise), the MAE left after
   the best affine map onto the truth ("affine-free", an oracle that also sets the unit's
   unknown gain aside), the fraction within 0.5 °C (Fig. 12), for the shipped KPN and the
   calibration-free baselines: a two-point calibration of another unit made at a nominal FPA of
   30 °C (pivot frame alone, and eq. 9 registered mean), and scene-based NUC (hardie2000 with
   the same homographies) followed by a global fit (the other unit's array-mean gain and
   offset); plus, for reference only, the same unit's own two-point calibration at the
   burst's FPA (not calibration-free); with ``--chamber`` (a model trained from unit A's
   chamber file, the real-camera path), the eq. 9 mean through that file's radial model; and
   the classical pipeline given the camera model the network was trained from (not
   calibration-free): the eq. 9 mean through the exact average training unit (with
   ``--chamber``: through unit A's chamber model) low-passed by a Gaussian of 6 px, plus the
   high-pass of the scene-based NUC baseline;
2. MAE by trajectory (walk / hover) and mean error by distance from the sensor's centre for every
   method, and per-scene MAE of the KPN;
3. speed and size: one 336×256 burst of 7 frames, parameters, multiply-adds, training
   throughput (samples/s, a few steps of the shipped configuration);

Fig. 7 (MAE against N for the three variants) is ``benchmarks/kpn_fig7.py``.

    python -m thermocal.evaluation.suites.kpn [--quick] [--json OUT.json] [--model MODEL.pt]
                                       [--register] [--accuracy-only] [--device cuda]
                                       [--units 3,8,12,17,21] [--chamber UNIT_A.h5]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import torch

from thermocal.evaluation.heldout import eval_bursts
from thermocal.evaluation.network import (
    VARIANT_ROWS,
    run_methods,
    speed,
    training_throughput,
)
from thermocal.evaluation.references import CHAMBER_ROW, ExactModel
from thermocal.evaluation.scoring import summarise
from thermocal.evaluation.tables import (
    accuracy_table,
    per_burst_table,
    radius_table,
    trajectory_table,
)
from thermocal.nn.data import (
    EVAL_UNITS,
)
from thermocal.nn.infer import shipped_model_path
from thermocal.nn.model import count_macs, count_parameters
from thermocal.nn.store import load_model
from thermocal.nn.train import resolve_device


def print_speed(sp: dict, sps: float, n: int, info: dict) -> None:
    """The speed-and-size table."""
    print("\n| speed and size | value |\n|---|---|")
    what = " (frames calibrated and warped, then the network)" if sp.get("calibrated") else ""
    print(
        f"| network{what}, one 336×256 burst of {n} (median of 5, 2 threads) | "
        f"{sp['network_ms_336x256']:.0f} ms |"
    )
    print(f"| parameters | {sp['parameters']:,} |")
    print(f"| multiply-adds, 336×256 | {sp['gmacs_336x256']:.2f} G |")
    print(
        f"| training throughput (crop {info['data'].get('crop')}, batch 16, data included) | "
        f"{sps:.1f} samples/s |"
    )
    meta = info["meta"]
    print(
        f"| shipped model: validation MAE at save | {meta.get('val_mae_c')} °C "
        f"(step {meta.get('step')}) |"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--model", type=Path, default=None)
    ap.add_argument(
        "--register",
        action="store_true",
        help="use register_burst's homographies instead of the perturbed true ones",
    )
    ap.add_argument(
        "--accuracy-only",
        action="store_true",
        help="the KPN's accuracy table alone (no baselines, speed or throughput)",
    )
    ap.add_argument("--device", default="cpu", help="where the model runs (cpu, cuda, auto)")
    ap.add_argument(
        "--units",
        default=None,
        help="comma-separated camera units instead of the held-out ones (a diagnosis, e.g. "
        "training units: not the evaluation set)",
    )
    ap.add_argument(
        "--chamber",
        type=Path,
        default=None,
        help="the chamber file of unit A the model was trained from (thermocal train --chamber):"
        " adds that file's radial camera model, inverted exactly, as the floor, and makes it the"
        " classical pipeline's low-pass in place of the family model",
    )
    args = ap.parse_args(argv)
    torch.set_num_threads(2)
    references = {}
    if args.chamber is not None:
        from thermocal.calibration import camera_model_from_chamber

        references[CHAMBER_ROW] = ExactModel(camera_model_from_chamber(args.chamber))
    path = args.model or shipped_model_path("kpn")
    model, norm, info = load_model(path)
    n = model.config.n_frames
    t0 = time.time()
    units = EVAL_UNITS if args.units is None else tuple(int(u) for u in args.units.split(","))
    bursts = eval_bursts(n, quick=args.quick, register=args.register, units=units)
    label = (f"{VARIANT_ROWS[model.config.variant]} "
             f"({'shipped' if args.model is None else path.name})")
    res = run_methods(
        bursts, model.to(resolve_device(args.device)), norm, baselines=not args.accuracy_only,
        label=label, references=references,
    )
    model.cpu()
    rows = summarise(res)
    eval_s = time.time() - t0

    scenes = sorted({b["scene"] for b in bursts})
    size = bursts[0]["frames"].shape
    print(f"## KPN benchmark ({'quick' if args.quick else 'full'})\n")
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} CPU cores, torch "
        f"{torch.__version__}, 2 threads; model `{path.name}` "
        f"({model.config.to_dict()})"
    )
    print(
        f"data: {len(bursts)} bursts of N = {n} frames {size[2]}x{size[1]} over held-out "
        f"scenes {', '.join(scenes)}; "
        f"{'held-out camera units' if units == EVAL_UNITS else 'camera units (NOT held out)'} "
        f"{sorted({b['unit'] for b in bursts})}"
        f" (training units {info['data'].get('units', '?')[:1]}…"
        f"{info['data'].get('units', '?')[-1:]}); FPA 15-45 °C; registration: "
        f"{'register_burst' if args.register else 'true homographies + Oz error'}; "
        f"stuck pixels replaced for every method; metrics on pixels seen by ≥ half the frames; "
        f"{eval_s:.0f} s\n"
    )
    print(accuracy_table(rows))
    print("\nMAE °C by trajectory:\n")
    print(trajectory_table(bursts, res))
    print("\nMean error °C by distance from the sensor's centre (fifths of the pixels, centre "
          "to corners), over the bursts:\n")
    print(radius_table(res))
    print("\nKPN per scene (MAE °C / bias-free MAE °C):\n")
    print(per_burst_table(bursts, res[label]))

    sp = sps = None
    if args.accuracy_only:
        print(
            f"\nparameters {count_parameters(model):,}; multiply-adds at 336×256 "
            f"{count_macs(model, 256, 336) / 1e9:.1f} G; validation MAE at save "
            f"{info['meta'].get('val_mae_c')} °C (step {info['meta'].get('step')})"
        )
    else:
        sp = speed(model, norm)
        sps = training_throughput(model.config, info["data"], steps=4 if args.quick else 8)
        print_speed(sp, sps, n, info)

    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "quick": args.quick,
                    "register": args.register,
                    "model": path.name,
                    "accuracy": rows,
                    "per_burst": [
                        {"scene": b["scene"], "unit": b["unit"], "fpa_c": b["fpa_c"],
                         "motion": b["motion"], **s}
                        for b, s in zip(bursts, res[label], strict=True)
                    ],
                    "per_burst_mae_c": {name: [s["mae"] for s in lst]
                                        for name, lst in res.items()},
                    "speed": sp,
                    "training_samples_per_s": sps,
                },
                indent=2,
            )
        )


if __name__ == "__main__":
    main()
