"""The network on the held-out set: its rows beside the references, its speed and its training
throughput (imports torch)."""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from thermocal.burst import fill_stuck_pixels
from thermocal.evaluation.heldout import other_unit_calibration
from thermocal.evaluation.references import FAMILY_ROW, ExactModel, reference_scores
from thermocal.evaluation.scoring import scores
from thermocal.nn.data import TRAIN_UNITS, BurstConfig, ScenePool
from thermocal.nn.infer import calibrated_warp, estimate_burst, run_network
from thermocal.nn.inputs import sensor_r2
from thermocal.nn.model import ModelConfig, count_macs, count_parameters
from thermocal.nn.train import TrainConfig, train

__all__ = ["KPN_ROW", "VARIANT_ROWS", "network_estimate", "run_methods", "speed",
           "training_throughput"]


def network_estimate(b: dict, frames: np.ndarray, model, norm, homographies=None):
    """The network's :class:`~thermocal.estimation.base.Estimate` for the evaluation burst
    ``b`` from ``frames`` (its frames with their stuck pixels replaced, or a diagnosis'
    substitute) and ``homographies`` (default: the burst's)."""
    return estimate_burst(frames, b["fpa_read"], model=model, norm=norm,
                          homographies=b["hs"] if homographies is None else homographies,
                          pivot=b["pivot"], fill_defects=False)


#: The row of the shipped network.
KPN_ROW = "KPN + offset"


#: Row names of the network variants.
VARIANT_ROWS = {"kpn": KPN_ROW, "kpn-no-offset": "KPN (no offset block)", "e2e": "E2E"}


def run_methods(bursts, model, norm, *, baselines: bool = True, label: str = KPN_ROW,
                references: dict[str, ExactModel] | None = None) -> dict[str, list[dict]]:
    """Every method on every burst: name → list of per-burst scores (the network's under
    ``label``, first; then :func:`~thermocal.evaluation.references.reference_scores`: an eq. 9
    mean through each of ``references``, and with ``baselines`` the family floor, the
    calibration-free baselines, the classical pipeline and the own two-point reference). Every
    method gets the burst with its stuck pixels replaced once."""
    res: dict[str, list[dict]] = {}
    other_cal = None
    if baselines:
        other_cal = other_unit_calibration()
        references = {FAMILY_ROW: ExactModel.family(TRAIN_UNITS)} | (references or {})
    for b in bursts:
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])  # as the estimation pipeline does
        if model is not None:
            e = network_estimate(b, frames, model, norm)
            res.setdefault(label, []).append(scores(e.temperature_c, b))
        for name, score in reference_scores(b, frames, references or {}, other_cal).items():
            res.setdefault(name, []).append(score)
    return res


def speed(model, norm, *, threads: int = 2) -> dict:
    """The network on one 336×256 burst (median of 5 runs after one warm-up; a calibrated
    model's time includes calibrating and warping the frames), its size and multiply-adds."""
    torch.set_num_threads(threads)
    rng = np.random.default_rng(0)
    n = model.config.n_frames
    warped = rng.uniform(6000, 9000, (n, 256, 336)).astype(np.float32)
    valid = np.ones(warped.shape, dtype=bool)
    r2f = np.repeat(sensor_r2(warped.shape[1:])[None], n, 0) if model.config.radial_frames else None
    still = np.repeat(np.eye(3)[None], n, 0)

    def once() -> None:  # a calibrated model's time includes calibrating and warping the frames
        x = calibrated_warp(model, warped, still, 30.0) if model.config.calibrated else warped
        run_network(model, norm, x, valid, 30.0, r2_frames=r2f)

    once()
    times = []
    for _ in range(5):
        t = time.perf_counter()
        once()
        times.append(time.perf_counter() - t)
    return {
        "network_ms_336x256": 1000 * statistics.median(times),
        "parameters": count_parameters(model),
        "gmacs_336x256": count_macs(model, 256, 336) / 1e9,
        "threads": threads,
        "calibrated": model.config.calibrated,
    }


def training_throughput(model_cfg: ModelConfig, data: dict, *, steps: int = 6) -> float:
    """Samples/s of the shipped configuration (data generation included), a few steps."""
    cfg = BurstConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})
    with tempfile.TemporaryDirectory() as tmp:
        res = train(
            Path(tmp) / "m.pt",
            model_cfg,
            cfg,
            TrainConfig(steps_per_epoch=steps, max_epochs=1, val_bursts=16, workers=1),
            pool_fn=lambda: ScenePool.training(n_procedural=6),
            val_pool_fn=lambda: ScenePool.training(seed=1, n_procedural=3),
            log=lambda s: None,
            progress=False,
        )
    return res.samples_per_s
