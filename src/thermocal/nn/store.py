"""The network's weights file: what :func:`save_model` writes and :func:`load_model` reads.

A weights file (``torch.save`` of plain values, read with ``weights_only=True``) holds the state
dict, the model configuration, the normalisation (eq. 20-21), how the training data were made and,
for a calibrated network, its nominal camera: the maps the frames go through before the network
sees them, stored whole with a SHA-256 of their bytes checked at load, and for a camera made from
a preset the preset's parameters (so that it can be made again, exactly, for another sensor size
without reading :data:`thermocal.camera.presets.PRESETS`, which may have changed since).

Version 3 adds ``sha256``, a SHA-256 of the whole file's content (:func:`weights_digest`: every
tensor of the state dict by name, shape, dtype and bytes; the configuration, normalisation,
training data and metadata; the nominal camera's own checksum), checked at load. A file is read
only if it is whole and sensible: its checksums match (a version-1 or 2 file, written before the
state checksum, is read with an :class:`~thermocal.calibration.base.UnverifiedFileWarning`;
:func:`upgrade` adds it), its configuration is valid (:class:`~thermocal.nn.model.ModelConfig`
checks its sizes), the network it describes has at most :data:`MAX_PARAMETERS` values (checked
before anything is built), its state dict has exactly the names, shapes and dtypes of that network
and only finite values (batch-norm variances ``>= 0``), its normalisation is finite and ordered
(:func:`check_normalisation`) and its nominal camera is well formed. Anything else is a
:class:`~thermocal.errors.FileFormatError` naming the file, in one line.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from thermocal.calibration.base import UnverifiedFileWarning
from thermocal.camera.model import CameraModel
from thermocal.camera.presets import CameraPreset, family_physics
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.atomic import atomic_path
from thermocal.nn.data import BurstConfig
from thermocal.nn.inputs import Normalisation, preset_nominal
from thermocal.nn.model import KPN, ModelConfig
from thermocal.radiometry import band_table

__all__ = ["FORMAT", "MAX_PARAMETERS", "VERSION", "check_normalisation", "load_model",
           "nominal_for", "save_model", "upgrade", "weights_digest"]


FORMAT = "thermocal-kpn"
#: 3: a SHA-256 of the whole content (``sha256``, :func:`weights_digest`), checked at load.
#: 2: the nominal camera is always stored, with its SHA-256 (1: only for chamber fits).
VERSION = 3
#: Versions this thermocal reads.
READ_VERSIONS = (1, 2, 3)
#: The maps of a calibrated model's nominal camera that a weights file keeps.
NOMINAL_MAPS = ("gain", "offset", "housing", "transient")
_NOMINAL_SCALARS = ("noise_sigma", "t_ref_c", "bit_depth")
#: Most values (parameters and buffers) a network read from a file may have: 2**27, 512 MiB of
#: float32. The paper's network (μ=64, L=4) has 69 million, the shipped one 1.1 million; a
#: damaged configuration (``levels`` 9) would ask for billions.
MAX_PARAMETERS = 2**27
#: Bounds of the normalisation (eq. 20-21), checked at load: temperatures above absolute zero and
#: at most 2000 °C (the hottest range of any thermal camera), spanning >= 1 °C; counts within
#: ±2**20 (16 times a 16-bit ADC), spanning >= 1 count; the FPA within −60…150 °C (the bounds
#: thermocal takes any FPA reading within), spanning >= 0.01 °C (an FPA sensor's resolution).
#: A span of zero (or a tiny one) would divide by zero (or overflow) when normalising.
NORMALISATION_LIMITS: dict[str, tuple[float, float, float]] = {
    "temp": (-273.15, 2000.0, 1.0),
    "counts": (-(2.0**20), 2.0**20, 1.0),
    "fpa": (-60.0, 150.0, 0.01),
}
#: Largest frame side of a nominal camera, px (as a calibration file's).
_MAX_SIDE = 16384
#: Largest training crop a file may name, px (E2E runs in tiles of it).
_MAX_CROP = 8192


def save_model(
    path: str | os.PathLike[str],
    model: KPN,
    norm: Normalisation,
    burst_cfg: BurstConfig,
    meta: dict[str, Any] | None = None,
) -> Path:
    """Write the weights file atomically: state dict, model configuration, normalisation,
    how the training data were made, free-form metadata, a calibrated model's nominal camera
    (:func:`nominal_payload`) and the SHA-256 of all of it (:func:`weights_digest`); plain values
    only, so that it loads with ``torch.load(weights_only=True)``."""
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
    payload["sha256"] = weights_digest(payload)
    with atomic_path(out) as tmp:
        torch.save(payload, tmp)
    return out


def weights_digest(payload: dict[str, Any]) -> str:
    """SHA-256 (hex) of a weights file's content: its ``format`` and ``version``, the JSON of its
    ``config``, ``normalisation``, ``data`` and ``meta`` (sorted keys), the nominal camera's own
    SHA-256 (``None`` without one) and every tensor of the state dict in sorted name order: name,
    shape, dtype and bytes.

    Raises ``TypeError``/``ValueError``/``AttributeError`` for a payload not made of plain values.
    """
    digest = hashlib.sha256(b"thermocal-kpn-sha256\n")
    nominal = payload.get("nominal")
    head = {k: payload.get(k) for k in ("format", "version", "config", "normalisation", "data",
                                        "meta")}
    head["nominal_sha256"] = nominal.get("sha256") if isinstance(nominal, dict) else None
    text = json.dumps(head, sort_keys=True, allow_nan=True, default=_not_json)
    digest.update(len(text).to_bytes(8, "little") + text.encode("utf-8", "surrogatepass"))
    state = payload.get("state_dict")
    if not isinstance(state, dict):
        raise TypeError("the state dict is not a dict")
    digest_tensors(digest, state)
    return digest.hexdigest()


def digest_tensors(digest: Any, state: dict[str, Any]) -> None:
    """Feed every tensor of ``state`` to the ``hashlib`` object ``digest``, in sorted name order:
    name, shape, dtype, byte count and bytes (the weights files of :mod:`thermocal.nn` and of
    :mod:`thermocal.nuc.he2018`). Raises ``TypeError`` for an entry that is not a named tensor."""
    for name in sorted(state, key=str):
        t = state[name]
        if not isinstance(name, str) or not isinstance(t, torch.Tensor):
            raise TypeError(f"state dict entry {name!r:.40} is not a named tensor")
        t = t.detach().cpu().contiguous()
        data = t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b""
        digest.update(f"{name}|{tuple(t.shape)}|{t.dtype}|{len(data)}|".encode())
        digest.update(data)


def _not_json(obj: Any) -> Any:
    raise TypeError(f"{type(obj).__name__} in the file's plain values")


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

    Returns the model, its normalisation and the file's ``{"data": …, "meta": …, "sha256": …}``
    (the content's SHA-256; None for a file older than version 3). A
    calibrated model's nominal camera is the one stored in the file, checked against its SHA-256
    (a version-1 file that did not store it has it made again from the preset it names). Every
    check of the module's docstring is made, the checksums first and the network's size before
    it is built.

    Raises
    ------
    FileFormatError
        Missing, truncated, damaged or not a thermocal KPN weights file.
    """
    p = Path(path)
    if p.is_dir():
        raise FileFormatError(f"{p}: a folder, not a weights file (a .pt of `thermocal train`)")
    if not p.is_file():
        raise FileFormatError(f"{p}: no such weights file (train one with `thermocal train`)")
    try:
        with warnings.catch_warnings():  # what torch notices of a damaged file: refused below
            warnings.simplefilter("ignore", UserWarning)
            payload = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a corrupt file
        # torch's messages run to paragraphs: their first sentence, at most 80 characters
        text = str(exc).strip().splitlines()[0].split(". ")[0] if str(exc).strip() else ""
        if len(text) > 80:
            text = text[:80].rsplit(" ", 1)[0] + " …"
        detail = type(exc).__name__ + (f": {text}" if text else "")
        hint = ("; an exported graph is run by `--backend onnxruntime|openvino` with --model "
                "the .pt weights it came from" if p.suffix.lower() in (".onnx", ".xml") else "")
        raise FileFormatError(f"{p}: not a thermocal weights file (PyTorch cannot read it: "
                              f"{detail}){hint}") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise FileFormatError(f"{p}: not a thermocal weights file (no '{FORMAT}' header)")
    version = payload.get("version")
    if type(version) is not int or version not in READ_VERSIONS:
        raise FileFormatError(f"{p}: weights file version {version!r:.20} not supported")
    try:
        verified = _check_digest(p, payload)
        config, norm, data = _check_header(payload)
        state = _check_state(payload["state_dict"], config, norm, verified=verified)
        model = KPN(config, init=False, temp_range_c=(norm.temp_min_c, norm.temp_max_c),
                    train_crop=data.get("crop"))
        model.load_state_dict(state)
        if config.calibrated:
            model.nominal = _nominal_of(payload, config)
    except Exception as exc:  # anything a damaged file makes the reader meet
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise FileFormatError(f"{p}: damaged weights file ({first[:160]})") from None
    model.eval()
    model.to(memory_format=torch.channels_last)  # faster CPU convolutions (oneDNN), same values
    return model, norm, {"data": payload.get("data", {}), "meta": payload.get("meta", {}),
                         "sha256": payload.get("sha256")}


