"""NUC benchmark: every method of thermocal.nuc on simulated flights over real scenes.

Per method: roughness (Wolf et al. 2016 eq. 13) of the corrected frames, cosine similarity with
the true scene (eq. 14; here of the zero-mean images, which is stricter than with the DC level
left in), RMSE in °C against the truth after the best affine fit (these methods are not
radiometric: their output is counts-like, only its structure can be compared), frames to
converge (first frame after which the roughness stays within 10 % of its final level, measured
from the raw level), ghosting (°C: how much a +25 °C object that crossed the view in the first
half still changes the output along its trail in the last 10 frames, against the same run
without the object, same noise), and speed at 640×512.
The registration-based methods (hardie2000, zuo2011) get the true homographies here, so that
their NUC is measured apart from registration; ``zuo2011 (phase)`` registers by itself.
``deepir`` fits one short burst (about two minutes for 11 frames of 160×128 on 2 cores), not a
walk of hundreds of frames: it is scored by ``benchmarks/fig9.py`` (Oz et al. Fig. 9).

    .venv/bin/python benchmarks/nuc.py [--quick] [--json OUT.json] [--out FIG.png]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np

from thermocal.calibration.base import ThermocalWarning
from thermocal.camera.model import render
from thermocal.camera.presets import make_camera
from thermocal.metrics import best_affine_fit, cosine_similarity, rmse, roughness
from thermocal.nuc import NUC_METHODS, correct_nonuniformity
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.scenes.real import list_shared_scenes, load_scene
from thermocal.simulate.flight import simulate_flight

SIZE = (160, 128)
SCENE_BASED = ("harris1999", "scribner", "ecr", "torres-kalman", "hardie2000", "zuo2011")
#: Methods of a short burst only, scored elsewhere (the module docstring).
BURST_ONLY = ("deepir",)
VARIANTS = ([(m, m) for m in NUC_METHODS if m not in BURST_ONLY]
            + [("zuo2011 (phase)", "zuo2011")])


def _run(variant: str, method: str, frames: np.ndarray, hs: np.ndarray) -> np.ndarray:
    """``method`` on the frames; its warnings about short stacks dropped (what they warn of is
    what this benchmark measures: how many frames each method needs)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ThermocalWarning)
        return _run_method(variant, method, frames, hs)


def _run_method(variant: str, method: str, frames: np.ndarray, hs: np.ndarray) -> np.ndarray:
    opts = {}
    if method in ("hardie2000", "zuo2011") and "phase" not in variant:
        opts["homographies"] = hs
    return correct_nonuniformity(frames, method=method, **opts)


def _zero_mean_cos(a: np.ndarray, b: np.ndarray) -> float:
    return cosine_similarity(a - a.mean(), b - b.mean())


