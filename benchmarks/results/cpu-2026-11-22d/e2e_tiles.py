"""A network on the held-out set of benchmarks/kpn.py, whole frames against tiles (diagnosis).
From the repository root: python THIS MODEL.pt"""

import sys

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
from kpn import eval_bursts  # noqa: E402

from thermocal.burst import fill_stuck_pixels  # noqa: E402
from thermocal.nn.infer import fpa_value, run_network  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402
from thermocal.registration.warp import warp_to_pivot  # noqa: E402

torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1])
n = model.config.n_frames
bursts = eval_bursts(n, quick=False)
for tile, margin in ((512, 32), (128, 32), (64, 16), (64, 0)):
    errs = []
    for b in bursts:
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        warped, valid = warp_to_pivot(frames, b["hs"])
        t = run_network(model, norm, warped, valid, fpa_value(b["fpa_read"], n), tile=tile,
                        margin=margin)
        errs.append(np.abs(t - b["truth"])[b["mask"]].mean())
    print(f"tile {tile} margin {margin}: MAE {np.mean(errs):.3f}", flush=True)
