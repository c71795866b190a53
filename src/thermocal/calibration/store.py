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
``sha256``          SHA-256 of the attributes above and of every dataset
                    (:func:`calibration_digest`), checked at load
=================== ==========================================================================

and one dataset per coefficient array. Writes are atomic (:func:`thermocal.io.atomic.atomic_path`).

A file is read only if it is whole and physically sensible:

* its checksum matches (a version-2 file without one is refused; a version-1 file, written before
  checksums, is read with an :class:`~thermocal.calibration.base.UnverifiedFileWarning`, and
  :func:`~thermocal.calibration.registry.upgrade_calibration` writes it again as version 2);
* its header is well formed: ``resolution`` two integers in ``1 … MAX_SIDE``, ``fpa_range_c`` two
  finite values in :data:`FPA_LIMITS_C`, low ≤ high, ``metadata`` a JSON object with no NaN;
* every dataset it must hold is there, numeric, of the frame's shape, and no dataset declares
  more bytes than the file holds (a damaged header cannot make the reader allocate more);
* each method checks its coefficients (``_check_fields``): finite, and within the bounds of
  :data:`RESPONSE_LIMITS_COUNTS`, :data:`OFFSET_LIMIT_COUNTS`, :data:`BAND_LIMITS_M`,
  :data:`MAX_BAD_FRACTION` and the method's own, each stated where it is checked.

Anything else is a :class:`~thermocal.errors.FileFormatError` naming the file, in one line.

A calibration class states what it keeps in the file with a :class:`FileLayout` and gets
``save``/``load`` from :class:`StoredCalibrationMixin`.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Self

import h5py
import numpy as np

from thermocal.calibration.base import UnverifiedFileWarning
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.atomic import atomic_path
from thermocal.io.chamber import damaged_attribute_type

FORMAT = "thermocal-calibration"
#: 2: the file holds its SHA-256 (``sha256``), checked at load. 1: no checksum (still read).
VERSION = 2
#: Versions this thermocal reads.
READ_VERSIONS = (1, 2)
#: The attribute holding the checksum.
CHECKSUM = "sha256"
#: The attributes the checksum covers (with every dataset), in this order.
HEADER = ("format", "version", "method", "resolution", "camera_unit", "fpa_range_c", "metadata")

#: FPA temperatures a calibration file may name (its fitted range and reference points), °C: the
#: bounds thermocal accepts for an FPA sensor reading anywhere (the chamber readers refuse
#: readings outside them); uncooled microbolometers operate within about −40…+80 °C.
FPA_LIMITS_C = (-60.0, 150.0)
#: Largest frame side, pixels (today's largest uncooled arrays are 1920×1200).
MAX_SIDE = 16384
#: The spectral band ``(λ1, λ2)`` must lie within these, m: thermal cameras see the MWIR
#: (3–5 µm) or the LWIR (7–14 µm) window; a band outside 1–30 µm is no thermal camera's.
BAND_LIMITS_M = (1e-6, 30e-6)
#: How far a scene change of 0 → 100 °C moves a pixel's counts, in absolute value: at least one
#: count (a pixel that moves less cannot measure temperature at all) and at most 2**20 counts
#: (16 times the whole range of a 16-bit ADC; a Tau2 moves ~7000 of its 16384). Each method
#: checks the response of every pixel with its own model, at the FPA temperatures it was fitted
#: on, and that it has the same sign on every pixel (a fit replaces the gain of every pixel it
#: marks bad by the median, so no stored pixel responds the other way).
RESPONSE_LIMITS_COUNTS = (1.0, 2.0**20)
#: Largest offset (counts at zero scene term) a method stores, in absolute value: 16 times the
#: whole range of a 16-bit ADC.
OFFSET_LIMIT_COUNTS = 2.0**20
#: Every fit refuses to make a calibration with more than half of its pixels bad: a file with more
#: is damaged (and one with every pixel bad would give NaN everywhere).
MAX_BAD_FRACTION = 0.5


