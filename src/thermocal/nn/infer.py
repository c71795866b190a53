"""Inference: the network as an estimator of the pipeline, tiled for any frame size.

:class:`NetworkEstimator` is the network behind :mod:`thermocal.estimation`'s protocol: its
per-pixel map is the frames through its nominal camera (a calibrated network) or the counts
themselves; its estimate normalises the warped frames (eq. 20-21) and runs the network over
overlapping tiles (:func:`run_network`). :func:`estimate_burst` is the pipeline with it.
"""

from __future__ import annotations

import os
import warnings
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np
import torch

from thermocal.calibration.base import ThermocalWarning
from thermocal.errors import InvalidInputError
from thermocal.estimation.base import Estimate, PreparedBurst
from thermocal.estimation.pipeline import estimate
from thermocal.nn.inputs import (
    Normalisation,
    calibrate_frames,
    frame_r2,
    input_frames,
    sensor_r2,
)
from thermocal.nn.model import KPN, frame_means
from thermocal.nn.runners import Runner, make_runner
from thermocal.nn.store import load_model, nominal_for
from thermocal.nn.uncertainty import SigmaModel, sidecar_path
from thermocal.nn.validity import REMEDY, Domain, beyond_training_c, outside_domain
from thermocal.nn.variants import VARIANTS, sigma_warning
from thermocal.registration.warp import warp_to_pivot

__all__ = [
    "SHIPPED_MODELS",
    "NetworkEstimator",
    "calibrated_frames",
    "calibrated_warp",
    "estimate_burst",
    "inference_tiling",
    "run_network",
    "shipped_model_path",
]

#: Weights shipped in the package, by method.
SHIPPED_MODELS = {name: v.weights for name, v in VARIANTS.items()}


def shipped_model_path(method: str) -> Path:
    """Path of the shipped weights for ``method`` (``kpn``, ``kpn-no-offset``, ``e2e``)."""
    if method not in SHIPPED_MODELS:
        raise InvalidInputError(f"no shipped model for method {method!r}")
    path = Path(str(files("thermocal.nn") / "weights" / SHIPPED_MODELS[method]))
    if not path.is_file():
        raise InvalidInputError(
            f"no {method} model is shipped with this installation; train one with "
            f"`thermocal train --variant {method} --out MODEL.pt` and give it (estimate, "
            "flight: --model MODEL.pt; export: MODEL.pt)"
        )
    return path


def _to_model_order(x: np.ndarray, pivot: int) -> np.ndarray:
    """Swap the pivot into the middle channel, where the network was trained to find it."""
    mid = x.shape[0] // 2
    if pivot == mid:
        return x
    order = list(range(x.shape[0]))
    order[mid], order[pivot] = order[pivot], order[mid]
    return x[order]


def inference_tiling(model: KPN) -> tuple[int, int]:
    """``(tile, margin)`` in px that :func:`run_network` uses by default for ``model``.

    E2E runs in tiles of its training crop overlapping by a quarter of it: it predicts the
    temperature itself from the levels in its whole view and does not carry over from its crops
    to larger ones (one trained on 64-px crops: 3.97 °C on whole 336×256 frames, 2.09 °C in
    64-px tiles; ``benchmarks/RESULTS.md``, E2E on whole frames and in tiles). The KPN variants
    give the same error whole or tiled (0.574 / 0.573 °C) and run whole frames up to 512 px,
    which is faster.
    """
    crop = model.train_crop
    if model.config.variant == "e2e" and crop:
        return crop, crop // 4
    return 512, 32