def _check_digest(p: Path, payload: dict[str, Any]) -> bool:
    """The file's SHA-256 (:func:`weights_digest`): required from version 3, checked wherever
    present; a file without one (version 1 or 2) is read with a warning. True if checked."""
    stored = payload.get("sha256")
    if stored is None:
        if payload["version"] >= 3:
            raise InvalidInputError("its checksum is missing")
        warnings.warn(
            f"{p}: a version-{payload['version']} weights file, written before thermocal stored "
            "a checksum of the weights: it cannot be checked for damage (only for range); "
            "thermocal.nn.store.upgrade rewrites it with one",
            UnverifiedFileWarning, stacklevel=4,
        )
        return False
    if not isinstance(stored, str) or stored != weights_digest(payload):
        raise InvalidInputError("its content does not match the SHA-256 checksum stored with it")
    return True


def _check_header(payload: dict[str, Any]) -> tuple[ModelConfig, Normalisation, dict[str, Any]]:
    """The configuration (its own checks), the normalisation (:func:`check_normalisation`) and
    the training data's crop (1…8192 px or none)."""
    for key in ("config", "normalisation", "state_dict"):
        if not isinstance(payload.get(key), dict):
            raise InvalidInputError(f"its {key!r} is missing or not a dict")
    for key in ("data", "meta"):
        if not isinstance(payload.get(key, {}), dict):
            raise InvalidInputError(f"its {key!r} is not a dict")
    config = ModelConfig(**payload["config"])
    norm = check_normalisation(payload["normalisation"])
    data = dict(payload.get("data", {}))
    crop = data.get("crop")
    if crop is not None and (type(crop) is not int or not 1 <= crop <= _MAX_CROP):
        raise InvalidInputError(f"training crop {crop!r:.20}, expected an integer in "
                                f"1…{_MAX_CROP} px")
    data["crop"] = crop or None
    return config, norm, data


