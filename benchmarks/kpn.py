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

    .venv/bin/python benchmarks/kpn.py [--quick] [--json OUT.json] [--model MODEL.pt]
                                       [--register] [--accuracy-only] [--device cuda]
                                       [--units 3,8,12,17,21] [--chamber UNIT_A.h5]
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from thermocal.burst import fill_stuck_pixels
from thermocal.calibration.two_point import fit_two_point
from thermocal.camera.model import render
from thermocal.camera.presets import make_camera
from thermocal.estimation.calibrated import naive_mean
from thermocal.metrics import best_affine_fit, fraction_within, mae
from thermocal.nn.data import (
    EVAL_UNITS,
    TRAIN_UNITS,
    BurstConfig,
    ScenePool,
    coverage_mask,
    evaluation_scenes,
)
from thermocal.nn.infer import calibrated_warp, estimate_burst, run_network, shipped_model_path
from thermocal.nn.inputs import calibrate_frames, nominal_camera, sensor_r2
from thermocal.nn.model import ModelConfig, count_macs, count_parameters
from thermocal.nn.store import load_model
from thermocal.nn.train import TrainConfig, resolve_device, train
from thermocal.radiometry import BandRadiance
from thermocal.scenes.trajectory import perturb_homographies
from thermocal.simulate.flight import simulate_flight

NOMINAL_FPA_C = 30.0
OTHER_UNIT = 7  # the unit whose two-point calibration the calibration-free baselines borrow


def eval_bursts(n_frames: int, *, quick: bool, register: bool = False,
                units: tuple[int, ...] = EVAL_UNITS, preset="tau2"):
    """The fixed evaluation bursts: list of dicts (frames, truth, valid mask, fpa, unit, …);
    ``units`` replaces the held-out camera units and ``preset`` (a name or a
    :class:`~thermocal.camera.presets.CameraPreset`) the camera family (diagnoses only)."""
    scenes = evaluation_scenes()
    per_scene = 1 if quick else 4
    size = (336, 256)  # whole sensor frames: a network with position terms needs them
    out = []
    for si, (name, scene) in enumerate(scenes.items()):
        for k in range(per_scene):
            seed = 1000 * si + k
            rng = np.random.default_rng([2026, seed])
            unit = units[(si + k) % len(units)]
            cam = make_camera(preset, unit=unit, size=size)
            fpa = float(rng.uniform(15.0, 45.0))
            motion = ("walk", "hover")[(si + k) % 2]
            fl = simulate_flight(scene, cam, n_frames=n_frames, motion=motion, fpa_c=fpa, seed=seed)
            hs = perturb_homographies(fl.homographies, rng=rng, frame_size=size, pivot=fl.pivot)
            if register:
                from thermocal.registration import register_burst

                hs = register_burst(fl.frames, pivot=fl.pivot).homographies
            from thermocal.registration.warp import warp_to_pivot

            _, valid = warp_to_pivot(fl.frames, hs)
            out.append(
                {
                    "scene": name,
                    "unit": unit,
                    "fpa_c": fpa,
                    "motion": motion,
                    "camera": cam,
                    "frames": fl.frames,
                    "fpa_read": fl.fpa_c,
                    "truth": fl.truth_c[fl.pivot],
                    "hs": hs,
                    "pivot": fl.pivot,
                    "mask": coverage_mask(valid),
                    "fpa_true": fl.fpa_true_c,
                    "housing": fl.housing_c,
                }
            )
    return out


def two_point_of(cam, fpa_c: float, housing_c: float, seed: int):
    rng = np.random.default_rng(seed)
    lo = render(cam, np.full(16, 10.0), fpa_c, housing_c=housing_c, rng=rng)
    hi = render(cam, np.full(16, 50.0), fpa_c, housing_c=housing_c, rng=rng)
    return fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=fpa_c)


class ExactModel:
    """A camera model inverted exactly, for the eq. 9 mean (``naive_mean``) through it.

    :meth:`family` is the average of the training units' models: a perfect calibration-free
    calibration of the camera *family*; on a held-out unit its error is the floor of any
    calibration-free method (what the unit differs from the family: offset, gain, radial
    strengths, averaged over the burst by eq. 9). With a model fitted on unit A's chamber file
    (``--chamber``) it is the floor of a network trained from that file.
    """

    def __init__(self, model) -> None:
        self.model = model

    @classmethod
    def family(cls, units) -> ExactModel:
        return cls(nominal_camera([make_camera("tau2", unit=u, size=(336, 256)) for u in units]))

    @property
    def shape(self):
        return self.model.shape

    def apply(self, frames, *, fpa_c=None):
        return calibrate_frames(self.model, frames, fpa_c)  # the camera settled, as in training


