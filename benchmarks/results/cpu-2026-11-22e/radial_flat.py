"""Is a KPN's walk-only radial error tied to the camera's radial pattern? (diagnosis) The
held-out set as it is, and again with units drawn without radial structure (radial strengths
0: no vignetting, radial offset or radial housing term); each burst's mean error by distance
from the sensor's centre. From the repository root: python THIS [MODEL.pt]"""

import sys
from dataclasses import replace

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
from kpn import KPN_ROW, eval_bursts, run_methods  # noqa: E402

from thermocal.camera import presets  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1] if len(sys.argv) > 1 else shipped_model_path("kpn"))
FLAT = replace(presets.PRESETS["tau2"], radial_strength_range=(0.0, 0.0), centre_jitter=0.0)
print("| cameras | bursts | 1st | 2nd | 3rd | 4th | 5th (corners) | rise | MAE °C |")
print("|---|---|---|---|---|---|---|---|---|")
for label, preset in (("as drawn", "tau2"), ("no radial structure", FLAT)):
    bursts = eval_bursts(model.config.n_frames, quick=False, preset=preset)
    res = run_methods(bursts, model, norm, baselines=False)[KPN_ROW]
    for motion in ("walk", "hover"):
        a = np.array([s["bias_by_radius"] + [s["mae"]]
                      for s, b in zip(res, bursts, strict=True) if b["motion"] == motion])
        print(f"| {label} | {motion} | " + " | ".join(f"{v:+.2f}" for v in a[:, :5].mean(0))
              + f" | {(a[:, 4] - a[:, 0]).mean():+.2f} | {a[:, 5].mean():.2f} |", flush=True)
