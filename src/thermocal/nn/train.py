"""Training the KPN on synthetic bursts (Oz et al. §IV-D).

Adam at 1e-4; the learning rate is halved after 3 epochs without improvement of the validation
loss and training stops after 8; orthogonal initialisation scaled by 0.1; seed 42 with
deterministic algorithms. An *epoch* here is ``steps_per_epoch`` batches (the paper's epochs of
~800 batches of 16 are far too long for 2 CPU cores), each followed by a validation pass on a fixed
set of bursts made once (noise and FPN fixed) from cameras units that are never trained on.

Checkpoints (``OUT.ckpt``: model, optimiser, scheduler, counters, history) are written after every
epoch and when the wall-clock budget runs out; ``resume=True`` continues from one. The weights file
``OUT`` holds the best model so far (validation loss), its configuration and the normalisation
constants (eq. 20-21) (:mod:`thermocal.nn.store`); it is written atomically.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from thermocal.camera.model import CameraModel
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.atomic import atomic_path
from thermocal.nn.data import (
    VAL_UNITS,
    Burst,
    BurstConfig,
    ScenePool,
    UnitCache,
    coverage_mask,
    make_burst,
)
from thermocal.nn.inputs import Normalisation, input_frames
from thermocal.nn.loss import kpn_loss
from thermocal.nn.model import KPN, ModelConfig
from thermocal.nn.store import check_calibrated, load_model, save_model

__all__ = [
    "TrainConfig",
    "TrainResult",
    "batch_tensors",
    "fit_normalisation",
    "train",
]


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings (defaults: Oz et al. §IV-D, with CPU-sized epochs).

    Attributes
    ----------
    batch : int
        Bursts per batch.
    steps_per_epoch : int
        Batches between validations.
    max_epochs : int
        Upper bound on epochs.
    lr : float
        Adam learning rate.
    lr_patience, stop_patience : int
        ``"plateau"``: epochs in a row without improvement tolerated before the learning rate is
        halved (PyTorch's ``patience``: halved at the next one) / after which the run stops.
    lr_schedule : str
        ``"plateau"`` (the paper's: halve on a validation plateau, stop early) or ``"step"``
        (halve at 50 % and 75 % of the budget, the first of ``max_steps``, ``max_minutes`` and
        ``max_epochs`` to run out; no early stop, the best validated weights are kept). A
        resumed run keeps its first call's schedule and budget for the rate (:func:`step_lr`).
    seed : int
        Seed of torch and of the data streams.
    val_bursts : int
        Size of the fixed validation set.
    max_minutes : float or None
        Wall-clock budget; when it runs out the run validates, saves and stops cleanly.
    max_steps : int or None
        Stop after this many batches (validating and saving first).
    threads : int
        torch intra-op threads.
    workers : int
        Data-generating processes (0: in the training process).
    device : str
        ``"cpu"``, ``"cuda"`` or ``"auto"`` (CUDA when PyTorch sees a GPU, else the CPU).
    """

    batch: int = 16
    steps_per_epoch: int = 100
    max_epochs: int = 60
    lr: float = 1e-4
    lr_patience: int = 3
    stop_patience: int = 8
    lr_schedule: str = "plateau"
    seed: int = 42
    val_bursts: int = 64
    max_minutes: float | None = None
    max_steps: int | None = None
    threads: int = 2
    workers: int = 1
    device: str = "cpu"


@dataclass(frozen=True)
class TrainResult:
    """What a run did: steps, epochs, best validation MAE (°C), wall time (s), why it stopped."""

    steps: int
    epochs: int
    best_val_mae_c: float
    best_val_loss: float
    wall_s: float
    stopped: str
    samples_per_s: float
    history: list[dict[str, float]]