class _NanInJson(ValueError):
    pass


def _no_constant(name: str) -> Any:
    raise _NanInJson(f"{name} in the metadata")


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


def _canonical(value: Any) -> bytes:
    """Bytes standing for one attribute or dataset value: its type, dtype, shape and content."""
    if isinstance(value, bytes):
        body = b"bytes:" + value
    elif isinstance(value, str):
        body = b"str:" + value.encode("utf-8", "surrogatepass")
    else:
        a = np.asarray(value)
        if a.dtype.kind in "OUSV":
            body = f"obj:{a.dtype.str}:{a.shape}:{a.tolist()!r}".encode("utf-8", "surrogatepass")
        else:
            a = np.ascontiguousarray(a)
            body = f"arr:{a.dtype.str}:{a.shape}:".encode() + a.tobytes()
    return len(body).to_bytes(8, "little") + body


def calibration_digest(attrs: Mapping[str, Any], arrays: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of a calibration file's content: the attributes of :data:`HEADER` (an absent
    one counts as absent) and every dataset (name, dtype, shape, bytes), in sorted order.

    ``attrs`` and ``arrays`` are the values as read back from the file (``h5py``'s attributes and
    ``dataset[()]``), so that a file's checksum is what any reader of it computes.
    """
    digest = hashlib.sha256(b"thermocal-calibration-sha256\n")
    for key in HEADER:
        digest.update(_canonical(key))
        digest.update(_canonical(attrs[key]) if key in attrs else b"absent")
    for name in sorted(arrays):
        digest.update(_canonical(name))
        digest.update(_canonical(arrays[name]))
    return digest.hexdigest()


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
    """Write a calibration file atomically, with its checksum (:func:`calibration_digest`).

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
        # Text as fixed-length ASCII (JSON escapes the rest): variable-length strings live in
        # HDF5's global heap, which a damaged file can send the reader searching for seconds.
        f.attrs["format"] = np.bytes_(FORMAT)
        f.attrs["version"] = VERSION
        f.attrs["method"] = np.bytes_(method.encode("ascii"))
        f.attrs["resolution"] = np.asarray(resolution, dtype=np.int64)
        f.attrs["camera_unit"] = int(-1 if camera_unit is None else camera_unit)
        f.attrs["fpa_range_c"] = np.asarray(fpa_range_c, dtype=np.float64)
        f.attrs["metadata"] = np.bytes_(text.encode("ascii"))
        for name, arr in arrays.items():
            f.create_dataset(name, data=np.asarray(arr))
        # the checksum of what a reader gets back, not of what was handed in
        f.attrs[CHECKSUM] = np.bytes_(calibration_digest(
            {k: f.attrs[k] for k in HEADER}, {name: f[name][()] for name in f}
        ).encode("ascii"))
    return Path(path)


