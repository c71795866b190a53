"""The shipped network and the family model on the evaluation bursts of benchmarks/kpn.py made
by other sets of camera units (same scenes, FPA, trajectories and seeds): does the network do
better on the units it was trained on (it would have learnt them), and how typical are the
held-out units 100-104?

    python benchmarks/results/cpu-2026-11-23/unit_sets.py [MODEL.pt] > unit_sets.md
"""

import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from kpn import FAMILY_ROW, ExactModel, eval_bursts, run_methods, summarise  # noqa: E402

from thermocal.nn.data import TRAIN_UNITS  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

SETS = [("training 0-4", (0, 1, 2, 3, 4)), ("training 10-14", (10, 11, 12, 13, 14)),
        ("validation 50-53", (50, 51, 52, 53)), ("held-out 100-104", (100, 101, 102, 103, 104)),
        ("new 200-204", (200, 201, 202, 203, 204)), ("new 300-304", (300, 301, 302, 303, 304))]


def main() -> None:
    torch.set_num_threads(2)
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else shipped_model_path("kpn")
    model, norm, _ = load_model(path)
    family = ExactModel.family(TRAIN_UNITS)
    print(f"model `{path.name}`; 20 bursts of N = 7 per set (benchmarks/kpn.py's held-out scenes, "
          "FPA, trajectories and seeds; only the camera units differ)\n")
    print("| units | network MAE °C | network bias °C | network bias-free °C | "
          "family model MAE °C | family model bias °C |")
    print("|---|---|---|---|---|---|")
    for name, units in SETS:
        rows = summarise(run_methods(eval_bursts(7, quick=False, units=units), model, norm,
                                     baselines=False, references={FAMILY_ROW: family}))
        net, fam = rows[0], rows[1]
        print(f"| {name} | {net['mae_c']:.2f} | {net['mean_abs_bias_c']:.2f} | "
              f"{net['bias_free_mae_c']:.2f} | {fam['mae_c']:.2f} | {fam['mean_abs_bias_c']:.2f} |",
              flush=True)


if __name__ == "__main__":
    main()
