"""Is a KPN's walk-only radial error tied to the camera's radial pattern? (diagnosis) The
held-out set as it is, and again with units drawn without radial structure (radial strengths
0: no vignetting, radial offset or radial housing term); each burst's mean error by distance
from the sensor's centre. From the repository root: python THIS [MODEL.pt]"""

import sys
from dataclasses import replace

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
import kpn  # noqa: E402

from thermocal.burst import fill_stuck_pixels  # noqa: E402
from thermocal.camera import presets  # noqa: E402
from thermocal.nn.infer import estimate_burst, shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1] if len(sys.argv) > 1 else shipped_model_path("kpn"))
FLAT = replace(presets.PRESETS["tau2"], radial_strength_range=(0.0, 0.0), centre_jitter=0.0)
print("| cameras | bursts | 1st | 2nd | 3rd | 4th | 5th (corners) | rise | MAE °C |")
print("|---|---|---|---|---|---|---|---|---|")
for label, preset in (("as drawn", "tau2"), ("no radial structure", FLAT)):
    kpn.make_camera = lambda _p="tau2", *, unit=0, size=(336, 256), _x=preset: (
        presets.make_camera(_x, unit=unit, size=size))
    res = {"walk": [], "hover": []}
    for b in kpn.eval_bursts(model.config.n_frames, quick=False):
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        e = estimate_burst(frames, b["fpa_read"], model=model, norm=norm, homographies=b["hs"],
                           pivot=b["pivot"], fill_defects=False)
        err, m = e.temperature_c - b["truth"], b["mask"]
        rb = kpn.radial_bins(err.shape)
        res[b["motion"]].append([err[m & (rb == r)].mean() for r in range(5)]
                                + [np.abs(err[m]).mean()])
    for motion, rows in res.items():
        a = np.array(rows)
        print(f"| {label} | {motion} | " + " | ".join(f"{v:+.2f}" for v in a[:, :5].mean(0))
              + f" | {(a[:, 4] - a[:, 0]).mean():+.2f} | {a[:, 5].mean():.2f} |", flush=True)
