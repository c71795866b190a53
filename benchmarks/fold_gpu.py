"""The folded kernel step against the formed kernels on a CUDA GPU: inference on one and 16
bursts and a training step (the shipped configuration, random weights; times in ms).

Run on a machine with a GPU: ``python benchmarks/fold_gpu.py [--json OUT]`` (CI has none; the
CPU figures are ``benchmarks/backends.py``'s)."""

import argparse
import json
import time

import torch

from thermocal.evaluation.suites.backends import _kernels_formed
from thermocal.nn.model import KPN, ModelConfig

SHIPPED = ModelConfig(n_frames=7, mu=16, xi=2, levels=3, kernel=5, degree=4, variant="kpn",
                      fpa_input=True, centre=True, radiance=True, radial=2, calibrated=True)


def _ms(fn, rounds: int = 20) -> float:
    for _ in range(3):
        fn()
    torch.cuda.synchronize()
    t = time.perf_counter()
    for _ in range(rounds):
        fn()
    torch.cuda.synchronize()
    return (time.perf_counter() - t) / rounds * 1e3


def run() -> dict:
    dev = "cuda"
    torch.manual_seed(0)
    folded = KPN(SHIPPED).to(dev).eval()
    formed = _kernels_formed(folded)
    out = {"device": torch.cuda.get_device_name(0), "torch": torch.__version__}
    p = SHIPPED.position_planes
    for h, w, b in [(256, 336, 1), (512, 640, 1), (256, 336, 16)]:
        x, f = torch.rand(b, 7, h, w, device=dev), torch.rand(b, device=dev)
        r2 = torch.rand(b, p, h, w, device=dev)
        with torch.inference_mode():
            out[f"infer_{w}x{h}_b{b}_maxdiff"] = float(
                (folded(x, f, r2=r2) - formed(x, f, r2=r2)).abs().max())
            for name, m in (("folded", folded), ("formed", formed)):
                key = f"infer_{w}x{h}_b{b}_{name}_ms"
                out[key] = _ms(lambda m=m, x=x, f=f, r2=r2: m(x, f, r2=r2))
    x, f = torch.rand(64, 7, 64, 64, device=dev), torch.rand(64, device=dev)
    r2 = torch.rand(64, p, 64, 64, device=dev)
    for name, m in (("folded", folded), ("formed", formed)):
        m.train()
        opt = torch.optim.Adam(m.parameters(), 1e-4)

        def step(m=m, opt=opt):
            opt.zero_grad(set_to_none=True)
            m(x, f, r2=r2).abs().mean().backward()
            opt.step()

        out[f"train_step_b64_crop64_{name}_ms"] = _ms(step)
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--json")
    args = parser.parse_args()
    res = run()
    print(json.dumps(res, indent=1))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(res, fh, indent=1)
