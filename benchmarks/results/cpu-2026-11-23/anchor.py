"""Diagnosis: each network's estimate shifted onto the family model's eq. 9 mean over the burst's
mask (its global level anchored to the family's, which is what the burst says of a new unit's
level), on the evaluation bursts of ``benchmarks/kpn.py`` made by six sets of camera units.

    python benchmarks/results/cpu-2026-11-23/anchor.py MODEL.pt [MODEL.pt ...] > anchor.md
"""

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from kpn import ExactModel, eval_bursts, network_estimate, scores  # noqa: E402
from unit_sets import SETS  # noqa: E402

from thermocal.burst import fill_stuck_pixels, naive_mean  # noqa: E402
from thermocal.nn.data import TRAIN_UNITS  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

torch.set_num_threads(2)
family = ExactModel.family(TRAIN_UNITS)
print("| model | units | network MAE °C | anchored MAE °C | family model MAE °C | "
      "anchored better |")
print("|---|---|---|---|---|---|")
for path in sys.argv[1:]:
    model, norm, _ = load_model(path)
    for name, units in SETS:
        net, anchored, fam = [], [], []
        for b in eval_bursts(7, quick=False, units=units):
            frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
            t = network_estimate(b, frames, model, norm).temperature_c
            m9 = naive_mean(frames, family, fpa_c=b["fpa_read"], homographies=b["hs"],
                            pivot=b["pivot"], fill_defects=False).temperature_c
            m = b["mask"]
            net.append(scores(t, b)["mae"])
            anchored.append(scores(t + (m9[m].mean() - t[m].mean()), b)["mae"])
            fam.append(scores(m9, b)["mae"])
        better = sum(a < n for a, n in zip(anchored, net, strict=True))
        print(f"| {Path(path).name} | {name} | {np.mean(net):.2f} | {np.mean(anchored):.2f} | "
              f"{np.mean(fam):.2f} | {better} of {len(net)} |", flush=True)
