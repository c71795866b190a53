"""Training the KPN on synthetic bursts (Oz et al. §IV-D).

Adam at 1e-4; the learning rate is halved after 3 epochs without improvement of the validation
loss and training stops after 8; orthogonal initialisation scaled by 0.1; seed 42 with
deterministic algorithms. An *epoch* here is ``steps_per_epoch`` batches (the paper's epochs of
~800 batches of 16 are far too long for 2 CPU cores), each followed by a validation pass on a fixed
set of bursts made once (noise and FPN fixed) from cameras units that are never trained on.

:class:`Trainer` holds a run: :meth:`~Trainer.step` (one batch), :meth:`~Trainer.epoch`,
:meth:`~Trainer.validate`, :meth:`~Trainer.checkpoint` / :meth:`Trainer.resume`,
:meth:`~Trainer.save` and :meth:`~Trainer.run` (the loop with its budget, learning-rate schedule
and stopping rule); :func:`train` is a run from start to end. The pieces a run is made of
(:func:`seed_everything`, :class:`BurstStream`, :func:`burst_loader`, :func:`train_step`,
:func:`step_lr`, :func:`fit_normalisation`) serve other loops too (``benchmarks/kpn_fig7.py``
trains several networks side by side on one stream).

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

from thermocal._validate import check_output_file, check_suffix
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
    "BurstStream",
    "TrainConfig",
    "TrainResult",
    "Trainer",
    "batch_tensors",
    "burst_loader",
    "fit_normalisation",
    "resolve_device",
    "seed_everything",
    "step_lr",
    "train",
    "train_step",
    "validate",
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


class BurstStream(torch.utils.data.IterableDataset):
    """Batches ``start_batch, start_batch + 1, …`` of the seeded training stream (burst ``i``
    depends only on ``(seed, i)``), as the tensors of :func:`batch_tensors`; the same batches in
    the same order whatever the number of :func:`burst_loader` workers."""

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
    return UnitCache(cfg.preset, cfg.sensor_size, cameras)


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
# pieces of a training loop
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


def seed_everything(seed: int, device: torch.device) -> None:
    """Seed torch (and numpy's global state) and make torch deterministic: strictly on the CPU;
    on CUDA a fixed cuBLAS workspace, and ops without a deterministic kernel only warn."""
    torch.manual_seed(seed)
    np.random.seed(seed)  # noqa: NPY002 - only for third-party code that reads the global state
    if device.type == "cuda":
        # cuBLAS is deterministic only with a fixed workspace; a CUDA op without a deterministic
        # kernel warns instead of stopping the run (CPU runs stay strictly deterministic)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
        torch.use_deterministic_algorithms(True, warn_only=True)
    else:
        torch.use_deterministic_algorithms(True)


def burst_loader(
    stream: BurstStream, workers: int, device: torch.device
) -> torch.utils.data.DataLoader:
    """The DataLoader over a :class:`BurstStream`: ``workers`` processes (0: this one), each
    ahead by up to 4 batches; pinned memory for a GPU."""
    return torch.utils.data.DataLoader(
        stream,
        batch_size=None,
        num_workers=workers,
        prefetch_factor=4 if workers else None,
        persistent_workers=False,
        pin_memory=device.type == "cuda",
    )


def train_step(
    model: KPN, opt: torch.optim.Optimizer, batch: tuple[torch.Tensor, ...],
    *, lr: float | None = None,
) -> float:
    """One optimisation step of ``model`` on ``batch`` (the tensors of :func:`batch_tensors`, on
    the model's device) with the loss of eq. 12; ``lr`` first sets the optimiser's rate.
    Returns the batch's loss."""
    if lr is not None:
        for g in opt.param_groups:
            g["lr"] = lr
    frames, fpa, valid, truth, mask, r2 = batch
    opt.zero_grad(set_to_none=True)
    loss = kpn_loss(model(frames, fpa, valid, r2=r2), truth, mask)
    loss.backward()
    opt.step()
    return float(loss.detach())


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


# --------------------------------------------------------------------------------------------
# a training run
# --------------------------------------------------------------------------------------------
#: What a resumed run takes from its own call, not from the checkpoint: the budget and the machine.
CALL_FIELDS = ("max_minutes", "max_steps", "max_epochs", "device", "workers", "threads")


class Trainer:
    """One training run of a KPN: its data, network, optimiser, counters and files.

    Making one checks the configurations, picks the device, seeds everything (:func:`train`'s
    determinism), builds the normalisation (fitted on the training data, or ``init``'s), the fixed
    validation set and the network (``init``'s weights, or a checkpoint's), and writes ``out``
    (``init``'s weights and scores, or the untrained network's) unless a resumed run has one.
    The training stream starts at the first :meth:`epoch` (or :meth:`next_batch`).

    Parameters are :func:`train`'s (``state``: a checkpoint's contents, as
    :meth:`resume` reads them).

    Attributes
    ----------
    out, ckpt_path : Path
        The weights file and the checkpoint (``OUT.ckpt``) the run writes.
    model_cfg, burst_cfg, train_cfg : ModelConfig, BurstConfig, TrainConfig
        The run's configurations (a resumed run's: the checkpoint's, with this call's budget).
    schedule_cfg : TrainConfig
        The budget the ``"step"`` schedule's rate follows: the first call's.
    device : torch.device
        Where the network trains.
    model, opt, sched
        The network (on ``device``), its Adam optimiser and the plateau scheduler.
    norm : Normalisation
        Eq. 20-21 constants of the run.
    val : list of tuple of tensors
        The validation batches, on ``device``.
    steps, epochs : int
        Batches and epochs done (since the run's start, resumed runs included).
    best_loss, best_mae : float
        The best validation loss so far and its MAE (°C).
    bad_epochs : int
        Epochs in a row without a better validation loss.
    history : list of dict
        One row per epoch (:meth:`record`).
    """

    def __init__(
        self,
        out: str | os.PathLike[str],
        model_cfg: ModelConfig,
        burst_cfg: BurstConfig,
        train_cfg: TrainConfig = TrainConfig(),
        *,
        pool_fn: Callable[[], ScenePool] | None = None,
        val_pool_fn: Callable[[], ScenePool] | None = None,
        cameras: dict[int, CameraModel] | None = None,
        val_units: tuple[int, ...] = VAL_UNITS,
        log: Callable[[str], None] = print,
        progress: bool = True,
        meta: dict[str, Any] | None = None,
        init: str | os.PathLike[str] | None = None,
        state: dict[str, Any] | None = None,
    ) -> None:
        self.t0 = time.monotonic()
        self.out = _weights_path(out)
        self.ckpt_path = self.out.with_suffix(".ckpt")
        self.model_cfg, self.burst_cfg, self.train_cfg = model_cfg, burst_cfg, train_cfg
        self.cameras, self.val_units = cameras, val_units
        self.log, self.progress, self.meta = log, progress, meta or {}
        _check_run(model_cfg, burst_cfg, train_cfg, cameras, val_units)
        # the step schedule's budget is the first call's: a resumed run continues its schedule
        # (the new call's budget only says when this call stops)
        self.schedule_cfg = (
            TrainConfig(**state.get("schedule_cfg", state["train_cfg"])) if state else train_cfg
        )
        self.band_m = model_cfg.band_m if model_cfg.radiance else None  # the calibrated input's
        self.device = resolve_device(train_cfg.device)
        torch.set_num_threads(train_cfg.threads)
        seed_everything(train_cfg.seed, self.device)
        seed = train_cfg.seed
        self.pool_fn = pool_fn or (lambda: ScenePool.training(seed=seed))
        val_pool_fn = val_pool_fn or (lambda: ScenePool.training(seed=seed + 1000, n_procedural=9))
        if init is not None and state:
            raise InvalidInputError(
                "--init starts a new run and --resume continues OUT.ckpt: give one"
            )
        init_model = self._normalise(self.pool_fn(), init, state)
        self.val = self._validation_set(val_pool_fn())
        self._build(init_model, state)
        if init is not None:  # a fine-tune keeps what it starts from unless an epoch beats it
            self.best_loss, self.best_mae, _ = self.validate()
            log(f"start from {init}: val_loss {self.best_loss:.5f} val_mae {self.best_mae:.3f} C")
            self.save(val=(self.best_loss, self.best_mae))
        elif not state or not self.out.is_file():
            self.save()
        self.samples, self.train_s = 0, 0.0  # this call's, for its samples/s
        self._loader: torch.utils.data.DataLoader | None = None
        self._batches: Iterator[tuple[torch.Tensor, ...]] | None = None
        self._bar: Any = None
        self._task: Any = None

    @classmethod
    def resume(
        cls,
        out: str | os.PathLike[str],
        train_cfg: TrainConfig = TrainConfig(),
        *,
        ckpt: str | os.PathLike[str] | None = None,
        **kwargs: Any,
    ) -> Trainer:
        """Continue the run of the checkpoint ``ckpt`` (default ``OUT.ckpt``): its
        configurations, weights, optimiser, counters, history and torch random state;
        ``train_cfg`` gives only the budget and the machine (:data:`CALL_FIELDS`). ``kwargs``:
        the constructor's (``cameras`` again for a run on a chamber file's camera model)."""
        out = _weights_path(out)
        ckpt_path = out.with_suffix(".ckpt") if ckpt is None else Path(ckpt)
        state = _read_checkpoint(ckpt_path, kwargs.get("cameras"))
        model_cfg = ModelConfig(**state["model_cfg"])
        burst_cfg = BurstConfig(
            **{k: tuple(v) if isinstance(v, list) else v for k, v in state["burst_cfg"].items()}
        )
        call = {k: getattr(train_cfg, k) for k in CALL_FIELDS}
        train_cfg = TrainConfig(**{**state["train_cfg"], **call})
        return cls(out, model_cfg, burst_cfg, train_cfg, state=state, **kwargs)

    # construction -------------------------------------------------------------------------
    def _normalise(
        self, pool: ScenePool, init: str | os.PathLike[str] | None, state: dict[str, Any] | None
    ) -> KPN | None:
        """Set :attr:`norm` (``init``'s, the checkpoint's or fitted on ``pool``); return the
        ``init`` model."""
        cfg, seed = self.burst_cfg, self.train_cfg.seed
        if init is None:
            self.norm = (Normalisation(**state["norm"]) if state else
                         fit_normalisation(pool, cfg, seed=seed, cameras=self.cameras))
            return None
        init_model, self.norm, _ = load_model(init)
        _check_same_network(init, init_model.config, self.model_cfg)
        fresh = fit_normalisation(pool, cfg, seed=seed, cameras=self.cameras)
        norm = self.norm
        counts_out = not self.model_cfg.calibrated and (  # a calibrated network never sees counts
            fresh.counts_min < norm.counts_min - 500 or fresh.counts_max > norm.counts_max + 500)
        if counts_out or fresh.fpa_min_c < norm.fpa_min_c or fresh.fpa_max_c > norm.fpa_max_c:
            self.log(f"warning: the new data (counts {fresh.counts_min:.0f}…{fresh.counts_max:.0f}"
                     f", FPA {fresh.fpa_min_c:g}…{fresh.fpa_max_c:g} °C) reach outside the range "
                     f"{init} was normalised for (counts {norm.counts_min:.0f}…"
                     f"{norm.counts_max:.0f}, FPA {norm.fpa_min_c:g}…{norm.fpa_max_c:g} °C)")
        return init_model

    def _validation_set(self, val_pool: ScenePool) -> list[tuple[torch.Tensor, ...]]:
        """The fixed validation batches (units ``val_units``, their own pixel FPN, no longer
        walks), made once and put on the device."""
        cfg, tc = self.burst_cfg, self.train_cfg
        val_cfg = BurstConfig(
            **{**asdict(cfg), "units": tuple(self.val_units), "redraw_pixel_fpn": False,
               "walk_frames": None, "nominal_units": cfg.nominal_of}
        )
        units = _unit_cache(val_cfg, self.cameras)
        bursts = [
            make_burst(val_pool, val_cfg, rng=np.random.default_rng([tc.seed, 7, i]), units=units)
            for i in range(tc.val_bursts)
        ]
        return [  # on the training device once, not at every validation
            tuple(t.to(self.device) for t in batch_tensors(
                bursts[i : i + tc.batch], self.norm, frame_positions=self.model_cfg.radial_frames,
                band_m=self.band_m))
            for i in range(0, len(bursts), tc.batch)
        ]

    def _build(self, init_model: KPN | None, state: dict[str, Any] | None) -> None:
        """The network, optimiser, scheduler and counters: new, ``init``'s or the checkpoint's."""
        mc, bc, norm = self.model_cfg, self.burst_cfg, self.norm
        model = KPN(mc, temp_range_c=(norm.temp_min_c, norm.temp_max_c), train_crop=bc.crop)
        if mc.calibrated:  # what its input goes through, saved with it
            model.nominal = _unit_cache(bc, self.cameras).nominal(bc.nominal_of)
        if init_model is not None:
            model.load_state_dict(init_model.state_dict())
        self.model = model.to(self.device)
        self.opt = torch.optim.Adam(self.model.parameters(), lr=self.train_cfg.lr)
        self.sched = torch.optim.lr_scheduler.ReduceLROnPlateau(
            self.opt, mode="min", factor=0.5, patience=self.train_cfg.lr_patience
        )
        self.steps, self.epochs, self.bad_epochs = 0, 0, 0
        self.best_loss, self.best_mae = math.inf, math.inf
        self.history: list[dict[str, float]] = []
        self.elapsed_before = 0.0  # the earlier calls' time, for a resumed run
        if state:
            self.model.load_state_dict(state["model"])
            self.opt.load_state_dict(state["opt"])
            self.sched.load_state_dict(state["sched"])
            self.steps, self.epochs = state["step"], state["epoch"]
            self.best_loss, self.best_mae = state["best"], state["best_mae"]
            self.bad_epochs, self.history = state["bad"], state["history"]
            self.elapsed_before = state.get("elapsed_s", 0.0)
            torch.set_rng_state(state["torch_rng"])

    # training ------------------------------------------------------------------------------
    def elapsed(self) -> float:
        """Seconds of training of the whole run (earlier calls of a resumed run included)."""
        return self.elapsed_before + time.monotonic() - self.t0

    def next_batch(self) -> tuple[torch.Tensor, ...]:
        """The next batch of the training stream (on the CPU); the stream starts, at the first
        call, at the batch after the last step done (:class:`BurstStream`)."""
        if self._batches is None:
            tc = self.train_cfg
            stream = BurstStream(
                self.pool_fn, self.burst_cfg, self.norm, seed=tc.seed, batch=tc.batch,
                start_batch=self.steps, cameras=self.cameras,
                frame_positions=self.model_cfg.radial_frames, band_m=self.band_m,
            )
            self._loader = burst_loader(stream, tc.workers, self.device)
            self._batches = iter(self._loader)
        return next(self._batches)

    def step(self, batch: tuple[torch.Tensor, ...]) -> float:
        """One optimisation step on ``batch`` (:func:`batch_tensors`' tensors), at the rate of
        the ``"step"`` schedule where that is the run's; returns its loss."""
        lr = None
        if self.train_cfg.lr_schedule == "step":
            lr = step_lr(self.schedule_cfg, self.steps, self.elapsed())
        batch = tuple(t.to(self.device, non_blocking=True) for t in batch)
        loss = train_step(self.model, self.opt, batch, lr=lr)
        self.samples += batch[0].shape[0]
        self.steps += 1
        return loss

    def out_of_time(self) -> bool:
        """Whether this call's ``max_minutes`` have run out."""
        budget = self.train_cfg.max_minutes
        return budget is not None and time.monotonic() - self.t0 > 60.0 * budget

    def steps_done(self) -> bool:
        """Whether ``max_steps`` batches are done."""
        return self.train_cfg.max_steps is not None and self.steps >= self.train_cfg.max_steps

    def epoch(self) -> dict[str, Any]:
        """``steps_per_epoch`` steps on the training stream (fewer where the time or
        ``max_steps`` runs out). Returns ``{"epoch", "step", "train_loss", "steps",
        "out_of_time"}``: the epochs and steps done after it, its mean loss, its steps and
        whether the time ran out."""
        self.model.train()
        loss_sum, n, out_of_time = 0.0, 0, False
        for _ in range(self.train_cfg.steps_per_epoch):
            ts = time.monotonic()
            loss = self.step(self.next_batch())
            self.train_s += time.monotonic() - ts
            loss_sum += loss
            n += 1
            if self._bar:
                self._bar.update(self._task, advance=1, description=(
                    f"epoch {self.epochs + 1} loss {loss_sum / n:.4f} "
                    f"val MAE {self.best_mae:.2f} °C"))
            if self.out_of_time():
                out_of_time = True
                break
            if self.steps_done():
                break
        self.epochs += 1
        return {"epoch": self.epochs, "step": self.steps, "train_loss": loss_sum / max(n, 1),
                "steps": n, "out_of_time": out_of_time}

    def validate(self) -> tuple[float, float, float]:
        """Loss, MAE and bias-free MAE (°C) on the validation set (:func:`validate`)."""
        return validate(self.model, self.val, self.norm)

    def samples_per_s(self) -> float:
        """Training speed of this call (bursts per second of steps, data included)."""
        return self.samples / max(self.train_s, 1e-9)

    def record(self, stats: dict[str, Any], val: tuple[float, float, float]) -> dict[str, float]:
        """What follows an epoch's validation: the plateau schedule's step, a history row, the
        weights file where the validation loss is the best so far, the log line. ``stats``:
        :meth:`epoch`'s; ``val``: :meth:`validate`'s. Returns the history row."""
        val_loss, val_mae, val_rel = val
        if self.train_cfg.lr_schedule == "plateau":
            self.sched.step(val_loss)
        lr = self.opt.param_groups[0]["lr"]
        row = {"epoch": self.epochs, "step": self.steps, "train_loss": stats["train_loss"],
               "val_loss": val_loss, "val_mae_c": val_mae, "val_mae_bias_free_c": val_rel,
               "lr": lr, "elapsed_s": self.elapsed()}
        self.history.append(row)
        if val_loss < self.best_loss:
            self.best_loss, self.best_mae, self.bad_epochs = val_loss, val_mae, 0
            self.save(val=val)
        else:
            self.bad_epochs += 1
        self.log(
            f"epoch {self.epochs} step {self.steps} train_loss {stats['train_loss']:.5f} "
            f"val_loss {val_loss:.5f} val_mae {val_mae:.3f} C (bias-free {val_rel:.3f} C) "
            f"best {self.best_mae:.3f} C "
            f"lr {lr:.2e} elapsed {self.elapsed():.0f} s "
            f"train {self.samples_per_s():.1f} samples/s"
        )
        return row

    def stop_reason(self, stats: dict[str, Any]) -> str | None:
        """Why the run stops after the epoch of ``stats`` (``"max_minutes"``, ``"max_steps"``,
        ``"early_stop"``), or None."""
        if stats["out_of_time"]:
            return "max_minutes"
        if self.steps_done():
            return "max_steps"
        tc = self.train_cfg
        if self.bad_epochs >= tc.stop_patience and tc.lr_schedule == "plateau":
            return "early_stop"
        return None

    def run(self) -> TrainResult:
        """Epochs, each validated, recorded and checkpointed, until ``max_epochs``, the budget
        or (the plateau schedule) the early stop."""
        tc, stopped = self.train_cfg, None
        with _bar(self.progress) as bar:
            self._bar = bar
            self._task = bar.add_task(
                "training", total=tc.max_epochs * tc.steps_per_epoch, completed=self.steps
            ) if bar else None
            while stopped is None and self.epochs < tc.max_epochs:
                stats = self.epoch()
                self.record(stats, self.validate())
                self.checkpoint()
                stopped = self.stop_reason(stats)
            self._bar = self._task = None
        self.close()
        return self.result(stopped or "max_epochs")

    def result(self, stopped: str) -> TrainResult:
        """The run so far as a :class:`TrainResult`."""
        return TrainResult(
            steps=self.steps,
            epochs=self.epochs,
            best_val_mae_c=self.best_mae,
            best_val_loss=self.best_loss,
            wall_s=self.elapsed(),
            stopped=stopped,
            samples_per_s=self.samples_per_s(),
            history=self.history,
        )

    def close(self) -> None:
        """Stop the data workers (a later :meth:`next_batch` starts them again, at the next
        batch of the stream)."""
        self._batches = self._loader = None

    # files ---------------------------------------------------------------------------------
    def save(
        self, path: str | os.PathLike[str] | None = None,
        val: tuple[float, ...] | None = None,
    ) -> Path:
        """Write the weights file (``out`` unless ``path``) with the run's normalisation, data
        configuration and ``meta``; ``val`` (:meth:`validate`'s loss and MAE) adds the scores,
        the step, the epoch and the validation units to the metadata."""
        scores: dict[str, Any] = {"val_mae_c": None}
        if val is not None:
            scores = {"val_mae_c": val[1], "val_loss": val[0], "step": self.steps,
                      "epoch": self.epochs, "val_units": list(self.val_units)}
        return save_model(self.out if path is None else path, self.model, self.norm,
                          self.burst_cfg, {**self.meta, **scores})

    def checkpoint(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write the checkpoint (``OUT.ckpt`` unless ``path``) that :meth:`resume` continues
        from, atomically."""
        payload = {
            "model": self.model.state_dict(),
            "opt": self.opt.state_dict(),
            "sched": self.sched.state_dict(),
            "step": self.steps,
            "epoch": self.epochs,
            "best": self.best_loss,
            "best_mae": self.best_mae,
            "bad": self.bad_epochs,
            "history": self.history,
            "norm": self.norm.to_dict(),
            "model_cfg": self.model_cfg.to_dict(),
            "burst_cfg": self.burst_cfg.to_dict(),
            "train_cfg": asdict(self.train_cfg),
            "schedule_cfg": asdict(self.schedule_cfg),
            "torch_rng": torch.get_rng_state(),
            "elapsed_s": self.elapsed(),
            "cameras": sorted(self.cameras) if self.cameras else None,  # resumed with them
        }
        path = self.ckpt_path if path is None else Path(path)
        with atomic_path(path) as tmp:
            torch.save(payload, tmp)
        return path


def _weights_path(out: str | os.PathLike[str]) -> Path:
    return check_output_file(check_suffix(out, (".pt",), "the weights file"))


def _read_checkpoint(path: Path, cameras: dict[int, CameraModel] | None) -> dict[str, Any]:
    if not path.is_file():
        raise FileFormatError(f"{path}: no checkpoint to resume from")
    try:
        state = torch.load(path, map_location="cpu", weights_only=False)
    except Exception:
        raise FileFormatError(f"{path}: damaged checkpoint") from None
    if state.get("cameras") and not cameras:
        raise InvalidInputError(
            f"{path}: this run was trained from a chamber file: resume it with --chamber"
        )
    return state


def _check_run(
    model_cfg: ModelConfig, burst_cfg: BurstConfig, train_cfg: TrainConfig,
    cameras: dict[int, CameraModel] | None, val_units: tuple[int, ...],
) -> None:
    if train_cfg.lr_schedule not in ("plateau", "step"):
        raise InvalidInputError(f"lr_schedule must be plateau or step, got {train_cfg.lr_schedule}")
    if model_cfg.n_frames != burst_cfg.n_frames:
        raise InvalidInputError(
            f"model has N = {model_cfg.n_frames} but the data N = {burst_cfg.n_frames}"
        )
    if cameras is None and set(val_units) & set(burst_cfg.units):
        raise InvalidInputError("validation units must not be training units")
    check_calibrated(model_cfg, burst_cfg)  # before training, not only at the first save


def _check_same_network(
    init: str | os.PathLike[str], have: ModelConfig, want: ModelConfig
) -> None:
    if have == want:
        return
    differ = [k for k, v in have.to_dict().items() if want.to_dict()[k] != v]
    raise InvalidInputError(
        f"{init}: its network differs from the one to train in "
        f"{', '.join(f'{k} ({getattr(have, k)} there)' for k in differ)}: "
        "give the same options (e.g. --no-calibrated for a model on raw counts)"
    )


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
    """Train a KPN and write the best weights to ``out`` (and a checkpoint to ``out.ckpt``):
    :meth:`Trainer.run` of a new :class:`Trainer`, or of :meth:`Trainer.resume`'s.

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
    kwargs = {"pool_fn": pool_fn, "val_pool_fn": val_pool_fn, "cameras": cameras,
              "val_units": val_units, "log": log, "progress": progress, "meta": meta,
              "init": init}
    if resume:
        return Trainer.resume(out, train_cfg, **kwargs).run()
    return Trainer(out, model_cfg, burst_cfg, train_cfg, **kwargs).run()


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
