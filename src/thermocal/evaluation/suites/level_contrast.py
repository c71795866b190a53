"""The network's level against the scene's contrast with the FPA: does the σ model's level hold?

The largest part of a calibration-free error is the unit's own level: a burst's mean error,
one draw per unit, which no view of the burst reveals. The network's σ model
(:mod:`thermocal.nn.uncertainty`) states its variance as ``floor² + (k · c)²``, ``c`` the
burst's mean estimate less its FPA temperature (°C). This suite measures the level's RMS by
``c`` (:data:`CONTRAST_BINS_C`) on populations of units, one unit per burst, beside the level
the σ model states there and the share of bursts whose level lies within it (1σ and 2σ):

- ``validation``: the bursts the σ model was fitted on (the units of
  :data:`~thermocal.evaluation.sigma_fit.SIGMA_UNITS` over the training scenes, drawn as
  :mod:`~thermocal.evaluation.sigma_fit` draws them): how well the fit describes its own data;
- ``A-B``: held-out units over the held-out scenes (``benchmarks/coverage.py``'s
  ``--more-units`` sets): whether it holds on units it never saw.

Every burst is scored, refused by the domain check or not, as the σ model is fitted on them.

Run: ``python -m thermocal.evaluation.suites.level_contrast [--quick] [--sets
validation,300-499,2000-2199,3000-3199] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy import stats

from thermocal._validate import parse_units
from thermocal.bench import machine
from thermocal.errors import InvalidInputError
from thermocal.evaluation.heldout import eval_bursts
from thermocal.evaluation.sigma_fit import (
    PER_SCENE,
    SIGMA_UNITS,
    scored_features,
    validation_scenes,
)
from thermocal.evaluation.suites.coverage import SCENE_LESS_FPA_BINS_C
from thermocal.evaluation.tables import markdown_table
from thermocal.nn.infer import NetworkEstimator
from thermocal.nn.uncertainty import level_variance

__all__ = ["CONTRAST_BINS_C", "burst_levels", "level_rows", "main"]

#: The bins of a burst's mean estimate less its FPA temperature, °C (the coverage suite's).
CONTRAST_BINS_C = SCENE_LESS_FPA_BINS_C

#: The sets scored by default: the σ model's own bursts, then three held-out populations.
DEFAULT_SETS = "validation,300-499,2000-2199,3000-3199"

#: Bursts per held-out scene of a population set (the coverage suite's ``--more-units``).
POPULATION_PER_SCENE = 40


def burst_levels(network: NetworkEstimator, bursts: list[dict]) -> dict[str, np.ndarray]:
    """Each burst's ``level`` (mean error over its scored pixels, °C), ``contrast`` (mean
    estimate less the burst's FPA temperature, °C) and ``unit``, ``(B,)`` arrays."""
    scored = scored_features(network, bursts)
    return {"level": np.array([float(np.mean(err)) for err, *_ in scored]),
            "contrast": np.array([float(np.mean(x)) for *_, x in scored]),
            "unit": np.array([int(b["unit"]) for b in bursts])}


