"""The NUC registry: every nonuniformity correction thermocal has, by name.

``thermocal nuc --method``'s choices and help and
:func:`~thermocal.nuc.correct_nonuniformity` read :data:`NUC_METHODS`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from thermocal.nuc.batch import hardie2000, tendero2012
from thermocal.nuc.deepir import deepir
from thermocal.nuc.streaming import (
    Harris1999,
    Pezoa2004,
    Scribner,
    StreamingNUC,
    TorresKalman,
    Zuo2011,
    harris1999,
    pezoa2004,
    scribner,
    torres_kalman,
    zuo2011,
)

__all__ = ["NUC_METHODS", "NucInfo", "method_help"]


def _he2018(frames: np.ndarray, **options: object) -> np.ndarray:
    """:func:`thermocal.nuc.he2018.he2018`, imported when first called: importing the
    package then leaves that module unloaded, so ``python -m thermocal.nuc.he2018`` (its
    training command) runs it once, without runpy's warning of a module loaded twice."""
    from thermocal.nuc.he2018 import he2018

    return he2018(frames, **options)  # type: ignore[arg-type]


@dataclass(frozen=True)
class NucInfo:
    """One registered NUC method.

    Attributes
    ----------
    name : str
        Its ``--method`` name.
    correct : callable
        ``correct(frames, **options)`` → float32 ``(N, H, W)``, counts-like (not radiometric),
        of raw frames ``(N, H, W)``.
    streaming : type or None
        The class that corrects frame by frame (a
        :class:`~thermocal.calibration.base.StreamingCorrector`; ``correct`` runs a fresh one
        over the stack); None for a method of a whole burst or of one frame.
    source : str
        The published method it implements.
    summary : str
        What it does, in a line.
    """

    name: str
    correct: Callable[..., np.ndarray]
    streaming: type[StreamingNUC] | None
    source: str
    summary: str


#: ``--method`` name → NUC method, in the order ``--help`` lists them.
NUC_METHODS: dict[str, NucInfo] = {
    info.name: info
    for info in (
        NucInfo("harris1999", harris1999, Harris1999, "Harris & Chiang 1999",
                "constant statistics"),
        NucInfo("scribner", scribner, Scribner, "Scribner et al. 1991", "retina-like LMS"),
        NucInfo("ecr", pezoa2004, Pezoa2004, "Pezoa et al. 2004", "enhanced constant range"),
        NucInfo("torres-kalman", torres_kalman, TorresKalman, "Torres & Hayat 2003",
                "Kalman filter on drifting gains and offsets"),
        NucInfo("hardie2000", hardie2000, None, "Hardie et al. 2000",
                "registration averaging"),
        NucInfo("zuo2011", zuo2011, Zuo2011, "Zuo et al. 2011", "interframe-registration LMS"),
        NucInfo("admire", tendero2012, None, "after ADMIRE, Tendero & Gilles 2012",
                "one frame at a time: column equalisation, DCT denoising"),
        NucInfo("deepir", deepir, None, "Saragadam et al. 2021 (DeepIR)",
                "burst: untrained-network scene prior, joint gain/offset/motion fit"),
        NucInfo("he2018", _he2018, None, "He et al. 2018 (single-image CNN)",
                "one frame at a time: a residual CNN estimates and subtracts the FPN"),
    )
}


def method_help() -> str:
    """The methods for ``--help``: one line each, name, summary and source (a click block)."""
    width = max(map(len, NUC_METHODS))
    lines = (f"{m.name:<{width}}  {m.summary} ({m.source})" for m in NUC_METHODS.values())
    return "Methods:\n\n\b\n" + "\n".join(lines)
