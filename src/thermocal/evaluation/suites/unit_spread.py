"""How far the camera units of a preset differ from their family: the calibration-free floor.

A calibration-free method (the KPN, or any model of the camera *family*) never sees the unit it
is run on. Whatever the unit's mean response differs from the family's shifts the whole frame,
and no burst of the scene alone can reveal it: a warmer scene seen by a colder-responding unit
gives the same counts. This script measures that shift, frame-mean counts of a uniform scene
through each unit (no noise) minus the same through the average of the training units (the
family model of ``benchmarks/kpn.py``), divided by the family's responsivity, in °C:

1. for each held-out unit of the KPN benchmark (100-104), at several FPA and scene temperatures;
2. over many other units of the preset (a population): its spread, and the least mean absolute
   shift that any single calibration-free estimate could leave (the mean absolute deviation from
   the population's median: min over c of mean ``|shift − c|``).

A burst's MAE is at least the absolute value of its mean error, so the second figure bounds
what a calibration-free method can reach on average over units, if the burst tells it nothing
about the unit's shift (true of the unit scalars, gain, offset and FPA coefficients, which move
every pixel alike, unless the scene's temperatures are known; the radial strengths leave a
pattern a burst could show) — in expectation over units, not for each unit. The pixel-level
errors of FPN, noise and the radial pattern come on top. ::

    .venv/bin/python benchmarks/unit_spread.py [--units 100-299] [--quick] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from dataclasses import replace
from pathlib import Path

import numpy as np

from thermocal._validate import parse_units
from thermocal.camera.model import expected_counts
from thermocal.camera.presets import PRESETS, CameraPreset, make_camera
from thermocal.evaluation.references import ExactModel
from thermocal.nn.data import EVAL_UNITS, TRAIN_UNITS
from thermocal.progress import progress_bar

SIZE = (336, 256)
FPAS_C = (15.0, 30.0, 45.0)
SCENES_C = (-20.0, 5.0, 30.0)
HOUSING_OFFSET_C = -1.5  # the camera settled: housing = FPA − 1.5 °C, as benchmarks/kpn.py
#: The preset with every unit's radial strengths nominal (1) and its optical centre in the middle;
#: the generator draws the same numbers (``uniform(a, a)`` consumes its draws), so each unit
#: keeps its gain, offset and FPA coefficients.
SCALARS_ONLY = replace(PRESETS["tau2"], radial_strength_range=(1.0, 1.0), centre_jitter=0.0)


def frame_mean(cam, scene_c: float, fpa_c: float) -> float:
    """Mean expected counts of a uniform scene, without ``cam``'s defects."""
    counts = expected_counts(cam, np.full((1, SIZE[1], SIZE[0]), scene_c, np.float32), fpa_c,
                             housing_c=fpa_c + HOUSING_OFFSET_C)[0]
    return float(counts[~cam.defects].mean())


def shifts_c(units, family, preset: CameraPreset = PRESETS["tau2"]) -> np.ndarray:
    """``(len(units), len(FPAS_C), len(SCENES_C))`` frame-mean shift from the family, °C, of
    units drawn from ``preset``."""
    fam = np.array([[frame_mean(family, t, f) for t in SCENES_C] for f in FPAS_C])
    resp = np.array([[frame_mean(family, t + 0.5, f) - frame_mean(family, t - 0.5, f)
                      for t in SCENES_C] for f in FPAS_C])
    out = np.empty((len(units), len(FPAS_C), len(SCENES_C)))
    with progress_bar() as bar:
        for i, u in enumerate(bar.track(units, description="camera units")):
            cam = make_camera(preset, unit=u, size=SIZE)
            counts = np.array([[frame_mean(cam, t, f) for t in SCENES_C] for f in FPAS_C])
            out[i] = (counts - fam) / resp
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", default="100-299", help="the population of units, A-B")
    ap.add_argument("--quick", action="store_true", help="a population of 40 units (100-139)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    if args.quick:
        args.units = "100-139"
    family = ExactModel.family(TRAIN_UNITS).model  # benchmarks/kpn.py's family model
    population = [u for u in parse_units(args.units) if u not in TRAIN_UNITS]
    held = shifts_c(EVAL_UNITS, family)
    pop = shifts_c(population, family)
    floor = np.mean(np.abs(pop - np.median(pop, axis=0)), axis=0)
    # The same units with nominal radial strengths and optical centre (the same draws of
    # everything else): what is left are the unit-level scalars (gain, offset, the FPA
    # coefficients), which change every pixel alike and are invisible in any burst; the radial
    # strengths leave a pattern that a burst could show.
    scalar = shifts_c(population, family, SCALARS_ONLY)
    scalar_floor = np.mean(np.abs(scalar - np.median(scalar, axis=0)), axis=0)

    print("## Camera units against their family (`benchmarks/unit_spread.py`)\n")
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPU cores; preset tau2 {SIZE[0]}x"
          f"{SIZE[1]}; family = mean model of training units {TRAIN_UNITS[0]}-{TRAIN_UNITS[-1]};"
          f" uniform scenes, no noise, housing = FPA {HOUSING_OFFSET_C:+.1f} °C; population: "
          f"{len(population)} units {population[0]}-{population[-1]}\n")
    print("Frame-mean shift of each held-out unit from the family, °C:\n")
    print("| FPA °C | scene °C | " + " | ".join(f"unit {u}" for u in EVAL_UNITS)
          + " | mean abs | population SD | population floor | of it, unit scalars alone |")
    print("|---" * (len(EVAL_UNITS) + 6) + "|")
    for i, f in enumerate(FPAS_C):
        for j, t in enumerate(SCENES_C):
            print(f"| {f:.0f} | {t:+.0f} | " + " | ".join(f"{v:+.2f}" for v in held[:, i, j])
                  + f" | {np.mean(np.abs(held[:, i, j])):.2f} | {np.std(pop[:, i, j]):.2f} | "
                  f"{floor[i, j]:.2f} | {scalar_floor[i, j]:.2f} |")
    print(f"\n(population floor: the least mean absolute frame-mean error a calibration-free "
          f"estimate can leave over the population's units, min over c of mean |shift − c|; "
          f"over the whole grid {floor.min():.2f}-{floor.max():.2f} °C, mean {floor.mean():.2f};"
          f" from the unit scalars alone (gain, offset, FPA coefficients; radial strengths and "
          f"centre nominal) {scalar_floor.min():.2f}-{scalar_floor.max():.2f} °C, "
          f"mean {scalar_floor.mean():.2f}; the five held-out units' mean absolute shift "
          f"{np.abs(held).mean(axis=0).min():.2f}-{np.abs(held).mean(axis=0).max():.2f} °C)")
    if args.json:
        args.json.write_text(json.dumps({
            "fpa_c": FPAS_C, "scene_c": SCENES_C, "eval_units": EVAL_UNITS,
            "eval_shift_c": held.tolist(), "population": population,
            "population_sd_c": np.std(pop, axis=0).tolist(), "population_floor_c": floor.tolist(),
            "scalar_floor_c": scalar_floor.tolist(),
        }, indent=1))


if __name__ == "__main__":
    main()
