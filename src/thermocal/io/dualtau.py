"""Flights recorded by the DualTauUAV rig (navotoz/DualTauUAV): a folder of ``.npz`` files.

The rig (a Tau2 336 on a TeAx grabber) saves one ``np.savez`` file about every 2 s of flight.
The layout read here is inferred from the rig's description (``shared/data/SOURCES.md``; no data
set is public), so it is an assumption:

=================== ====================================== =====================================
key                 type, shape                            meaning
=================== ====================================== =====================================
``frames``          uint16 ``(N, H, W)`` (or ``(H, W)``)   raw 14-bit counts
``fpa``             integer ``(N,)`` or a scalar           FPA temperature, **hundredths of °C**
                                                           (uint16 values above 32767 are
                                                           negative temperatures that wrapped)
``time_ns_start``   integer ``(N,)``                       start of each frame, ns (epoch)
``time_ns_end``     integer ``(N,)``, optional             end of each frame, ns (not used)
=================== ====================================== =====================================

A flight is the folder's files ordered by their first ``time_ns_start`` (then by name);
``time_s`` is ``time_ns_start`` minus the flight's first, in s. Frames whose times go backwards
inside a file, or files whose times overlap, are refused (naming the file): the frames cannot
be put in order without guessing. A file that cannot be read (a damaged zip, an array that does
not load) is left out of the flight and listed in :attr:`DualTauIndex.damaged`; a file without
the arrays above is refused.

**FPA unit.** Values whose hundredths are a plausible FPA temperature (−60…120 °C) are read as
hundredths of °C, the rig's unit. Values that are clearly in another unit are converted with a
warning: integers whose thousandths less 273.15 are plausible (millikelvin), fractional values
plausible as °C or as kelvin. Integers all within ±120 would be an FPA held within ±1.2 °C of
freezing in hundredths and are as likely whole °C: refused, since either reading may be wrong.

**FPA temperature.** The rig reads it from the camera only every 30 s, rounded to 0.1 °C, and
repeats the last reading on every frame. A *reading* is taken to be the first frame and every
frame whose value differs from the frame before; between readings the FPA temperature is
interpolated linearly in time, and held before the first and after the last. ``fpa_measured``
is True on the frames of a reading, False on interpolated ones.

:func:`index_dualtau_folder` reads only the small arrays (``fpa``, times) and the frames'
shape, so that the frames can be streamed file by file (:func:`read_dualtau_frames`).
"""

from __future__ import annotations

import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import FPA_RANGE_C
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import FileFormatError

__all__ = [
    "DUALTAU_KEYS",
    "DualTauIndex",
    "index_dualtau_folder",
    "interpolate_fpa_readings",
    "npz_keys",
    "read_dualtau_frames",
]

#: Arrays a DualTauUAV ``.npz`` must hold.
DUALTAU_KEYS: tuple[str, ...] = ("frames", "fpa", "time_ns_start")


@dataclass(frozen=True)
class DualTauIndex:
    """A flight's files in time order and its per-frame series (frames not loaded);
    ``damaged``: ``(file name, reason)`` of the files left out as unreadable."""

    files: tuple[Path, ...]
    counts: tuple[int, ...]
    frame_shape: tuple[int, int]
    time_s: np.ndarray
    time_origin_ns: int
    fpa_c: np.ndarray
    fpa_measured: np.ndarray
    fpa_readings_c: np.ndarray
    damaged: tuple[tuple[str, str], ...] = ()


class UnreadableFileError(FileFormatError):
    """A file that cannot be read (damaged), as opposed to one of another layout."""


def npz_keys(path: Path) -> list[str]:
    """Array names of an ``.npz`` (without loading them)."""
    try:
        with zipfile.ZipFile(path) as zf:
            return [n[:-4] if n.endswith(".npy") else n for n in zf.namelist()]
    except (OSError, zipfile.BadZipFile, ValueError) as exc:
        raise UnreadableFileError(f"{path}: not a readable .npz file ({exc})") from None


def _frames_shape(path: Path) -> tuple[int, ...]:
    """Shape of ``frames`` in an ``.npz`` from its .npy header only."""
    try:
        with zipfile.ZipFile(path) as zf, zf.open("frames.npy") as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
    except Exception as exc:  # zipfile and numpy raise many types on damaged files
        raise UnreadableFileError(f"{path}: 'frames' cannot be read ({exc})") from None
    if dtype.kind not in "ui" or len(shape) not in (2, 3):
        raise FileFormatError(
            f"{path}: 'frames' must be integer counts (N, H, W), got {dtype} {shape}"
        )
    return tuple(int(v) for v in shape)