FAMILY_ROW = "(floor) exact model of the average training unit (eq. 9 mean)"
CHAMBER_ROW = "(floor) unit A's chamber model, exact (eq. 9 mean)"


@functools.lru_cache(maxsize=2)
def radial_bins(shape: tuple[int, int], n: int = 5) -> np.ndarray:
    """Each pixel's quintile (``n``-tile) of distance from the sensor's centre, ``(H, W)`` int."""
    r2 = sensor_r2(shape)
    return np.searchsorted(np.quantile(r2, np.linspace(0, 1, n + 1)[1:-1]), r2)


#: Gaussian σ, px, that splits the bias-free error into a smooth and a fine part.
SPLIT_SIGMA_PX = 6.0
#: The classical pipeline given the camera model the network was trained from (not
#: calibration-free, as the family row): the eq. 9 mean through that model, low-passed by a
#: Gaussian of SPLIT_SIGMA_PX, plus the scene-based NUC baseline's high-pass (:func:`fuse`).
HYBRID_ROW = ("(classical, the network's camera model) the exact average training unit's eq. 9 "
              f"mean, low-pass σ = {SPLIT_SIGMA_PX:.0f} px, + hardie2000 NUC's high-pass")
HYBRID_CHAMBER_ROW = ("(classical, the network's camera model) unit A's chamber model's eq. 9 "
                      f"mean, low-pass σ = {SPLIT_SIGMA_PX:.0f} px, + hardie2000 NUC's high-pass")


