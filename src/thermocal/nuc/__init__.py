"""Scene-based and single-frame nonuniformity correction (NUC) baselines, behind one registry.

``correct_nonuniformity(frames, method=NAME, **options)`` runs the method registered under
``NAME`` in :data:`NUC_METHODS` (a :class:`NucInfo` each: its function, its streaming class,
its published source and a summary) and returns float32 ``(N, H, W)`` corrected frames in
counts-like units. None of these methods is radiometric: compare their output with a temperature
only after an affine fit (:func:`thermocal.metrics.best_affine_fit`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError
from thermocal.nuc.batch import hardie2000, tendero2012
from thermocal.nuc.registry import NUC_METHODS, NucInfo
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

__all__ = [
    "NUC_METHODS",
    "Harris1999",
    "NucInfo",
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
        return NUC_METHODS[method].correct(frames, **options)
    except TypeError as exc:
        if "argument" in str(exc):
            raise InvalidInputError(f"NUC method {method!r}: {exc}") from None
        raise
