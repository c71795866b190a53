"""Radiometric calibration from chamber data, and the per-frame methods that apply it.

One registry, :data:`CALIBRATION_METHODS` (CLI name → fitting function), one dispatcher
:func:`fit_calibration`, one file layout (:mod:`thermocal.calibration.store`) read back by
:func:`load_any_calibration`. Every fitted calibration is a frozen dataclass with
``apply(frames, *, fpa_c=None, time_s=None)`` → float32 °C ``(N, H, W)`` (the scene's
blackbody-equivalent temperature) and ``save(path)``/``load(path)``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from thermocal.calibration.base import OutsideCalibrationRangeWarning, ThermocalWarning
from thermocal.calibration.dataset import (
    ChamberData,
    classify_stability,
    fpa_rate_c_per_min,
    prepare_chamber,
)
from thermocal.calibration.lin import LinCalibration, fit_planck_curve, lin, lin_level
from thermocal.calibration.polynomial import (
    PolynomialCalibration,
    camera_model_from_chamber,
    polynomial,
)
from thermocal.calibration.shutter import ShutterCalibration, shutter
from thermocal.calibration.store import load_calibration
from thermocal.calibration.two_point import (
    TwoPointCalibration,
    fit_two_point,
    one_point,
    two_point,
)
from thermocal.calibration.wolf2016 import Wolf2016Calibration, Wolf2016Stream, wolf2016
from thermocal.errors import InvalidInputError

#: CLI name → function fitting that method to a chamber session (or file).
CALIBRATION_METHODS: dict[str, Callable[..., Any]] = {
    "two-point": two_point,
    "one-point": one_point,
    "shutter": shutter,
    "polynomial": polynomial,
    "wolf2016": wolf2016,
    "lin": lin,
    "lin-level": lin_level,  # an extension of lin, not in the paper (see calibration.lin)
}

#: method name stored in a calibration file → class that loads it.
CALIBRATION_CLASSES: dict[str, type] = {
    "two-point": TwoPointCalibration,
    "one-point": TwoPointCalibration,
    "shutter": ShutterCalibration,
    "polynomial": PolynomialCalibration,
    "wolf2016": Wolf2016Calibration,
    "lin": LinCalibration,
    "lin-level": LinCalibration,
}


def fit_calibration(session: Any, method: str = "polynomial", **options: Any) -> Any:
    """Fit calibration ``method`` (a key of :data:`CALIBRATION_METHODS`) to a chamber session.

    ``session`` is a :class:`~thermocal.io.chamber.ChamberSession`, a prepared
    :class:`ChamberData`, or the path of a chamber ``.h5`` / EnvChamberCtrl ``.npz``;
    ``options`` go to the method's function.
    """
    if method not in CALIBRATION_METHODS:
        raise InvalidInputError(
            f"unknown calibration method {method!r}; choose from {', '.join(CALIBRATION_METHODS)}"
        )
    return CALIBRATION_METHODS[method](session, **options)


def load_any_calibration(path: str | Path) -> Any:
    """Read any calibration file, dispatching on the method it records."""
    stored = load_calibration(path)
    cls = CALIBRATION_CLASSES.get(stored.method)
    if cls is None:
        raise InvalidInputError(
            f"{path}: unknown calibration method {stored.method!r} (made by a newer thermocal?)"
        )
    return cls.load(path)  # type: ignore[attr-defined]


__all__ = [
    "CALIBRATION_CLASSES",
    "CALIBRATION_METHODS",
    "ChamberData",
    "LinCalibration",
    "OutsideCalibrationRangeWarning",
    "PolynomialCalibration",
    "ShutterCalibration",
    "ThermocalWarning",
    "TwoPointCalibration",
    "Wolf2016Calibration",
    "Wolf2016Stream",
    "camera_model_from_chamber",
    "classify_stability",
    "fit_calibration",
    "fit_planck_curve",
    "fit_two_point",
    "fpa_rate_c_per_min",
    "lin",
    "lin_level",
    "load_any_calibration",
    "one_point",
    "polynomial",
    "prepare_chamber",
    "shutter",
    "two_point",
    "wolf2016",
]