def masked_smooth(x: np.ndarray, mask: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian of ``sigma`` px of ``x (H, W)`` over the pixels of ``mask (H, W) bool`` only
    (normalised by the mask's own Gaussian), ``(H, W)`` float."""
    from scipy.ndimage import gaussian_filter

    return gaussian_filter(np.where(mask, x, 0.0), sigma) / np.maximum(
        gaussian_filter(mask.astype(float), sigma), 1e-9)


def split_error(err: np.ndarray, mask: np.ndarray,
                sigma: float = SPLIT_SIGMA_PX) -> tuple[float, float]:
    """``(smooth, fine)`` MAE, °C, of the error ``err (H, W)`` °C less its mean over ``mask
    (H, W) bool``: the smooth part is a Gaussian of ``sigma`` px of it, normalised over the mask
    (radial patterns, the scene's low frequencies; not zero-mean in general), the fine part the
    rest (pixel FPN left, noise, blurred detail). MAEs do not add up to the bias-free MAE."""
    e = np.where(mask, err - err[mask].mean(), 0.0)
    smooth = masked_smooth(e, mask, sigma)
    return float(np.mean(np.abs(smooth[mask]))), float(np.mean(np.abs((e - smooth)[mask])))


def scores(est: np.ndarray, b: dict) -> dict:
    m = b["mask"]
    err = est - b["truth"]
    bias = float(err[m].mean())
    fit = best_affine_fit(est, b["truth"], m)
    bins = radial_bins(est.shape)
    smooth, fine = split_error(err, m)
    return {
        "mae": mae(est, b["truth"], valid=m),
        "bias_free": float(np.mean(np.abs(err[m] - bias))),
        "smooth": smooth,
        "fine": fine,
        "affine_free": mae(fit, b["truth"], valid=m),
        "within_0_5": fraction_within(est, b["truth"], 0.5, valid=m),
        "bias": bias,
        "bias_by_radius": [
            float(err[sel].mean()) if sel.any() else float("nan")
            for sel in (m & (bins == k) for k in range(5))
        ],
    }


def network_estimate(b: dict, frames: np.ndarray, model, norm, homographies=None):
    """The network's :class:`~thermocal.nn.infer.Estimate` for the evaluation burst ``b`` from
    ``frames`` (its frames with their stuck pixels replaced, or a diagnosis' substitute) and
    ``homographies`` (default: the burst's)."""
    return estimate_burst(frames, b["fpa_read"], model=model, norm=norm,
                          homographies=b["hs"] if homographies is None else homographies,
                          pivot=b["pivot"], fill_defects=False)


def other_unit_calibration():
    """The two-point calibration of :data:`OTHER_UNIT` at :data:`NOMINAL_FPA_C` that the
    calibration-free baselines borrow (a whole 336×256 sensor, as every burst)."""
    other = make_camera("tau2", unit=OTHER_UNIT, size=(336, 256))
    return two_point_of(other, NOMINAL_FPA_C, NOMINAL_FPA_C - 1.5, 5)


def fuse(low: np.ndarray, high: np.ndarray, mask: np.ndarray,
         sigma: float = SPLIT_SIGMA_PX) -> np.ndarray:
    """``low``'s Gaussian low-pass (σ = ``sigma`` px, over ``mask``) plus ``high``'s remainder:
    two ``(H, W)`` estimates, °C, joined across spatial frequencies."""
    return masked_smooth(low, mask, sigma) + high - masked_smooth(high, mask, sigma)


def nuc_global_fit(frames: np.ndarray, homographies: np.ndarray, pivot: int, cal) -> np.ndarray:
    """The scene-based NUC baseline: hardie2000 on the registered burst ``frames (N, H, W)``
    counts, its pivot frame turned into °C by a global fit (``cal``'s array-mean gain and
    offset, a two-point calibration), ``(H, W)``."""
    from thermocal.nuc import correct_nonuniformity

    nuc = correct_nonuniformity(frames, method="hardie2000", homographies=homographies)[pivot]
    g, o = float(cal.gain.mean()), float(cal.offset.mean())
    band = BandRadiance()
    lo, hi = band.radiance_range
    return band.temperature(np.clip((nuc - o) / g, lo, hi)) - 273.15


KPN_ROW = "KPN + offset"
#: Row names of the network variants.
VARIANT_ROWS = {"kpn": KPN_ROW, "kpn-no-offset": "KPN (no offset block)", "e2e": "E2E"}


def run_methods(bursts, model, norm, *, baselines: bool = True, label: str = KPN_ROW,
                references: dict[str, ExactModel] | None = None) -> dict[str, list[dict]]:
    """Every method on every burst: name → list of per-burst scores (the network's under
    ``label``; an eq. 9 mean through each of ``references``, and with ``baselines`` through the
    family model, the calibration-free baselines, the classical pipeline given the model the
    network was trained from: :data:`HYBRID_ROW`, or :data:`HYBRID_CHAMBER_ROW` where
    ``references`` hold :data:`CHAMBER_ROW`, and the own two-point reference). Every method
    gets the burst with its stuck pixels replaced."""
    res: dict[str, list[dict]] = {}
    if baselines:
        other_cal = other_unit_calibration()
        references = {FAMILY_ROW: ExactModel.family(TRAIN_UNITS)} | (references or {})
    for b in bursts:
        cam = b["camera"]
        # the burst's stuck pixels replaced once, for every method (as the estimation pipeline does)
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        if model is not None:
            e = network_estimate(b, frames, model, norm)
            res.setdefault(label, []).append(scores(e.temperature_c, b))
        piv = b["pivot"]
        through = {}  # each reference's eq. 9 mean, °C
        for name, ref in (references or {}).items():
            through[name] = naive_mean(
                frames, ref, fpa_c=b["fpa_read"], homographies=b["hs"], pivot=piv,
                fill_defects=False,
            ).temperature_c
            res.setdefault(name, []).append(scores(through[name], b))
        if not baselines:
            continue
        t_piv = other_cal.apply(frames[piv : piv + 1])[0]
        res.setdefault("two-point, other unit, FPA 30 °C (pivot frame)", []).append(
            scores(t_piv, b)
        )
        m9 = naive_mean(frames, other_cal, homographies=b["hs"], pivot=piv,
                        fill_defects=False)
        res.setdefault("two-point, other unit, FPA 30 °C (eq. 9 mean)", []).append(
            scores(m9.temperature_c, b)
        )
        t_nuc = nuc_global_fit(frames, b["hs"], piv, other_cal)
        res.setdefault("hardie2000 NUC + global fit (other unit)", []).append(scores(t_nuc, b))
        # what the network was trained from: unit A's chamber model if given, else the family
        prior, row = ((through[CHAMBER_ROW], HYBRID_CHAMBER_ROW) if CHAMBER_ROW in through
                      else (through[FAMILY_ROW], HYBRID_ROW))
        res.setdefault(row, []).append(scores(fuse(prior, t_nuc, b["mask"]), b))
        own = two_point_of(cam, float(np.mean(b["fpa_true"])), float(np.mean(b["housing"])), 6)
        m9o = naive_mean(frames, own, homographies=b["hs"], pivot=piv, fill_defects=False)
        res.setdefault("(reference) own two-point at the burst FPA (eq. 9 mean)", []).append(
            scores(m9o.temperature_c, b)
        )
    return res


def summarise(res: dict[str, list[dict]]) -> list[dict]:
    rows = []
    for name, lst in res.items():
        maes = [r["mae"] for r in lst]
        rows.append(
            {
                "method": name,
                "mae_c": float(np.mean(maes)),
                "median_mae_c": float(np.median(maes)),
                "bias_free_mae_c": float(np.mean([r["bias_free"] for r in lst])),
                "affine_free_mae_c": float(np.mean([r["affine_free"] for r in lst])),
                "within_0_5": float(np.mean([r["within_0_5"] for r in lst])),
                "mean_abs_bias_c": float(np.mean([abs(r["bias"]) for r in lst])),
                "smooth_mae_c": float(np.mean([r["smooth"] for r in lst])),
                "fine_mae_c": float(np.mean([r["fine"] for r in lst])),
            }
        )
    return rows


def speed(model, norm, *, threads: int = 2) -> dict:
    torch.set_num_threads(threads)
    rng = np.random.default_rng(0)
    n = model.config.n_frames
    warped = rng.uniform(6000, 9000, (n, 256, 336)).astype(np.float32)
    valid = np.ones(warped.shape, dtype=bool)
    r2f = np.repeat(sensor_r2(warped.shape[1:])[None], n, 0) if model.config.radial_frames else None
    still = np.repeat(np.eye(3)[None], n, 0)

    def once() -> None:  # a calibrated model's time includes calibrating and warping the frames
        x = calibrated_warp(model, warped, still, 30.0) if model.config.calibrated else warped
        run_network(model, norm, x, valid, 30.0, r2_frames=r2f)

    once()
    times = []
    for _ in range(5):
        t = time.perf_counter()
        once()
        times.append(time.perf_counter() - t)
    return {
        "network_ms_336x256": 1000 * statistics.median(times),
        "parameters": count_parameters(model),
        "gmacs_336x256": count_macs(model, 256, 336) / 1e9,
        "threads": threads,
        "calibrated": model.config.calibrated,
    }


def training_throughput(model_cfg: ModelConfig, data: dict, *, steps: int = 6) -> float:
    """Samples/s of the shipped configuration (data generation included), a few steps."""
    cfg = BurstConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})
    with tempfile.TemporaryDirectory() as tmp:
        res = train(
            Path(tmp) / "m.pt",
            model_cfg,
            cfg,
            TrainConfig(steps_per_epoch=steps, max_epochs=1, val_bursts=16, workers=1),
            pool_fn=lambda: ScenePool.training(n_procedural=6),
            val_pool_fn=lambda: ScenePool.training(seed=1, n_procedural=3),
            log=lambda s: None,
            progress=False,
        )
    return res.samples_per_s


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


