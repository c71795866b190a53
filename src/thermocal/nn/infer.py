"""Inference: the pivot frame's temperature from a burst, tiled for any frame size.

:func:`estimate_burst` registers the burst onto its pivot (or takes it as registered), checks it
(length against the model, saturation, overlap), normalises it (eq. 21) and runs the network over
overlapping tiles; :func:`naive_mean` is eq. 9, the registered average of a per-frame
calibration. :func:`estimate_file` is ``thermocal estimate``.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np
import torch

from thermocal._validate import as_frames
from thermocal.errors import InvalidInputError, RegistrationError, ResolutionMismatchError
from thermocal.nn.data import Normalisation
from thermocal.nn.model import KPN, frame_means
from thermocal.nn.train import load_model
from thermocal.registration.warp import as_homographies, warp_to_pivot

__all__ = [
    "SHIPPED_MODELS",
    "Estimate",
    "check_burst",
    "estimate_burst",
    "estimate_file",
    "naive_mean",
    "register",
    "shipped_model_path",
]

#: Weights shipped in the package, by method.
SHIPPED_MODELS = {
    "kpn": "kpn_n7.pt",
    "kpn-no-offset": "kpn_no_offset_n7.pt",
    "e2e": "e2e_n7.pt",
}

#: A frame with more than this fraction of its pixels at 0 or at the largest count is saturated.
SATURATED_FRACTION = 0.02
#: Every frame must see at least this fraction of the pivot frame.
MIN_OVERLAP = 0.1


class Estimate:
    """The result of :func:`estimate_burst`.

    Attributes
    ----------
    temperature_c : (H, W) float32
        Estimated scene temperature of the pivot frame, °C.
    coverage : (H, W) int
        How many frames see each pivot pixel.
    homographies : (N, 3, 3) float64
        Frame → pivot homographies used.
    pivot : int
    """

    def __init__(
        self, temperature_c: np.ndarray, coverage: np.ndarray, homographies: np.ndarray, pivot: int
    ) -> None:
        self.temperature_c = temperature_c
        self.coverage = coverage
        self.homographies = homographies
        self.pivot = pivot


def shipped_model_path(method: str) -> Path:
    """Path of the shipped weights for ``method`` (``kpn``, ``kpn-no-offset``, ``e2e``)."""
    if method not in SHIPPED_MODELS:
        raise InvalidInputError(f"no shipped model for method {method!r}")
    path = Path(str(files("thermocal.nn") / "weights" / SHIPPED_MODELS[method]))
    if not path.is_file():
        raise InvalidInputError(
            f"no {method} model is shipped with this installation; train one with "
            f"`thermocal train --variant {method} --out MODEL.pt` and pass --model MODEL.pt"
        )
    return path


def check_burst(
    frames: Any, *, bit_depth: int = 14, name: str = "frames", registered: bool = False
) -> np.ndarray:
    """Validate a raw burst: ``(N, H, W)`` counts, no saturated or dead frames.

    Raises :class:`InvalidInputError` for saturated frames (more than 2 % of the pixels at 0 or
    at ``2**bit_depth − 1``) or constant frames. For ``registered`` frames, 0 marks pixels a
    frame does not cover: they are not counted.
    """
    arr = as_frames(frames, name)
    top = 2**bit_depth - 1
    for k, f in enumerate(arr):
        covered = np.count_nonzero(f > 0) if registered else f.size
        n_pix = max(covered, 1)
        sat = np.count_nonzero(f >= top) / n_pix
        low = 0.0 if registered else np.count_nonzero(f <= 0) / n_pix
        if sat > SATURATED_FRACTION or low > SATURATED_FRACTION:
            which = f"{100 * sat:.0f} % at {top}" if sat >= low else f"{100 * low:.0f} % at 0"
            raise InvalidInputError(
                f"{name}: frame {k} is saturated ({which}); use frames within the sensor's range"
            )
        if covered == 0 or float(f.max()) == float(f[f > 0].min() if registered else f.min()):
            raise InvalidInputError(f"{name}: frame {k} is constant (a dead or blank frame)")
    return arr


def register(
    frames: np.ndarray,
    *,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Warp a burst onto its pivot: ``(warped float32, valid bool, homographies, pivot)``.

    Known frame → pivot ``homographies`` are used as given. ``registered=True`` takes the frames
    as already registered (identity homographies; pixels at 0 counts are taken as not covered).
    Otherwise :func:`thermocal.registration.register_burst` finds the homographies.
    """
    n = frames.shape[0]
    if pivot is None:
        pivot = n // 2
    if not 0 <= pivot < n:
        raise InvalidInputError(f"pivot {pivot} is not a frame index (0 … {n - 1})")
    if homographies is not None:
        hs = as_homographies(homographies, n=n)
        warped, valid = warp_to_pivot(frames, hs)
        return warped, valid, hs, pivot
    if registered:
        hs = np.repeat(np.eye(3)[None], n, axis=0)
        warped = frames.astype(np.float32)
        valid = frames > 0
        valid[pivot] = True
        return warped, valid, hs, pivot
    try:
        from thermocal.registration import register_burst
    except ImportError:
        raise RegistrationError(
            "burst registration is not available in this installation; register the frames "
            "yourself and pass --registered"
        ) from None
    reg = register_burst(frames, pivot=pivot)
    hs = as_homographies(reg.homographies, n=n)
    warped, valid = warp_to_pivot(frames, hs)
    return warped, valid, hs, int(reg.pivot)