# --------------------------------------------------------------------------------------------
# tensors
# --------------------------------------------------------------------------------------------
def batch_tensors(
    bursts: list[Burst], norm: Normalisation, *, frame_positions: bool = False,
    band_m: tuple[float, float] | None = None,
) -> tuple[torch.Tensor, ...]:
    """Stack bursts into ``frames (B,N,H,W)``, ``fpa (B,)``, ``valid (B,N,H,W)``,
    ``truth (B,1,H,W)`` (all normalised, float32), the loss mask ``(B,1,H,W)`` bool and the
    pivot pixels' sensor position ``R² (B,1,H,W)`` float32 (with ``frame_positions``, each
    frame's, ``(B,N,H,W)``: :attr:`ModelConfig.radial_frames`). Bursts made with
    :attr:`BurstConfig.calibrated` give their calibrated frames (:func:`input_frames`; ``band_m``
    for a ``radiance`` model)."""
    frames = np.stack([
        input_frames(b.frames if b.frames_c is None else b.frames_c, b.valid, norm,
                     calibrated=b.frames_c is not None, band_m=band_m)
        for b in bursts
    ])
    valid = np.stack([b.valid for b in bursts])
    truth = np.stack([norm.temp(b.truth_c) for b in bursts])[:, None]
    mask = np.stack([coverage_mask(b.valid) for b in bursts])[:, None]
    fpa = np.array([norm.fpa(b.fpa_c) for b in bursts])
    r2 = np.stack([b.r2_frames if frame_positions else b.r2[None] for b in bursts])
    return (
        torch.from_numpy(frames.astype(np.float32)),
        torch.from_numpy(fpa.astype(np.float32)),
        torch.from_numpy(valid),
        torch.from_numpy(truth.astype(np.float32)),
        torch.from_numpy(mask),
        torch.from_numpy(r2.astype(np.float32)),
    )


class _Stream(torch.utils.data.IterableDataset):
    """Batches ``start, start+1, …`` of the seeded training stream (burst ``i`` depends only on
    ``(seed, i)``), as tensors."""

    def __init__(
        self,
        pool_fn: Callable[[], ScenePool],
        cfg: BurstConfig,
        norm: Normalisation,
        *,
        seed: int,
        batch: int,
        start_batch: int,
        cameras: dict[int, CameraModel] | None,
        frame_positions: bool = False,
        band_m: tuple[float, float] | None = None,
    ) -> None:
        self.pool_fn, self.cfg, self.norm = pool_fn, cfg, norm
        self.seed, self.batch, self.start = seed, batch, start_batch
        self.cameras, self.frame_positions, self.band_m = cameras, frame_positions, band_m

    def __iter__(self) -> Iterator[tuple[torch.Tensor, ...]]:
        pool = self.pool_fn()
        units = _unit_cache(self.cfg, self.cameras)
        # W workers: worker w makes batches start + w, start + w + W, …; the DataLoader takes
        # one from each in turn, so the stream is the same whatever the number of workers.
        info = torch.utils.data.get_worker_info()
        k, stride = (self.start, 1) if info is None else (self.start + info.id, info.num_workers)
        while True:
            bursts = [
                make_burst(pool, self.cfg, rng=np.random.default_rng([self.seed, i]), units=units)
                for i in range(k * self.batch, (k + 1) * self.batch)
            ]
            yield batch_tensors(bursts, self.norm, frame_positions=self.frame_positions,
                                band_m=self.band_m)
            k += stride


def _unit_cache(cfg: BurstConfig, cameras: dict[int, CameraModel] | None) -> UnitCache:
    cache = UnitCache(cfg.preset, cfg.sensor_size)
    if cameras:
        cache._units.update(cameras)
    return cache


def fit_normalisation(
    pool: ScenePool,
    cfg: BurstConfig,
    *,
    seed: int,
    count: int = 64,
    cameras: dict[int, CameraModel] | None = None,
) -> Normalisation:
    """Eq. 20-21 constants from the training data.

    Counts: the 0.01 and 99.99 percentiles of ``count`` training bursts (rounded outward to
    100 counts; defective pixels are outliers, not range); temperatures: the clip range of the
    re-levelled training maps; FPA: the operating range of the data.
    """
    units = _unit_cache(cfg, cameras)
    vals = []
    for i in range(count):
        b = make_burst(pool, cfg, rng=np.random.default_rng([seed, 99991, i]), units=units)
        vals.append(b.raw.ravel()[::7])
    allv = np.concatenate(vals).astype(np.float64)
    lo, hi = np.percentile(allv, [0.01, 99.99])
    return Normalisation(
        temp_min_c=float(cfg.temp_clip_c[0]),
        temp_max_c=float(cfg.temp_clip_c[1]),
        counts_min=float(np.floor(lo / 100.0) * 100.0),
        counts_max=float(np.ceil(hi / 100.0) * 100.0),
        fpa_min_c=float(cfg.fpa_range_c[0]),
        fpa_max_c=float(cfg.fpa_range_c[1]),
    )