def check_normalisation(values: dict[str, Any]) -> Normalisation:
    """The :class:`~thermocal.nn.inputs.Normalisation` of a file's values, checked: every value a
    finite number, each range within and as wide as :data:`NORMALISATION_LIMITS`
    (:class:`~thermocal.errors.InvalidInputError` otherwise)."""
    norm = Normalisation(**values)
    for name, (lo, hi, span) in NORMALISATION_LIMITS.items():
        unit = "_c" if name != "counts" else ""
        a, b = getattr(norm, f"{name}_min{unit}"), getattr(norm, f"{name}_max{unit}")
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b)):
            raise InvalidInputError(f"normalisation {name} range ({a!r:.20}, {b!r:.20}) is not "
                                    "numbers")
        if not (math.isfinite(a) and math.isfinite(b) and lo <= a and b <= hi
                and b - a >= span):
            raise InvalidInputError(
                f"normalisation {name} range {a:g}…{b:g}: expected finite, within {lo:g}…{hi:g}, "
                f"increasing by at least {span:g} (a zero span divides by zero)"
            )
    if norm.temp_min_c <= -273.15:
        raise InvalidInputError(f"normalisation temperature {norm.temp_min_c:g} °C is not above "
                                "absolute zero")
    return norm


def _check_state(state: dict[str, Any], config: ModelConfig, norm: Normalisation, *,
                 verified: bool = True) -> dict[str, torch.Tensor]:
    """The state dict against the network ``config`` describes, made without memory (PyTorch's
    ``meta`` device): at most :data:`MAX_PARAMETERS` values, the same names, shapes and dtypes,
    every value finite and every batch-norm running variance ``>= 0``.

    A file whose checksum could not be checked (``verified`` False: versions 1 and 2) must also
    have no convolution whose weights are all zero: training never makes one (the weights start
    orthogonal), damage (zeroed tensors) does."""
    # (without radiance: its table is not part of the state, and takes time to make)
    with torch.device("meta"):
        skeleton = KPN(replace(config, radiance=False), init=False)
    want = skeleton.state_dict()
    total = sum(t.numel() for t in want.values())
    if total > MAX_PARAMETERS:
        raise InvalidInputError(
            f"its configuration asks for {total:,} network values, more than {MAX_PARAMETERS:,}"
        )
    extra = sorted(set(map(str, state)) - set(want))
    missing = sorted(set(want) - set(state))
    if extra or missing:
        raise InvalidInputError(
            f"its state dict does not match its configuration (missing {missing[:3]}, "
            f"unexpected {extra[:3]})"
        )
    for name, ref in want.items():
        t = state[name]
        if not isinstance(t, torch.Tensor) or t.layout != torch.strided:
            raise InvalidInputError(f"state dict entry {name!r} is not a dense tensor")
        if tuple(t.shape) != tuple(ref.shape) or t.dtype != ref.dtype:
            raise InvalidInputError(
                f"state dict entry {name!r} is {t.dtype} {tuple(t.shape)}, its configuration "
                f"needs {ref.dtype} {tuple(ref.shape)}"
            )
        if t.is_floating_point() and not bool(torch.isfinite(t).all()):
            raise InvalidInputError(f"state dict entry {name!r} has non-finite values")
        if name.endswith("running_var") and bool((t < 0).any()):
            raise InvalidInputError(f"state dict entry {name!r} has a negative variance")
        if (not verified and t.ndim == 4 and name.endswith(".weight")
                and not bool(t.any())):
            raise InvalidInputError(f"convolution {name!r} has weights all zero")
    return state