def load_calibration(path: str | Path, *, method: str | None = None) -> StoredCalibration:
    """Read a calibration file; ``method`` (if given) must match the file's method.

    The file's checksum and header are checked (see the module's docstring); the method's
    coefficients are checked by its class's ``load``.

    Raises
    ------
    FileFormatError
        If the file is missing, not HDF5, not a thermocal calibration, of another version,
        damaged (its checksum does not match, an attribute or a dataset is malformed), or lacks a
        required attribute.
    InvalidInputError
        If the file holds a calibration of another method than ``method``.
    """
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{p}: calibration file not found")
    try:
        with h5py.File(p, "r") as f:
            damaged = damaged_attribute_type(f)
            if damaged is not None:
                raise FileFormatError(f"{p}: the calibration file is damaged (attribute "
                                      f"{damaged!r} has a damaged type); calibrate again")
            fmt = _attr(f, "format", p)
            if isinstance(fmt, bytes):
                fmt = fmt.decode()
            if fmt == "thermocal-chamber" or ("frames" in f and "blackbody_c" in f):
                raise FileFormatError(f"{p}: a chamber session, not a calibration: fit one "
                                      f"from it first (`thermocal calibrate {p.name} --out "
                                      "CAL.h5`)")
            if not isinstance(fmt, str) or fmt != FORMAT:
                raise FileFormatError(f"{p}: not a thermocal calibration file")
            raw_version = _attr(f, "version", p)
            version = _version(raw_version)
            if version not in READ_VERSIONS:
                raise FileFormatError(
                    f"{p}: calibration format version {raw_version!r:.20}, this thermocal "
                    f"reads versions {', '.join(map(str, READ_VERSIONS))}; calibrate again"
                )
            missing = [k for k in ("method", "resolution", "fpa_range_c") if k not in f.attrs]
            if missing:
                raise FileFormatError(f"{p}: calibration file lacks attribute(s) {missing}")
            arrays = _read_datasets(f, p)
            attrs = {k: _attr(f, k, p) for k in HEADER if k in f.attrs}
            stored_sum = _attr(f, CHECKSUM, p)
        _check_checksum(p, version, stored_sum, calibration_digest(attrs, arrays))
        stored = StoredCalibration(
            method=_method_of(attrs["method"], p),
            arrays=arrays,
            resolution=_resolution_of(attrs["resolution"], p),
            fpa_range_c=_fpa_range_of(attrs["fpa_range_c"], p),
            camera_unit=_camera_unit_of(attrs.get("camera_unit", -1), p),
            metadata=_metadata_of(attrs.get("metadata", "{}"), p),
        )
    except FileFormatError:
        raise
    except Exception as exc:  # h5py raises many types for a damaged file
        text = str(exc).strip().splitlines()[0][:120] if str(exc).strip() else ""
        raise FileFormatError(
            f"{p}: unreadable calibration file ({type(exc).__name__}{': ' if text else ''}{text})"
        ) from None
    if method is not None and stored.method != method:
        raise InvalidInputError(f"{p}: holds a {stored.method} calibration, not {method}")
    return stored


#: Largest attribute a calibration file's reader reads, bytes (its metadata is a few kB).
_MAX_ATTR_BYTES = 1 << 20


def _attr(f: h5py.File, name: str, p: Path) -> Any:
    """Attribute ``name`` (None when absent), refused before it is read when it declares more
    than :data:`_MAX_ATTR_BYTES` (a damaged dataspace must not make the reader allocate)."""
    if name not in f.attrs:
        return None
    aid = h5py.h5a.open(f.id, name.encode())
    shape = aid.shape or ()
    if math.prod(shape) * aid.dtype.itemsize > _MAX_ATTR_BYTES:
        raise FileFormatError(f"{p}: damaged calibration file (attribute {name!r} declares "
                              f"shape {shape})")
    return f.attrs[name]


def _version(value: Any) -> int | None:
    a = np.asarray(value) if value is not None else None
    if a is None or a.shape != () or a.dtype.kind not in "iu":
        return None
    return int(a)


def _read_datasets(f: h5py.File, p: Path) -> dict[str, np.ndarray]:
    """Every dataset of the file, refusing groups, empty datasets, and a dataset that declares
    more bytes than the file holds (datasets are written uncompressed)."""
    size = p.stat().st_size
    arrays: dict[str, np.ndarray] = {}
    for name in f:
        ds = f.get(name)
        if not isinstance(ds, h5py.Dataset) or ds.shape is None:
            raise FileFormatError(f"{p}: damaged calibration file ({name!r} is not an array)")
        nbytes = math.prod(ds.shape) * ds.dtype.itemsize
        limit = size if ds.compression is None else 1 << 31
        if nbytes > limit:
            raise FileFormatError(
                f"{p}: damaged calibration file (dataset {name!r} declares {ds.shape}, "
                f"{nbytes} bytes: more than the file holds)"
            )
        value = ds[()]
        if not isinstance(value, np.ndarray):
            value = np.asarray(value)
        arrays[name] = value
    return arrays


