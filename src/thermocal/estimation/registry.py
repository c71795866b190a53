"""The estimator registry: every way thermocal turns a burst into a temperature, by name.

The CLI's ``--method`` choices and help come from :data:`ESTIMATORS` (and a test checks that
README.md names each); :func:`make_estimator` builds one (importing torch only for a network).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from thermocal.calibration.base import Calibration
from thermocal.errors import InvalidInputError
from thermocal.estimation.base import Estimator
from thermocal.nn.variants import VARIANTS

__all__ = ["ESTIMATORS", "EstimatorInfo", "make_estimator", "method_help"]


@dataclass(frozen=True)
class EstimatorInfo:
    """One registered estimator.

    Attributes
    ----------
    name : str
        Its ``--method`` name.
    needs : {"model", "calibration", "recording", "pass"}
        A network's weights file (the shipped one by default), a calibration file, the
        recording's own constants (a FLIR file's Planck constants), or a whole pass to fit on
        (a flight-level estimator: the camera family's average unit or a calibration to start
        from).
    source : str
        The published method it implements.
    summary : str
        What it does, in a line.
    per_frame : bool
        It estimates from the pivot frame alone (no registration).
    """

    name: str
    needs: str
    source: str
    summary: str
    per_frame: bool = False


#: ``--method`` name → estimator; the network variants first (the default is ``kpn``).
ESTIMATORS: dict[str, EstimatorInfo] = {
    **{name: EstimatorInfo(name, "model", "Oz et al. (KPN, §IV; ablations §V-C)", v.summary)
       for name, v in VARIANTS.items()},
    "mean": EstimatorInfo("mean", "calibration", "Oz et al. eq. 9",
                          "registered average of the frames through a per-pixel calibration"),
    "calibration": EstimatorInfo("calibration", "calibration", "the calibration's own method",
                                 "the pivot frame alone through a per-pixel calibration",
                                 per_frame=True),
    "camera": EstimatorInfo("camera", "recording", "FLIR's radiometric formula",
                            "the pivot frame through the camera's own calibration in the file "
                            "(FLIR R-JPEG, FFF, SEQ, CSQ)", per_frame=True),
    "selfcal": EstimatorInfo("selfcal", "pass", "Hardie et al. 2000, over a whole pass",
                             "flight-level self-calibration: the unit's fixed pattern fitted over "
                             "the whole pass from the family's average unit (or --calibration), "
                             "then eq. 9's mean of the corrected frames (thermocal flight only)"),
}


def method_help() -> str:
    """One line per estimator, for ``--help``."""
    return "; ".join(f"{e.name}: {e.summary}" for e in ESTIMATORS.values())


def make_estimator(
    name: str,
    *,
    model: str | os.PathLike[str] | None = None,
    calibration: str | os.PathLike[str] | Calibration | None = None,
    family: str = "tau2",
    backend: str = "torch",
    threads: int | None = None,
    concurrent: int = 1,
) -> Estimator:
    """Build the estimator ``name`` of :data:`ESTIMATORS`.

    ``model`` is a weights file for a network (default: the shipped one of that variant);
    ``calibration`` a calibration file (or a fitted calibration) for ``mean`` and
    ``calibration``; ``selfcal`` starts from that calibration when given, else from the camera
    ``family``'s average unit, and is fitted on a pass by the flight. ``camera`` is made from
    the recording it runs on, once read (:class:`~thermocal.estimation.vendor.VendorCalibration`),
    not here. ``backend`` and ``threads``: what runs a network, on how many threads
    (:func:`thermocal.nn.runners.make_runner`), refused for the other methods; ``concurrent``:
    how many threads may run a network at once (every estimator may be called from several
    threads at once).

    Raises
    ------
    InvalidInputError
        Unknown name, a missing calibration, or weights of another variant.
    FileFormatError
        A weights or calibration file that cannot be read.
    """
    info = ESTIMATORS.get(name)
    if info is None:
        raise InvalidInputError(f"unknown method {name!r}; choose from {', '.join(ESTIMATORS)}")
    check_method_options(name, backend=backend, threads=threads, calibration=calibration,
                         model=model, family=family)
    if info.needs == "recording":
        raise InvalidInputError(
            f"--method {name} is made from the recording's own constants once it is read: "
            "VendorCalibration.from_recording (thermocal estimate and flight do so)"
        )
    if info.needs == "pass":
        from thermocal.estimation.selfcal import SelfCalibration

        return SelfCalibration(_calibration(calibration), family=family,
                               report_needed=isinstance(calibration, (str, os.PathLike)))
    if info.needs == "calibration":
        if calibration is None:
            raise InvalidInputError(
                f"--method {name} needs a per-pixel calibration: give --calibration CAL.h5"
            )
        from thermocal.estimation.calibrated import OzMean, PivotCalibration

        # a file must carry its report (what it was fitted on); a fit in hand is the caller's
        checked = isinstance(calibration, (str, os.PathLike))
        kind = OzMean if name == "mean" else PivotCalibration
        return kind(_calibration(calibration), report_needed=checked)
    from thermocal.optional import require

    require("torch", f"--method {name} (a network)", "nn")
    from thermocal.nn.infer import NetworkEstimator  # torch: only for a network

    return NetworkEstimator.from_file(name, model, backend=backend, threads=threads,
                                      concurrent=concurrent)


def check_method_options(name: str, *, backend: str = "torch", threads: int | None = None,
                         calibration: Any = None, model: Any = None,
                         family: str = "tau2", fpa_c: float | None = None,
                         force: bool = False) -> None:
    """Refuse an option that ``--method name`` would ignore (the user would believe it used):
    ``--backend`` or ``--threads`` or ``--model`` for a method that runs no network,
    ``--calibration`` for one that takes none, ``--family`` (other than the default) for one
    that does not start from a family's average unit or is given a calibration to start from,
    ``--fpa-c`` for the camera's own constants (they convert counts without the FPA);
    ``--threads`` beyond
    :data:`~thermocal.cores.MAX_PER_CORE` per core."""
    needs = ESTIMATORS[name].needs
    if threads is not None:
        from thermocal.cores import check_per_core

        check_per_core(threads, "--threads")
    if needs == "recording" and fpa_c is not None:
        raise InvalidInputError(
            f"--method {name} converts counts with the file's own constants, which take no FPA "
            "temperature: leave --fpa-c out")
    if needs != "model" and (backend != "torch" or threads is not None):
        raise InvalidInputError(
            f"--backend and --threads choose how a network runs; --method {name} runs none")
    if model is not None and needs != "model":
        raise InvalidInputError(f"--model is a network's weights; --method {name} runs none")
    if calibration is not None and needs not in ("calibration", "pass"):
        takes = "|".join(n for n, e in ESTIMATORS.items() if e.needs in ("calibration", "pass"))
        raise InvalidInputError(
            f"--calibration is for --method {takes}; --method {name} does not use one")
    if family != "tau2" and needs != "pass":
        raise InvalidInputError(
            f"--family chooses the average unit --method selfcal starts from; --method {name} "
            "does not use one")
    if family != "tau2" and calibration is not None:
        raise InvalidInputError(
            "--family chooses the average unit selfcal starts from without a calibration; "
            "with --calibration it starts from that: leave --family out")


def _calibration(calibration: str | os.PathLike[str] | Calibration | None) -> Calibration | None:
    """A calibration file loaded (a fitted calibration as it is)."""
    if isinstance(calibration, (str, os.PathLike)):
        from thermocal.calibration import load_any_calibration

        return load_any_calibration(calibration)
    return calibration