def _check_overlap(valid: np.ndarray, pivot: int) -> None:
    frac = valid.reshape(valid.shape[0], -1).mean(axis=1)
    for k, f in enumerate(frac):
        if k != pivot and f < MIN_OVERLAP:
            raise RegistrationError(
                f"frame {k} overlaps the pivot frame {pivot} by only {100 * f:.0f} %; a burst "
                f"needs overlapping views (at least {100 * MIN_OVERLAP:.0f} %)"
            )


def _to_model_order(x: np.ndarray, pivot: int) -> np.ndarray:
    """Swap the pivot into the middle channel, where the network was trained to find it."""
    mid = x.shape[0] // 2
    if pivot == mid:
        return x
    order = list(range(x.shape[0]))
    order[mid], order[pivot] = order[pivot], order[mid]
    return x[order]


def run_network(
    model: KPN,
    norm: Normalisation,
    warped: np.ndarray,
    valid: np.ndarray,
    fpa_c: float,
    *,
    tile: int = 512,
    margin: int = 32,
) -> np.ndarray:
    """The network on registered frames ``(N, H, W)`` (counts), tiled; returns °C ``(H, W)``.

    The frames are zero outside their valid masks (as in training) and zero-padded to a multiple
    of ``ξ^L``. The offset block's frame means are taken over each whole frame's valid pixels,
    so that every tile gets the same offset. Tiles of ``tile`` pixels overlap by ``margin``
    pixels on each side; only their centres are kept, so that the seams see the same context
    as the interior. It runs where the model's parameters are (CPU or GPU).
    """
    n, h, w = warped.shape
    device = next(model.parameters()).device
    x = np.where(valid, norm.counts(warped), 0.0).astype(np.float32)
    xt = torch.from_numpy(x)[None].to(device)
    vt = torch.from_numpy(valid)[None].to(device)
    means = frame_means(xt, vt)
    fpa = torch.tensor([norm.fpa(float(fpa_c))], dtype=torch.float32, device=device)
    mult = model.config.multiple
    out = np.empty((h, w), dtype=np.float32)
    step = max(tile - 2 * margin, mult)
    model.eval()
    with torch.inference_mode():
        for y0 in range(0, h, step):
            for x0 in range(0, w, step):
                y1, x1 = min(y0 + step, h), min(x0 + step, w)
                if h <= tile and w <= tile:
                    y0, x0, y1, x1 = 0, 0, h, w
                ya, xa = max(y0 - margin, 0), max(x0 - margin, 0)
                yb, xb = min(y1 + margin, h), min(x1 + margin, w)
                if h <= tile and w <= tile:
                    ya, xa, yb, xb = 0, 0, h, w
                sub = xt[:, :, ya:yb, xa:xb]
                vsub = vt[:, :, ya:yb, xa:xb]
                ph = (-sub.shape[2]) % mult
                pw = (-sub.shape[3]) % mult
                if ph or pw:
                    sub = torch.nn.functional.pad(sub, (0, pw, 0, ph))
                    vsub = torch.nn.functional.pad(vsub, (0, pw, 0, ph))
                sub = sub.contiguous(memory_format=torch.channels_last)
                est = model(sub, fpa, vsub, means=means)[0, 0].cpu().numpy()
                out[y0:y1, x0:x1] = est[y0 - ya : y1 - ya, x0 - xa : x1 - xa]
                if h <= tile and w <= tile:
                    break
            if h <= tile and w <= tile:
                break
    return norm.temp_inverse(out).astype(np.float32)


