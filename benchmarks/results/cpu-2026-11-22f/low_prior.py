"""Does a KPN know its training family's low frequencies? (diagnosis) On the held-out set: the
network's estimate; the exact average training unit's eq. 9 mean (``FAMILY_ROW`` of
``benchmarks/kpn.py``); the network's estimate shifted to the family mean's burst mean; and,
joined by ``kpn.fuse``, the family mean's Gaussian low-pass of σ px (over the mask) plus the
high-pass of the network's estimate, or of the scene-based NUC baseline of ``benchmarks/kpn.py``
(hardie2000 + another unit's global fit). The family model is what the network was trained
from (the chamber path's counterpart: unit A's fitted model), not the held-out unit's
calibration. From the repository root: python THIS [MODEL.pt]"""

import sys

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
from kpn import (  # noqa: E402
    ExactModel,
    eval_bursts,
    fuse,
    network_estimate,
    nuc_global_fit,
    other_unit_calibration,
    scores,
)

from thermocal.burst import fill_stuck_pixels, naive_mean  # noqa: E402
from thermocal.nn.data import TRAIN_UNITS  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

SIGMAS_PX = (3, 6, 12, 24, 48)
torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1] if len(sys.argv) > 1 else shipped_model_path("kpn"))
family = ExactModel.family(TRAIN_UNITS)
other_cal = other_unit_calibration()
rows: dict[str, list[dict]] = {}
for b in eval_bursts(model.config.n_frames, quick=False):
    frames, m = fill_stuck_pixels(b["frames"], b["hs"])[0], b["mask"]
    net = network_estimate(b, frames, model, norm).temperature_c
    fam = naive_mean(frames, family, fpa_c=b["fpa_read"], homographies=b["hs"], pivot=b["pivot"],
                     fill_defects=False).temperature_c
    rows.setdefault("network", []).append(scores(net, b))
    rows.setdefault("family model (eq. 9 mean)", []).append(scores(fam, b))
    rows.setdefault("network shifted to the family mean's burst mean", []).append(
        scores(net - net[m].mean() + fam[m].mean(), b))
    nuc = nuc_global_fit(frames, b["hs"], b["pivot"], other_cal)
    for s in SIGMAS_PX:
        for name, est in (("network", net), ("hardie2000 NUC", nuc)):
            rows.setdefault(f"family low-pass σ = {s} px + {name} high-pass", []).append(
                scores(fuse(fam, est, m, s), b))
net_mae = np.array([r["mae"] for r in rows["network"]])
print("| estimate | MAE °C | mean abs bias °C | bias-free °C | smooth part °C | fine part °C | "
      "bursts better than the network |")
print("|---|---|---|---|---|---|---|")
for name, lst in rows.items():
    wins = int((np.array([r["mae"] for r in lst]) < net_mae).sum())
    print(f"| {name} | " + " | ".join(f"{np.mean([abs(r[k]) for r in lst]):.2f}" for k in (
        "mae", "bias", "bias_free", "smooth", "fine")) + f" | {wins} of {len(lst)} |")