def run_network(
    model: KPN,
    norm: Normalisation,
    warped: np.ndarray,
    valid: np.ndarray,
    fpa_c: float,
    *,
    tile: int | None = None,
    margin: int | None = None,
    r2_frames: np.ndarray | None = None,
    runner: Runner | None = None,
) -> np.ndarray:
    """The network on registered frames ``(N, H, W)`` (counts; for a
    :attr:`~thermocal.nn.model.ModelConfig.calibrated` model, °C through its nominal camera:
    :func:`calibrated_warp`), tiled; returns °C ``(H, W)``.

    The frames are zero outside their valid masks (as in training) and zero-padded to a multiple
    of ``ξ^L``. The offset block's frame means are taken over each whole frame's valid pixels,
    so that every tile gets the same offset. Tiles of ``tile`` pixels (shifted inwards at the
    borders, so that every tile is whole) overlap by at least ``margin`` pixels on each side
    (default: :func:`inference_tiling`); only their centres are kept, so that the seams see the
    same context as the interior. It runs where the model's parameters
    are (CPU or GPU). A model with position terms (``radial > 0``) takes the frames to be whole
    sensor frames (``R²`` of Oz et al. eq. 16 over ``H × W``); one with ``radial_frames`` also
    needs ``r2_frames (N, H, W)``, where each frame saw each pivot pixel
    (:func:`~thermocal.nn.inputs.frame_r2`). ``runner`` runs the network on each tile (an
    inference backend: :func:`thermocal.nn.backends.make_runner`; default the model itself,
    eager, on the process's torch threads).
    """
    if tile is None or margin is None:
        default_tile, default_margin = inference_tiling(model)
        tile = default_tile if tile is None else tile
        margin = default_margin if margin is None else margin
    n, h, w = warped.shape
    device = next(model.parameters()).device
    c = model.config
    x = input_frames(warped, valid, norm, calibrated=c.calibrated,
                     band_m=c.band_m if c.radiance else None)
    xt = torch.from_numpy(x)[None].to(device)
    vt = torch.from_numpy(valid)[None].to(device)
    means = frame_means(xt, vt)
    r2 = None
    if r2_frames is not None and not model.config.radial_frames:
        raise InvalidInputError("r2_frames given to a model without radial_frames")
    if model.config.radial_frames:
        if r2_frames is None or np.shape(r2_frames) != (n, h, w):
            raise InvalidInputError(
                f"this model needs each frame's sensor position R² ({n}, {h}, {w}) (r2_frames)"
            )
        r2 = torch.from_numpy(np.asarray(r2_frames, dtype=np.float32))[None].to(device)
    elif model.config.radial:
        r2 = torch.tensor(sensor_r2((h, w)))[None, None].to(device)
    fpa = torch.tensor([norm.fpa(float(fpa_c))], dtype=torch.float32, device=device)
    mult = model.config.multiple
    out = np.empty((h, w), dtype=np.float32)
    step = max(tile - 2 * margin, mult)
    model.eval()
    if runner is None:
        def runner(*args: Any) -> torch.Tensor:
            return model(args[0].contiguous(memory_format=torch.channels_last), *args[1:3],
                         means=args[3], r2=args[4])
    with torch.inference_mode():
        for y0 in range(0, h, step):
            for x0 in range(0, w, step):
                y1, x1 = min(y0 + step, h), min(x0 + step, w)
                if h <= tile and w <= tile:
                    y0, x0, y1, x1 = 0, 0, h, w
                # full tiles also at the borders (shifted inwards): the network sees the
                # context size it is run at everywhere
                ya, xa = max(min(y0 - margin, h - tile), 0), max(min(x0 - margin, w - tile), 0)
                yb, xb = min(ya + tile, h), min(xa + tile, w)
                if h <= tile and w <= tile:
                    ya, xa, yb, xb = 0, 0, h, w
                sub = xt[:, :, ya:yb, xa:xb]
                vsub = vt[:, :, ya:yb, xa:xb]
                rsub = None if r2 is None else r2[:, :, ya:yb, xa:xb]
                ph = (-sub.shape[2]) % mult
                pw = (-sub.shape[3]) % mult
                if ph or pw:
                    sub = torch.nn.functional.pad(sub, (0, pw, 0, ph))
                    vsub = torch.nn.functional.pad(vsub, (0, pw, 0, ph))
                    if rsub is not None:
                        rsub = torch.nn.functional.pad(rsub, (0, pw, 0, ph), mode="replicate")
                est = runner(sub, fpa, vsub, means, rsub)[0, 0].cpu().numpy()
                out[y0:y1, x0:x1] = est[y0 - ya : y1 - ya, x0 - xa : x1 - xa]
                if h <= tile and w <= tile:
                    break
            if h <= tile and w <= tile:
                break
    return norm.temp_inverse(out).astype(np.float32)


