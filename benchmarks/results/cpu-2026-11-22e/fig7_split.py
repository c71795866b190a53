"""Fig. 7's KPN + offset models of a sweep kept with ``kpn_fig7.py --out-dir DIR``, and the exact
family model, on the held-out set of each N with the error split into bias, smooth and fine
parts (diagnosis). From the repository root: python THIS DIR"""

import sys
from pathlib import Path

import torch

sys.path.insert(0, "benchmarks")
from kpn import FAMILY_ROW, ExactModel, eval_bursts, run_methods, summarise  # noqa: E402

from thermocal.nn.data import TRAIN_UNITS  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

torch.set_num_threads(2)
family = ExactModel.family(TRAIN_UNITS)
print("| N | method | MAE °C | mean abs bias °C | bias-free °C | smooth part °C | fine part °C |")
print("|---|---|---|---|---|---|---|")
for n in (1, 3, 5, 7, 9, 11):
    model, norm, _ = load_model(Path(sys.argv[1]) / f"fig7_kpn_n{n}.pt")
    rows = summarise(run_methods(eval_bursts(n, quick=False), model, norm, baselines=False,
                                 references={FAMILY_ROW: family}))
    for r in rows:
        print(f"| {n} | {r['method']} | {r['mae_c']:.2f} | {r['mean_abs_bias_c']:.2f} | "
              f"{r['bias_free_mae_c']:.2f} | {r['smooth_mae_c']:.2f} | {r['fine_mae_c']:.2f} |",
              flush=True)
