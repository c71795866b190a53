"""Real radiometric scenes: FLIR R-JPEG, radiometric TIFF and FLIR FFF files as °C maps.

:func:`load_scene` looks at a file's first bytes and returns a float32 ``(H, W)`` temperature map
in °C:

* FLIR radiometric JPEG (R-JPEG): decoded by ``flyr`` (raw counts and Planck constants from the
  FLIR APP1 segments);
* TIFF: integer counts scaled to kelvin (``tiff_kelvin_per_count``, 0.04 K for the flirpy / FLIR
  Duo Pro R radiometric TIFF), or float values taken as °C;
* FLIR FFF (the raw file a FLIR core writes, ``"FFF\\0"``): read by :func:`read_fff` and converted
  with :class:`thermocal.radiometry.FlirPlanck`.

:func:`find_shared_data` locates the project's ``shared/data`` folder of real files (see its
``SOURCES.md``) so that tests and benchmarks can use them without packaging them.
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import replace
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.fff import FFF_MAGICS, fff_raw_image, parse_fff_record
from thermocal.io.recording import quiet_tifffile
from thermocal.io.rjpeg import rjpeg_metadata, scan_jpeg
from thermocal.radiometry import FlirPlanck

__all__ = [
    "bundled_shared_data",
    "find_shared_data",
    "list_shared_scenes",
    "load_scene",
    "read_fff",
]

_JPEG_MAGIC = b"\xff\xd8\xff"
_TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")


# --------------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------------
def load_scene(
    path: str | os.PathLike[str],
    *,
    emissivity: float | None = None,
    tiff_kelvin_per_count: float = 0.04,
) -> np.ndarray:
    """Load a real radiometric scene as a temperature map in °C.

    The format is chosen from the file's content, not its name: FLIR R-JPEG, TIFF or FLIR FFF.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    emissivity : float, optional
        Object emissivity (0 < ε ≤ 1) used instead of the one stored in an R-JPEG or FFF file.
        ``None`` (default) keeps the file's value. Not applicable to TIFF files, which hold
        temperatures already.
    tiff_kelvin_per_count : float, optional
        Scale of integer TIFF values, in K per count (default 0.04 K, the FLIR Duo Pro R /
        flirpy radiometric TIFF). Float TIFFs are taken as °C and not scaled.

    Returns
    -------
    numpy.ndarray
        Temperature in °C, float32, shape ``(H, W)``, all finite.

    Raises
    ------
    FileFormatError
        Missing, empty, truncated or unknown file; a JPEG without FLIR radiometric data; a TIFF
        that is not a single 2-D map; a map with non-finite values or values at or below 0 K.
    InvalidInputError
        An invalid ``emissivity`` or ``tiff_kelvin_per_count``, or ``emissivity`` for a TIFF.
    """
    if emissivity is not None:
        emissivity = float(emissivity)
        if not (0.0 < emissivity <= 1.0):
            raise InvalidInputError(f"emissivity: must be in (0, 1], got {emissivity}")
    scale = float(tiff_kelvin_per_count)
    if not (math.isfinite(scale) and scale > 0.0):
        raise InvalidInputError(f"tiff_kelvin_per_count: must be > 0 K, got {scale}")

    p = Path(path)
    data = _read_bytes(p)
    head = data[:4]
    if head[:3] == _JPEG_MAGIC:
        celsius = _load_rjpeg(data, p, emissivity)
    elif head in _TIFF_MAGICS:
        if emissivity is not None:
            raise InvalidInputError(
                f"{p}: emissivity applies only to files with raw counts (R-JPEG, FFF); "
                "a TIFF holds temperatures already"
            )
        celsius = _load_tiff(data, p, scale)
    elif head in FFF_MAGICS:
        raw, planck = _parse_fff(data, p)
        if emissivity is not None:
            planck = replace(planck, emissivity=emissivity)
        try:
            celsius = planck.raw_to_temperature_c(raw)
        except InvalidInputError as exc:
            raise FileFormatError(f"{p}: {exc}") from None
    else:
        raise FileFormatError(
            f"{p}: unknown file format (expected a FLIR radiometric JPEG, a TIFF or a FLIR FFF "
            "file)"
        )
    return _finish(celsius, p)


def read_fff(path: str | os.PathLike[str]) -> tuple[np.ndarray, FlirPlanck]:
    """Read the raw counts and the calibration of a FLIR FFF file.

    Parameters
    ----------
    path : str or os.PathLike
        An FFF file (starts with ``"FFF\\0"``), e.g. one frame of a FLIR Duo Pro R / Tau2 core.

    Returns
    -------
    raw : numpy.ndarray
        Raw counts, uint16, shape ``(H, W)``.
    planck : FlirPlanck
        Planck constants and object/atmosphere parameters from the camera-info record (humidity
        as a fraction, temperatures in °C).

    Raises
    ------
    FileFormatError
        Missing, truncated or non-FFF file, or one without raw-data or camera-info records.
    """
    p = Path(path)
    return _parse_fff(_read_bytes(p), p)


def find_shared_data() -> Path | None:
    """Locate the project's ``shared/data`` folder of real measurement files.

    Looks, in order, at the environment variable ``THERMOCAL_DATA``; then, walking up from this
    source file and then from the current working directory, at ``<dir>/shared/data`` for every
    ancestor ``<dir>`` (this finds ``<repo root>/../shared/data`` as well as
    ``<repo root>/shared/data``); then at the copy bundled with the package
    (``thermocal/data/shared``: the same files, all under licenses that allow it, listed in its
    ``SOURCES.md``), so that training, tests and benchmarks find the real scenes anywhere. A
    folder counts only if it holds ``SOURCES.md``, ``scenes/`` or ``flirpy/``.

    Returns
    -------
    pathlib.Path or None
        The folder (absolute), or ``None`` if none was found.
    """
    env = os.environ.get("THERMOCAL_DATA")
    if env:
        candidate = Path(env).expanduser()
        if candidate.is_dir():
            return candidate.resolve()
    for start in (Path(__file__).resolve().parent, Path.cwd().resolve()):
        for directory in (start, *start.parents):
            candidate = directory / "shared" / "data"
            if _looks_like_shared_data(candidate):
                return candidate
    bundled = bundled_shared_data()
    return bundled if _looks_like_shared_data(bundled) else None


def bundled_shared_data() -> Path:
    """The copy of ``shared/data`` shipped inside the package (``thermocal/data/shared``)."""
    return Path(str(files("thermocal") / "data" / "shared")).resolve()


def list_shared_scenes(data_dir: str | os.PathLike[str] | None = None) -> dict[str, Path]:
    """Real scene files in ``shared/data``, by short name.

    Parameters
    ----------
    data_dir : str or os.PathLike, optional
        The ``shared/data`` folder; default :func:`find_shared_data`.

    Returns
    -------
    dict of str to Path
        File stem → path for ``scenes/*.jpg`` and the flirpy TIFF and FFF files, sorted by name;
        empty when no data folder is found.
    """
    root = Path(data_dir) if data_dir is not None else find_shared_data()
    if root is None or not root.is_dir():
        return {}
    files = sorted((root / "scenes").glob("*.jpg"))
    for pattern in ("*.tif", "*.tiff", "*.fff"):
        files += sorted((root / "flirpy").glob(pattern))
    return {f.stem: f for f in files}


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _looks_like_shared_data(candidate: Path) -> bool:
    return candidate.is_dir() and any(
        (candidate / name).exists() for name in ("SOURCES.md", "scenes", "flirpy")
    )


def _read_bytes(p: Path) -> bytes:
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise FileFormatError(f"{p}: file not found") from None
    except IsADirectoryError:
        raise FileFormatError(f"{p}: is a directory, not a file") from None
    except OSError as exc:
        raise FileFormatError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not data:
        raise FileFormatError(f"{p}: file is empty")
    return data


def _finish(celsius: Any, p: Path) -> np.ndarray:
    arr = np.asarray(celsius)
    if arr.ndim != 2 or arr.size == 0:
        raise FileFormatError(f"{p}: expected a single 2-D temperature map, got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        n_bad = int(arr.size - np.count_nonzero(finite))
        raise FileFormatError(f"{p}: {n_bad} pixel(s) decode to NaN or infinite temperatures")
    # checked before the cast to float32, which would round absolute zero up
    if float(arr.min()) <= -ZERO_CELSIUS_K:
        raise FileFormatError(
            f"{p}: temperatures at or below absolute zero ({float(arr.min()):.2f} °C); "
            "check the file's scale (tiff_kelvin_per_count)"
        )
    return arr.astype(np.float32)


def _load_rjpeg(data: bytes, p: Path, emissivity: float | None) -> np.ndarray:
    import flyr  # imported here: only needed for R-JPEG files

    has_flir, state = scan_jpeg(data)
    if state == "corrupt":
        raise FileFormatError(f"{p}: corrupt JPEG (bad marker segment structure)")
    if state == "truncated" and not has_flir:
        raise FileFormatError(f"{p}: truncated JPEG (file ends inside its header segments)")
    if not has_flir:
        raise FileFormatError(
            f"{p}: JPEG without FLIR radiometric data (no FLIR APP1 segment); "
            "only FLIR radiometric JPEGs (R-JPEG) can be loaded"
        )
    if state == "truncated":
        raise FileFormatError(f"{p}: truncated JPEG (file ends before its end-of-image marker)")
    try:
        thermogram = flyr.unpack(io.BytesIO(data))
        if emissivity is not None:
            thermogram = thermogram.adjust_metadata(emissivity=emissivity)
        with np.errstate(all="ignore"):
            celsius = np.asarray(thermogram.celsius, dtype=np.float64)
    except Exception as exc:  # flyr raises ValueError, KeyError, struct.error, PIL errors, ...
        flyr_error = f"{type(exc).__name__}: {exc}"
    else:
        return celsius
    # flyr cannot read a DJI Zenmuse XT/XT-R's R-JPEG (a Tau2 core: its record in one APP1
    # segment, the raw image a TIFF); thermocal's own reader can, as `thermocal info` does
    try:
        record, _, planck, _ = rjpeg_metadata(data, str(p))
        if emissivity is not None:
            planck = replace(planck, emissivity=emissivity)
        raw = fff_raw_image(record, str(p)).astype(np.float64)
        with np.errstate(all="ignore"):
            return np.asarray(planck.raw_to_temperature_c(raw), dtype=np.float64)
    except (FileFormatError, InvalidInputError) as exc:
        raise FileFormatError(f"{p}: corrupt FLIR radiometric data (flyr: {flyr_error}; "
                              f"thermocal's reader: {exc})") from None


def _load_tiff(data: bytes, p: Path, kelvin_per_count: float) -> np.ndarray:
    import tifffile

    try:
        with quiet_tifffile(), tifffile.TiffFile(io.BytesIO(data)) as tif:
            arr = tif.asarray()
    except Exception as exc:  # tifffile/imagecodecs raise many types for corrupt files
        raise FileFormatError(
            f"{p}: corrupt or truncated TIFF ({type(exc).__name__}: {exc})"
        ) from None
    if arr.ndim == 3 and arr.shape[0] == 1:
        arr = arr[0]
    if arr.ndim != 2:
        raise FileFormatError(
            f"{p}: expected a single-page, single-channel TIFF (H, W), got shape {arr.shape}"
        )
    if arr.dtype.kind == "f":
        return arr.astype(np.float64)
    if arr.dtype.kind in "iu" and arr.dtype.itemsize >= 2:
        return arr.astype(np.float64) * kelvin_per_count - ZERO_CELSIUS_K
    raise FileFormatError(
        f"{p}: TIFF of dtype {arr.dtype} is not a radiometric map (expected 16/32-bit counts "
        "or float °C)"
    )


def _parse_fff(data: bytes, p: Path) -> tuple[np.ndarray, FlirPlanck]:
    """An FFF file's raw counts and Planck constants (:func:`thermocal.io.fff.parse_fff_record`)."""
    frame = parse_fff_record(data, str(p))
    return frame.raw, frame.planck