def check_calibrated(model_cfg: ModelConfig, burst_cfg: BurstConfig) -> None:
    """A calibrated network needs calibrated bursts, and only it (:class:`InvalidInputError`)."""
    if model_cfg.calibrated != burst_cfg.calibrated:
        raise InvalidInputError("a calibrated network needs calibrated bursts, and only it")


def _nominal_of(payload: dict[str, Any], config: ModelConfig) -> CameraModel:
    """The nominal camera of a calibrated model's weights file: the stored maps, checked
    against their SHA-256 (version 2, and version-1 chamber fits), or for a version-1 file made
    from a preset, made again from that preset.

    Beyond its checksum, the stored camera must be well formed: maps ``gain``, ``offset``
    ``(4, H, W)`` and ``housing``, ``transient`` ``(H, W)`` with sides of 1…16384 px, finite,
    with positive gains; ``noise_sigma >= 0``, ``t_ref_c`` within −60…150 °C, ``bit_depth`` an
    integer of 1…16; ``units`` integers ``>= 0``, at least one where it names preset parameters
    (it is made again from them at another frame size)."""
    if "nominal" not in payload:
        if payload["version"] != 1:
            raise InvalidInputError("a calibrated network without its camera model")
        data = payload["data"]  # version 1, trained from a preset's units: made again
        size = tuple(data["sensor_size"])
        units = tuple(data.get("nominal_units") or data["units"])
        if not isinstance(data["preset"], str):
            raise InvalidInputError("its training data name no camera preset")
        _check_size(size, "sensor_size")
        _check_units(units, required=True)
        return preset_nominal(data["preset"], size, units)
    d = payload["nominal"]
    if not isinstance(d, dict):
        raise InvalidInputError("its camera model is not a dict")
    for k in NOMINAL_MAPS:
        if not isinstance(d.get(k), torch.Tensor) or not d[k].is_floating_point():
            raise InvalidInputError(f"its camera model's {k!r} map is not a float tensor")
    maps = {k: np.ascontiguousarray(d[k].numpy(), dtype=np.float32) for k in NOMINAL_MAPS}
    if maps["housing"].ndim != 2:
        raise InvalidInputError(f"its camera model's maps have shape {maps['housing'].shape}")
    h, w = maps["housing"].shape
    _check_size((w, h), "camera model")
    for k, want in (("gain", (4, h, w)), ("offset", (4, h, w)), ("transient", (h, w))):
        if maps[k].shape != want:
            raise InvalidInputError(f"its camera model's {k!r} has shape {maps[k].shape}, "
                                    f"expected {want}")
    if type(d.get("bit_depth")) is not int or not 1 <= d["bit_depth"] <= 16:
        raise InvalidInputError(f"its camera model's bit depth {d.get('bit_depth')!r:.20}")
    scalars = {"noise_sigma": float(d["noise_sigma"]), "t_ref_c": float(d["t_ref_c"]),
               "bit_depth": int(d["bit_depth"])}
    if not (math.isfinite(scalars["noise_sigma"]) and scalars["noise_sigma"] >= 0
            and math.isfinite(scalars["t_ref_c"]) and -60.0 <= scalars["t_ref_c"] <= 150.0):
        raise InvalidInputError(f"its camera model's noise ({scalars['noise_sigma']:g}) or "
                                f"reference FPA temperature ({scalars['t_ref_c']:g} °C)")
    params = d.get("preset_parameters")
    if params is not None and not isinstance(params, dict):
        raise InvalidInputError("its camera preset parameters are not a dict")
    raw_units = d.get("units") or []
    _check_units(raw_units, required=bool(params))
    units = [int(u) for u in raw_units]
    origin = {"preset_parameters": params, "units": units}
    if payload["version"] != 1 and d.get("sha256") != _nominal_sha256(maps, scalars, origin):
        raise InvalidInputError("its camera model does not match the checksum stored with it")
    if not all(np.all(np.isfinite(m)) for m in maps.values()) or not np.all(maps["gain"][0] > 0):
        raise InvalidInputError("its camera model has non-finite or non-positive gain terms")
    # the family's physics beyond the maps (refused here, not when another frame size first
    # needs the preset); a chamber fit is of the polynomial form
    preset = _preset_of(params) if params else None
    physics = family_physics(preset) if preset else {}
    response = tuple(preset.spectral_response) if preset else ()
    return CameraModel(
        **maps, defects=np.zeros(maps["housing"].shape, bool),
        defect_counts=np.zeros(maps["housing"].shape, np.uint16),
        **scalars, **physics, band=band_table(tuple(config.band_m), response),
        info={"preset": params["name"] if params else None, "units": units,
              "preset_parameters": params},
    )