def main() -> None:
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
    args = ap.parse_args()
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
    print(
        "| method | MAE °C | median MAE °C | within 0.5 °C | mean abs bias °C | "
        "bias-free MAE °C | smooth part °C | fine part °C | affine-free MAE °C |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['method']} | {r['mae_c']:.2f} | {r['median_mae_c']:.2f} | "
            f"{100 * r['within_0_5']:.0f} % | {r['mean_abs_bias_c']:.2f} | "
            f"{r['bias_free_mae_c']:.2f} | {r['smooth_mae_c']:.2f} | {r['fine_mae_c']:.2f} | "
            f"{r['affine_free_mae_c']:.2f} |"
        )
    print(
        "\n(bias-free: after removing each burst's mean error; its smooth part: a Gaussian of "
        f"σ = {SPLIT_SIGMA_PX:.0f} px of it (radial patterns, low frequencies), its fine part: "
        "the rest (pixel FPN left, noise, blurred detail), each as an MAE; affine-free: after "
        "the best affine map onto the truth (an oracle): what is left of non-uniformity and "
        "noise once the unit's unknown global offset / gain are set aside)"
    )
    print("\nMAE °C by trajectory:\n")
    print("| method | walk (60-80 % overlap) | hover (±3 px jitter) |\n|---|---|---|")
    for name, lst in res.items():
        by = {m: [s["mae"] for b, s in zip(bursts, lst, strict=True) if b["motion"] == m]
              for m in ("walk", "hover")}
        print(f"| {name} | {np.mean(by['walk']):.2f} | {np.mean(by['hover']):.2f} |")
    print("\nMean error °C by distance from the sensor's centre (fifths of the pixels, centre "
          "to corners), over the bursts:\n")
    print("| method | 1st | 2nd | 3rd | 4th | 5th (corners) |\n|---|---|---|---|---|---|")
    for name, lst in res.items():
        by_r = np.nanmean([s["bias_by_radius"] for s in lst], axis=0)
        print(f"| {name} | " + " | ".join(f"{v:+.2f}" for v in by_r) + " |")
    print("\nKPN per scene (MAE °C / bias-free MAE °C):\n")
    print("| scene | unit | FPA °C | MAE °C | bias °C | bias-free °C | affine-free °C |")
    print("|---|---|---|---|---|---|---|")
    for b, s in zip(bursts, res[label], strict=True):
        print(
            f"| {b['scene']} ({b['motion']}) | {b['unit']} | {b['fpa_c']:.1f} | "
            f"{s['mae']:.2f} | {s['bias']:+.2f} | {s['bias_free']:.2f} | "
            f"{s['affine_free']:.2f} |"
        )

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