def _check_checksum(p: Path, version: int | None, stored: Any, actual: str) -> None:
    if isinstance(stored, bytes):
        stored = stored.decode("ascii", "replace")
    if stored is None:
        if version == 1:
            warnings.warn(
                f"{p}: a version-1 calibration file, written before thermocal stored checksums: "
                "it cannot be checked for damage (its coefficients are checked for range only); "
                "thermocal.calibration.upgrade_calibration rewrites it with one",
                UnverifiedFileWarning, stacklevel=4,
            )
            return
        raise FileFormatError(f"{p}: damaged calibration file (its checksum is missing)")
    if not isinstance(stored, str) or stored != actual:
        raise FileFormatError(
            f"{p}: damaged calibration file (its content does not match the SHA-256 checksum "
            "stored with it)"
        )


def _bad_attr(p: Path, name: str, value: Any, expected: str) -> FileFormatError:
    desc = repr(value) if not isinstance(value, np.ndarray) else (
        f"{value.dtype} array of shape {value.shape}")
    return FileFormatError(
        f"{p}: damaged calibration file (attribute {name!r} is {desc[:60]}, expected {expected})"
    )


def _method_of(value: Any, p: Path) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if not isinstance(value, str) or not value:
        raise _bad_attr(p, "method", value, "a method name")
    return value


def _resolution_of(value: Any, p: Path) -> tuple[int, int]:
    a = np.asarray(value)
    if (a.shape != (2,) or a.dtype.kind not in "iu"
            or not all(1 <= int(v) <= MAX_SIDE for v in a)):
        raise _bad_attr(p, "resolution", a, f"(W, H), two integers in 1…{MAX_SIDE}")
    return int(a[0]), int(a[1])


def _fpa_range_of(value: Any, p: Path) -> tuple[float, float]:
    a = np.asarray(value)
    lo_lim, hi_lim = FPA_LIMITS_C
    if (a.shape != (2,) or a.dtype.kind not in "iuf" or not np.all(np.isfinite(a))
            or not lo_lim <= float(a[0]) <= float(a[1]) <= hi_lim):
        raise _bad_attr(p, "fpa_range_c", a,
                        f"(low, high) °C, finite, low <= high, within {lo_lim:g}…{hi_lim:g} °C")
    return float(a[0]), float(a[1])


def _camera_unit_of(value: Any, p: Path) -> int:
    a = np.asarray(value)
    if a.shape != () or a.dtype.kind not in "iu" or int(a) < -1:
        raise _bad_attr(p, "camera_unit", a, "an integer >= -1")
    return int(a)


def _metadata_of(value: Any, p: Path) -> dict[str, Any]:
    if isinstance(value, bytes):
        value = value.decode("utf-8")
    if not isinstance(value, str):
        raise _bad_attr(p, "metadata", value, "a JSON object")
    try:
        meta = json.loads(value, parse_constant=_no_constant)
    except ValueError as exc:
        raise FileFormatError(
            f"{p}: damaged calibration file (metadata is not JSON: {str(exc)[:80]})"
        ) from None
    if not isinstance(meta, dict):
        raise _bad_attr(p, "metadata", meta, "a JSON object")
    return meta


def require_arrays(stored: StoredCalibration, names: tuple[str, ...], path: str | Path,
                   stacks: Mapping[str, int] | None = None) -> None:
    """Raise FileFormatError unless every array in ``names`` is in the file, numeric (bool,
    integer or float) and of the frame's shape ``(H, W)``, or ``(stacks[name], H, W)``."""
    missing = [n for n in names if n not in stored.arrays]
    if missing:
        raise FileFormatError(f"{path}: {stored.method} calibration lacks dataset(s) {missing}")
    for n in names:
        a = stored.arrays[n]
        depth = (stacks or {}).get(n)
        want = stored.shape if depth is None else (depth, *stored.shape)
        if a.shape != want:
            raise FileFormatError(
                f"{path}: dataset {n!r} has shape {a.shape}, expected {want}"
            )
        if a.dtype.kind not in "biuf":
            raise FileFormatError(f"{path}: dataset {n!r} holds {a.dtype}, not numbers")


