"""Estimation: a burst of raw frames → the pivot frame's temperature, one pipeline for every
method.

============== ==============================================================================
``base``       the :class:`Estimator` protocol, :class:`PreparedBurst`, :class:`Estimate`
``pipeline``   the stages: validate → register → fill stuck pixels → calibrate → warp →
               estimate
``registry``   :data:`ESTIMATORS` (every ``--method``) and :func:`make_estimator`
``calibrated`` estimators from a per-pixel calibration: eq. 9's mean, the pivot frame alone
``commands``   ``thermocal estimate``
============== ==============================================================================

The network estimator lives in :mod:`thermocal.nn.infer` (it imports torch) and is built by
:func:`make_estimator` only when asked for.
"""

from thermocal.estimation.base import Estimate, Estimator, PreparedBurst
from thermocal.estimation.pipeline import estimate
from thermocal.estimation.registry import ESTIMATORS, EstimatorInfo, make_estimator

__all__ = [
    "ESTIMATORS",
    "Estimate",
    "Estimator",
    "EstimatorInfo",
    "PreparedBurst",
    "estimate",
    "make_estimator",
]
