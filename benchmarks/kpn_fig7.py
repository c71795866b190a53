"""Fig. 7 of Oz et al.: MAE against the burst length N for KPN + offset, KPN and E2E.

Every (variant, N) model is trained for the same wall-clock budget on the *same* stream of
synthetic bursts: bursts of N_max = max(N) frames are made once and each model takes the N frames
around the pivot (so the N-frame bursts are sub-bursts of the N_max ones: shorter ones overlap
their pivot more than the 60-80 % of the extreme views of an N_max burst). Sharing the data makes
the comparison fair (every model sees the same scenes, units and noise) and the sweep affordable:
burst generation, not the network, bounds the training speed. Each model then runs on the fixed
held-out evaluation set of ``benchmarks/kpn.py`` made with N frames (held-out real scenes, held-out
camera units 100-104, full 336×256 frames).

Optimisation: Adam at ``--lr``, halved at 50 % and 75 % of the budget (``--minutes``, or
``--steps`` where that comes first: ``thermocal train --lr-schedule step``; a fixed schedule: the
models share one budget, so none stops early); the loss of eq. 12 over the pixels seen by at least
half of the model's N frames. Network sizes are the shipped model's unless given.

    .venv/bin/python benchmarks/kpn_fig7.py --minutes 7 --device auto --workers 4 \\
        --variants kpn,kpn-no-offset,e2e --ns 1,3,5,7,9,11 --json fig7.json [--out-dir DIR] \\
        [--sensor-motion] [--radial-frames] [--no-calibrated] [--seed 42]

Several processes (say one per variant, or one per ``--seed``) can share a GPU; ``--merge A.json
B.json --json OUT`` joins their results into the file that ships beside the weights
(``nn/weights/fig7.json``): runs of several seeds of the same (variant, N) are averaged, with
their SD over seeds.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from thermocal.evaluation.heldout import eval_bursts
from thermocal.evaluation.network import run_methods
from thermocal.evaluation.references import FAMILY_ROW, ExactModel
from thermocal.evaluation.scoring import summarise
from thermocal.nn.data import BurstConfig, ScenePool, min_views
from thermocal.nn.infer import shipped_model_path
from thermocal.nn.model import KPN, ModelConfig
from thermocal.nn.store import load_model, save_model
from thermocal.nn.train import (
    BurstStream,
    TrainConfig,
    burst_loader,
    fit_normalisation,
    resolve_device,
    seed_everything,
    step_lr,
    train_step,
)


def sub_burst(batch: tuple[torch.Tensor, ...], n: int, n_max: int,
              frame_positions: bool = False) -> tuple[torch.Tensor, ...]:
    """The ``n`` frames around the pivot of an ``n_max``-frame batch, with their coverage mask
    and, with ``frame_positions``, their ``R²`` planes (the batch's other tensors unchanged)."""
    frames, fpa, valid, truth, _, r2 = batch
    p = n_max // 2
    sel = slice(p - n // 2, p - n // 2 + n)
    v = valid[:, sel]
    mask = v.sum(dim=1, keepdim=True) >= min_views(n)
    if frame_positions:  # each frame's sensor position: the sub-burst's own
        r2 = r2[:, sel].contiguous()
    return frames[:, sel].contiguous(), fpa, v.contiguous(), truth, mask, r2


def train_side_by_side(args: argparse.Namespace, base: ModelConfig) -> dict:
    """Every (variant, N) model trained on one stream of N_max-frame bursts (each on its
    sub-bursts: :func:`sub_burst`) with ``thermocal train``'s pieces: its seeding, burst stream,
    optimisation step and ``--lr-schedule step`` rate, for ``--minutes`` or ``--steps``."""
    device = resolve_device(args.device)
    torch.set_num_threads(args.threads)
    seed_everything(args.seed, device)
    ns = [int(x) for x in args.ns.split(",")]
    if any(n % 2 == 0 for n in ns):
        raise SystemExit("N must be odd (a pivot in the middle)")
    n_max = max(ns)
    cfg = BurstConfig(n_frames=n_max, crop=args.crop, sensor_motion=args.sensor_motion,
                      calibrated=base.calibrated)
    pool_fn = lambda: ScenePool.training(seed=42, n_procedural=24)  # noqa: E731
    norm = fit_normalisation(pool_fn(), cfg, seed=42)
    models, opts = {}, {}
    for v in args.variants.split(","):
        for n in ns:
            mc = ModelConfig(**{**base.to_dict(), "n_frames": n, "variant": v,
                                "centre": base.centre and v == "kpn"})
            models[(v, n)] = KPN(mc, temp_range_c=(norm.temp_min_c, norm.temp_max_c))
            models[(v, n)] = models[(v, n)].to(device).train()
            opts[(v, n)] = torch.optim.Adam(models[(v, n)].parameters(), lr=args.lr)
    stream = BurstStream(pool_fn, cfg, norm, seed=args.seed, batch=args.batch, start_batch=0,
                         cameras=None, frame_positions=base.radial_frames,
                         band_m=base.band_m if base.radiance else None)
    loader = burst_loader(stream, args.workers, device)
    t0, steps, budget = time.monotonic(), 0, 60.0 * args.minutes
    losses = {k: [] for k in models}
    it = iter(loader)
    # thermocal train --lr-schedule step's rate, over the first of --minutes and --steps to run out
    schedule = TrainConfig(lr=args.lr, steps_per_epoch=1, max_epochs=2**62,
                           max_minutes=args.minutes, max_steps=args.steps)
    while time.monotonic() - t0 < budget and (args.steps is None or steps < args.steps):
        lr = step_lr(schedule, steps, time.monotonic() - t0)
        batch = tuple(t.to(device, non_blocking=True) for t in next(it))
        for key, model in models.items():
            sub = sub_burst(batch, key[1], n_max, base.radial_frames)
            losses[key].append(train_step(model, opts[key], sub, lr=lr))
        steps += 1
        if steps % 100 == 0:
            print(
                f"step {steps} {time.monotonic() - t0:.0f} s "
                + " ".join(f"{v}/{n}:{np.mean(losses[(v, n)][-100:]):.4f}" for v, n in models),
                flush=True,
            )
    wall = time.monotonic() - t0
    print(
        f"trained {len(models)} models for {steps} steps each (batch {args.batch}) in "
        f"{wall:.0f} s: {steps * args.batch / wall:.0f} bursts/s",
        flush=True,
    )
    return {"models": models, "norm": norm, "cfg": cfg, "ns": ns, "variants":
            args.variants.split(","), "steps": steps, "wall": wall, "losses": losses,
            "device": device}


def train_sweep(args: argparse.Namespace, base: ModelConfig) -> list[dict]:
    run = train_side_by_side(args, base)
    models, norm, cfg, ns, variants = (run[k] for k in ("models", "norm", "cfg", "ns",
                                                        "variants"))
    steps, wall, losses, device = (run[k] for k in ("steps", "wall", "losses", "device"))
    out_dir = Path(args.out_dir) if args.out_dir else None
    rows = []
    torch.set_num_threads(args.eval_threads)
    family = ExactModel.family(cfg.units)
    for n in ns:
        bursts = eval_bursts(n, quick=args.quick)
        floor = summarise(run_methods(bursts, None, None, baselines=False,
                                      references={FAMILY_ROW: family}))[0]
        rows.append({"n": n, "variant": FLOOR, **{k: floor[k] for k in ACCURACY_KEYS}})
        print(f"N={n} {FLOOR}: MAE {floor['mae_c']:.3f} °C, bias-free "
              f"{floor['bias_free_mae_c']:.3f}", flush=True)
        for v in variants:
            model = models[(v, n)].cpu().eval()
            with tempfile.TemporaryDirectory() as tmp:
                path = (out_dir or Path(tmp)) / f"fig7_{v}_n{n}.pt"
                save_model(path, model, norm, cfg, {"fig7": True, "steps": steps})
                model, norm_, _ = load_model(path)  # as `thermocal estimate` would run it
            model = model.to(device)
            s = summarise(run_methods(bursts, model, norm_, baselines=False))[0]
            rows.append(
                {
                    "n": n,
                    "variant": v,
                    **{k: s[k] for k in ACCURACY_KEYS},
                    "seed": args.seed,
                    "steps": steps,
                    "minutes": round(wall / 60, 2),
                    "batch": args.batch,
                    "train_loss_last100": float(np.mean(losses[(v, n)][-100:])),
                }
            )
            print(
                f"N={n} {v}: MAE {s['mae_c']:.3f} °C, bias-free {s['bias_free_mae_c']:.3f} "
                f"(smooth {s['smooth_mae_c']:.3f}, fine {s['fine_mae_c']:.3f}), "
                f"within 0.5 °C {100 * s['within_0_5']:.0f} %",
                flush=True,
            )
    return rows


#: The rows of the eq. 9 mean through the exact model of the average training unit.
FLOOR = "family-floor"
#: What each row keeps of ``benchmarks/kpn.py``'s summary (the smooth and fine parts of the
#: bias-free error tell what more frames can reveal, the pixel FPN, from what they cannot).
ACCURACY_KEYS = ("mae_c", "mean_abs_bias_c", "bias_free_mae_c", "smooth_mae_c", "fine_mae_c",
                 "affine_free_mae_c", "within_0_5")


def to_figure_json(rows: list[dict], note: str) -> dict:
    """The ``fig7.json`` layout the demo reads: ``{"n": [...], "mae_c": {variant: [...]}}``;
    the family model's floor, where measured, under ``"floor"``. Rows of several training seeds
    of the same (variant, N) are averaged; their standard deviation over seeds (ddof 1) is under
    ``"mae_sd_c"`` and ``"bias_free_mae_sd_c"``, their count under ``"seeds"``."""
    ns = sorted({r["n"] for r in rows})
    order = ["kpn", "kpn-no-offset", "e2e"]
    variants = sorted({r["variant"] for r in rows} & set(order), key=order.index)
    groups: dict[tuple[str, int], list[dict]] = {}
    seen = set()
    for r in rows:
        key = (r["variant"], r["n"])
        if r["variant"] == FLOOR:  # the same in every run: kept once, and checked
            if key in groups and not np.isclose(groups[key][0]["mae_c"], r["mae_c"]):
                raise SystemExit(f"the family model's rows at N={r['n']} differ between the "
                                 "files: runs on different evaluation sets (--quick?)")
            groups.setdefault(key, [r])
            continue
        run = (*key, r.get("seed", 42))  # rows from before --seed: 42
        if run in seen:
            raise SystemExit(f"{r['variant']} N={r['n']} seed {run[2]} is given twice: merge "
                             "each run once (not a merged file with its parts)")
        seen.add(run)
        groups.setdefault(key, []).append(r)
    missing = [f"{v} N={n}" for v in variants for n in ns if (v, n) not in groups]
    if missing:
        raise SystemExit(f"no result for {', '.join(missing)}: merge files covering every pair")

    def mean(key: str) -> dict[str, list[float]]:
        return {v: [float(np.mean([r[key] for r in groups[(v, n)]])) for n in ns]
                for v in variants}

    def sd(key: str) -> dict[str, list[float | None]]:
        return {v: [float(np.std([r[key] for r in groups[(v, n)]], ddof=1))
                    if len(groups[(v, n)]) > 1 else None for n in ns] for v in variants}

    several = any(len(groups[(v, n)]) > 1 for v in variants for n in ns)
    return {
        "n": ns,
        "mae_c": mean("mae_c"),
        "bias_free_mae_c": mean("bias_free_mae_c"),
        "within_0_5": mean("within_0_5"),
        **({"mae_sd_c": sd("mae_c"), "bias_free_mae_sd_c": sd("bias_free_mae_c"),
            "seeds": {v: [len(groups[(v, n)]) for n in ns] for v in variants}}
           if several else {}),
        **({"floor": {k: [groups[(FLOOR, n)][0][k] if (FLOOR, n) in groups else None
                          for n in ns]
                      for k in ("mae_c", "bias_free_mae_c")}}
           if any(r["variant"] == FLOOR for r in rows) else {}),
        "rows": rows,
        "note": note,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=5.0)
    ap.add_argument("--steps", type=int, default=None,
                    help="stop after this many steps if the --minutes run out later")
    ap.add_argument("--ns", default="1,3,5,7,9,11")
    ap.add_argument("--variants", default="kpn,kpn-no-offset,e2e")
    ap.add_argument("--device", default="auto")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--eval-threads", type=int, default=2)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--crop", type=int, default=64)
    ap.add_argument("--seed", type=int, default=42,
                    help="seed of the initialisation and the burst stream (the scene pool and "
                    "the normalisation keep 42); merge runs of several seeds for error bars")
    ap.add_argument("--quick", action="store_true", help="the small evaluation set")
    ap.add_argument("--sensor-motion", action="store_true",
                    help="thermocal train --sensor-motion: frames displaced as on the whole sensor")
    ap.add_argument("--radial-frames", action="store_true",
                    help="thermocal train --radial-frames: each frame's sensor position")
    ap.add_argument("--no-calibrated", action="store_true",
                    help="thermocal train --no-calibrated: raw counts in (the models before "
                    "2026-11-23)")
    ap.add_argument("--out-dir", default=None, help="keep the trained models here")
    ap.add_argument("--json", type=Path, required=True)
    ap.add_argument(
        "--merge",
        nargs="+",
        type=Path,
        default=None,
        help="join the rows of these result files instead of training",
    )
    args = ap.parse_args()
    if args.merge:
        runs = [json.loads(p.read_text()) for p in args.merge]
        rows = [r for run in runs for r in run["rows"]]
        steps = sorted({r["steps"] for r in rows if "steps" in r}) or [0]
        span = str(steps[0]) if len(steps) == 1 else f"{steps[0]}–{steps[-1]}"
        notes = {re.sub(r", seed \d+", "", re.sub(r"\d+ steps each", f"{span} steps each",
                                                  run["note"])) for run in runs}
        seeds = sorted({r["seed"] for r in rows if "seed" in r})
        note = " / ".join(sorted(notes)) + (f"; seeds {', '.join(map(str, seeds))}"
                                            if len(seeds) > 1 else "")
        args.json.write_text(json.dumps(to_figure_json(rows, note), indent=2))
        return
    base, _, _ = load_model(shipped_model_path("kpn"))
    rows = train_sweep(args, replace(base.config, radial_frames=args.radial_frames,
                                     calibrated=not args.no_calibrated))
    dev = torch.cuda.get_device_name() if resolve_device(args.device).type == "cuda" else "CPU"
    note = (
        f"the models trained side by side for {rows[-1]['minutes']:g} min, "
        f"{rows[-1]['steps']} steps each, on shared bursts (batch {args.batch}, "
        f"crop {args.crop}, lr {args.lr:g}, seed {args.seed}"
        f"{', raw counts in' if args.no_calibrated else ''}) "
        f"on {dev} ({os.cpu_count()} cores, "
        f"{platform.machine()}); evaluated on the held-out set of benchmarks/kpn.py"
        f"{' (quick)' if args.quick else ''}: MAE °C on pixels seen by >= half the frames"
    )
    args.json.write_text(json.dumps(to_figure_json(rows, note), indent=2))


if __name__ == "__main__":
    main()