def estimate_burst(
    frames: Any,
    fpa_c: Any,
    *,
    model: KPN,
    norm: Normalisation,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
) -> Estimate:
    """Temperature of the pivot frame of a burst, °C.

    Parameters
    ----------
    frames : (N, H, W) uint16
        Raw 14-bit counts (N must be the model's).
    fpa_c : float or (N,) array
        FPA temperature, °C (a series is averaged: a burst lasts well under a second).
    model, norm
        From :func:`thermocal.nn.train.load_model`.
    pivot : int, optional
        Pivot frame (default the middle one).
    registered : bool
        The frames are already registered onto the pivot.
    homographies : (N, 3, 3), optional
        Known frame → pivot homographies (skips registration).

    Raises
    ------
    InvalidInputError
        Wrong length, saturated frames, no or bad FPA temperature.
    RegistrationError
        Registration failed or the frames do not overlap.
    """
    arr = check_burst(frames, registered=registered)
    n_model = model.config.n_frames
    if arr.shape[0] != n_model:
        raise InvalidInputError(
            f"the model was trained for N = {n_model} frames, got {arr.shape[0]}; give a burst "
            f"of {n_model} frames"
        )
    fpa = _fpa_value(fpa_c, arr.shape[0])
    warped, valid, hs, p = register(
        arr, pivot=pivot, registered=registered, homographies=homographies
    )
    _check_overlap(valid, p)
    temp = run_network(model, norm, _to_model_order(warped, p), _to_model_order(valid, p), fpa)
    return Estimate(temp, valid.sum(axis=0), hs, p)


def _fpa_value(fpa_c: Any, n: int) -> float:
    if fpa_c is None:
        raise InvalidInputError(
            "no FPA temperature: give --fpa-c or a sidecar JSON with fpa_c (the network needs it)"
        )
    arr = np.asarray(fpa_c, dtype=np.float64).ravel()
    if arr.size not in (1, n) or not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"fpa_c: expected one finite value or {n}, got {arr.size}")
    value = float(arr.mean())
    if not -60.0 <= value <= 120.0:
        raise InvalidInputError(f"fpa_c: {value:.1f} °C is not a plausible FPA temperature")
    return value


def naive_mean(
    frames: Any,
    calibration: Any,
    *,
    fpa_c: Any = None,
    pivot: int | None = None,
    registered: bool = False,
    homographies: Any = None,
) -> Estimate:
    """Eq. 9: the registered average of the per-frame temperatures given by a calibration.

    Every frame goes through ``calibration.apply(frames, fpa_c=…)`` (°C), is warped onto the
    pivot, and the valid values of each pivot pixel are averaged.
    """
    arr = check_burst(frames, registered=registered)
    if calibration.shape != arr.shape[1:]:
        raise ResolutionMismatchError(
            f"frames are {arr.shape[2]}x{arr.shape[1]} but the calibration is "
            f"{calibration.shape[1]}x{calibration.shape[0]}"
        )
    temps = calibration.apply(arr, fpa_c=fpa_c)
    _, valid, hs, p = register(arr, pivot=pivot, registered=registered, homographies=homographies)
    _check_overlap(valid, p)
    warped_t, valid_t = warp_to_pivot(temps, hs)
    valid_t &= valid
    count = valid_t.sum(axis=0)
    mean = (warped_t * valid_t).sum(axis=0) / np.maximum(count, 1)
    return Estimate(mean.astype(np.float32), count, hs, p)


def estimate_file(
    frames_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    fpa_c: float | None = None,
    method: str = "kpn",
    model_path: str | os.PathLike[str] | None = None,
    pivot: int | None = None,
    registered: bool = False,
    calibration: str | os.PathLike[str] | None = None,
) -> Path:
    """``thermocal estimate``: read a recording, estimate the pivot's temperature, write it.

    The output (float32 °C TIFF, ``(H, W)``) is written atomically and only after every check.
    """
    from thermocal.io.recording import read_recording, write_temperature_tiff

    out = Path(out)
    if out.suffix.lower() not in (".tif", ".tiff"):
        raise InvalidInputError(f"{out}: the output must be a .tiff file")
    if not out.parent.is_dir():
        raise InvalidInputError(f"{out.parent}: output folder does not exist")
    if method == "mean" and calibration is None:
        raise InvalidInputError(
            "--method mean needs a per-pixel calibration: give --calibration CAL.h5"
        )
    rec = read_recording(frames_path, fpa_c=fpa_c)
    fpa = rec.fpa_c
    if method == "mean":
        from thermocal.calibration import load_any_calibration

        cal = load_any_calibration(calibration)
        result = naive_mean(rec.frames, cal, fpa_c=fpa, pivot=pivot, registered=registered)
    else:
        path = Path(model_path) if model_path is not None else shipped_model_path(method)
        model, norm, _ = load_model(path)
        expected = "kpn" if method == "kpn" else method
        if model.config.variant != expected:
            raise InvalidInputError(
                f"{path} holds a {model.config.variant} model, not {method}; pass the right "
                "--model or --method"
            )
        result = estimate_burst(
            rec.frames, fpa, model=model, norm=norm, pivot=pivot, registered=registered
        )
    write_temperature_tiff(out, result.temperature_c)
    return out
