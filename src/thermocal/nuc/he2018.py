"""Single-image CNN NUC after He et al. 2018 [``he2018``].

Zewei He, Yanpeng Cao, Yafei Dong, Jiangxin Yang, Yanlong Cao, Christel-Löic Tisse,
"Single-image-based nonuniformity correction of uncooled long-wave infrared detectors: a
deep-learning approach", Applied Optics 57(18):D155-D164 (2018).

A fully convolutional network predicts the fixed-pattern noise (FPN) of one raw frame, and the
frame less that prediction is the corrected frame (residual learning). The topology is that of
the authors' released model (their MatConvNet demo, ``des_ds_Matconvnet.m``, model 1): a
full-resolution feature layer; a low-resolution branch (max-pooling by 3, a stack of 3×3
convolutions with ReLU, a transposed convolution back up by 3) that gives the network the wide
receptive field that stripes need; the two concatenated and mapped to the FPN estimate; the
loss is the mean squared error between the estimated and the true noise.

Scaled down to train on two CPU cores in minutes (the paper trains on a GPU):

* 32 feature maps (the paper: 64), 6 low-resolution convolutions with ReLU (the released
  model: 7) plus the linear one before the upsampling, and one 3×3 convolution with ReLU to 16
  maps after the concatenation, before the output convolution (the released model: none; its
  variant 1 has one);
* trained for a few thousand Adam steps on 66×66 patches made on the fly by thermocal's
  camera simulator (the paper: natural infrared images with additive stripe and Gaussian noise);
* stuck (dead / hot) pixels are replaced by their 3×3 median before the network (as
  :func:`thermocal.nuc.batch.tendero2012` does), so that the network never sees 14-bit outliers;
* the input is the frame less its mean over :data:`SCALE_COUNTS` counts, and the output keeps the
  frame's mean (the estimated pattern is made zero-mean): the network fixes structure, not level.

Training data (:func:`train`): patches of the ``tau2`` *training* units
(:data:`thermocal.nn.data.TRAIN_UNITS`) over the *training* scenes
(:meth:`thermocal.nn.data.ScenePool.training`: procedural maps and the real scenes not held
out), at an FPA temperature drawn over 10-50 °C. The input is the raw frame rendered by the unit's
sensor window with pixel and column FPN (the unit's own, or a fresh draw of the preset's spreads
scaled by 0.5-1.5, as :mod:`thermocal.nn.data` redraws FPN), its defects and temporal noise. The
**target** is the noise-free, unquantised counts of the same window without its pixel and column
FPN and without defects (:func:`fpn_free`): the unit's smooth response (mean responsivity with its
vignetting, radial offset and housing self-radiation) to the same scene at the same FPA
temperature. The smooth radial terms are left in the target: they depend on where a pixel lies on
the sensor, which a single-frame, translation-invariant network cannot know; that is a job for a
calibration, not for a single-image NUC.

The output is counts-like, **not radiometric**: compare it with a temperature only after an
affine fit (:func:`thermocal.metrics.best_affine_fit`).

Weights: ``weights/he2018.pt`` beside this module (``torch.save`` of plain values, read with
``weights_only=True``) with a SHA-256 of its tensors checked at load; ``weights/he2018.json``
records how they were trained. Regenerate them with::

    python -m thermocal.nuc.he2018 --train --out src/thermocal/nuc/weights/he2018.pt

torch is imported only inside the functions that need it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.nuc._common import as_nuc_frames

__all__ = ["CONFIG", "FORMAT", "SCALE_COUNTS", "fpn_free", "he2018", "load_weights",
           "tensor_sha256", "train"]

#: Weights file format name and version.
FORMAT = "thermocal-he2018"
VERSION = 1
#: Counts per unit of the network's input and output.
SCALE_COUNTS = 256.0
#: The network's size: feature maps, low-resolution ReLU convolutions, down-sampling factor,
#: feature maps of the full-resolution convolution after the concatenation.
CONFIG: dict[str, int] = {"channels": 32, "low_layers": 6, "factor": 3, "fuse": 16}
#: Training defaults: steps, batch, patch side (px, a multiple of ``factor``), seed.
TRAIN_STEPS = 1400
TRAIN_BATCH = 16
TRAIN_PATCH = 66
TRAIN_SEED = 2018
#: Sensor size of the training units (the Tau2 336×256 core), ``(W, H)``.
SENSOR_SIZE = (336, 256)
#: A stuck pixel: more than this many robust σ from its 3×3 median.
OUTLIER_SIGMA = 6.0
_WEIGHTS = "weights/he2018.pt"


# --------------------------------------------------------------------------------------------
# the network
# --------------------------------------------------------------------------------------------


@lru_cache(maxsize=1)
def _net_class() -> type:
    """The network class (made on first use: torch is imported here, not at module import)."""
    import torch
    from torch import nn
    from torch.nn import functional as F  # noqa: N812 - torch's convention

    class He2018Net(nn.Module):
        """Full-resolution features + a ×3 down-sampled ReLU stack, concatenated → FPN."""

        def __init__(self, channels: int, low_layers: int, factor: int, fuse: int) -> None:
            super().__init__()
            c = channels
            self.factor = factor

            def conv(cin: int, cout: int) -> nn.Conv2d:
                return nn.Conv2d(cin, cout, 3, padding=1, padding_mode="reflect")

            self.head = conv(1, c)
            self.low = nn.ModuleList(conv(c, c) for _ in range(low_layers))
            self.low_out = conv(c, c)
            self.up = nn.ConvTranspose2d(c, c, factor, stride=factor)
            self.fuse = conv(2 * c, fuse)
            self.out = conv(fuse, 1)

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            f = self.head(x)
            z = F.max_pool2d(f, self.factor)
            for layer in self.low:
                z = F.relu(layer(z))
            z = self.up(self.low_out(z))
            return self.out(F.relu(self.fuse(torch.cat([f, z], dim=1))))

    return He2018Net


def _build(config: dict[str, int]) -> Any:
    return _net_class()(*(int(config[k]) for k in ("channels", "low_layers", "factor", "fuse")))


def tensor_sha256(state: dict[str, Any]) -> str:
    """SHA-256 of a state dict: every tensor by name, shape, dtype and bytes, names sorted."""
    from thermocal.nn.store import digest_tensors  # torch: only here

    digest = hashlib.sha256(b"thermocal-he2018-sha256\n")
    digest_tensors(digest, state)
    return digest.hexdigest()


def _package_weights() -> Path:
    return Path(str(resources.files("thermocal.nuc").joinpath(_WEIGHTS)))


def load_weights(weights: str | os.PathLike[str] | None = None) -> tuple[Any, dict[str, Any]]:
    """The network (eval mode) and its file's header (``config``, ``sha256``, ``train``).

    Parameters
    ----------
    weights : str or os.PathLike, optional
        A weights file written by :func:`train`; default the shipped ``weights/he2018.pt``.

    Raises
    ------
    FileFormatError
        Missing, truncated or damaged file, a checksum that does not match its tensors, or a
        file that is not a he2018 weights file (one line).
    """
    path = _package_weights() if weights is None else Path(os.fspath(weights))
    try:
        stat = path.stat()
    except (OSError, ValueError):
        raise FileFormatError(f"{path}: no such he2018 weights file") from None
    if not path.is_file():
        raise FileFormatError(f"{path}: not a file")
    return _load(str(path.resolve()), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=4)
def _load(path: str, _mtime_ns: int, _size: int) -> tuple[Any, dict[str, Any]]:
    import warnings

    from thermocal.optional import require

    torch = require("torch", "he2018 (its network's weights)", "nn")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged file
        first = (str(exc).strip().splitlines() or [""])[0][:80]
        raise FileFormatError(f"{path}: not a readable he2018 weights file "
                              f"({type(exc).__name__}: {first})") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise FileFormatError(f"{path}: not a he2018 weights file (no '{FORMAT}' header)")
    if payload.get("version") != VERSION:
        raise FileFormatError(f"{path}: he2018 weights version {payload.get('version')!r:.20} "
                              "not supported")
    state, config = payload.get("state_dict"), payload.get("config")
    if not isinstance(state, dict) or not isinstance(config, dict):
        raise FileFormatError(f"{path}: he2018 weights file without state dict or config")
    try:
        digest = tensor_sha256(state)
    except TypeError as exc:
        raise FileFormatError(f"{path}: damaged he2018 weights file ({exc})") from None
    if digest != payload.get("sha256"):
        recorded = str(payload.get("sha256"))[:12]
        raise FileFormatError(f"{path}: he2018 weights checksum mismatch (damaged file): "
                              f"SHA-256 {digest[:12]}…, recorded {recorded}…")
    try:
        if set(config) != set(CONFIG) or not all(
                type(v) is int and 1 <= v <= 256 for v in config.values()):
            raise ValueError(f"bad config {config!r:.60}")
        net = _build(config)
        net.load_state_dict(state, strict=True)
    except (ValueError, RuntimeError, TypeError) as exc:
        first = (str(exc).strip().splitlines() or [""])[0][:80]
        raise FileFormatError(f"{path}: he2018 weights do not fit the network ({first})") from None
    if not all(bool(torch.isfinite(t).all()) for t in state.values()):
        raise FileFormatError(f"{path}: he2018 weights hold NaN or infinite values")
    net.eval()
    header = {"config": dict(config), "sha256": digest, "train": payload.get("train", {})}
    return net, header


# --------------------------------------------------------------------------------------------
# inference
# --------------------------------------------------------------------------------------------


def _replace_stuck(frame: np.ndarray) -> np.ndarray:
    """Pixels more than :data:`OUTLIER_SIGMA` robust σ from their 3×3 median, replaced by it."""
    med = cv2.medianBlur(frame, 3)
    resid = frame - med
    spread = float(np.median(np.abs(resid))) / 0.6745
    return np.where(np.abs(resid) > OUTLIER_SIGMA * max(spread, 1e-6), med, frame)


def _normalise(frame: np.ndarray, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """The de-stuck frame and the network's input: zero-mean, / SCALE_COUNTS, padded (reflect)
    on the bottom and right to a multiple of ``factor``."""
    f = _replace_stuck(frame)
    x = (f - np.float32(f.mean(dtype=np.float64))) / np.float32(SCALE_COUNTS)
    h, w = f.shape
    pad = ((0, (-h) % factor), (0, (-w) % factor))
    return f, np.pad(x, pad, mode="reflect").astype(np.float32)


#: Frames through the network at once.
INFER_BATCH = 16


def he2018(frames: Any, *, weights: str | os.PathLike[str] | None = None) -> np.ndarray:
    """Single-image CNN NUC (He et al. 2018): each frame corrected on its own.

    Parameters
    ----------
    frames : array_like, shape (N, H, W) or (H, W)
        Raw frames (counts; any size of at least 4×4 pixels); never modified.
    weights : str or os.PathLike, optional
        A weights file of :func:`train`; default the shipped weights.

    Returns
    -------
    numpy.ndarray, float32, shape (N, H, W)
        Corrected frames, counts-like (each keeps its frame's mean level), not radiometric.

    Raises
    ------
    InvalidInputError
        Frames that are not 2-D/3-D numbers of at least 4×4 pixels, NaN or infinite values.
    FileFormatError
        A missing or damaged weights file.
    """
    x = as_nuc_frames(frames, min_frames=1)
    net, header = load_weights(weights)
    import torch

    factor = int(header["config"]["factor"])
    out = np.empty_like(x)
    with torch.inference_mode():
        for a in range(0, x.shape[0], INFER_BATCH):  # frames of one size: a batch at a time
            pairs = [_normalise(x[k], factor) for k in range(a, min(x.shape[0], a + INFER_BATCH))]
            pred = net(torch.from_numpy(np.stack([inp for _, inp in pairs])[:, None]))[:, 0]
            for j, (f, _) in enumerate(pairs):
                p = pred[j].numpy()[: f.shape[0], : f.shape[1]]
                p = p - np.float32(p.mean(dtype=np.float64))
                out[a + j] = f - np.float32(SCALE_COUNTS) * p
    return out


# --------------------------------------------------------------------------------------------
# training data
# --------------------------------------------------------------------------------------------


def fpn_free(camera: Any, unit_info: dict[str, Any], top: int, left: int) -> Any:
    """The sensor window ``camera`` (at ``top, left`` of a preset unit whose ``info`` is
    ``unit_info``) without its pixel and column FPN and without defects.

    The responsivity maps are divided by the pixel gain and by the column gain over the mean of
    the preset's column-gain range; the pixel and column offsets are taken out of the offset.
    What is left is the unit's smooth response (its gain with vignetting, radial offset, FPA
    dependence, housing self-radiation): the training target's camera.
    """
    from dataclasses import replace

    h, w = camera.shape
    rows, cols = slice(top, top + h), slice(left, left + w)
    p = unit_info["preset_parameters"]
    cbar = float(np.mean(p["column_gain_range"]))
    factor = (unit_info["pixel_gain"][rows, cols]
              * (unit_info["column_gain"][cols] / np.float32(cbar))[None, :])
    gain = camera.gain / factor[None]
    offset = camera.offset.copy()
    offset[0] -= unit_info["pixel_offset"][rows, cols] + unit_info["column_offset"][cols][None, :]
    return replace(camera, gain=gain.astype(np.float32), offset=offset.astype(np.float32),
                   defects=np.zeros_like(camera.defects),
                   defect_counts=np.zeros_like(camera.defect_counts))


def _with_new_fpn(smooth: Any, camera: Any, rng: np.random.Generator) -> Any:
    """``smooth`` with fresh pixel and column FPN (the preset's spreads × U[0.5, 1.5]), the
    window's own defects and a few more (rate 5e-4)."""
    from dataclasses import replace

    p = camera.info["preset_parameters"]
    h, w = smooth.shape
    k_pix, k_col = rng.uniform(0.5, 1.5, 2)
    lo, hi = p["column_gain_range"]
    cbar = 0.5 * (lo + hi)
    col_gain = cbar + k_col * (rng.uniform(lo, hi, w) - cbar)
    col_off = k_col * p["column_offset_sigma"] * rng.standard_normal(w)
    pix_gain = 1.0 + k_pix * p["gain_pixel_sigma"] * rng.standard_normal((h, w))
    pix_off = k_pix * p["offset_pixel_sigma"] * rng.standard_normal((h, w))
    factor = (pix_gain * (col_gain / cbar)[None, :]).astype(np.float32)
    offset = smooth.offset.copy()
    offset[0] += (pix_off + col_off[None, :]).astype(np.float32)
    defects = camera.defects.copy()
    counts = camera.defect_counts.copy()
    extra = rng.random((h, w)) < 5e-4
    hot = rng.random((h, w)) < p["hot_fraction"]
    stuck = np.where(hot, 2 ** p["bit_depth"] - 1, rng.integers(0, 2000, (h, w)))
    counts[extra] = stuck[extra].astype(np.uint16)
    defects |= extra
    return replace(smooth, gain=(smooth.gain * factor[None]).astype(np.float32), offset=offset,
                   defects=defects, defect_counts=counts)


def _scene_patch(pool: Any, size: int, rng: np.random.Generator) -> np.ndarray:
    """A ``size²`` °C map cut from a pool scene at a random scale and place, flipped / rotated,
    its mean re-drawn over −15…60 °C and its contrast scaled by 0.3…2 (log-uniform)."""
    from thermocal.scenes.maps import random_augment

    scene, _ = pool.draw(rng)
    if min(scene.shape) >= 8:
        scene = random_augment(scene, rng=rng)
    sh, sw = scene.shape
    scale = max(float(np.exp(rng.uniform(np.log(0.5), np.log(2.0)))), size / sh, size / sw)
    ch, cw = min(sh, math.ceil(size / scale)), min(sw, math.ceil(size / scale))
    top, left = int(rng.integers(0, sh - ch + 1)), int(rng.integers(0, sw - cw + 1))
    region = scene[top : top + ch, left : left + cw]
    interp = cv2.INTER_AREA if scale < 1.0 else cv2.INTER_CUBIC
    m = np.clip(cv2.resize(region, (size, size), interpolation=interp), region.min(), region.max())
    k = float(np.exp(rng.uniform(np.log(0.3), np.log(2.0))))
    m = (m - m.mean()) * k + rng.uniform(-15.0, 60.0)
    return np.clip(m, -40.0, 100.0).astype(np.float32)


class _Units:
    """Full-sensor ``tau2`` units, made once each."""

    def __init__(self) -> None:
        self._cams: dict[int, Any] = {}

    def get(self, unit: int) -> Any:
        from thermocal.camera.presets import make_camera

        if unit not in self._cams:
            self._cams[unit] = make_camera("tau2", unit=unit, size=SENSOR_SIZE)
        return self._cams[unit]


def _sample(pool: Any, units: _Units, unit_list: tuple[int, ...], size: int,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One training pair: the network's input ``(size, size)`` and its target pattern (the
    de-stuck raw frame less the FPN-free counts, zero-mean, / SCALE_COUNTS)."""
    from thermocal.camera.model import expected_counts, render

    scene = _scene_patch(pool, size, rng)
    full = units.get(int(unit_list[int(rng.integers(len(unit_list)))]))
    sh, sw = full.shape
    top, left = int(rng.integers(0, sh - size + 1)), int(rng.integers(0, sw - size + 1))
    cam = full.crop(top, left, size, size)
    smooth = fpn_free(cam, full.info, top, left)
    noisy = cam if rng.random() < 0.25 else _with_new_fpn(smooth, cam, rng)
    fpa = float(rng.uniform(10.0, 50.0))
    housing = fpa - cam.thermal.fpa_self_heating_c
    raw = render(noisy, scene, fpa, housing_c=housing, rng=rng)[0].astype(np.float32)
    target = expected_counts(smooth, scene, fpa, housing_c=housing)[0]
    f, x = _normalise(raw, CONFIG["factor"])
    r = (f - target) / np.float32(SCALE_COUNTS)
    return x, (r - np.float32(r.mean(dtype=np.float64))).astype(np.float32)


def _batch(pool: Any, units: _Units, unit_list: tuple[int, ...], size: int, n: int,
           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    pairs = [_sample(pool, units, unit_list, size, rng) for _ in range(n)]
    return (np.stack([p[0] for p in pairs])[:, None], np.stack([p[1] for p in pairs])[:, None])


# --------------------------------------------------------------------------------------------
# training
# --------------------------------------------------------------------------------------------


def _loss(pred: Any, target: Any) -> Any:
    """MSE between the zero-mean predicted pattern and the zero-mean true one, per patch."""
    pred = pred - pred.mean(dim=(2, 3), keepdim=True)
    return ((pred - target) ** 2).mean()


def train(out: str | os.PathLike[str], *, steps: int = TRAIN_STEPS, seed: int = TRAIN_SEED,
          batch: int = TRAIN_BATCH, patch: int = TRAIN_PATCH, log: Any = print,
          command: str | None = None) -> dict[str, Any]:
    """Train the network from scratch and write ``out`` (weights) and ``out`` with ``.json``.

    Deterministic: the same arguments give the same weights (one torch thread, seeded torch;
    batch ``i`` is drawn from ``numpy.random.default_rng([seed, i])``). Adam, learning rate
    1e-3 with a cosine decay to 1e-5, gradient norm clipped at 1. The validation loss (a fixed
    set of 64 patches of the validation units, :data:`thermocal.nn.data.VAL_UNITS`, over the
    training scenes) is measured at the end, only for the record.

    Returns the record written to the ``.json`` sidecar.
    """
    import torch

    if steps < 1 or batch < 1 or patch < 12 or patch % CONFIG["factor"]:
        raise InvalidInputError(f"steps, batch >= 1 and patch >= 12, a multiple of "
                                f"{CONFIG['factor']}: got {steps}, {batch}, {patch}")
    threads, deterministic = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True)
    try:
        return _train(Path(out), steps=steps, seed=seed, batch=batch, patch=patch, log=log,
                      command=command)
    finally:  # the caller's settings back (a test session, a notebook)
        torch.set_num_threads(threads)
        torch.use_deterministic_algorithms(deterministic)


def _train(out: Path, *, steps: int, seed: int, batch: int, patch: int, log: Any,
           command: str | None) -> dict[str, Any]:
    import torch

    from thermocal.nn.data import TRAIN_UNITS, VAL_UNITS, ScenePool

    t0 = time.perf_counter()
    torch.manual_seed(seed)
    pool = ScenePool.training()
    units = _Units()
    net = _build(CONFIG)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda i: 0.01 + 0.99 * 0.5 * (1.0 + math.cos(math.pi * min(i, steps) / steps)))
    ema, history = None, []
    for step in range(steps):
        x, r = _batch(pool, units, TRAIN_UNITS, patch, batch, np.random.default_rng([seed, step]))
        loss = _loss(net(torch.from_numpy(x)), torch.from_numpy(r))
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        sched.step()
        value = float(loss.detach())
        ema = value if ema is None else 0.98 * ema + 0.02 * value
        if (step + 1) % 100 == 0 or step + 1 == steps:
            history.append([step + 1, round(ema, 6)])
            log(f"step {step + 1}/{steps}  loss {value:.5f}  ema {ema:.5f}  "
                f"{time.perf_counter() - t0:.0f} s")
    net.eval()
    vx, vr = _batch(pool, units, VAL_UNITS, patch, 64, np.random.default_rng([seed, 10**6]))
    with torch.no_grad():
        val = float(_loss(net(torch.from_numpy(vx)), torch.from_numpy(vr)))
    val_raw = float(np.mean(vr**2))  # the loss of predicting no pattern at all
    state = {k: v.detach().clone().contiguous() for k, v in net.state_dict().items()}
    digest = tensor_sha256(state)
    seconds = time.perf_counter() - t0
    record = {
        "method": "he2018",
        "paper": "He et al. 2018, Appl. Opt. 57(18):D155-D164",
        "command": command or (f"python -m thermocal.nuc.he2018 --train --out {out} "
                               f"--steps {steps} --seed {seed}"),
        "steps": steps, "seed": seed, "batch": batch, "patch": patch,
        "config": dict(CONFIG), "scale_counts": SCALE_COUNTS,
        "optimiser": "Adam lr 1e-3, cosine to 1e-5, grad-norm clip 1",
        "loss": "MSE of the zero-mean FPN estimate vs the zero-mean true pattern "
                "((de-stuck raw - FPN-free noise-free counts) / scale_counts)",
        "final_loss_ema": round(float(ema), 6),
        "val_loss": round(val, 6), "val_loss_no_correction": round(val_raw, 6),
        "loss_history": history,
        "data": {"preset": "tau2", "units": list(TRAIN_UNITS), "sensor_size": list(SENSOR_SIZE),
                 "scenes": pool.names, "val_units": list(VAL_UNITS),
                 "fpa_range_c": [10.0, 50.0], "scene_mean_range_c": [-15.0, 60.0],
                 "contrast_range": [0.3, 2.0],
                 "fpn": "unit's own (p=0.25) or fresh pixel+column FPN, preset spreads x "
                        "U[0.5, 1.5]; unit defects + 5e-4 extra; temporal noise",
                 "target": "noise-free counts of the same window without pixel/column FPN "
                           "and defects (fpn_free)"},
        "train_seconds": round(seconds, 1),
        "threads": 1,
        "torch": torch.__version__,
        "sha256": digest,
    }
    payload = {"format": FORMAT, "version": VERSION, "config": dict(CONFIG),
               "scale_counts": SCALE_COUNTS, "state_dict": state, "sha256": digest,
               "train": {k: record[k] for k in ("command", "steps", "seed", "final_loss_ema",
                                                "val_loss")}}
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, out)
    out.with_suffix(".json").write_text(json.dumps(record, indent=1) + "\n")
    log(f"wrote {out} ({out.stat().st_size} bytes, sha256 {digest[:12]}…) in {seconds:.0f} s; "
        f"val loss {val:.5f} (no correction {val_raw:.5f})")
    return record


def main(argv: list[str] | None = None) -> int:
    """``python -m thermocal.nuc.he2018 --train --out PATH [--steps K] [--seed S]``."""
    ap = argparse.ArgumentParser(prog="python -m thermocal.nuc.he2018",
                                 description="Train the he2018 single-image NUC network.")
    ap.add_argument("--train", action="store_true", help="train and write the weights")
    ap.add_argument("--out", type=Path, help="weights file to write (.pt; a .json beside it)")
    ap.add_argument("--steps", type=int, default=TRAIN_STEPS)
    ap.add_argument("--seed", type=int, default=TRAIN_SEED)
    args = ap.parse_args(argv)
    if not args.train or args.out is None:
        ap.error("give --train and --out PATH")
    command = "python -m thermocal.nuc.he2018 " + " ".join(
        sys.argv[1:] if argv is None else argv)
    train(args.out, steps=args.steps, seed=args.seed, command=command,
          log=lambda s: print(s, flush=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