def calibrated_frames(model: KPN, frames: np.ndarray, fpa_c: float) -> np.ndarray:
    """Whole-sensor raw frames ``(N, H, W)`` (stuck pixels replaced) through a calibrated
    model's nominal camera (:func:`~thermocal.nn.inputs.calibrate_frames`) where each pixel lies
    on the sensor, °C ``(N, H, W)``.

    The nominal camera is the one stored with the weights (:func:`~thermocal.nn.store.nominal_for`:
    made again from its stored preset parameters for another sensor size; a chamber fit fits its
    own size only).
    """
    return calibrate_frames(nominal_for(model, frames.shape[1:]), frames, fpa_c)


def calibrated_warp(model: KPN, frames: np.ndarray, homographies: np.ndarray,
                    fpa_c: float) -> np.ndarray:
    """:func:`calibrated_frames` warped onto the pivot by ``homographies`` ``(N, 3, 3)``: the
    frames :func:`run_network` takes for a calibrated model, °C ``(N, H, W)``."""
    return warp_to_pivot(calibrated_frames(model, frames, fpa_c), homographies)[0]


class NetworkEstimator:
    """A network variant (``kpn``, ``kpn-no-offset``, ``e2e``) as an estimator of the pipeline
    (:class:`thermocal.estimation.base.Estimator`).

    Parameters
    ----------
    model, norm
        From :func:`thermocal.nn.store.load_model`.
    backend, threads, concurrent
        What runs the network, on how many threads, for how many callers at once
        (:func:`thermocal.nn.runners.make_runner`).
    """

    needs_fpa = True
    per_frame = False
    remedy = REMEDY
    fpa_paces: dict = {}  # the network is no calibration: its domain has no paces

    def __init__(self, model: KPN, norm: Normalisation, domain: Domain | None = None,
                 sigma_model: SigmaModel | None = None, *, backend: str = "torch",
                 threads: int | None = None, concurrent: int = 1) -> None:
        self.model = model
        self.runner = make_runner(model, backend, threads=threads, concurrent=concurrent)
        self.norm = norm
        self.domain = domain
        self.sigma_model = sigma_model
        self.name = model.config.variant
        self.n_frames = model.config.n_frames
        # a calibrated network calibrates each frame where it lies on the sensor
        self.accepts_registered = not model.config.calibrated

    @classmethod
    def from_file(cls, method: str, path: str | os.PathLike[str] | None = None, *,
                  backend: str = "torch", threads: int | None = None, concurrent: int = 1
                  ) -> NetworkEstimator:
        """The network ``method`` from weights file ``path`` (default: the shipped one),
        refused when the file holds another variant; run on ``backend`` with ``threads``
        threads for ``concurrent`` callers (:func:`~thermocal.nn.runners.make_runner`). A
        variant whose σ is known not to hold somewhere
        (:func:`~thermocal.nn.variants.sigma_warning`) warns so when it has one."""
        path = Path(path) if path is not None else shipped_model_path(method)
        model, norm, content = load_model(path)
        if model.config.variant != method:
            raise InvalidInputError(
                f"{path} holds the variant {model.config.variant}, not {method}; pass the right "
                "--model or --method"
            )
        nominal = model.nominal.info if model.config.calibrated else None
        sidecar = sidecar_path(path)
        sigma = (SigmaModel.load(sidecar, weights_sha256=content["sha256"])
                 if sidecar.is_file() else None)
        if sigma is not None and (said := sigma_warning(method)):
            warnings.warn(said, ThermocalWarning, stacklevel=2)
        return cls(model, norm, Domain.of_network(content["data"], nominal), sigma,
                   backend=backend, threads=threads, concurrent=concurrent)

    def check(self, frames: np.ndarray, *, registered: bool, homographies: Any) -> None:
        n_model = self.model.config.n_frames
        if frames.shape[0] != n_model:
            raise InvalidInputError(
                f"the model was trained for N = {n_model} frames, got {frames.shape[0]}; give a "
                f"burst of {n_model} frames"
            )
        if self.model.config.radial_frames and registered and homographies is None:
            raise InvalidInputError(
                "this model needs where on the sensor each frame saw the scene: give the burst "
                "as recorded (not --registered) or its homographies"
            )

    def calibrate(self, frames: np.ndarray, fpa_c: Any, time_s: Any, *,
                  pace: Any = None) -> np.ndarray:
        if not self.model.config.calibrated:
            return frames
        return calibrated_frames(self.model, frames, fpa_c)

    def outside(self, calibrated: np.ndarray, fpa_c: float | None, *,
                pace: Any = None, burst: PreparedBurst | None = None) -> tuple[str, ...]:
        """:func:`thermocal.nn.validity.outside_domain` of the network's training domain (the
        FPA range alone for a network of raw counts; nothing without a ``domain``); ``burst``,
        registered, lets the family's fixed pattern be read without the scene."""
        if self.domain is None or fpa_c is None:
            return ()
        if not self.model.config.calibrated:
            return outside_domain(self.domain, None, fpa_c)
        moved = {} if burst is None else {"warped_c": burst.warped, "valid": burst.valid,
                                          "homographies": burst.homographies}
        return outside_domain(self.domain, calibrated, fpa_c, **moved)

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> np.ndarray | None:
        """σ of the network's σ model (:mod:`thermocal.nn.uncertainty`, the ``NAME.sigma.json``
        beside its weights); None without one. ``outside`` its domain (forced), σ also grows by
        the whole distance beyond its training scenes (:func:`~thermocal.nn.validity.
        beyond_training_c`)."""
        if self.sigma_model is None:
            return None
        sigma = self.sigma_model.sigma(burst.warped, burst.valid, temperature_c, outside=outside,
                                       fpa_c=burst.fpa_c)
        if not outside or self.domain is None:
            return sigma
        frame_c = burst.warped[burst.pivot] if self.model.config.calibrated else None
        return sigma + beyond_training_c(self.domain, frame_c, temperature_c)

    def estimate(self, burst: PreparedBurst) -> np.ndarray:
        p, valid = burst.pivot, burst.valid
        r2f = None
        if self.model.config.radial_frames:
            r2f = _to_model_order(frame_r2(sensor_r2(valid.shape[1:]), burst.homographies,
                                           valid), p)
        return run_network(self.model, self.norm, _to_model_order(burst.warped, p),
                           _to_model_order(valid, p), burst.fpa_c, r2_frames=r2f,
                           runner=self.runner)


def estimate_burst(
    frames: Any,
    fpa_c: Any,
    *,
    model: KPN,
    norm: Normalisation,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
    fill_defects: bool = True,
) -> Estimate:
    """Temperature of the pivot frame of a burst through the network, °C: the pipeline
    (:func:`thermocal.estimation.pipeline.estimate`) with :class:`NetworkEstimator`.

    Parameters
    ----------
    frames : (N, H, W) uint16
        Raw 14-bit counts (N must be the model's).
    fpa_c : float or (N,) array
        FPA temperature, °C (a series is averaged: a burst lasts well under a second).
    model, norm
        From :func:`thermocal.nn.store.load_model`.
    pivot, registered, homographies, fill_defects
        As for :func:`thermocal.estimation.pipeline.estimate`.
    """
    return estimate(frames, NetworkEstimator(model, norm), fpa_c=fpa_c, pivot=pivot,
                    registered=registered, homographies=homographies, fill_defects=fill_defects)
