"""The calibration registry: every calibration method thermocal fits, by name.

``thermocal calibrate --method``'s choices and help, ``thermocal correct``'s help,
:func:`fit_calibration` and :func:`load_any_calibration` all read :data:`CALIBRATION_METHODS`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from thermocal.calibration.base import Calibration, ProtocolWarning, UnverifiedFileWarning
from thermocal.calibration.dataset import prepare_chamber
from thermocal.calibration.lin import RATE_LAGS_S, LinCalibration, lin, lin_lag, lin_level
from thermocal.calibration.polynomial import PolynomialCalibration, polynomial
from thermocal.calibration.protocol import ProtocolCheck, ProtocolNeeds, check_protocol
from thermocal.calibration.shutter import ShutterCalibration, shutter
from thermocal.calibration.store import load_calibration
from thermocal.calibration.two_point import TwoPointCalibration, one_point, two_point
from thermocal.calibration.wolf2016 import Wolf2016Calibration, wolf2016
from thermocal.errors import FileFormatError, FitError, InvalidInputError

__all__ = [
    "CALIBRATION_METHODS",
    "CalibrationInfo",
    "check_session",
    "fit_calibration",
    "load_any_calibration",
    "upgrade_calibration",
    "method_help",
]


@dataclass(frozen=True)
class CalibrationInfo:
    """One registered calibration method.

    Attributes
    ----------
    name : str
        Its ``--method`` name, also recorded in its calibration files.
    fit : callable
        ``fit(session, **options)`` → a fitted :class:`~thermocal.calibration.base.Calibration`
        (``session``: a chamber session, prepared data or a chamber file).
    loads : type
        The :class:`~thermocal.calibration.base.Calibration` class that reads its files.
    source : str
        The published method it implements.
    summary : str
        What it does, in a line.
    takes_fpa_ref : bool
        Whether ``fit`` takes a reference FPA temperature ``fpa_ref_c`` (``--fpa-ref-c``).
    needs : ProtocolNeeds
        What a chamber session must hold for its fit (checked by
        :func:`~thermocal.calibration.protocol.check_protocol`).
    auto : bool
        Whether ``--method auto`` tries it.
    auto_note : str
        Why ``--method auto`` does not (said by ``thermocal calibrate --method auto``).
    learns_online : bool
        Whether its ``apply`` learns as frames stream by (an online estimator that starts cold
        on every recording): its report then measures the error by time since the start.
    memoryless : bool
        Whether its model takes the camera to have no memory of how its FPA changed (a rate
        term, if any, sees the present rate only): optics that lag the FPA then make its error
        depend on the pace history, so it vouches only for the paces its session held (its
        report lists them; :meth:`~thermocal.calibration.uncertainty.CalibrationSigma.outside`).
    """

    name: str
    fit: Callable[..., Calibration]
    loads: type[Calibration]
    source: str
    summary: str
    takes_fpa_ref: bool = True
    needs: ProtocolNeeds = ProtocolNeeds("all", 2)
    auto: bool = True
    auto_note: str = ""
    learns_online: bool = False
    memoryless: bool = True


#: What the methods fitted at one reference FPA temperature need: two set points there.
_AT_REFERENCE = ProtocolNeeds("reference", 2)
#: Lin et al.: eq. 1 quadratic in the FPA temperature on stable frames, eq. 4 on >= 4 set points,
#: eq. 2 on frames with a changing FPA.
_LIN = ProtocolNeeds("stable", 4, fpa_span_c=2.0, fpa_levels=3, rate_term=True)


#: ``--method`` name → calibration method, in the order ``--help`` lists them.
CALIBRATION_METHODS: dict[str, CalibrationInfo] = {
    info.name: info
    for info in (
        CalibrationInfo("two-point", two_point, TwoPointCalibration, "Riou et al.",
                        "per-pixel gain and offset from two blackbody temperatures at one FPA "
                        "temperature", needs=_AT_REFERENCE),
        CalibrationInfo("one-point", one_point, TwoPointCalibration, "Schulz & Caldwell",
                        "one gain for the array, per-pixel offsets from one flat field",
                        needs=ProtocolNeeds("reference", 2, setpoints_option=("gain", 1))),
        # its offsets come from shutter closures when applied, which a chamber session has none
        # of: there it is two-point, so auto leaves it out
        CalibrationInfo("shutter", shutter, ShutterCalibration,
                        "Lin et al.'s baseline, FLIR GEV-style",
                        "two-point gains; offsets re-read on the shutter every few minutes",
                        needs=_AT_REFERENCE, auto=False,
                        auto_note="its offsets are re-read on the camera's shutter as it is "
                        "applied, which a chamber session never closes: fitted there it is "
                        "two-point (give --method shutter to fit it all the same)"),
        CalibrationInfo("polynomial", polynomial, PolynomialCalibration,
                        "Oz et al. eq. 13–15; Nugent et al. 2013",
                        "per-pixel gain and offset cubic in the FPA temperature",
                        takes_fpa_ref=False,
                        needs=ProtocolNeeds("stable", 2, fpa_span_c=4.0, fpa_levels=4,
                                            fallback=("settled", "all"))),
        CalibrationInfo("wolf2016", wolf2016, Wolf2016Calibration, "Wolf et al. 2016",
                        "per-pixel S0/S1/S2, Hammerstein–Wiener Ω, online LMS of the FPA "
                        "temperature change",
                        needs=ProtocolNeeds("reference", 2, fpa_span_c=1.0, fpa_levels=2,
                                            window_c=3.0, window_option="fpa_window_c",
                                            fpa_both_ways=True),
                        learns_online=True, memoryless=False),
        CalibrationInfo("lin", lin, LinCalibration, "Lin et al.",
                        "2nd-order FPA projection, 3rd-order FPA-rate correction, Planck "
                        "R/B/F/O fit", needs=_LIN),
        CalibrationInfo("lin-level", lin_level, LinCalibration,
                        "extension of Lin et al., not in the paper",
                        "lin whose projection follows the scene level", needs=_LIN),
        CalibrationInfo("lin-lag", lin_lag, LinCalibration,
                        "extension of Lin et al., not in the paper",
                        "lin-level whose rate term also sees the FPA rate through lags of "
                        f"{', '.join(f'{v:g}' for v in RATE_LAGS_S)} s (optics lagging the FPA)",
                        needs=_LIN, memoryless=False),
    )
}


def method_help() -> str:
    """The methods for ``--help``: one line each, name, summary and source (a click block)."""
    width = max(map(len, CALIBRATION_METHODS))
    lines = (f"{c.name:<{width}}  {c.summary} ({c.source})" for c in CALIBRATION_METHODS.values())
    return "Methods:\n\n\b\n" + "\n".join(lines)


def _info(method: str) -> CalibrationInfo:
    """The registered method ``method``; :class:`InvalidInputError` naming the others."""
    info = CALIBRATION_METHODS.get(method)
    if info is None:
        raise InvalidInputError(
            f"unknown calibration method {method!r}; choose from {', '.join(CALIBRATION_METHODS)}"
        )
    return info


def check_session(session: Any, method: str, **options: Any) -> ProtocolCheck:
    """Check a chamber session (a session, prepared data or a path) against the needs of the
    registered ``method`` (:func:`~thermocal.calibration.protocol.check_protocol`): its
    refusal, its warnings and the options to fit with."""
    smooth = {"rate_smooth_s": options["rate_smooth_s"]} if "rate_smooth_s" in options else {}
    return check_protocol(prepare_chamber(session, **smooth), method, _info(method).needs,
                          **options)


def fit_calibration(session: Any, method: str = "polynomial", *, check: bool = True,
                    **options: Any) -> Calibration:
    """Fit calibration ``method`` (a key of :data:`CALIBRATION_METHODS`) to a chamber session.

    ``session`` is a :class:`~thermocal.io.chamber.ChamberSession`, a prepared
    :class:`~thermocal.calibration.dataset.ChamberData`, or the path of a chamber ``.h5`` /
    EnvChamberCtrl ``.npz``; ``options`` go to the method's ``fit`` function.

    With ``check`` (the default) the session is first checked against the method's needs
    (:func:`check_session`): a session that cannot support the
    method raises :class:`~thermocal.errors.FitError` saying what to record, one that supports it
    in part warns (:class:`~thermocal.calibration.base.ProtocolWarning`) and may be fitted to a
    fallback frame selection (polynomial: the settled frames when the FPA never holds still).
    """
    info = _info(method)
    if not check:
        return info.fit(session, **options)
    smooth = {"rate_smooth_s": options["rate_smooth_s"]} if "rate_smooth_s" in options else {}
    data = prepare_chamber(session, **smooth)
    verdict = check_protocol(data, method, info.needs, **options)
    if not verdict.ok:
        raise FitError(verdict.refusal)
    for text in verdict.warnings:
        warnings.warn(text, ProtocolWarning, stacklevel=2)
    return info.fit(data, **verdict.options)


def load_any_calibration(path: str | Path) -> Calibration:
    """Read any calibration file, with the class of the method it records.

    The file is read once, and checked as the method's class checks it (``load``).

    Raises
    ------
    FileFormatError
        A missing, damaged or foreign file, or one of a method this thermocal does not know (a
        file made by a newer one?).
    """
    stored = load_calibration(path)
    if stored.method not in CALIBRATION_METHODS:
        raise FileFormatError(
            f"{path}: unknown calibration method {stored.method!r:.40} (made by a newer "
            "thermocal?)"
        )
    return CALIBRATION_METHODS[stored.method].loads.from_stored(stored, path)


def upgrade_calibration(path: str | Path, out: str | Path) -> Path:
    """Write the calibration file ``path`` (any version this thermocal reads, its coefficients
    checked) again as the current version, with its checksum, to ``out`` (atomically).

    Upgrading a version-1 file vouches for it: do it only for a file known to be intact."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnverifiedFileWarning)
        cal = load_any_calibration(path)
    return cal.save(out)