# ------------------------------------------------------------------------ coefficient checks


def damaged(path: str | Path, method: str, what: str) -> FileFormatError:
    """The error for a file whose coefficients fail a check (one line)."""
    return FileFormatError(f"{path}: damaged {method} calibration file ({what})")


def check_finite(kw: Mapping[str, Any], names: tuple[str, ...], path: str | Path,
                 method: str) -> None:
    """Every value of ``names`` in ``kw`` (arrays or numbers) is finite."""
    for name in names:
        value = kw.get(name)
        if value is None:
            continue
        a = np.asarray(value)
        if a.dtype.kind not in "biuf" or not np.all(np.isfinite(a)):
            raise damaged(path, method, f"{name!r} is not finite everywhere")


def check_scalar(value: Any, name: str, lo: float, hi: float, path: str | Path, method: str,
                 *, unit: str = "", low_open: bool = False, integer: bool = False) -> None:
    """``lo <= value <= hi`` (``lo < value`` with ``low_open``), finite, a real number (an
    integer with ``integer``)."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if ok and integer:
        ok = float(value).is_integer() if math.isfinite(float(value)) else False
    if ok:
        v = float(value)
        ok = math.isfinite(v) and (lo < v if low_open else lo <= v) and v <= hi
    if not ok:
        rng = f"{'(' if low_open else '['}{lo:g}, {hi:g}]{(' ' + unit) if unit else ''}"
        kind = "an integer " if integer else ""
        raise damaged(path, method, f"{name} = {value!r:.40}, expected {kind}in {rng}")


def check_band(band_m: Any, path: str | Path, method: str) -> None:
    """``band_m`` is ``(λ1, λ2)`` m, increasing, within :data:`BAND_LIMITS_M`."""
    lo, hi = BAND_LIMITS_M
    try:
        b = tuple(float(v) for v in band_m)
        ok = len(b) == 2 and lo <= b[0] < b[1] <= hi
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise damaged(path, method, f"band_m = {band_m!r:.60}, expected (λ1, λ2) within "
                                    f"{lo:g}…{hi:g} m, increasing")


def check_response(response: np.ndarray, path: str | Path, method: str, where: str) -> None:
    """The counts a 0 → 100 °C scene change gives each pixel (:data:`RESPONSE_LIMITS_COUNTS`):
    finite, of one sign on every pixel, within the limits in absolute value."""
    lo, hi = RESPONSE_LIMITS_COUNTS
    r = np.asarray(response, dtype=np.float64)
    if not np.all(np.isfinite(r)):
        raise damaged(path, method, f"its response {where} is not finite everywhere")
    sign = np.sign(np.median(r))
    mag = r * sign
    if sign == 0 or not np.all(mag >= lo) or not np.all(mag <= hi):
        worst = float(r.flat[np.argmin(mag)]) if sign and np.any(mag < lo) else float(
            r.flat[np.argmax(np.abs(r))])
        raise damaged(
            path, method,
            f"a pixel's response to a 0 to 100 °C scene {where} is {worst:.4g} counts: every "
            f"pixel must respond with the same sign, by {lo:g} to {hi:g} counts"
        )


def check_offsets(value: np.ndarray, name: str, path: str | Path, method: str) -> None:
    """``|value| <= OFFSET_LIMIT_COUNTS`` everywhere (and finite)."""
    a = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > OFFSET_LIMIT_COUNTS):
        raise damaged(path, method, f"{name!r} is not finite or exceeds ±{OFFSET_LIMIT_COUNTS:g} "
                                    "counts")


def check_bad(bad: np.ndarray, path: str | Path, method: str) -> None:
    """At most :data:`MAX_BAD_FRACTION` of the pixels are bad."""
    if float(np.mean(bad)) > MAX_BAD_FRACTION:
        raise damaged(path, method, f"{float(np.mean(bad)):.0%} of its pixels are marked bad; "
                                    f"every fit refuses more than {MAX_BAD_FRACTION:.0%}")


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
    stacks : dict of str to int
        Datasets that are stacks of maps, ``(depth, H, W)``, by name (the others are ``(H, W)``).
    """

    methods: tuple[str, ...]
    arrays: dict[str, Any]
    metadata: dict[str, Callable[[Any], Any]]
    optional_arrays: tuple[str, ...] = ()
    optional_metadata: tuple[str, ...] = ()
    method_arrays: dict[str, dict[str, Any]] = field(default_factory=dict)
    fpa_range: str = "fpa_range_c"
    stacks: dict[str, int] = field(default_factory=dict)

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
        """Read a calibration file written by :meth:`save`: its checksum, header, datasets and
        coefficients checked (:class:`~thermocal.errors.FileFormatError` if any fails)."""
        methods = cls._layout.methods
        stored = load_calibration(path, method=methods[0] if len(methods) == 1 else None)
        return cls.from_stored(stored, path)

    @classmethod
    def from_stored(cls, stored: StoredCalibration, path: str | Path) -> Self:
        """The calibration of a file already read by :func:`load_calibration`, its coefficients
        checked (``_check_fields``)."""
        methods = cls._layout.methods
        if stored.method not in methods:
            raise InvalidInputError(f"{path}: a {stored.method} calibration, not {methods[0]}")
        kw = cls._fields(stored, path)
        try:
            with np.errstate(all="ignore"):  # overflow to inf in a check: refused as not finite
                cls._check_fields(kw, stored, path)
        except FileFormatError:
            raise
        except Exception as exc:  # a check that met a value of the wrong kind
            raise damaged(path, stored.method, f"{type(exc).__name__}: {str(exc)[:100]}"
                          ) from None
        return cls(**kw)

    def _metadata(self) -> dict[str, Any]:
        """The ``metadata`` entries to write (JSON-serialisable)."""
        meta = {name: getattr(self, name) for name in self._layout.metadata}
        return meta | {"info": self.info}

    @classmethod
    def _check_stored(cls, stored: StoredCalibration, path: str | Path) -> None:
        """Further checks of a file, after its datasets and before its metadata are read."""

    @classmethod
    def _check_fields(cls, kw: dict[str, Any], stored: StoredCalibration,
                      path: str | Path) -> None:
        """The method's checks of its coefficients (the constructor's keyword arguments ``kw``),
        raising :class:`~thermocal.errors.FileFormatError` (:func:`damaged`); by default only
        that the arrays are finite and at most half of the pixels bad."""
        check_finite(kw, tuple(cls._layout.arrays_for(stored.method)), path, stored.method)
        if "bad" in kw:
            check_bad(kw["bad"], path, stored.method)

    @classmethod
    def _fields(cls, stored: StoredCalibration, path: str | Path) -> dict[str, Any]:
        """The constructor's keyword arguments from a file of one of the class's methods."""
        layout = cls._layout
        arrays = layout.arrays_for(stored.method)
        require_arrays(stored, tuple(arrays), path, layout.stacks)
        cls._check_stored(stored, path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # overflow to inf: refused later
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
        except (TypeError, ValueError, OverflowError) as exc:
            raise FileFormatError(
                f"{path}: unreadable {stored.method} calibration metadata ({str(exc)[:100]})"
            ) from None
        kw["fpa_range_c"] = stored.fpa_range_c
        if any(f.name == "method" for f in fields(cls)):  # type: ignore[arg-type]
            kw["method"] = stored.method
        return kw
