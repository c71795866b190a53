"""The network's weights file: what :func:`save_model` writes and :func:`load_model` reads.

A weights file (``torch.save`` of plain values, read with ``weights_only=True``) holds the state
dict, the model configuration, the normalisation (eq. 20-21), how the training data were made and,
for a calibrated network, its nominal camera: the maps the frames go through before the network
sees them, stored whole with a SHA-256 of their bytes checked at load, and for a camera made from
a preset the preset's parameters (so that it can be made again, exactly, for another sensor size
without reading :data:`thermocal.camera.presets.PRESETS`, which may have changed since).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import torch

from thermocal.camera.model import CameraModel
from thermocal.camera.presets import CameraPreset
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.atomic import atomic_path
from thermocal.nn.data import BurstConfig
from thermocal.nn.inputs import Normalisation, preset_nominal
from thermocal.nn.model import KPN, ModelConfig
from thermocal.radiometry import band_table

__all__ = ["FORMAT", "VERSION", "load_model", "nominal_for", "save_model", "upgrade"]


FORMAT = "thermocal-kpn"
#: 2: the nominal camera is always stored, with its SHA-256 (1: only for chamber fits).
VERSION = 2
#: The maps of a calibrated model's nominal camera that a weights file keeps.
NOMINAL_MAPS = ("gain", "offset", "housing", "transient")
_NOMINAL_SCALARS = ("noise_sigma", "t_ref_c", "bit_depth")


def save_model(
    path: str | os.PathLike[str],
    model: KPN,
    norm: Normalisation,
    burst_cfg: BurstConfig,
    meta: dict[str, Any] | None = None,
) -> Path:
    """Write the weights file atomically: state dict, model configuration, normalisation,
    how the training data were made, free-form metadata and a calibrated model's nominal camera
    (:func:`nominal_payload`); plain values only, so that it loads with
    ``torch.load(weights_only=True)``."""
    out = Path(path)
    check_calibrated(model.config, burst_cfg)
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "config": model.config.to_dict(),
        "normalisation": norm.to_dict(),
        "data": json.loads(json.dumps(burst_cfg.to_dict())),
        "meta": json.loads(json.dumps(meta or {}, default=float)),
        "state_dict": {k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
    }
    if model.config.calibrated:
        if model.nominal is None:
            raise InvalidInputError("a calibrated network without its nominal camera")
        payload["nominal"] = nominal_payload(model.nominal)
    with atomic_path(out) as tmp:
        torch.save(payload, tmp)
    return out


def nominal_payload(nominal: CameraModel) -> dict[str, Any]:
    """A nominal camera as the weights file keeps it: its maps (float32 tensors), scalars,
    the SHA-256 of both (:func:`_nominal_sha256`), and where it came from: the preset's
    parameters and units when it is an average of a preset's units (to make it again for another
    sensor size), else ``None``."""
    maps = {k: np.ascontiguousarray(getattr(nominal, k), dtype=np.float32) for k in NOMINAL_MAPS}
    scalars = {"noise_sigma": float(nominal.noise_sigma), "t_ref_c": float(nominal.t_ref_c),
               "bit_depth": int(nominal.bit_depth)}
    params = nominal.info.get("preset_parameters")
    origin = {"preset_parameters": json.loads(json.dumps(params)) if params else None,
              "units": [int(u) for u in nominal.info.get("units") or [] if u is not None]}
    return {
        **{k: torch.from_numpy(v.copy()) for k, v in maps.items()},
        **scalars,
        "sha256": _nominal_sha256(maps, scalars, origin),
        **origin,
    }


def _nominal_sha256(maps: dict[str, np.ndarray], scalars: dict[str, Any],
                    origin: dict[str, Any]) -> str:
    """SHA-256 of a nominal camera as stored: its maps (names, shapes, dtypes, bytes), its
    scalars and where it came from (the preset parameters and units)."""
    digest = hashlib.sha256()
    for k in NOMINAL_MAPS:
        a = maps[k]
        digest.update(f"{k}{a.shape}{a.dtype}".encode())
        digest.update(a.tobytes())
    digest.update(json.dumps([scalars, origin], sort_keys=True).encode())
    return digest.hexdigest()


def load_model(path: str | os.PathLike[str]) -> tuple[KPN, Normalisation, dict[str, Any]]:
    """Read a weights file written by :func:`save_model`; the model is in eval mode.

    Returns the model, its normalisation and the file's ``{"data": …, "meta": …}``. A
    calibrated model's nominal camera is the one stored in the file, checked against its SHA-256
    (a version-1 file that did not store it has it made again from the preset it names).

    Raises
    ------
    FileFormatError
        Missing, truncated, damaged or not a thermocal KPN weights file.
    """
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{p}: no such weights file (train one with `thermocal train`)")
    try:
        payload = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a corrupt file
        text = str(exc).strip()
        detail = type(exc).__name__ + (f": {text.splitlines()[0][:100]}" if text else "")
        raise FileFormatError(f"{p}: not a thermocal weights file (PyTorch cannot read it: "
                              f"{detail})") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise FileFormatError(f"{p}: not a thermocal weights file (no '{FORMAT}' header)")
    if payload.get("version") not in (1, VERSION):
        raise FileFormatError(f"{p}: weights file version {payload.get('version')} not supported")
    try:
        config = ModelConfig(**payload["config"])
        norm = Normalisation(**payload["normalisation"])
        crop = payload.get("data", {}).get("crop")
        model = KPN(config, init=False, temp_range_c=(norm.temp_min_c, norm.temp_max_c),
                    train_crop=int(crop) if crop else None)
        model.load_state_dict(payload["state_dict"])
        if config.calibrated:
            model.nominal = _nominal_of(payload, config)
    except (KeyError, TypeError, RuntimeError, InvalidInputError, ValueError,
            AttributeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise FileFormatError(f"{p}: damaged weights file ({first[:120]})") from None
    model.eval()
    model.to(memory_format=torch.channels_last)  # faster CPU convolutions (oneDNN), same values
    return model, norm, {"data": payload.get("data", {}), "meta": payload.get("meta", {})}


def check_calibrated(model_cfg: ModelConfig, burst_cfg: BurstConfig) -> None:
    """A calibrated network needs calibrated bursts, and only it (:class:`InvalidInputError`)."""
    if model_cfg.calibrated != burst_cfg.calibrated:
        raise InvalidInputError("a calibrated network needs calibrated bursts, and only it")


def _nominal_of(payload: dict[str, Any], config: ModelConfig) -> CameraModel:
    """The nominal camera of a calibrated model's weights file: the stored maps, checked
    against their SHA-256 (version 2, and version-1 chamber fits), or for a version-1 file made
    from a preset, made again from that preset."""
    if "nominal" not in payload:
        if payload["version"] != 1:
            raise InvalidInputError("a calibrated network without its camera model")
        data = payload["data"]  # version 1, trained from a preset's units: made again
        return preset_nominal(data["preset"], tuple(data["sensor_size"]),
                              tuple(data.get("nominal_units") or data["units"]))
    d = payload["nominal"]
    maps = {k: np.ascontiguousarray(d[k].numpy(), dtype=np.float32) for k in NOMINAL_MAPS}
    scalars = {"noise_sigma": float(d["noise_sigma"]), "t_ref_c": float(d["t_ref_c"]),
               "bit_depth": int(d["bit_depth"])}
    params = d.get("preset_parameters")
    units = [int(u) for u in d.get("units") or []]
    origin = {"preset_parameters": params, "units": units}
    if payload["version"] != 1 and d.get("sha256") != _nominal_sha256(maps, scalars, origin):
        raise InvalidInputError("its camera model does not match the checksum stored with it")
    if not all(np.all(np.isfinite(m)) for m in maps.values()) or not np.all(maps["gain"][0] > 0):
        raise InvalidInputError("its camera model has non-finite or non-positive gain terms")
    if params:
        _preset_of(params)  # refused here, not when another frame size first needs it
    return CameraModel(
        **maps, defects=np.zeros(maps["housing"].shape, bool),
        defect_counts=np.zeros(maps["housing"].shape, np.uint16),
        **scalars, band=band_table(tuple(config.band_m)),
        info={"preset": params["name"] if params else None, "units": units,
              "preset_parameters": params},
    )


def nominal_for(model: KPN, shape: tuple[int, int]) -> CameraModel:
    """A calibrated model's nominal camera for whole-sensor frames of ``shape = (H, W)``.

    The stored camera at its own size; for a camera averaged from a preset's units, the same
    average made again at another size from the preset parameters stored with it (never from
    :data:`~thermocal.camera.presets.PRESETS` as it is now). A chamber fit has one size only.
    """
    nominal = model.nominal
    if nominal is None:
        raise InvalidInputError("this calibrated model has no nominal camera (load it with "
                                "thermocal.nn.store.load_model)")
    if nominal.shape == tuple(shape):
        return nominal
    params = nominal.info.get("preset_parameters")
    units = tuple(nominal.info.get("units") or ())
    if not params or not units:
        h, w = nominal.shape
        raise InvalidInputError(
            f"this network's camera model is {w}x{h} (fitted on a chamber file of that size) but "
            f"the frames are {shape[1]}x{shape[0]}; train it from a chamber session of this size"
        )
    return preset_nominal(_preset_of(params), (int(shape[1]), int(shape[0])), units)


def _preset_of(params: dict[str, Any]) -> CameraPreset:
    """The :class:`~thermocal.camera.presets.CameraPreset` of stored parameters
    (:class:`InvalidInputError` for parameters it does not have)."""
    try:
        return CameraPreset(**{k: tuple(v) if isinstance(v, list) else v
                               for k, v in params.items()})
    except TypeError as exc:
        raise InvalidInputError(f"its camera preset parameters are not thermocal's ({exc})"
                                ) from None


def upgrade(path: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Write a version-1 weights file ``path`` as version 2 to ``out`` (atomically): the same
    weights, with the nominal camera its version-1 reader makes stored in it, so that later
    changes to the preset no longer change what the network sees."""
    model, _, _ = load_model(path)
    payload = torch.load(Path(path), map_location="cpu", weights_only=True)
    if payload["version"] != VERSION:
        payload["version"] = VERSION
        if model.config.calibrated:
            payload["nominal"] = nominal_payload(model.nominal)
    with atomic_path(Path(out)) as tmp:
        torch.save(payload, tmp)
    return Path(out)
