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

A calibration class states what it keeps in the file with a :class:`FileLayout` and gets
``save``/``load`` from :class:`StoredCalibrationMixin`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Self

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


@dataclass(frozen=True)
class FileLayout:
    """What a calibration class keeps in its file beside the common header.

    Attributes
    ----------
    methods : tuple of str
        Method names the class reads; the first is the one named in messages.
    arrays : dict of str to dtype
        Datasets every file holds, in the order written; read back with ``astype(dtype)`` after
        :func:`require_arrays`.
    metadata : dict of str to callable
        Metadata entries (attribute name → parser of the stored JSON value), in the order
        written; ``info`` follows them, always.
    optional_arrays : tuple of str
        Datasets written when not None and read back as stored when present (otherwise the
        field keeps its default).
    optional_metadata : tuple of str
        Entries of ``metadata`` a file may lack (the field keeps its default).
    method_arrays : dict of str to dict
        Further datasets (name → dtype) that only the files of one method hold.
    fpa_range : str
        The attribute written as ``fpa_range_c``; read back into the field ``fpa_range_c``.
    """

    methods: tuple[str, ...]
    arrays: dict[str, Any]
    metadata: dict[str, Callable[[Any], Any]]
    optional_arrays: tuple[str, ...] = ()
    optional_metadata: tuple[str, ...] = ()
    method_arrays: dict[str, dict[str, Any]] = field(default_factory=dict)
    fpa_range: str = "fpa_range_c"

    def arrays_for(self, method: str) -> dict[str, Any]:
        """The datasets (name → dtype) a file of ``method`` must hold."""
        return self.arrays | self.method_arrays.get(method, {})


class StoredCalibrationMixin:
    """``save``/``load`` for a frozen calibration dataclass described by ``_layout``.

    The class needs ``shape`` ``(H, W)``, ``method``, ``info`` (a dict; its ``camera_unit`` is
    written to the header), a field ``fpa_range_c`` and a field for every name of its layout.
    """

    _layout: ClassVar[FileLayout]
    if TYPE_CHECKING:  # provided by the dataclass
        method: str
        info: dict[str, Any]
        shape: tuple[int, int]

    def save(self, path: str | Path) -> Path:
        """Write the calibration file (HDF5, atomic)."""
        layout = self._layout
        arrays = {name: getattr(self, name) for name in layout.arrays_for(self.method)}
        for name in layout.optional_arrays:
            if getattr(self, name) is not None:
                arrays[name] = getattr(self, name)
        h, w = self.shape
        return save_calibration(
            path, self.method, arrays, resolution=(w, h),
            fpa_range_c=getattr(self, layout.fpa_range),
            camera_unit=self.info.get("camera_unit"), metadata=self._metadata(),
        )

    @classmethod
    def load(cls, path: str | Path) -> Self:
        """Read a calibration file written by :meth:`save`."""
        methods = cls._layout.methods
        stored = load_calibration(path, method=methods[0] if len(methods) == 1 else None)
        if stored.method not in methods:
            raise InvalidInputError(f"{path}: a {stored.method} calibration, not {methods[0]}")
        return cls(**cls._fields(stored, path))

    def _metadata(self) -> dict[str, Any]:
        """The ``metadata`` entries to write (JSON-serialisable)."""
        meta = {name: getattr(self, name) for name in self._layout.metadata}
        return meta | {"info": self.info}

    @classmethod
    def _check_stored(cls, stored: StoredCalibration, path: str | Path) -> None:
        """Further checks of a file, after its datasets and before its metadata are read."""

    @classmethod
    def _fields(cls, stored: StoredCalibration, path: str | Path) -> dict[str, Any]:
        """The constructor's keyword arguments from a file of one of the class's methods."""
        layout = cls._layout
        arrays = layout.arrays_for(stored.method)
        require_arrays(stored, tuple(arrays), path)
        cls._check_stored(stored, path)
        kw: dict[str, Any] = {name: stored.arrays[name].astype(dtype)
                              for name, dtype in arrays.items()}
        kw |= {name: stored.arrays[name] for name in layout.optional_arrays
               if name in stored.arrays}
        meta = stored.metadata
        missing = [name for name in layout.metadata
                   if name not in meta and name not in layout.optional_metadata]
        if missing:
            raise FileFormatError(f"{path}: {stored.method} calibration lacks metadata {missing}")
        try:
            kw |= {name: parse(meta[name]) for name, parse in layout.metadata.items()
                   if name in meta}
            kw["info"] = dict(meta.get("info", {}))
        except (TypeError, ValueError) as exc:
            raise FileFormatError(
                f"{path}: unreadable {stored.method} calibration metadata ({exc})"
            ) from None
        kw["fpa_range_c"] = stored.fpa_range_c
        if any(f.name == "method" for f in fields(cls)):  # type: ignore[arg-type]
            kw["method"] = stored.method
        return kw
