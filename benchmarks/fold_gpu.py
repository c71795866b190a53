"""The folded kernel step against the formed kernels on a CUDA GPU: inference on one and 16
bursts and a training step at the shipped network's batch and crop (its configuration, random
weights; times in ms, CUDA's default TF32 convolutions; the largest difference of the outputs
with TF32 off, so that it shows the folding's rounding alone).

Run on a machine with a GPU: ``python benchmarks/fold_gpu.py [--json OUT]`` (CI has none; the
CPU figures are ``benchmarks/backends.py``'s)."""

import argparse
import json
import time
from dataclasses import fields

import torch

from thermocal.nn.commands import SHIPPED
from thermocal.nn.model import KPN, ModelConfig, with_formed_kernels


def _ms(fn, rounds: int = 20) -> float:
    for _ in range(3):
        fn()
    torch.cuda.synchronize()
    t = time.perf_counter()
    for _ in range(rounds):
        fn()
    torch.cuda.synchronize()
    return (time.perf_counter() - t) / rounds * 1e3


def _max_diff(a: KPN, b: KPN, *inputs: torch.Tensor, r2: torch.Tensor) -> float:
    """The largest difference of two networks' outputs with TF32 off (float32 throughout)."""
    keep = torch.backends.cudnn.allow_tf32
    torch.backends.cudnn.allow_tf32 = False
    try:
        with torch.inference_mode():
            return float((a(*inputs, r2=r2) - b(*inputs, r2=r2)).abs().max())
    finally:
        torch.backends.cudnn.allow_tf32 = keep


def run() -> dict:
    dev = "cuda"
    config = ModelConfig(**{f.name: SHIPPED[f.name] for f in fields(ModelConfig)
                            if f.name in SHIPPED})
    torch.manual_seed(0)
    folded = KPN(config).to(dev).eval()
    formed = with_formed_kernels(folded)
    out = {"device": torch.cuda.get_device_name(0), "torch": torch.__version__,
           "tf32_convolutions": torch.backends.cudnn.allow_tf32}
    p, n = config.position_planes, config.n_frames
    for h, w, b in [(256, 336, 1), (512, 640, 1), (256, 336, 16)]:
        x, f = torch.rand(b, n, h, w, device=dev), torch.rand(b, device=dev)
        r2 = torch.rand(b, p, h, w, device=dev)
        out[f"infer_{w}x{h}_b{b}_maxdiff_fp32"] = _max_diff(folded, formed, x, f, r2=r2)
        with torch.inference_mode():
            for name, m in (("folded", folded), ("formed", formed)):
                key = f"infer_{w}x{h}_b{b}_{name}_ms"
                out[key] = _ms(lambda m=m, x=x, f=f, r2=r2: m(x, f, r2=r2))
    batch, crop = SHIPPED["batch"], SHIPPED["crop"]
    x, f = torch.rand(batch, n, crop, crop, device=dev), torch.rand(batch, device=dev)
    r2 = torch.rand(batch, p, crop, crop, device=dev)
    for name, m in (("folded", folded), ("formed", formed)):
        m.train()
        opt = torch.optim.Adam(m.parameters(), 1e-4)

        def step(m=m, opt=opt):
            opt.zero_grad(set_to_none=True)
            m(x, f, r2=r2).abs().mean().backward()
            opt.step()

        out[f"train_step_b{batch}_crop{crop}_{name}_ms"] = _ms(step)
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
