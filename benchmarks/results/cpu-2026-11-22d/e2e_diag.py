"""Diagnose an E2E model: training-like batches in eval- vs train-mode batch norm, then its
per-burst errors on the held-out set. From the repository root: python THIS MODEL.pt"""

import sys

import torch

sys.path.insert(0, "benchmarks")
from kpn import eval_bursts, run_methods  # noqa: E402

from thermocal.nn.data import BurstConfig, ScenePool  # noqa: E402
from thermocal.nn.train import _Stream, load_model  # noqa: E402


def masked_mae_c(est, truth, mask, span):
    m = mask.float()
    return float(((est - truth).abs() * m).sum() / m.sum() * span)


torch.set_num_threads(2)
model, norm, _ = load_model(sys.argv[1])
n = model.config.n_frames
span = norm.temp_max_c - norm.temp_min_c
stream = _Stream(lambda: ScenePool.training(seed=42, n_procedural=24),
                 BurstConfig(n_frames=n, crop=64), norm, seed=7, batch=32, start_batch=0,
                 cameras=None)
it = iter(stream)
for k in range(3):
    frames, fpa, valid, truth, mask, r2 = next(it)
    with torch.no_grad():
        e_eval = model.eval()(frames, fpa, valid, r2=r2)
        e_train = model.train()(frames, fpa, valid, r2=r2)  # batch statistics
    print(f"training batch {k}: MAE eval-mode BN {masked_mae_c(e_eval, truth, mask, span):.2f} "
          f"°C, train-mode BN {masked_mae_c(e_train, truth, mask, span):.2f} °C")
model, norm, _ = load_model(sys.argv[1])  # fresh: train mode above moved the running stats
res = run_methods(eval_bursts(n, quick=False), model.eval(), norm, baselines=False)
for r in next(iter(res.values())):
    print({k: round(r[k], 2) for k in ("mae", "bias", "bias_free")})
