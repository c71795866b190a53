"""Import a chamber session saved by EnvChamberCtrl (an ``.npz`` of ``np.savez``).

EnvChamberCtrl stores temperatures in 1/100 °C and time stamps in ns;
:func:`import_envchamberctrl_npz` converts them to a :class:`~thermocal.io.chamber.ChamberSession`
(°C, s), checking that the unit is plausible.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import FPA_RANGE_C
from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.io.chamber import ChamberSession

__all__ = ["import_envchamberctrl_npz"]


#: Plausible housing temperatures, °C: outside, the 1/100 °C unit is probably wrong (FPA
#: temperatures: :data:`thermocal._validate.FPA_RANGE_C`).
_CAMERA_RANGE_C = (-60.0, 150.0)


#: What numpy and zipfile raise on a damaged .npz: many types (OSError, ValueError, BadZipFile,
#: EOFError; a bad .npy header's tokenizer TokenError or SyntaxError; NotImplementedError for
#: an unknown zip version; MemoryError for a huge declared shape). Nothing else runs inside.
_NPZ_ERRORS = (Exception,)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:120] or type(exc).__name__


def _centi_c(values: Any, key: str, path: Path) -> np.ndarray:
    """Convert an EnvChamberCtrl temperature in 1/100 °C to °C (float64)."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "iuf" or arr.ndim != 1:
        raise FileFormatError(
            f"{path}: {key!r} must be a 1-D array of temperatures in 1/100 °C, "
            f"got {arr.dtype} {arr.shape}"
        )
    if arr.dtype == np.uint16 and arr.size and int(arr.max()) > 32767:
        # EnvChamberCtrl saves with astype('uint16'): negative temperatures wrap around
        arr = arr.view(np.int16)
    return arr.astype(np.float64) / 100.0


def import_envchamberctrl_npz(
    path: str | os.PathLike[str], *, frame_rate_hz: float | None = None
) -> ChamberSession:
    """Import a chamber session saved by EnvChamberCtrl (``np.savez``) as a ChamberSession.

    The ``.npz`` holds ``frames`` (uint16 ``(M, H, W)``), ``fpa``, ``housing`` and ``blackbody``
    (temperatures in 1/100 °C, so 2534 means 25.34 °C) and ``time_ns`` (time stamps in ns, e.g.
    from :func:`time.time_ns`). ``housing`` is optional.

    Conversions: temperatures ``°C = value / 100`` (uint16 values above 32767 are read as the
    negative int16 they wrapped from); ``time_s = (time_ns - time_ns[0]) / 1e9``, computed in
    integers so that epoch time stamps keep their precision, with ``time_ns[0]`` kept in
    ``attrs["time_origin_ns"]``. The session has no ambient series.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.npz`` file.
    frame_rate_hz : float or None, optional
        Frame rate, Hz, used to make ``time_s = arange(M) / frame_rate_hz`` for files saved
        without ``time_ns`` (older EnvChamberCtrl scripts). Ignored when ``time_ns`` exists.

    Returns
    -------
    ChamberSession
        With ``attrs`` ``source="EnvChamberCtrl"``, ``source_file`` and ``bit_depth=14``.

    Raises
    ------
    FileFormatError
        If the file is not an ``.npz``, lacks a required array, has arrays of different lengths,
        counts above 14 bits, or FPA temperatures outside −60…120 °C or housing temperatures
        outside −60…150 °C after conversion (a sign the unit is not 1/100 °C).
    InvalidInputError
        If ``frame_rate_hz`` is not positive and finite.
    """
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"{p}: no such file")
    if frame_rate_hz is not None:
        rate = float(frame_rate_hz)
        if not np.isfinite(rate) or rate <= 0:
            raise InvalidInputError(f"frame_rate_hz: must be positive, got {frame_rate_hz!r}")
    try:
        npz = np.load(p, allow_pickle=False)
    except _NPZ_ERRORS as exc:
        raise FileFormatError(f"{p}: not a readable .npz file ({_one_line(exc)})") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise FileFormatError(f"{p}: a single .npy array, expected an EnvChamberCtrl .npz")
    with npz:
        missing = [k for k in ("frames", "fpa", "blackbody") if k not in npz.files]
        if "time_ns" not in npz.files and frame_rate_hz is None:
            missing.append("time_ns")
        if missing:
            raise FileFormatError(
                f"{p}: missing array(s) {missing} (has {sorted(npz.files)}); "
                + (
                    "pass frame_rate_hz for files without time_ns"
                    if missing == ["time_ns"]
                    else "not an EnvChamberCtrl session?"
                )
            )
        try:
            frames = npz["frames"]
            fpa_c = _centi_c(npz["fpa"], "fpa", p)
            blackbody_c = _centi_c(npz["blackbody"], "blackbody", p)
            housing_c = _centi_c(npz["housing"], "housing", p) if "housing" in npz.files else None
            time_ns = npz["time_ns"] if "time_ns" in npz.files else None
        except _NPZ_ERRORS as exc:
            raise FileFormatError(f"{p}: an array cannot be read ({_one_line(exc)})") from None
    m = len(frames) if frames.ndim == 3 else 1
    attrs: dict[str, Any] = {"source": "EnvChamberCtrl", "source_file": p.name, "bit_depth": 14}
    if time_ns is not None:
        t = np.asarray(time_ns)
        if t.ndim != 1 or t.dtype.kind not in "iu" or t.size == 0:
            raise FileFormatError(f"{p}: 'time_ns' must be 1-D integers, got {t.dtype} {t.shape}")
        t = t.astype(np.int64)
        attrs["time_origin_ns"] = int(t[0])
        time_s = (t - t[0]).astype(np.float64) / 1e9
    else:
        time_s = np.arange(m, dtype=np.float64) / float(frame_rate_hz)  # type: ignore[arg-type]
        attrs["frame_rate_hz"] = float(frame_rate_hz)  # type: ignore[arg-type]
    for key, values, (lo, hi) in (("fpa", fpa_c, FPA_RANGE_C),
                                  ("housing", housing_c, _CAMERA_RANGE_C)):
        if values is not None and values.size and (values.min() < lo or values.max() > hi):
            raise FileFormatError(
                f"{p}: {key!r} gives {values.min():.2f}..{values.max():.2f} °C after dividing "
                f"by 100; expected 1/100 °C values of a camera ({lo:g}..{hi:g} °C)"
            )
    try:
        return ChamberSession(
            frames,
            blackbody_c=blackbody_c,
            fpa_c=fpa_c,
            time_s=time_s,
            housing_c=housing_c,
            attrs=attrs,
        )
    except InvalidInputError as exc:
        raise FileFormatError(f"{p}: {exc}") from None
