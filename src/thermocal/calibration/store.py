"""Calibration files: one HDF5 layout for every calibration method.

Attributes ``format = "thermocal-calibration"``, ``version``, ``method``, ``resolution = (W, H)``,
``fpa_range_c``, free metadata (camera unit, source file); one dataset per coefficient map.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from thermocal.errors import FileFormatError
from thermocal.io.atomic import atomic_path

FORMAT = "thermocal-calibration"
VERSION = 1


def save_calibration(
    path: str | Path, method: str, arrays: dict[str, np.ndarray], attrs: dict[str, Any]
) -> None:
    """Write a calibration atomically: ``arrays`` become datasets, ``attrs`` JSON metadata."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["method"] = method
        f.attrs["metadata"] = json.dumps(attrs)
        for name, arr in arrays.items():
            f.create_dataset(name, data=np.asarray(arr))


def load_calibration(path: str | Path) -> tuple[str, dict[str, np.ndarray], dict[str, Any]]:
    """Read a calibration file: ``(method, arrays, metadata)``; anything else is FileFormatError."""
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{p}: calibration file not found")
    try:
        with h5py.File(p, "r") as f:
            if f.attrs.get("format") != FORMAT:
                raise FileFormatError(f"{p}: not a thermocal calibration file")
            if int(f.attrs.get("version", -1)) != VERSION:
                raise FileFormatError(f"{p}: calibration format version {f.attrs.get('version')}")
            method = str(f.attrs["method"])
            metadata = json.loads(str(f.attrs.get("metadata", "{}")))
            arrays = {name: f[name][()] for name in f}
    except FileFormatError:
        raise
    except (OSError, KeyError, ValueError) as exc:
        raise FileFormatError(f"{p}: unreadable calibration file ({exc})") from None
    return method, arrays, metadata
