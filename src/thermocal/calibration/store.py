"""Calibration files: one HDF5 layout for every calibration method.

=================== ==========================================================================
attribute           meaning
=================== ==========================================================================
``format``          ``"thermocal-calibration"``
``version``         layout version (:data:`VERSION`)
``method``          registry name of the method (``"two-point"``, ``"polynomial"``, ...)
``resolution``      ``(W, H)`` of the frames it applies to, pixels
``camera_unit``     the camera unit it was fitted on (``-1`` if unknown)
``fpa_range_c``     ``(low, high)`` FPA temperatures covered by the fit, °C
``metadata``        JSON: every other scalar parameter of the method and where it came from
=================== ==========================================================================

and one dataset per coefficient array. Writes are atomic (:func:`thermocal.io.atomic.atomic_path`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.atomic import atomic_path

FORMAT = "thermocal-calibration"
VERSION = 1


@dataclass(frozen=True)
class StoredCalibration:
    """What a calibration file holds: the method, its arrays and its metadata."""

    method: str
    arrays: dict[str, np.ndarray]
    resolution: tuple[int, int]
    fpa_range_c: tuple[float, float]
    camera_unit: int = -1
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        """Frame shape ``(H, W)``."""
        return self.resolution[1], self.resolution[0]


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def save_calibration(
    path: str | Path,
    method: str,
    arrays: dict[str, np.ndarray],
    *,
    resolution: tuple[int, int],
    fpa_range_c: tuple[float, float],
    camera_unit: int | None = None,
    metadata: dict[str, Any] | None = None,
) -> Path:
    """Write a calibration file atomically.

    Parameters
    ----------
    path : str or Path
        Output ``.h5``; its folder must exist.
    method : str
        Registry name of the method.
    arrays : dict of str to ndarray
        Coefficient maps, written as datasets.
    resolution : (W, H)
        Frame size, pixels.
    fpa_range_c : (low, high)
        FPA temperatures the fit covered, °C.
    camera_unit : int or None
        The camera unit it was fitted on.
    metadata : dict
        Further JSON-serialisable parameters.
    """
    try:
        text = json.dumps(metadata or {}, default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{path}: calibration metadata cannot be written ({exc})") from None
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["method"] = method
        f.attrs["resolution"] = np.asarray(resolution, dtype=np.int64)
        f.attrs["camera_unit"] = int(-1 if camera_unit is None else camera_unit)
        f.attrs["fpa_range_c"] = np.asarray(fpa_range_c, dtype=np.float64)
        f.attrs["metadata"] = text
        for name, arr in arrays.items():
            f.create_dataset(name, data=np.asarray(arr))
    return Path(path)


def load_calibration(path: str | Path, *, method: str | None = None) -> StoredCalibration:
    """Read a calibration file; ``method`` (if given) must match the file's method.

    Raises
    ------
    FileFormatError
        If the file is missing, not HDF5, not a thermocal calibration, of another version, or
        lacks a required attribute.
    InvalidInputError
        If the file holds a calibration of another method than ``method``.
    """
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{p}: calibration file not found")
    try:
        with h5py.File(p, "r") as f:
            fmt = f.attrs.get("format")
            if isinstance(fmt, bytes):
                fmt = fmt.decode()
            if fmt != FORMAT:
                raise FileFormatError(f"{p}: not a thermocal calibration file")
            if int(f.attrs.get("version", -1)) != VERSION:
                raise FileFormatError(
                    f"{p}: calibration format version {f.attrs.get('version')}, this thermocal "
                    f"reads version {VERSION}; calibrate again"
                )
            missing = [k for k in ("method", "resolution", "fpa_range_c") if k not in f.attrs]
            if missing:
                raise FileFormatError(f"{p}: calibration file lacks attribute(s) {missing}")
            stored = StoredCalibration(
                method=str(f.attrs["method"]),
                arrays={name: f[name][()] for name in f},
                resolution=tuple(int(v) for v in f.attrs["resolution"]),  # type: ignore[arg-type]
                fpa_range_c=tuple(float(v) for v in f.attrs["fpa_range_c"]),  # type: ignore[arg-type]
                camera_unit=int(f.attrs.get("camera_unit", -1)),
                metadata=json.loads(str(f.attrs.get("metadata", "{}"))),
            )
    except FileFormatError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise FileFormatError(f"{p}: unreadable calibration file ({str(exc)[:120]})") from None
    if method is not None and stored.method != method:
        raise InvalidInputError(f"{p}: holds a {stored.method} calibration, not {method}")
    return stored


def require_arrays(stored: StoredCalibration, names: tuple[str, ...], path: str | Path) -> None:
    """Raise FileFormatError unless every array in ``names`` is in the file with the right size."""
    missing = [n for n in names if n not in stored.arrays]
    if missing:
        raise FileFormatError(f"{path}: {stored.method} calibration lacks dataset(s) {missing}")
    for n in names:
        if stored.arrays[n].shape[-2:] != stored.shape and stored.arrays[n].ndim >= 2:
            raise FileFormatError(
                f"{path}: dataset {n!r} has shape {stored.arrays[n].shape}, expected "
                f"(..., {stored.shape[0]}, {stored.shape[1]})"
            )
