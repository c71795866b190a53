"""Scene-based and single-frame nonuniformity correction (NUC) baselines, behind one registry.

``correct_nonuniformity(frames, method=NAME, **options)`` runs the method registered under
``NAME`` in :data:`NUC_METHODS` and returns float32 ``(N, H, W)`` corrected frames in counts-like
units. None of these methods is radiometric: compare their output with a temperature only after
an affine fit (:func:`thermocal.metrics.best_affine_fit`).

========================  ==========================================  ===========================
CLI name                  source                                      object / function
========================  ==========================================  ===========================
``harris1999``            Harris & Chiang 1999, constant statistics   :class:`Harris1999`
``scribner``              Scribner et al. 1991, retina-like LMS       :class:`Scribner`
``ecr``                   Pezoa et al. 2004, enhanced constant range  :class:`Pezoa2004`
``torres-kalman``         Torres & Hayat 2003, Kalman filter          :class:`TorresKalman`
``hardie2000``            Hardie et al. 2000, registration averaging  :func:`hardie2000`
``zuo2011``               Zuo et al. 2011, interframe-registr. LMS    :class:`Zuo2011`
``admire``                Tendero & Gilles 2012 (ADMIRE-style)        :func:`tendero2012`
========================  ==========================================  ===========================
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError
from thermocal.nuc.batch import hardie2000, tendero2012
from thermocal.nuc.streaming import (
    Harris1999,
    Pezoa2004,
    Scribner,
    StreamingNUC,
    TorresKalman,
    Zuo2011,
)

__all__ = [
    "NUC_METHODS",
    "STREAMING_METHODS",
    "Harris1999",
    "Pezoa2004",
    "Scribner",
    "StreamingNUC",
    "TorresKalman",
    "Zuo2011",
    "correct_nonuniformity",
    "hardie2000",
    "harris1999",
    "pezoa2004",
    "scribner",
    "tendero2012",
    "torres_kalman",
    "zuo2011",
]


def harris1999(frames: Any, **options: Any) -> np.ndarray:
    """Constant statistics (Harris & Chiang 1999) over ``(N, H, W)`` frames; see
    :class:`Harris1999` for the options. Returns float32 ``(N, H, W)``."""
    return Harris1999(**options).correct(frames)


def scribner(frames: Any, **options: Any) -> np.ndarray:
    """Retina-like LMS (Scribner et al. 1991); see :class:`Scribner`. float32 ``(N, H, W)``."""
    return Scribner(**options).correct(frames)


def pezoa2004(frames: Any, **options: Any) -> np.ndarray:
    """Enhanced constant range (Pezoa et al. 2004); see :class:`Pezoa2004`."""
    return Pezoa2004(**options).correct(frames)


def torres_kalman(frames: Any, **options: Any) -> np.ndarray:
    """Kalman-filter NUC (Torres & Hayat 2003); see :class:`TorresKalman`."""
    return TorresKalman(**options).correct(frames)


def zuo2011(frames: Any, *, homographies: Any = None, **options: Any) -> np.ndarray:
    """Interframe-registration LMS (Zuo et al. 2011); see :class:`Zuo2011`.

    ``homographies`` (N, 3, 3), frame → pivot, when known (else phase correlation per pair).
    """
    return Zuo2011(**options).correct(frames, homographies=homographies)


#: CLI name → function ``f(frames, **options) -> (N, H, W) float32``.
NUC_METHODS: dict[str, Callable[..., np.ndarray]] = {
    "harris1999": harris1999,
    "scribner": scribner,
    "ecr": pezoa2004,
    "torres-kalman": torres_kalman,
    "hardie2000": hardie2000,
    "zuo2011": zuo2011,
    "admire": tendero2012,
}

#: CLI name → streaming class (update/apply per frame), for the per-frame methods.
STREAMING_METHODS: dict[str, type[StreamingNUC]] = {
    "harris1999": Harris1999,
    "scribner": Scribner,
    "ecr": Pezoa2004,
    "torres-kalman": TorresKalman,
    "zuo2011": Zuo2011,
}


def correct_nonuniformity(frames: Any, *, method: str, **options: Any) -> np.ndarray:
    """Correct the nonuniformity of ``frames`` with the method registered as ``method``.

    Parameters
    ----------
    frames : array_like, shape (N, H, W)
        Raw frames (uint16 14-bit counts, or float); never modified. Multi-frame methods need
        N ≥ 2; ``admire`` also takes one ``(H, W)`` frame.
    method : str
        A key of :data:`NUC_METHODS`.
    **options
        Keyword options of that method.

    Returns
    -------
    numpy.ndarray, float32, shape (N, H, W)
        Corrected frames, counts-like units (not radiometric).

    Raises
    ------
    InvalidInputError
        Unknown method or option, too few frames, NaN, frames of mixed sizes.
    RegistrationError
        ``hardie2000`` without homographies, on frames that cannot be registered.
    """
    if method not in NUC_METHODS:
        raise InvalidInputError(
            f"unknown NUC method {method!r}; choose from {', '.join(NUC_METHODS)}"
        )
    try:
        return NUC_METHODS[method](frames, **options)
    except TypeError as exc:
        if "argument" in str(exc):
            raise InvalidInputError(f"NUC method {method!r}: {exc}") from None
        raise