# --------------------------------------------------------------------------------------------
# training
# --------------------------------------------------------------------------------------------
def resolve_device(name: str) -> torch.device:
    """``"cpu"``, ``"cuda"`` (an error without a GPU) or ``"auto"`` (CUDA when there is one)."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name not in ("cpu", "cuda"):
        raise InvalidInputError(f"device must be cpu, cuda or auto, got {name!r}")
    if name == "cuda" and not torch.cuda.is_available():
        raise InvalidInputError("device cuda asked for, but PyTorch sees no GPU here")
    return torch.device(name)


def _seed_everything(seed: int, device: torch.device) -> None:
    torch.manual_seed(seed)
    np.random.seed(seed)  # noqa: NPY002 - only for third-party code that reads the global state
    if device.type == "cuda":
        # cuBLAS is deterministic only with a fixed workspace; a CUDA op without a deterministic
        # kernel warns instead of stopping the run (CPU runs stay strictly deterministic)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
        torch.use_deterministic_algorithms(True, warn_only=True)
    else:
        torch.use_deterministic_algorithms(True)


def validate(
    model: KPN, val: list[tuple[torch.Tensor, ...]], norm: Normalisation
) -> tuple[float, float, float]:
    """Mean loss, MAE and bias-free MAE (°C, over the coverage masks) on validation batches.

    The bias-free MAE removes each burst's mean error first: what is left once the camera
    unit's unknown global offset is set aside (the non-uniformity and noise that remain).
    """
    model.eval()
    losses, abs_sum, rel_sum, n_pix = [], 0.0, 0.0, 0
    span = norm.temp_max_c - norm.temp_min_c
    with torch.no_grad():
        device = next(model.parameters()).device
        for batch in val:
            frames, fpa, valid, truth, mask, r2 = (t.to(device) for t in batch)
            est = model(frames, fpa, valid, r2=r2)
            losses.append(float(kpn_loss(est, truth, mask)))
            m = mask.to(est.dtype)
            err = (est - truth) * m
            bias = err.sum(dim=(1, 2, 3), keepdim=True) / m.sum(dim=(1, 2, 3), keepdim=True)
            abs_sum += float(err.abs().sum()) * span
            rel_sum += float(((err - bias) * m).abs().sum()) * span
            n_pix += int(mask.sum())
    model.train()
    return float(np.mean(losses)), abs_sum / max(n_pix, 1), rel_sum / max(n_pix, 1)


def step_lr(cfg: TrainConfig, step: int, elapsed_s: float) -> float:
    """The learning rate of the ``"step"`` schedule after ``step`` batches and ``elapsed_s``
    seconds of training: ``lr``, halved once half of the budget is spent and again at three
    quarters (the budget: the first of ``max_steps``, ``max_minutes`` and
    ``max_epochs · steps_per_epoch`` to run out)."""
    spent = step / (cfg.max_epochs * cfg.steps_per_epoch)
    if cfg.max_steps is not None:
        spent = max(spent, step / cfg.max_steps)
    if cfg.max_minutes is not None:
        spent = max(spent, elapsed_s / (60.0 * cfg.max_minutes))
    return cfg.lr * (0.25 if spent >= 0.75 else 0.5 if spent >= 0.5 else 1.0)


def train(
    out: str | os.PathLike[str],
    model_cfg: ModelConfig,
    burst_cfg: BurstConfig,
    train_cfg: TrainConfig = TrainConfig(),
    *,
    resume: bool = False,
    pool_fn: Callable[[], ScenePool] | None = None,
    val_pool_fn: Callable[[], ScenePool] | None = None,
    cameras: dict[int, CameraModel] | None = None,
    val_units: tuple[int, ...] = VAL_UNITS,
    log: Callable[[str], None] = print,
    progress: bool = True,
    meta: dict[str, Any] | None = None,
    init: str | os.PathLike[str] | None = None,
) -> TrainResult:
    """Train a KPN and write the best weights to ``out`` (and a checkpoint to ``out.ckpt``).

    Parameters
    ----------
    out : path
        The weights file (``.pt``).
    model_cfg, burst_cfg, train_cfg
        Network sizes, training data, optimisation.
    resume : bool
        Continue from ``out.ckpt`` (its configurations replace the ones given).
    pool_fn, val_pool_fn : callables returning ScenePool, optional
        Training / validation scene pools (default :meth:`ScenePool.training` with different
        seeds; both exclude the evaluation scenes).
    cameras : dict of int to CameraModel, optional
        Camera models by unit number, replacing the preset's units (the real-camera path:
        a model fitted on a chamber file). With them, ``val_units`` must be among their keys.
    val_units : tuple of int
        Units of the validation set (never the training units).
    log : callable
        Receives one line per epoch.
    init : path, optional
        Start from the weights and the normalisation of this weights file (fine-tuning, e.g. on
        a wider scene range or another camera model); its configuration must be ``model_cfg``.
    """
    t0 = time.monotonic()
    out = Path(out)
    if out.suffix != ".pt":
        raise InvalidInputError(f"{out}: the weights file must end in .pt")
    if not out.parent.is_dir():
        raise InvalidInputError(f"{out.parent}: output folder does not exist")
    ckpt_path = out.with_suffix(".ckpt")
    state: dict[str, Any] | None = None
    if resume:
        if not ckpt_path.is_file():
            raise FileFormatError(f"{ckpt_path}: no checkpoint to resume from")
        try:
            state = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        except Exception:
            raise FileFormatError(f"{ckpt_path}: damaged checkpoint") from None
        if state.get("cameras") and not cameras:
            raise InvalidInputError(
                f"{ckpt_path}: this run was trained from a chamber file: resume it with --chamber"
            )
        model_cfg = ModelConfig(**state["model_cfg"])
        burst_cfg = BurstConfig(
            **{k: tuple(v) if isinstance(v, list) else v for k, v in state["burst_cfg"].items()}
        )
        # the budget (epochs, minutes, steps) is the new call's; everything else the checkpoint's
        train_cfg = TrainConfig(
            **{
                **state["train_cfg"],
                "max_minutes": train_cfg.max_minutes,
                "max_steps": train_cfg.max_steps,
                "max_epochs": train_cfg.max_epochs,
                "device": train_cfg.device,
                "workers": train_cfg.workers,
                "threads": train_cfg.threads,
            }
        )
    if train_cfg.lr_schedule not in ("plateau", "step"):
        raise InvalidInputError(f"lr_schedule must be plateau or step, got {train_cfg.lr_schedule}")
    # the step schedule's budget is the first call's: a resumed run continues its schedule (the
    # new call's budget only says when this call stops)
    schedule_cfg = (
        TrainConfig(**state.get("schedule_cfg", state["train_cfg"])) if state else train_cfg
    )
    if model_cfg.n_frames != burst_cfg.n_frames:
        raise InvalidInputError(
            f"model has N = {model_cfg.n_frames} but the data N = {burst_cfg.n_frames}"
        )
    if cameras is None and set(val_units) & set(burst_cfg.units):
        raise InvalidInputError("validation units must not be training units")
    check_calibrated(model_cfg, burst_cfg)  # before training, not only at the first save
    band_m = model_cfg.band_m if model_cfg.radiance else None  # the calibrated input's units

    device = resolve_device(train_cfg.device)
    torch.set_num_threads(train_cfg.threads)
    _seed_everything(train_cfg.seed, device)
    pool_fn = pool_fn or (lambda: ScenePool.training(seed=train_cfg.seed))
    val_pool_fn = val_pool_fn or (
        lambda: ScenePool.training(seed=train_cfg.seed + 1000, n_procedural=9)
    )
    pool = pool_fn()
    init_model = None
    if init is not None and state:
        raise InvalidInputError("--init starts a new run and --resume continues OUT.ckpt: give one")
    if init is not None:
        init_model, norm, _ = load_model(init)
        if init_model.config != model_cfg:
            differ = [k for k, v in init_model.config.to_dict().items()
                      if model_cfg.to_dict()[k] != v]
            raise InvalidInputError(
                f"{init}: its network differs from the one to train in "
                f"{', '.join(f'{k} ({getattr(init_model.config, k)} there)' for k in differ)}: "
                "give the same options (e.g. --no-calibrated for a model on raw counts)"
            )
        fresh = fit_normalisation(pool, burst_cfg, seed=train_cfg.seed, cameras=cameras)
        counts_out = not model_cfg.calibrated and (  # a calibrated network never sees counts
            fresh.counts_min < norm.counts_min - 500 or fresh.counts_max > norm.counts_max + 500)
        if counts_out or fresh.fpa_min_c < norm.fpa_min_c or fresh.fpa_max_c > norm.fpa_max_c:
            log(f"warning: the new data (counts {fresh.counts_min:.0f}…{fresh.counts_max:.0f}, "
                f"FPA {fresh.fpa_min_c:g}…{fresh.fpa_max_c:g} °C) reach outside the range "
                f"{init} was normalised for (counts {norm.counts_min:.0f}…"
                f"{norm.counts_max:.0f}, FPA {norm.fpa_min_c:g}…{norm.fpa_max_c:g} °C)")
    elif state:
        norm = Normalisation(**state["norm"])
    else:
        norm = fit_normalisation(pool, burst_cfg, seed=train_cfg.seed, cameras=cameras)

    val_cfg = BurstConfig(
        **{**asdict(burst_cfg), "units": tuple(val_units), "redraw_pixel_fpn": False,
           "walk_frames": None, "nominal_units": burst_cfg.nominal_of}
    )
    val_pool = val_pool_fn()
    val_units_cache = _unit_cache(val_cfg, cameras)
    val_bursts = [
        make_burst(
            val_pool,
            val_cfg,
            rng=np.random.default_rng([train_cfg.seed, 7, i]),
            units=val_units_cache,
        )
        for i in range(train_cfg.val_bursts)
    ]
    val = [  # on the training device once, not at every validation
        tuple(t.to(device) for t in batch_tensors(val_bursts[i : i + train_cfg.batch], norm,
                                                  frame_positions=model_cfg.radial_frames,
                                                  band_m=band_m))
        for i in range(0, len(val_bursts), train_cfg.batch)
    ]

    model = KPN(model_cfg, temp_range_c=(norm.temp_min_c, norm.temp_max_c),
                train_crop=burst_cfg.crop)
    if model_cfg.calibrated:  # what its input goes through, saved with it
        model.nominal = _unit_cache(burst_cfg, cameras).nominal(burst_cfg.nominal_of)
    if init_model is not None:
        model.load_state_dict(init_model.state_dict())
    model = model.to(device)
    opt = torch.optim.Adam(model.parameters(), lr=train_cfg.lr)
    sched = torch.optim.lr_scheduler.ReduceLROnPlateau(
        opt, mode="min", factor=0.5, patience=train_cfg.lr_patience
    )
    step, epoch, best, best_mae, bad = 0, 0, math.inf, math.inf, 0
    history: list[dict[str, float]] = []
    elapsed_before = 0.0
    if state:
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["opt"])
        sched.load_state_dict(state["sched"])
        step, epoch = state["step"], state["epoch"]
        best, best_mae, bad = state["best"], state["best_mae"], state["bad"]
        history = state["history"]
        elapsed_before = state.get("elapsed_s", 0.0)
        torch.set_rng_state(state["torch_rng"])
    if init_model is not None:
        # a fine-tune keeps what it starts from unless an epoch beats it on the validation set
        best, best_mae, _ = validate(model, val, norm)
        log(f"start from {init}: val_loss {best:.5f} val_mae {best_mae:.3f} C")
        save_model(out, model, norm, burst_cfg, {
            **(meta or {}), "val_mae_c": best_mae, "val_loss": best, "step": 0, "epoch": 0,
            "val_units": list(val_units)})
    elif not state or not out.is_file():
        save_model(out, model, norm, burst_cfg, {**(meta or {}), "val_mae_c": None})

    def checkpoint() -> None:
        payload = {
            "model": model.state_dict(),
            "opt": opt.state_dict(),
            "sched": sched.state_dict(),
            "step": step,
            "epoch": epoch,
            "best": best,
            "best_mae": best_mae,
            "bad": bad,
            "history": history,
            "norm": norm.to_dict(),
            "model_cfg": model_cfg.to_dict(),
            "burst_cfg": burst_cfg.to_dict(),
            "train_cfg": asdict(train_cfg),
            "schedule_cfg": asdict(schedule_cfg),
            "torch_rng": torch.get_rng_state(),
            "elapsed_s": elapsed_before + time.monotonic() - t0,
            "cameras": sorted(cameras) if cameras else None,  # a chamber run resumes with it
        }
        with atomic_path(ckpt_path) as tmp:
            torch.save(payload, tmp)

    stream = _Stream(
        pool_fn,
        burst_cfg,
        norm,
        seed=train_cfg.seed,
        batch=train_cfg.batch,
        start_batch=step,
        cameras=cameras,
        frame_positions=model_cfg.radial_frames,
        band_m=band_m,
    )
    loader = torch.utils.data.DataLoader(
        stream,
        batch_size=None,
        num_workers=train_cfg.workers,
        prefetch_factor=4 if train_cfg.workers else None,
        persistent_workers=False,
        pin_memory=device.type == "cuda",
    )
    budget_s = None if train_cfg.max_minutes is None else 60.0 * train_cfg.max_minutes
    stopped = "max_epochs"
    samples, t_train = 0, 0.0
    it = iter(loader)
    bar_ctx = _bar(progress)
    with bar_ctx as bar:
        task = (
            bar.add_task(
                "training", total=train_cfg.max_epochs * train_cfg.steps_per_epoch, completed=step
            )
            if bar
            else None
        )
        model.train()
        while epoch < train_cfg.max_epochs:
            run_loss, n_run = 0.0, 0
            out_of_time = False
            for _ in range(train_cfg.steps_per_epoch):
                ts = time.monotonic()
                if train_cfg.lr_schedule == "step":
                    for g in opt.param_groups:
                        g["lr"] = step_lr(
                            schedule_cfg, step, elapsed_before + time.monotonic() - t0
                        )
                frames, fpa, valid, truth, mask, r2 = (
                    t.to(device, non_blocking=True) for t in next(it)
                )
                opt.zero_grad(set_to_none=True)
                loss = kpn_loss(model(frames, fpa, valid, r2=r2), truth, mask)
                loss.backward()
                opt.step()
                t_train += time.monotonic() - ts
                samples += frames.shape[0]
                step += 1
                run_loss += float(loss.detach())
                n_run += 1
                if bar:
                    bar.update(
                        task,
                        advance=1,
                        description=(
                            f"epoch {epoch + 1} loss {run_loss / n_run:.4f} "
                            f"val MAE {best_mae:.2f} °C"
                        ),
                    )
                if budget_s is not None and time.monotonic() - t0 > budget_s:
                    out_of_time = True
                    break
                if train_cfg.max_steps is not None and step >= train_cfg.max_steps:
                    break
            epoch += 1
            val_loss, val_mae, val_rel = validate(model, val, norm)
            if train_cfg.lr_schedule == "plateau":
                sched.step(val_loss)
            lr = opt.param_groups[0]["lr"]
            history.append(
                {
                    "epoch": epoch,
                    "step": step,
                    "train_loss": run_loss / max(n_run, 1),
                    "val_loss": val_loss,
                    "val_mae_c": val_mae,
                    "val_mae_bias_free_c": val_rel,
                    "lr": lr,
                    "elapsed_s": elapsed_before + time.monotonic() - t0,
                }
            )
            if val_loss < best:
                best, best_mae, bad = val_loss, val_mae, 0
                save_model(
                    out,
                    model,
                    norm,
                    burst_cfg,
                    {
                        **(meta or {}),
                        "val_mae_c": val_mae,
                        "val_loss": val_loss,
                        "step": step,
                        "epoch": epoch,
                        "val_units": list(val_units),
                    },
                )
            else:
                bad += 1
            log(
                f"epoch {epoch} step {step} train_loss {run_loss / max(n_run, 1):.5f} "
                f"val_loss {val_loss:.5f} val_mae {val_mae:.3f} C (bias-free {val_rel:.3f} C) "
                f"best {best_mae:.3f} C "
                f"lr {lr:.2e} elapsed {elapsed_before + time.monotonic() - t0:.0f} s "
                f"train {samples / max(t_train, 1e-9):.1f} samples/s"
            )
            checkpoint()
            if out_of_time:
                stopped = "max_minutes"
                break
            if train_cfg.max_steps is not None and step >= train_cfg.max_steps:
                stopped = "max_steps"
                break
            if bad >= train_cfg.stop_patience and train_cfg.lr_schedule == "plateau":
                stopped = "early_stop"
                break
    del it, loader
    return TrainResult(
        steps=step,
        epochs=epoch,
        best_val_mae_c=best_mae,
        best_val_loss=best,
        wall_s=elapsed_before + time.monotonic() - t0,
        stopped=stopped,
        samples_per_s=samples / max(t_train, 1e-9),
        history=history,
    )


class _NoBar:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def _bar(enabled: bool):
    if not enabled:
        return _NoBar()
    from thermocal.progress import progress_bar

    return progress_bar()
