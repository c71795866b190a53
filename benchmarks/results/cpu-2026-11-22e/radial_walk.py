"""Where a KPN's error lies on the sensor (diagnosis): each burst's mean error by fifths of the
pixels by distance from the sensor's centre, for walks and hovers; and, for walks, by distance
and by how many frames see the pixel. From the repository root: python THIS [MODEL.pt]"""

import sys

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
from kpn import eval_bursts, network_estimate, radial_bins, scores  # noqa: E402

from thermocal.burst import fill_stuck_pixels  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1] if len(sys.argv) > 1 else shipped_model_path("kpn"))
n = model.config.n_frames
by_motion = {"walk": [], "hover": []}
by_cover = {}
for b in eval_bursts(n, quick=False):
    e = network_estimate(b, fill_stuck_pixels(b["frames"], b["hs"])[0], model, norm)
    by_motion[b["motion"]].append(scores(e.temperature_c, b)["bias_by_radius"])
    if b["motion"] == "walk":
        err, m = e.temperature_c - b["truth"], b["mask"]
        rb = radial_bins(err.shape)
        bias = err[m].mean()
        for c in range(1, n + 1):
            for r in range(5):
                sel = m & (e.coverage == c) & (rb == r)
                if sel.sum() > 200:  # enough pixels for a mean
                    by_cover.setdefault((c, r), []).append(err[sel].mean() - bias)

print("Mean error °C by distance from the sensor's centre (fifths of the pixels), averaged over "
      "the bursts, and its rise from the first fifth to the last:\n")
print("| bursts | 1st | 2nd | 3rd | 4th | 5th (corners) | rise |\n|---|---|---|---|---|---|---|")
for motion, rows in by_motion.items():
    a = np.array(rows)
    rises = a[:, -1] - a[:, 0]
    print(f"| {motion} ({len(a)}) | " + " | ".join(f"{v:+.2f}" for v in a.mean(0))
          + f" | {rises.mean():+.2f} (> 0 in {(rises > 0).sum()} of {len(a)}) |")
print("\nWalks: mean error less each burst's bias, °C, by the number of frames that see the "
      "pixel (rows) and distance fifth (columns); in brackets the number of bursts with more "
      "than 200 such pixels:\n")
print("| frames | 1st | 2nd | 3rd | 4th | 5th |\n|---|---|---|---|---|---|")
for c in range(1, n + 1):
    cells = [f"{np.mean(by_cover[(c, r)]):+.2f} ({len(by_cover[(c, r)])})"
             if (c, r) in by_cover else "–" for r in range(5)]
    if any(x != "–" for x in cells):
        print(f"| {c} | " + " | ".join(cells) + " |")
