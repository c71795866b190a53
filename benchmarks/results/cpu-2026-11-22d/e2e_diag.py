"""Diagnose an E2E model: training batch in train-mode vs eval-mode BN; per-burst held-out errors."""
import sys
import numpy as np
import torch
sys.path.insert(0, "benchmarks")
from kpn import eval_bursts, run_methods
from thermocal.nn.data import BurstConfig, ScenePool
from thermocal.nn.loss import kpn_loss
from thermocal.nn.train import _Stream, load_model
torch.set_num_threads(2)
model, norm, info = load_model(sys.argv[1])
n = model.config.n_frames
span = norm.temp_max_c - norm.temp_min_c
cfg = BurstConfig(n_frames=n, crop=64)
stream = _Stream(lambda: ScenePool.training(seed=42, n_procedural=24), cfg, norm, seed=7, batch=32,
                 start_batch=0, cameras=None)
it = iter(stream)
for k in range(3):
    frames, fpa, valid, truth, mask, r2 = next(it)
    with torch.no_grad():
        model.eval(); e_eval = model(frames, fpa, valid, r2=r2)
        model.train(); e_train = model(frames, fpa, valid, r2=r2)  # batch statistics (running stats updated: copy discarded below)
    m = mask.float()
    mae = lambda e: float(((e - truth).abs() * m).sum() / m.sum() * span)
    print(f"training batch {k}: MAE eval-mode BN {mae(e_eval):.2f} °C, train-mode BN {mae(e_train):.2f} °C")
model, norm, info = load_model(sys.argv[1])
res = run_methods(eval_bursts(n, quick=False), model.eval(), norm, baselines=False)
for r in list(res.values())[0]:
    print({k: (round(v, 2) if isinstance(v, float) else v) for k, v in r.items() if k in ("mae", "bias", "bias_free")})
