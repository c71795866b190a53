"""Does the σ of a network trained on one camera's chamber file hold on that camera?

``thermocal train --chamber FILE`` trains on the camera model fitted on the file, and fits the
network's σ model on bursts of that same fitted model (:mod:`thermocal.evaluation.sigma_fit`),
σ taking in what the fitted model misses of the camera's level on the file's own frames at the
scene's temperature (``model_misfit`` by set point, growing beyond them). This scores it on the
camera itself:
the simulated unit the chamber file was recorded from, flown over the held-out scenes (the kpn
benchmark's bursts: N = 7, FPA 15–45 °C, true homographies + Oz et al.'s registration error),
through the product's pipeline, domain check included. Prints the MAE, coverage within 1σ and
2σ (targets 68 ± 5 %, 95 ± 3 %), median σ, refusals and silent bursts (MAE above 1 °C and
twice the median σ), and what the fitted model itself errs on the chamber's own frames.

The weights are made by (CPU, 8 minutes each; README "Trust")::

    thermocal simulate chamber u7.h5 --unit 7 --seed 7 --ambient-c 5:45
    thermocal train --out u7.pt --chamber u7.h5 --init shipped --max-minutes 8
    thermocal simulate chamber b101.h5 --preset boson --unit 101 --seed 101 --ambient-c 5:45
    thermocal train --out b101.pt --chamber b101.h5 --init shipped --max-minutes 8

    .venv/bin/python benchmarks/chamber_sigma.py u7.pt:u7.h5:tau2:7 b101.pt:b101.h5:boson:101
"""

import argparse
import time

from thermocal.bench import machine
from thermocal.evaluation.heldout import eval_bursts
from thermocal.evaluation.sigma_fit import model_misfit
from thermocal.evaluation.suites.coverage import _run
from thermocal.evaluation.tables import markdown_table
from thermocal.nn.infer import NetworkEstimator


def score(weights: str, chamber: str, preset: str, unit: int) -> dict:
    """The network of ``weights`` (its σ model beside it) on bursts of ``unit`` of ``preset``."""
    network = NetworkEstimator.from_file("kpn", weights)
    if network.sigma_model is None:
        raise SystemExit(f"{weights}: no σ model beside it; fit it: python -m "
                         f"thermocal.evaluation.sigma_fit {weights} --chamber {chamber}")
    bursts = eval_bursts(network.n_frames, quick=False, units=(unit,), preset=preset)
    return {"weights": weights, "chamber": chamber, "preset": preset, "unit": unit,
            "floor_c": network.sigma_model.floor_c, **_run(network, bursts),
            "misfit": model_misfit(chamber)}


def report(rows: list[dict], info: dict) -> str:
    header = ("camera (chamber file → its unit)", "bursts", "refused", "MAE °C",
              "within 1σ", "within 2σ", "median σ °C", "σ floor °C", "silent",
              "fitted model on its chamber frames: RMS / low-passed / frame level °C")
    cells = []
    for r in rows:
        acc, m = r["accepted"], r["misfit"]
        cells.append((f"`{r['preset']}` unit {r['unit']}", r["bursts"], r["refused"],
                      f"{r['mae_c']:.2f}",
                      "–" if acc is None else f"{100 * acc['within_1sigma']:.1f} %",
                      "–" if acc is None else f"{100 * acc['within_2sigma']:.1f} %",
                      "–" if acc is None else f"{acc['median_sigma_c']:.2f}",
                      f"{r['floor_c']:.2f}", r["silent_over_1c"],
                      f"{m['rms_c']:.2f} / {m['low_pass_rms_c']:.2f} / {m['level_rms_c']:.2f}"))
    return (f"## The σ of networks trained on a chamber file, on their own camera\n\n"
            f"machine: {info['machine']}; {info['wall_s']:.0f} s\n\n"
            "Each network trained by `thermocal train --chamber FILE --init shipped "
            "--max-minutes 8` (2 CPU cores), its σ model fitted on 44 bursts of the camera "
            "model fitted on FILE (4 per validation scene), with the fitted model's level "
            "misfit on FILE's frames (RMS over them: the last column's third figure) at the "
            "scene's temperature, by set point and growing beyond them, in quadrature; "
            "scored on 20 bursts of the "
            "simulated unit the file was recorded from, over the held-out scenes (N = 7, "
            "336×256, FPA 15–45 °C). Targets: 68 ± 5 % within 1σ, 95 ± 3 % within 2σ.\n\n"
            + markdown_table(header, cells) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="WEIGHTS:CHAMBER:PRESET:UNIT")
    args = parser.parse_args()
    start = time.perf_counter()
    rows = []
    for run in args.runs:
        weights, chamber, preset, unit = run.split(":")
        rows.append(score(weights, chamber, preset, int(unit)))
    print(report(rows, {"machine": machine(), "wall_s": time.perf_counter() - start}))


if __name__ == "__main__":
    main()
