"""Radiometric calibration from chamber data, and the per-frame methods that apply it.

One registry, :data:`CALIBRATION_METHODS` (CLI name → :class:`CalibrationInfo`: its fitting
function, the class that loads its files, its source and summary), one dispatcher
:func:`fit_calibration`, one file layout (:mod:`thermocal.calibration.store`) read back by
:func:`load_any_calibration`. Every fitted calibration is a :class:`Calibration`: a frozen
dataclass with ``apply(frames, *, fpa_c=None, time_s=None)`` → float32 °C ``(N, H, W)`` (the
scene's blackbody-equivalent temperature) and ``save(path)``/``load(path)``. Each method states
what a chamber session must hold for it (:mod:`thermocal.calibration.protocol`); a fit is
cross-validated on its session by :mod:`thermocal.calibration.report`.
"""

from __future__ import annotations

from thermocal.calibration.base import (
    Calibration,
    OutsideCalibrationRangeWarning,
    ProtocolWarning,
    StreamingCorrector,
    ThermocalWarning,
    UnverifiedFileWarning,
)
from thermocal.calibration.dataset import (
    ChamberData,
    classify_stability,
    fpa_rate_c_per_min,
    prepare_chamber,
)
from thermocal.calibration.lin import LinCalibration, fit_planck_curve, lin, lin_lag, lin_level
from thermocal.calibration.polynomial import (
    PolynomialCalibration,
    camera_model_from_chamber,
    polynomial,
)
from thermocal.calibration.protocol import ProtocolCheck, ProtocolNeeds
from thermocal.calibration.registry import (
    CALIBRATION_METHODS,
    CalibrationInfo,
    check_session,
    fit_calibration,
    load_any_calibration,
    upgrade_calibration,
)
from thermocal.calibration.report import (
    CalibrationReport,
    auto_calibration,
    cross_validate,
    fit_with_report,
    report_of,
)
from thermocal.calibration.shutter import ShutterCalibration, shutter
from thermocal.calibration.two_point import (
    TwoPointCalibration,
    fit_two_point,
    one_point,
    two_point,
)
from thermocal.calibration.wolf2016 import Wolf2016Calibration, Wolf2016Stream, wolf2016

__all__ = [
    "CALIBRATION_METHODS",
    "Calibration",
    "CalibrationInfo",
    "CalibrationReport",
    "ChamberData",
    "LinCalibration",
    "OutsideCalibrationRangeWarning",
    "PolynomialCalibration",
    "ProtocolCheck",
    "ProtocolNeeds",
    "ProtocolWarning",
    "ShutterCalibration",
    "StreamingCorrector",
    "ThermocalWarning",
    "UnverifiedFileWarning",
    "TwoPointCalibration",
    "Wolf2016Calibration",
    "Wolf2016Stream",
    "auto_calibration",
    "camera_model_from_chamber",
    "check_session",
    "classify_stability",
    "cross_validate",
    "fit_calibration",
    "fit_planck_curve",
    "fit_with_report",
    "fit_two_point",
    "fpa_rate_c_per_min",
    "lin",
    "lin_lag",
    "lin_level",
    "load_any_calibration",
    "one_point",
    "polynomial",
    "prepare_chamber",
    "report_of",
    "shutter",
    "two_point",
    "upgrade_calibration",
    "wolf2016",
]
