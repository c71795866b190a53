"""What the other frames of a burst buy a KPN (diagnosis): each held-out burst as flown against
the same burst with every frame replaced by the pivot (no multi-frame information).
From the repository root: python THIS [MODEL.pt]"""

import sys

import numpy as np
import torch

sys.path.insert(0, "benchmarks")
from kpn import eval_bursts, network_estimate, scores  # noqa: E402

from thermocal.burst import fill_stuck_pixels  # noqa: E402
from thermocal.nn.infer import shipped_model_path  # noqa: E402
from thermocal.nn.train import load_model  # noqa: E402

torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1] if len(sys.argv) > 1 else shipped_model_path("kpn"))
bursts = eval_bursts(model.config.n_frames, quick=False)
rows = {"burst as flown": [], "pivot frame repeated": []}
for b in bursts:
    frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
    p, n = b["pivot"], len(frames)
    inputs = {
        "burst as flown": (frames, b["hs"]),
        "pivot frame repeated": (np.repeat(frames[p : p + 1], n, 0),
                                 np.repeat(np.eye(3)[None], n, 0)),
    }
    for name, (fr, hs) in inputs.items():
        e = network_estimate(b, fr, model, norm, homographies=hs)
        rows[name].append(scores(e.temperature_c, b))


def mean(lst, key, motion=None):
    return np.mean([abs(s[key]) for s, b in zip(lst, bursts, strict=True)
                    if motion in (None, b["motion"])])


print("| input | MAE °C | mean abs bias °C | bias-free °C | smooth part °C | fine part °C | "
      "walk MAE °C | hover MAE °C |")
print("|---|---|---|---|---|---|---|---|")
for name, lst in rows.items():
    print(f"| {name} | " + " | ".join(f"{mean(lst, k):.2f}" for k in (
        "mae", "bias", "bias_free", "smooth", "fine")) + f" | {mean(lst, 'mae', 'walk'):.2f} | "
        f"{mean(lst, 'mae', 'hover'):.2f} |")