def _fpa_c(values: np.ndarray, n: int, path: Path) -> tuple[np.ndarray, str]:
    """The ``fpa`` of one file in °C and the unit it was read in (``"1/100 °C"``, ``"°C"``,
    ``"K"``, ``"mK"``); see the module's notes on the FPA unit."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "iuf" or arr.ndim > 1:
        raise FileFormatError(f"{path}: 'fpa' must hold 1/100 °C numbers, got {arr.dtype} "
                              f"{arr.shape}")
    if arr.dtype == np.uint16 and arr.size and int(arr.max()) > 32767:
        arr = arr.view(np.int16)  # negative temperatures saved with astype('uint16')
    v = arr.astype(np.float64).reshape(-1)
    if v.size == 1:
        v = np.full(n, v[0])
    if v.size != n:
        raise FileFormatError(f"{path}: 'fpa' has {v.size} values for {n} frames")
    if not n:
        return v, "1/100 °C"
    if not np.all(np.isfinite(v)):
        raise FileFormatError(f"{path}: 'fpa' holds NaN or infinite values")
    lo, hi = FPA_RANGE_C

    def plausible(c: np.ndarray) -> bool:
        return bool(c.min() >= lo and c.max() <= hi)

    whole = bool(np.all(v == np.round(v)))
    if whole and plausible(v / 100.0):
        return v / 100.0, "1/100 °C"
    if whole and plausible(v / 1000.0 - ZERO_CELSIUS_K):
        return v / 1000.0 - ZERO_CELSIUS_K, "mK"
    if not whole and plausible(v):
        return v, "°C"
    if not whole and plausible(v - ZERO_CELSIUS_K):
        return v - ZERO_CELSIUS_K, "K"
    raise FileFormatError(
        f"{path}: 'fpa' holds {v.min():g}..{v.max():g}, no plausible FPA temperature "
        f"({lo:g}..{hi:g} °C) in any unit thermocal knows (the rig's 1/100 °C; °C, K, mK)"
    )


def _small_arrays(path: Path) -> tuple[np.ndarray, str, np.ndarray, tuple[int, int], int]:
    keys = npz_keys(path)
    missing = [k for k in DUALTAU_KEYS if k not in keys]
    if missing:
        raise FileFormatError(
            f"{path}: missing array(s) {missing} (has {sorted(keys)}); not a DualTauUAV file?"
        )
    shape = _frames_shape(path)
    n = 1 if len(shape) == 2 else shape[0]
    try:
        with np.load(path, allow_pickle=False) as npz:
            fpa = npz["fpa"]
            t_ns = npz["time_ns_start"]
    except Exception as exc:  # numpy/zipfile raise many types on damaged files
        raise UnreadableFileError(f"{path}: an array cannot be read ({exc})") from None
    t_ns = np.asarray(t_ns).reshape(-1)
    if t_ns.dtype.kind not in "iu" or t_ns.size != n:
        raise FileFormatError(
            f"{path}: 'time_ns_start' must be {n} integers (one per frame), got {t_ns.dtype} "
            f"{t_ns.shape}"
        )
    t_ns = t_ns.astype(np.int64)
    if np.any(np.diff(t_ns) < 0):
        k = int(np.flatnonzero(np.diff(t_ns) < 0)[0]) + 1
        raise FileFormatError(
            f"{path}: frame times go backwards inside the file (frame {k} is "
            f"{(t_ns[k - 1] - t_ns[k]) / 1e9:.9g} s before frame {k - 1}); thermocal reads "
            "frames in time order only"
        )
    return (*_fpa_c(fpa, n, path), t_ns, (shape[-2], shape[-1]), n)


def _check_fpa_units(units: dict[str, str], entries: list, folder: Path) -> None:
    """One FPA unit for the flight; a warning when it is not the rig's; refused when the
    hundredths are as likely whole °C (every value within ±120)."""
    if len(units) > 1:
        found = ", ".join(f"{u} ({name})" for u, name in units.items())
        raise FileFormatError(f"{folder}: files with 'fpa' in different units ({found})")
    unit = next(iter(units))
    where = entries[0][2] if len(entries) == 1 else folder
    if unit != "1/100 °C":
        warnings.warn(f"{where}: 'fpa' is in {unit}, not the rig's 1/100 °C; converted to °C",
                      stacklevel=3)
        return
    held = np.concatenate([e[3] for e in entries])
    if float(np.abs(held).max()) <= 1.2:
        raise FileFormatError(
            f"{where}: 'fpa' holds {held.min() * 100:g}..{held.max() * 100:g}: as the rig's "
            f"1/100 °C an FPA within ±1.2 °C of freezing all flight, more likely whole °C; "
            "save it in 1/100 °C (multiply by 100) to be read"
        )


def interpolate_fpa_readings(time_s: np.ndarray, held_c: np.ndarray) -> tuple[
    np.ndarray, np.ndarray
]:
    """Interpolate an FPA series that repeats its last sparse reading on every frame.

    A reading is the first frame and every frame whose value differs from the one before.
    Returns ``(fpa_c, measured)``: linear in time between readings, held outside them; and True
    on the readings' frames.
    """
    held = np.asarray(held_c, dtype=np.float64)
    measured = np.ones(held.shape, dtype=bool)
    if held.size:
        measured[1:] = held[1:] != held[:-1]
    knots = np.flatnonzero(measured)
    if knots.size < 2:
        return held.copy(), measured
    return np.interp(time_s, time_s[knots], held[knots]), measured


def index_dualtau_folder(folder: Path, files: list[Path] | None = None) -> DualTauIndex:
    """Index a DualTauUAV flight: order its ``.npz`` files and build the per-frame series.

    Raises
    ------
    FileFormatError
        No ``.npz`` file, a file without the DualTauUAV arrays or with its FPA in no known unit,
        files of different frame sizes or FPA units, times that go backwards within a file or
        files that overlap in time, or no file that can be read.
    """
    paths = sorted(files if files is not None else folder.glob("*.npz"))
    if not paths:
        raise FileFormatError(f"{folder}: no DualTauUAV .npz file in the folder")
    entries: list[tuple[int, str, Path, np.ndarray, np.ndarray, int]] = []
    damaged: list[tuple[str, str]] = []
    units: dict[str, str] = {}
    shape: tuple[int, int] | None = None
    first: Path | None = None
    for p in paths:
        try:
            fpa_c, unit, t_ns, shp, n = _small_arrays(p)
        except UnreadableFileError as exc:
            damaged.append((p.name, str(exc).removeprefix(f"{p}: ")))
            continue
        if shape is None:
            shape, first = shp, p
        elif shp != shape:
            raise FileFormatError(
                f"{p}: frames of {shp[1]}x{shp[0]} in a flight of {shape[1]}x{shape[0]} "
                f"frames (first file {first.name if first else ''}; width x height)"
            )
        if n == 0:
            continue
        units.setdefault(unit, p.name)
        entries.append((int(t_ns[0]), p.name, p, fpa_c, t_ns, n))
    if shape is None:
        if len(damaged) == 1 and files is not None and len(paths) == 1:
            raise FileFormatError(f"{paths[0]}: {damaged[0][1]}")
        raise FileFormatError(f"{folder}: none of its {len(damaged)} DualTauUAV files can be "
                              f"read (the first, {damaged[0][0]}: {damaged[0][1]})")
    if not entries:
        raise FileFormatError(f"{folder}: the DualTauUAV files hold no frames")
    _check_fpa_units(units, entries, folder)
    entries.sort(key=lambda e: (e[0], e[1]))
    for before, after in zip(entries, entries[1:], strict=False):
        if after[0] < before[4][-1]:
            raise FileFormatError(
                f"{after[2]}: its frames overlap in time those of {before[1]} (it starts "
                f"{(before[4][-1] - after[0]) / 1e9:.3f} s before that file's last frame); "
                "two recordings in one folder?"
            )
    t_all = np.concatenate([e[4] for e in entries])
    origin = int(t_all[0])
    time_s = (t_all - origin).astype(np.float64) / 1e9
    held = np.concatenate([e[3] for e in entries])
    fpa_c, measured = interpolate_fpa_readings(time_s, held)
    return DualTauIndex(
        files=tuple(e[2] for e in entries),
        counts=tuple(e[5] for e in entries),
        frame_shape=shape,
        time_s=time_s,
        time_origin_ns=origin,
        fpa_c=fpa_c,
        fpa_measured=measured,
        fpa_readings_c=held,
        damaged=tuple(damaged),
    )


def read_dualtau_frames(path: Path, expected: tuple[int, ...]) -> np.ndarray:
    """The ``frames`` of one DualTauUAV file as uint16 ``(N, H, W)``, checked against
    ``expected`` (the shape its index recorded)."""
    try:
        with np.load(path, allow_pickle=False) as npz:
            frames: Any = npz["frames"]
    except Exception as exc:  # numpy/zipfile raise many types on damaged files
        raise UnreadableFileError(f"{path}: 'frames' cannot be read ({exc})") from None
    frames = np.asarray(frames)
    if frames.ndim == 2:
        frames = frames[None]
    if frames.shape != expected:
        raise FileFormatError(f"{path}: 'frames' is {frames.shape}, expected {expected} (the "
                              "file changed while it was read?)")
    if frames.size and (int(frames.min()) < 0 or int(frames.max()) > 0xFFFF):
        raise FileFormatError(f"{path}: 'frames' holds values outside 0..65535")
    return frames.astype(np.uint16, copy=False)