def _rms_interval(level: np.ndarray, unit: np.ndarray, *, confidence: float = 0.90,
                  n_resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """A percentile bootstrap interval of the RMS of ``level``, resampling whole units (a
    unit's bursts share its level): scipy's, paired over each unit's sum of squares and count,
    as :func:`~thermocal.metrics.coverage_interval` resamples its groups."""
    _, idx = np.unique(unit, return_inverse=True)
    ss, n = np.bincount(idx, level**2), np.bincount(idx).astype(np.float64)

    def rms(s: np.ndarray, m: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.sqrt(np.sum(s, axis=axis) / np.sum(m, axis=axis))

    ci = stats.bootstrap((ss, n), rms, paired=True, vectorized=True, method="percentile",
                         confidence_level=confidence, n_resamples=n_resamples,
                         rng=np.random.default_rng(seed)).confidence_interval
    return float(ci.low), float(ci.high)


def level_rows(level: np.ndarray, contrast: np.ndarray, unit: np.ndarray, *, floor_c: float,
               contrast_per_c: float | None, bins_c=CONTRAST_BINS_C) -> list[dict]:
    """The level's RMS by contrast bin (and over all bursts, the last row) against the level
    the σ model states, ``sqrt(floor_c² + (contrast_per_c · contrast)²)`` per burst.

    Parameters
    ----------
    level, contrast, unit : (B,) arrays
        Per burst: its mean error (°C), its mean estimate less its FPA temperature (°C), its
        camera unit (the bootstrap resamples whole units).
    floor_c, contrast_per_c
        The σ model's level (°C, and °C per °C; None: no contrast term).

    Returns
    -------
    list of dict
        Per bin with bursts: ``bin`` ``(lo, hi)`` (°C; None for all), ``bursts``, ``units``,
        ``rms_c`` and its 90 % ``interval_c`` over units (None for one unit), ``stated_c``
        (RMS of the stated level σ), ``within_1sigma`` and ``within_2sigma`` (shares of bursts
        whose level lies within ±1 and ±2 stated σ).
    """
    level, contrast, unit = (np.asarray(a, np.float64) for a in (level, contrast, unit))
    if not (level.ndim == 1 and level.shape == contrast.shape == unit.shape and level.size
            and np.all(np.isfinite(level)) and np.all(np.isfinite(contrast))):
        raise InvalidInputError("level_rows: need finite (B,) levels, contrasts and units")
    stated = np.sqrt(level_variance(floor_c, contrast_per_c, contrast))
    z = np.abs(level) / stated
    k = np.searchsorted(np.asarray(bins_c), contrast, side="right") - 1
    cells = [((bins_c[i], bins_c[i + 1]), k == i) for i in range(len(bins_c) - 1)]
    rows = []
    for edges, sel in [*cells, (None, np.ones(level.size, bool))]:
        if not sel.any():
            continue
        units = np.unique(unit[sel])
        rows.append({
            "bin": edges, "bursts": int(sel.sum()), "units": int(units.size),
            "rms_c": float(np.sqrt(np.mean(level[sel] ** 2))),
            "interval_c": (_rms_interval(level[sel], unit[sel]) if units.size > 1 else None),
            "stated_c": float(np.sqrt(np.mean(stated[sel] ** 2))),
            "within_1sigma": float(np.mean(z[sel] <= 1.0)),
            "within_2sigma": float(np.mean(z[sel] <= 2.0))})
    return rows


def _bursts_of(name: str, n_frames: int, *, quick: bool) -> tuple[str, list[dict]]:
    """A set's label and bursts: ``validation``, or a population of units ``A-B``."""
    if name == "validation":
        units = SIGMA_UNITS
        bursts = eval_bursts(n_frames, quick=False, units=units, scenes=validation_scenes(),
                             per_scene=2 if quick else PER_SCENE, unit_per_burst=True)
        return "tau2 units of the σ fit, training scenes (its own bursts)", bursts
    units = parse_units(name)
    bursts = eval_bursts(n_frames, quick=False, units=units,
                         per_scene=2 if quick else POPULATION_PER_SCENE, unit_per_burst=True)
    return f"tau2 units {units[0]}–{units[-1]}, held-out scenes", bursts


def report(sets: list[dict], info: dict) -> str:
    """The Markdown report of :func:`main`'s sets."""
    def where(edges) -> str:
        return "all" if edges is None else f"{edges[0]:g}…{edges[1]:g} °C"

    cells = [(s["label"], where(r["bin"]), r["bursts"],
              f"{r['rms_c']:.2f}" + ("" if r["interval_c"] is None
                                     else " ({:.2f}–{:.2f})".format(*r["interval_c"])),
              f"{r['stated_c']:.2f}", f"{100 * r['within_1sigma']:.1f} %",
              f"{100 * r['within_2sigma']:.1f} %") for s in sets for r in s["rows"]]
    header = ("set", "mean estimate − FPA", "bursts", "level RMS °C", "stated level σ °C",
              "levels within 1σ", "within 2σ")
    floor, k = info["floor_c"], info["contrast_per_c"]
    stated = (f"{floor:.3f} °C" if k is None else
              f"sqrt({floor:.3f}² + ({k:.4f} · c)²) °C")
    return ("## The network's level against the scene's contrast with the FPA\n\n"
            f"machine: {info['machine']}; {info['wall_s']:.0f} s\n\n"
            "data: bursts of N = 7 frames, 336×256, one camera unit each (a population of "
            "units); level: a burst's mean error over its scored pixels (seen by ≥ half the "
            "frames), the part no view reveals; c: the burst's mean estimate less its FPA "
            f"temperature; stated level σ: the shipped σ model's, {stated}, RMS over the bin's "
            "bursts; every burst scored (refused by the domain check or not, as the σ model is "
            "fitted); in brackets a 90 % bootstrap interval over units.\n\n"
            + markdown_table(header, cells) + "\n")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="Two bursts per scene, the validation set and units 300-499.")
    parser.add_argument("--sets", default=DEFAULT_SETS,
                        help="validation and/or populations of units A-B, comma separated "
                        "(default %(default)s).")
    parser.add_argument("--json", default=None, help="Write the results as JSON here.")
    args = parser.parse_args(argv)
    names = ["validation", "300-499"] if args.quick else args.sets.split(",")
    start = time.perf_counter()
    network = NetworkEstimator.from_file("kpn")
    sigma = network.sigma_model
    if sigma is None:
        raise SystemExit("level_contrast: the shipped network has no σ model")
    fitted = set((sigma.fitted_on or {}).get("units", []))
    sets = []
    for name in names:
        label, bursts = _bursts_of(name, network.n_frames, quick=args.quick)
        if name != "validation" and fitted & {int(b["unit"]) for b in bursts}:
            raise SystemExit(f"level_contrast: units {name} include units the σ model was "
                             "fitted on: choose held-out units")
        lv = burst_levels(network, bursts)
        sets.append({"name": name, "label": label,
                     "rows": level_rows(lv["level"], lv["contrast"], lv["unit"],
                                        floor_c=sigma.floor_c,
                                        contrast_per_c=sigma.contrast_per_c),
                     "bursts": {key: v.tolist() for key, v in lv.items()}})
    info = {"machine": machine(), "wall_s": time.perf_counter() - start, "quick": args.quick,
            "floor_c": sigma.floor_c, "contrast_per_c": sigma.contrast_per_c}
    print(report(sets, info))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({**info, "sets": sets}, f, indent=1)


if __name__ == "__main__":
    main()