def _check_size(size: Any, what: str) -> None:
    if (len(size) != 2 or not all(type(v) is int and 1 <= v <= _MAX_SIDE for v in size)):
        raise InvalidInputError(f"its {what} size {size!r:.40} is not (W, H) of 1…{_MAX_SIDE} px")


def _check_units(units: Any, *, required: bool) -> None:
    if not isinstance(units, (list, tuple)) or not all(
            type(u) is int and 0 <= u < 2**31 for u in units):
        raise InvalidInputError(f"its camera units {units!r:.40} are not unit numbers")
    if required and not units:
        raise InvalidInputError("its camera model names a preset but no units to make it from")


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
        return CameraPreset.from_dict(params)
    except (TypeError, InvalidInputError) as exc:
        raise InvalidInputError(f"its camera preset parameters are not thermocal's ({exc})"
                                ) from None


def upgrade(path: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Write the weights file ``path`` (any version this thermocal reads, checked as
    :func:`load_model` checks it) as the current version to ``out`` (atomically): the same
    weights, tensor for tensor, with what the versions since added. From version 1: the nominal
    camera its version-1 reader makes, stored in it, so that later changes to the preset no
    longer change what the network sees. From versions 1 and 2: the SHA-256 of the whole
    content (:func:`weights_digest`).

    Upgrading a file vouches for it: do it only for a file known to be intact."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnverifiedFileWarning)
        model, _, _ = load_model(path)
    payload = torch.load(Path(path), map_location="cpu", weights_only=True)
    if payload["version"] != VERSION:
        if payload["version"] == 1 and model.config.calibrated:
            payload["nominal"] = nominal_payload(model.nominal)
        payload["version"] = VERSION
        payload["sha256"] = weights_digest(payload)
    with atomic_path(Path(out)) as tmp:
        torch.save(payload, tmp)
    return Path(out)