def per_frame_curves(out: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rough = np.asarray(roughness(out))
    cos = np.array([_zero_mean_cos(out[k], truth[k]) for k in range(len(out))])
    return rough, cos


def frames_to_converge(rough: np.ndarray, raw_rough: np.ndarray) -> int:
    final = float(np.mean(rough[-20:]))
    start = float(np.mean(raw_rough))
    band = 0.1 * abs(start - final)
    outside = np.flatnonzero(np.abs(rough - final) > band)
    return int(outside[-1] + 1) if outside.size else 0


def ghosting_flight(cam, scene, n: int, seed: int):
    """A hover over ``scene`` with a hot disc crossing the view in the first half."""
    fl = simulate_flight(scene, cam, n_frames=n, motion="hover", seed=seed)
    h, w = cam.shape
    yy, xx = np.mgrid[0:h, 0:w]
    truth = fl.truth_c.copy()
    trail = np.zeros((h, w), bool)
    cross = n // 2
    for k in range(cross):
        cx = -8 + (w + 16) * k / max(cross - 1, 1)
        disc = (xx - cx) ** 2 + (yy - h / 2) ** 2 <= 7**2
        truth[k][disc] += 25.0
        trail |= disc
    frames = render(cam, truth, fl.fpa_true_c, housing_c=fl.housing_c,
                    rng=np.random.default_rng(seed + 99))
    clean = render(cam, fl.truth_c, fl.fpa_true_c, housing_c=fl.housing_c,
                   rng=np.random.default_rng(seed + 99))  # same noise, no object
    return frames, clean, fl.truth_c, fl.homographies, trail


def ghost_measure(out: np.ndarray, clean_out: np.ndarray, truth: np.ndarray,
                  trail: np.ndarray) -> float:
    """Mean absolute difference (°C, after each output's affine fit) along the object's trail
    over the last 10 frames, between the run that saw the object and the run that did not."""
    vals = []
    for k in range(len(out) - 10, len(out)):
        a = best_affine_fit(out[k], truth[k])
        b = best_affine_fit(clean_out[k], truth[k])
        vals.append(float(np.abs(a - b)[trail].mean()))
    return float(np.mean(vals))


def speed(method: str, variant: str, frames: np.ndarray, hs: np.ndarray) -> float:
    # warm-up (imports, caches) on enough frames for every method (torres-kalman: a block)
    _run(variant, method, frames[:12], hs[:12])
    t0 = time.perf_counter()
    _run(variant, method, frames, hs)
    return len(frames) / (time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", default=None)
    ap.add_argument("--out", default=None, help="figure path (PNG; default: no figure)")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    n = 120 if args.quick else 300
    shared = list_shared_scenes()
    names = list(shared)[: 2 if args.quick else 6]
    scene_maps = {nm: load_scene(shared[nm]) for nm in names}
    scene_maps["builtin:aerial"] = load_builtin_scene("aerial")
    unit = 5
    cam = make_camera("tau2", unit=unit, size=SIZE)

    results: dict[str, dict[str, list]] = {v: {} for v, _ in VARIANTS}
    results["raw"] = {}
    curves = {}
    for si, scene in enumerate(scene_maps.values()):
        fl = simulate_flight(scene, cam, n_frames=n, motion="walk", seed=40 + si)
        truth = fl.truth_c
        last = slice(n - 20, n)
        raw = fl.frames.astype(np.float32)
        raw_rough, raw_cos = per_frame_curves(raw, truth)
        outs = {"raw": raw}
        for variant, method in VARIANTS:
            outs[variant] = _run(variant, method, fl.frames, fl.homographies)
        for variant, out in outs.items():
            rough, cos = per_frame_curves(out, truth)
            err = np.mean([rmse(best_affine_fit(out[k], truth[k]), truth[k])
                           for k in range(n - 20, n)])
            r = results[variant]
            r.setdefault("roughness", []).append(float(rough[last].mean()))
            r.setdefault("cosine", []).append(float(cos[last].mean()))
            r.setdefault("rmse_c", []).append(float(err))
            r.setdefault("converge", []).append(frames_to_converge(rough, raw_rough))
            r.setdefault("below_raw", []).append(bool(rough[last].mean() < raw_rough[last].mean()))
            if si == 0:
                curves[variant] = (rough, cos)

    # ghosting with a moving hot object
    gscene = scene_maps["builtin:aerial"]
    gframes, gclean, gtruth, ghs, trail = ghosting_flight(cam, gscene, n, seed=7)
    for variant, method in VARIANTS:
        results[variant]["ghost_c"] = ghost_measure(
            _run(variant, method, gframes, ghs), _run(variant, method, gclean, ghs), gtruth, trail)
    results["raw"]["ghost_c"] = ghost_measure(
        gframes.astype(np.float32), gclean.astype(np.float32), gtruth, trail)

    # speed at 640x512
    big = make_camera("tau2", unit=unit, size=(640, 512))
    n_speed = 20 if args.quick else 60
    sfl = simulate_flight(scene_maps["builtin:aerial"], big, n_frames=n_speed, motion="walk",
                          seed=3)
    for variant, method in VARIANTS:
        results[variant]["fps"] = speed(method, variant, sfl.frames, sfl.homographies)

    print(f"## NUC benchmark{' (quick)' if args.quick else ''}\n")
    print(f"- machine: {platform.node()} {platform.machine()}, {os.cpu_count()} CPUs, "
          f"Python {platform.python_version()}")
    print(f"- data: simulated walks of {n} frames at {SIZE[0]}x{SIZE[1]}, tau2 unit {unit}, FPA "
          f"30 °C, over {len(scene_maps)} real scenes ({', '.join(scene_maps)}); metrics on the "
          "last 20 frames, averaged over scenes; ghosting on a hover over the aerial scene with "
          f"a +25 °C disc crossing the view in the first {n // 2} frames; speed on "
          f"{n_speed} frames at 640x512")
    print("- ghosting: mean |output with object − output without| (each affinely mapped onto the "
          "truth) along the object's trail, last 10 frames, °C")
    print("- outputs are NOT radiometric: RMSE is after the best affine map onto the truth; "
          "cosine similarity is of zero-mean images\n")
    print("| method | roughness | below raw (scenes) | cosine sim. | RMSE after affine °C | "
          "frames to converge | ghosting °C | frames/s 640x512 |")
    print("|---|---|---|---|---|---|---|---|")
    for variant in ["raw"] + [v for v, _ in VARIANTS]:
        r = results[variant]
        fps = f"{r['fps']:.0f}" if "fps" in r else "-"
        below = f"{sum(r['below_raw'])}/{len(r['below_raw'])}" if variant != "raw" else "-"
        conv = {"raw": "-", "hardie2000": "batch", "admire": "1 (single frame)"}.get(
            variant, f"{np.median(r['converge']):.0f}")
        print(f"| {variant} | {np.mean(r['roughness']):.4f} | {below} | "
              f"{np.mean(r['cosine']):.3f} | {np.mean(r['rmse_c']):.3f} | {conv} | "
              f"{r['ghost_c']:.3f} | {fps} |")
    fails = [v for v, m in VARIANTS if m in SCENE_BASED and not all(results[v]["below_raw"])]
    print(f"\nScene-based methods whose roughness is not below raw on every scene: "
          f"{', '.join(fails) if fails else 'none'}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for variant, (rough, cos) in curves.items():
        style = "k--" if variant == "raw" else "-"
        ax[0].plot(rough, style, label=variant, lw=1)
        ax[1].plot(cos, style, label=variant, lw=1)
    ax[0].set(xlabel="frame", ylabel="roughness ρ", title="(a) roughness", yscale="log")
    ax[1].set(xlabel="frame", ylabel="cosine similarity (zero-mean)", title="(b) cosine similarity")
    ax[1].legend(fontsize=7)
    fig.suptitle(f"NUC on a simulated walk over {next(iter(scene_maps))} (cf. Wolf et al. Fig. 7)")
    fig.tight_layout()
    if args.out:
        fig_path = Path(args.out)
        fig_path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(fig_path, dpi=120)
        print(f"\nfigure: {fig_path}")
    print(f"\n(total {time.perf_counter() - t_start:.0f} s)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
