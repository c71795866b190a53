"""Does a KPN know its training family's low frequencies? (diagnosis) On the held-out set: the
network's estimate, the exact average training unit's eq. 9 mean (``FAMILY_ROW`` of
``benchmarks/kpn.py``), and the two fused: the family mean's Gaussian of σ px (over the mask)
plus the rest of the network's estimate; and the network's estimate shifted to the family
mean's burst mean; and the classical pipeline given the same prior: the scene-based NUC
baseline of ``benchmarks/kpn.py`` (hardie2000 + another unit's global fit) above σ, the family
mean below. The family model is what the network was trained from (the chamber path's
counterpart: unit A's fitted model), not the held-out unit's calibration.
From the repository root: python THIS [MODEL.pt]"""

import sys

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
from kpn import (  # noqa: E402
    NOMINAL_FPA_C,
    OTHER_UNIT,
    ExactModel,
    eval_bursts,
    masked_smooth,
    network_estimate,
    nuc_global_fit,
    scores,
    two_point_of,
)

from thermocal.burst import fill_stuck_pixels, naive_mean  # noqa: E402
from thermocal.camera.presets import make_camera  # noqa: E402
from thermocal.nn.data import TRAIN_UNITS  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

SIGMAS_PX = (3, 6, 12, 24, 48)
torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1] if len(sys.argv) > 1 else shipped_model_path("kpn"))
family = ExactModel.family(TRAIN_UNITS)
other_cal = two_point_of(make_camera("tau2", unit=OTHER_UNIT), NOMINAL_FPA_C,
                         NOMINAL_FPA_C - 1.5, 5)  # as run_methods' baselines
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
            fused = masked_smooth(fam, m, s) + est - masked_smooth(est, m, s)
            rows.setdefault(f"family below σ = {s} px, {name} above", []).append(scores(fused, b))
print("| estimate | MAE °C | mean abs bias °C | bias-free °C | smooth part °C | fine part °C |")
print("|---|---|---|---|---|---|")
for name, lst in rows.items():
    print(f"| {name} | " + " | ".join(f"{np.mean([abs(r[k]) for r in lst]):.2f}" for k in (
        "mae", "bias", "bias_free", "smooth", "fine")) + " |")
